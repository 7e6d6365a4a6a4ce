"""Name -> implementation registries for arms, problem kinds and solver backends.

Later modules extend them with ``@ARMS.register("name")`` etc.; an unknown name
raises :class:`optikin.errors.UnknownNameError` listing the known ones.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Generic, TypeVar

from optikin.errors import UnknownNameError

if TYPE_CHECKING:
    from optikin.problems import ProblemKind
    from optikin.solvers import Backend

T = TypeVar("T")


class Registry(Generic[T]):
    """A named collection of implementations of one kind of thing."""

    def __init__(self, what: str) -> None:
        self.what = what
        self._items: dict[str, T] = {}

    def register(self, name: str) -> Callable[[T], T]:
        """Decorator that registers its argument under ``name`` (twice is a ``ValueError``)."""

        def add(item: T) -> T:
            if name in self._items:
                raise ValueError(f"{self.what} {name!r} is registered twice")
            self._items[name] = item
            return item

        return add

    def get(self, name: str) -> T:
        """The implementation registered as ``name``; :class:`~optikin.errors.UnknownNameError` if none."""
        if name not in self._items:
            raise UnknownNameError(self.what, name, list(self._items))
        return self._items[name]

    def names(self) -> list[str]:
        """The registered names, sorted."""
        return sorted(self._items)

    def __contains__(self, name: str) -> bool:
        return name in self._items


ARMS: Registry[Callable[..., object]] = Registry("arm")
PROBLEM_KINDS: Registry[ProblemKind] = Registry("problem kind")
BACKENDS: Registry[Backend] = Registry("solver backend")
