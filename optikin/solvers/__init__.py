"""Solver backends: one adapter module per backend, each registered by name.

A preset in ``solvers/*.yaml`` names a backend and its options; a problem kind
lists the backend families it accepts. Each backend declares its options as an
:class:`~optikin.options.Options` model, validated by :func:`load_preset` with
every error naming the preset file and the dotted field; its ``build(preset,
options)`` returns an adapter that keeps its family's protocol
(:mod:`optikin.solvers.base`).
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

from optikin.errors import SpecError, UnknownNameError
from optikin.options import NoOptions, Options, validate_options
from optikin.registry import BACKENDS
from optikin.spec import SolverSpec, load_solver

FAMILIES = ("evaluation", "nonlinear", "ph", "qp")
"""Backend families; their calling conventions are the protocols of :mod:`optikin.solvers.base`."""

BACKEND_MODULES: dict[str, str] = {
    "casadi_call": "optikin.solvers.evaluation",
    "casadi_compiled": "optikin.solvers.evaluation",
    "casadi_map": "optikin.solvers.evaluation",
    "gauss_newton": "optikin.solvers.gauss_newton",
    "ipopt": "optikin.solvers.nlpsol",
    "lm": "optikin.solvers.scipy_least_squares",
    "newton": "optikin.solvers.newton",
    "ph_grid": "optikin.solvers.ph_backends",
    "ph_ipopt": "optikin.solvers.ph_backends",
    "ph_newton": "optikin.solvers.ph_backends",
    "qp_cvxpy": "optikin.solvers.qp.qp_cvxpy",
    "qp_cvxpy_rebuild": "optikin.solvers.qp.qp_cvxpy_rebuild",
    "qp_daqp": "optikin.solvers.qp.qp_daqp",
    "qp_osqp": "optikin.solvers.qp.qp_osqp",
    "qp_qpsolvers": "optikin.solvers.qp.qp_qpsolvers",
    "sqpmethod": "optikin.solvers.nlpsol",
    "trf": "optikin.solvers.scipy_least_squares",
}
"""Backend name -> the module whose import registers it, so that a preset imports its own backend's module only
(:func:`load_backend`); a test checks it against the registrations of every module (:func:`load_backends`)."""


@dataclass(frozen=True)
class Backend:
    """A registered backend: family, one-line summary, options model, and how to build its adapter."""

    name: str
    family: str
    summary: str
    build: Callable[[SolverSpec, Any], Any]
    options: type[Options] = NoOptions
    module: str = ""


def register_backend(name: str, family: str, summary: str, options: type[Options] = NoOptions) -> Callable:
    """Decorator registering ``build(preset, options) -> adapter`` as backend ``name``.

    ``options`` is the model the preset's ``options:`` are validated against; the
    adapter receives the validated instance.
    """
    if family not in FAMILIES:
        raise ValueError(f"backend {name!r}: unknown family {family!r}; known: {', '.join(FAMILIES)}")

    def add(build: Callable[..., Any]) -> Callable[..., Any]:
        BACKENDS.register(name)(Backend(name, family, summary, build, options, build.__module__))
        return build

    return add


@dataclass(frozen=True)
class LoadedPreset:
    """A validated preset: its spec, the file it came from, its backend and its typed options."""

    spec: SolverSpec
    path: Path
    backend: Backend
    options: Any

    def build(self) -> Any:
        """The adapter this preset describes."""
        return self.backend.build(self.spec, self.options)


def load_preset(name_or_path: str) -> LoadedPreset:
    """A solver preset with its backend and validated options; every error names the file and field."""
    spec, path = load_solver(name_or_path)
    return preset_of(spec, path)


def preset_of(spec: SolverSpec, path: str | Path | None = None) -> LoadedPreset:
    """A preset built in code (or read elsewhere) with its backend and validated options.

    ``path`` is where errors say the preset came from (default: ``solver preset NAME``).
    """
    where = Path(path) if path is not None else Path(f"solver preset {spec.name}")
    try:
        backend = load_backend(spec.backend)
    except UnknownNameError as exc:
        raise SpecError(where, "backend", str(exc)) from None
    options = validate_options(backend.options, spec.options, where, "options")
    return LoadedPreset(spec, where, backend, options)


def build_preset(name_or_path: str) -> Any:
    """The adapter of a named solver preset (e.g. a baseline listed in a problem file)."""
    return load_preset(name_or_path).build()


def load_backend(name: str) -> Backend:
    """The backend registered as ``name``, importing its module of :data:`BACKEND_MODULES` only.

    A name the table lacks, or one its module does not register, is looked for among every backend
    (:func:`load_backends`).

    Raises
    ------
    UnknownNameError
        No module registers ``name``; the message lists every backend.
    """
    if name not in BACKENDS and name in BACKEND_MODULES:
        importlib.import_module(BACKEND_MODULES[name])
    if name not in BACKENDS:
        load_backends()
    return BACKENDS.get(name)


def load_backends() -> None:
    """Import every adapter module in this package so its backends are registered."""
    import_all(__name__, __path__)


def import_all(package: str, path: Iterable[str]) -> None:
    """Import every public module and subpackage of ``package`` (so their registrations run)."""
    for module in pkgutil.iter_modules(path):
        if not module.name.startswith("_"):
            importlib.import_module(f"{package}.{module.name}")
