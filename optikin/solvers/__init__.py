"""Solver backends: one adapter module per backend, each registered by name.

A preset in ``solvers/*.yaml`` names a backend and its options; a problem kind
lists the backends it accepts. Backends of the same family share one calling
convention (e.g. every ``evaluation`` backend offers ``evaluate(arm, name, Q)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from optikin.errors import SpecError, UnknownNameError
from optikin.registry import BACKENDS
from optikin.spec import SolverSpec, load_solver


@dataclass(frozen=True)
class Backend:
    """A registered backend: its family, a one-line summary, and how to build its adapter from a preset."""

    name: str
    family: str
    summary: str
    build: Callable[[SolverSpec], Any]


def register_backend(name: str, family: str, summary: str) -> Callable:
    """Decorator registering ``build(preset) -> adapter`` as backend ``name``."""

    def add(build: Callable[[SolverSpec], Any]) -> Callable[[SolverSpec], Any]:
        BACKENDS.register(name)(Backend(name, family, summary, build))
        return build

    return add


def load_preset(name_or_path: str) -> tuple[SolverSpec, Path, Backend]:
    """A solver preset, its file and its registered backend; an unknown backend names the file's field."""
    load_backends()
    preset, path = load_solver(name_or_path)
    try:
        return preset, path, BACKENDS.get(preset.backend)
    except UnknownNameError as exc:
        raise SpecError(path, "backend", str(exc)) from None


def build_preset(name_or_path: str) -> Any:
    """The adapter of a named solver preset (e.g. a baseline listed in a problem file)."""
    preset, _, backend = load_preset(name_or_path)
    return backend.build(preset)


def load_backends() -> None:
    """Import every adapter module in this package so its backends are registered."""
    _import_all(__name__, __path__)


def _import_all(package: str, path) -> None:
    import importlib
    import pkgutil

    for module in pkgutil.iter_modules(path):
        if not module.name.startswith("_"):
            importlib.import_module(f"{package}.{module.name}")
