"""One registry of data sources per data family, so ``data.source`` is resolved one way everywhere.

A problem kind reads its samples from one *family* of sources (``configurations``
for ``fk``, ``targets`` for ``ik``, ``markers`` for the PH kinds, ...). Each source
registers under its ``data.source`` name with a params model (an
:class:`~optikin.options.Options`, validated against ``data.params`` by the runner
before the run) and a loader::

    @register_source("configurations", "random", "uniform draws inside the arm's bounds")
    def random_configurations(arm, data, params, path): ...

A loader is called as ``load(arm, data, params, path)``: the arm model, the
file's ``data`` section (:class:`~optikin.spec.DataSpec`: seed, samples), the
validated params, and the problem file's path (relative file names in params
are resolved against its folder). What it returns is the family's own type.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from optikin.errors import SpecError, UnknownNameError
from optikin.options import NoOptions, Options
from optikin.registry import Registry

Loader = Callable[..., Any]


@dataclass(frozen=True)
class DataSource:
    """A registered source: its family, name, one-line summary, params model and loader."""

    family: str
    name: str
    summary: str
    params: type[Options]
    load: Loader


DATA_SOURCES: dict[str, Registry[DataSource]] = {}
"""Family -> registry of its sources."""


def register_source(
    family: str, name: str, summary: str, params: type[Options] = NoOptions
) -> Callable[[Loader], Loader]:
    """Decorator registering ``load(arm, data, params, path)`` as source ``name`` of ``family``."""

    def add(load: Loader) -> Loader:
        registry = DATA_SOURCES.setdefault(family, Registry(f"{family} source"))
        registry.register(name)(DataSource(family, name, summary, params, load))
        return load

    return add


def source_of(family: str, name: str, path: str | Path) -> DataSource:
    """The source ``name`` of ``family``; an unknown one is a :class:`SpecError` on ``data.source``
    listing the family's sources."""
    registry = DATA_SOURCES.get(family)
    if registry is None:
        raise SpecError(path, "data.source", f"no data sources of family {family!r} are registered")
    try:
        return registry.get(name)
    except UnknownNameError as exc:
        raise SpecError(path, "data.source", str(exc)) from None
