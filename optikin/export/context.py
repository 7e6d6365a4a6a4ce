"""The problem context of an export: :func:`optikin.runner.prepare` of a problem of the kinds the export takes.

``prepare`` imports the problem's own kind and the module of its preset's backend only, so an export
reads the problem as ``optikin solve`` does (the same :class:`~optikin.errors.SpecError` on a bad field)
without importing the other kinds and backends; the baselines, which an export does not run, are not
checked (:func:`optikin.runner.prepare_spec` with ``run=False``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any, Sequence

from optikin.errors import SpecError

if TYPE_CHECKING:
    from optikin.problems import ProblemContext
    from optikin.solvers import LoadedPreset


def context(
    problem: str,
    kinds: Sequence[str] | None,
    what: str,
    overrides: Sequence[tuple[str, Any]] = (),
    backend_modules: Sequence[str] = (),
) -> ProblemContext:
    """The :class:`~optikin.problems.ProblemContext` of ``problem``, which must be of one of ``kinds``.

    Parameters
    ----------
    problem:
        A problem name or file, as for ``optikin solve``.
    kinds:
        The kinds the export takes (None: any).
    what:
        The export, for the error message (``--what ...``).
    overrides:
        ``(dotted field, value)`` pairs set in the problem file before it is validated.
    backend_modules:
        Modules whose import registers the backends the export uses besides the problem's own preset.

    Raises
    ------
    SpecError
        The problem is of another kind, has no arm, or a field of it is invalid.
    """
    from optikin.runner import prepare_spec
    from optikin.spec import load_problem

    spec, path = load_problem(problem, overrides)
    if kinds is not None and spec.kind not in kinds:
        raise SpecError(path, "kind", f"{what} exports a problem of kind {' or '.join(kinds)}, not {spec.kind!r}")
    for module in backend_modules:
        importlib.import_module(module)
    kind, ctx = prepare_spec(spec, path, run=False)
    if ctx.arm_model is None:
        raise SpecError(path, "arm", f"missing: kind {kind.name!r} needs an arm (arm: {{type: ..., params: ...}})")
    return ctx


def registered_preset(name: str) -> LoadedPreset | None:
    """Solver preset ``name`` (a :class:`~optikin.solvers.LoadedPreset`) if its backend is registered, else None.

    Unlike :func:`optikin.solvers.load_preset`, imports no backend module.
    """
    from optikin.registry import BACKENDS
    from optikin.solvers import preset_of
    from optikin.spec import load_solver

    solver, where = load_solver(name)
    return preset_of(solver, where) if solver.backend in BACKENDS else None
