"""Name -> implementation registries for arms, problem kinds, solver backends and data sources.

optikin's own modules extend them with ``@ARMS.register("name")`` etc.; an unknown name
raises :class:`optikin.errors.UnknownNameError` listing the known ones.

Plugins: another installed package adds its own arm, kind, backend or data source, without
editing optikin, by declaring an entry point in its ``pyproject.toml``::

    [project.entry-points."optikin.arms"]
    routed_tendon = "my_lab.arm:RoutedTendonArm"      # name = the object registered under it

The groups are :data:`PLUGIN_GROUPS`. An entry point is loaded when its name is first asked for
(``arm: {type: routed_tendon}``) or when the names are listed (``optikin list --kinds``); what it
loads is registered under the entry point's name (unless importing it registered it already) and
validated like a shipped one (an arm must be an :class:`~optikin.arms.base.ArmModel` subclass, a
kind a :class:`~optikin.problems.ProblemKind`, a backend a :class:`~optikin.solvers.Backend`, a source
a :class:`~optikin.data.sources.DataSource`). A plugin that cannot be imported, or loads the wrong
thing, is a :class:`PluginError` naming the entry point and its distribution.
"""

from __future__ import annotations

from functools import lru_cache
from importlib import metadata
from typing import TYPE_CHECKING, Callable, Generic, TypeVar, cast

from optikin.errors import OptikinError, UnknownNameError

if TYPE_CHECKING:
    from optikin.problems import ProblemKind
    from optikin.solvers import Backend

__all__ = ["ARMS", "BACKENDS", "PLUGIN_GROUPS", "PROBLEM_KINDS", "PluginError", "Registry", "plugin_entry_points"]

T = TypeVar("T")

PLUGIN_GROUPS = {
    "arm": "optikin.arms",
    "problem kind": "optikin.kinds",
    "solver backend": "optikin.backends",
    "source": "optikin.sources",
}
"""Entry-point group of each registry (by what it holds); every data-source family shares ``optikin.sources``."""


class PluginError(OptikinError):
    """An installed plugin (an entry point of :data:`PLUGIN_GROUPS`) cannot be loaded or loads the wrong thing."""

    def __init__(self, entry: metadata.EntryPoint, message: str) -> None:
        dist = entry.dist
        owner = f"{dist.name} {dist.version}" if dist is not None else "an unknown distribution"
        super().__init__(f"plugin {entry.name!r} ({entry.group} = {entry.value!r}, from {owner}): {message}")


@lru_cache(maxsize=None)
def plugin_entry_points(group: str) -> tuple[metadata.EntryPoint, ...]:
    """The installed entry points of ``group``, by name (the first distribution of a name wins); read
    once per process (``plugin_entry_points.cache_clear()`` after installing a plugin in it)."""
    seen: dict[str, metadata.EntryPoint] = {}
    for entry in metadata.entry_points(group=group):
        seen.setdefault(entry.name, entry)
    return tuple(seen[name] for name in sorted(seen))


class Registry(Generic[T]):
    """A named collection of implementations of one kind of thing, extensible by plugins.

    Parameters
    ----------
    what:
        What it holds, for messages (``"arm"``); its plugin group is ``PLUGIN_GROUPS`` of the last word
        (``"constant_curvature source"`` -> ``optikin.sources``).
    check:
        Validates a plugin's object: returns None when it is acceptable, else the reason it is not.
    """

    def __init__(self, what: str, check: Callable[[object], str | None] | None = None) -> None:
        self.what = what
        self.group = PLUGIN_GROUPS.get(what) or PLUGIN_GROUPS.get(what.rsplit(" ", 1)[-1])
        self._check = check
        self._items: dict[str, T] = {}
        self._tried: set[str] = set()

    def register(self, name: str) -> Callable[[T], T]:
        """Decorator that registers its argument under ``name`` (twice is a ``ValueError``)."""

        def add(item: T) -> T:
            if name in self._items:
                raise ValueError(f"{self.what} {name!r} is registered twice")
            self._items[name] = item
            return item

        return add

    def get(self, name: str) -> T:
        """The implementation registered as ``name`` (a plugin's, loaded now if need be);
        :class:`~optikin.errors.UnknownNameError` if none."""
        if name not in self._items:
            self._load_plugins(name)
        if name not in self._items:
            raise UnknownNameError(self.what, name, list(self._items))
        return self._items[name]

    def names(self) -> list[str]:
        """The registered names, every installed plugin's included, sorted."""
        self._load_plugins()
        return sorted(self._items)

    def __contains__(self, name: str) -> bool:
        return name in self._items

    def _load_plugins(self, name: str | None = None) -> None:
        """Load the plugins of this registry's group named ``name`` (all when None) not yet tried."""
        if self.group is None:
            return
        for entry in plugin_entry_points(self.group):
            if entry.name in self._tried or (name is not None and entry.name != name):
                continue
            self._tried.add(entry.name)
            if self.group == PLUGIN_GROUPS["source"]:
                self._load_source(entry)
                continue
            if entry.name in self._items:
                continue  # a shipped name is never replaced by a plugin
            item = _load(entry)
            reason = self._check(item) if self._check is not None else None
            if reason is not None:
                raise PluginError(entry, reason)
            if entry.name not in self._items:
                self.register(entry.name)(cast(T, item))

    def _load_source(self, entry: metadata.EntryPoint) -> None:
        """A data-source plugin registers itself in its own family's registry (``register_source``)."""
        from optikin.data.sources import DATA_SOURCES, DataSource

        item = _load(entry)
        if not isinstance(item, DataSource):
            raise PluginError(entry, f"loads {type(item).__name__}, not an optikin.data.sources.DataSource")
        registry = DATA_SOURCES.setdefault(item.family, Registry(f"{item.family} source"))
        if item.name not in registry:
            registry.register(item.name)(item)


def _load(entry: metadata.EntryPoint) -> object:
    try:
        return entry.load()
    except Exception as error:
        raise PluginError(entry, f"cannot be imported: {type(error).__name__}: {error}") from None


def _is_arm(item: object) -> str | None:
    from optikin.arms.base import ArmModel

    return None if isinstance(item, type) and issubclass(item, ArmModel) else "not a subclass of ArmModel"


def _is_kind(item: object) -> str | None:
    from optikin.problems import ProblemKind

    return None if isinstance(item, ProblemKind) else "not an optikin.problems.ProblemKind"


def _is_backend(item: object) -> str | None:
    from optikin.solvers import Backend

    return None if isinstance(item, Backend) else "not an optikin.solvers.Backend"


ARMS: Registry[Callable[..., object]] = Registry("arm", _is_arm)
PROBLEM_KINDS: Registry[ProblemKind] = Registry("problem kind", _is_kind)
BACKENDS: Registry[Backend] = Registry("solver backend", _is_backend)
