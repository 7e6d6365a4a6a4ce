"""The problem context of an export, built importing only the problem's own kind and the backends it names.

:func:`optikin.runner.prepare` imports every problem kind and every solver backend (seconds of
imports: plotting, cvxpy, scikit-learn) before it reads the problem; an export needs one kind
and at most one backend family. :func:`context` reads and validates the problem file as
``prepare`` does (the same :class:`~optikin.errors.SpecError` on a bad field), importing the
kind's package ``optikin.problems.<kind>`` and the modules in ``backend_modules`` only; the
problem's solver preset is built when one of those modules registers its backend, and left
out otherwise.
"""

from __future__ import annotations

import importlib
from typing import Any, Sequence

from optikin.errors import SpecError, UnknownNameError


def context(
    problem: str,
    kinds: Sequence[str] | None,
    what: str,
    overrides: Sequence[tuple[str, Any]] = (),
    backend_modules: Sequence[str] = (),
):
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
        Modules whose import registers the backends the export can use.

    Raises
    ------
    SpecError
        The problem is of another kind, or a field of it is invalid.
    """
    from optikin.arms import build_arm
    from optikin.data.sources import source_of
    from optikin.options import validate_options
    from optikin.problems import ProblemContext
    from optikin.progress import SILENT
    from optikin.registry import PROBLEM_KINDS
    from optikin.spec import load_problem

    spec, path = load_problem(problem, overrides)
    if kinds is not None and spec.kind not in kinds:
        raise SpecError(path, "kind", f"{what} exports a problem of kind {' or '.join(kinds)}, not {spec.kind!r}")
    importlib.import_module(f"optikin.problems.{spec.kind}")
    for module in backend_modules:
        importlib.import_module(module)
    kind = PROBLEM_KINDS.get(spec.kind)
    options = validate_options(kind.options, spec.options, path, "options")
    data_source = source_of(kind.data_family, spec.data.source, path)
    data_params = validate_options(data_source.params, spec.data.params, path, "data.params")
    name = spec.solver or kind.default_solver
    preset = None if name is None else registered_preset(name)
    if spec.arm is None:
        raise SpecError(path, "arm", f"missing: kind {kind.name!r} needs an arm (arm: {{type: ..., params: ...}})")
    arm = build_arm(spec.arm.type, spec.arm.params, path)
    return ProblemContext(
        spec=spec,
        path=path,
        arm_model=arm,
        progress=SILENT,
        options=options,
        data_source=data_source,
        data_params=data_params,
        preset=preset,
        adapter=None if preset is None else preset.build(),
    )


def registered_preset(name: str):
    """Solver preset ``name`` (a :class:`~optikin.solvers.LoadedPreset`) if its backend is registered, else None.

    Unlike :func:`optikin.solvers.load_preset`, imports no backend module.
    """
    from optikin.options import validate_options
    from optikin.registry import BACKENDS
    from optikin.solvers import LoadedPreset
    from optikin.spec import load_solver

    solver, where = load_solver(name)
    try:
        backend = BACKENDS.get(solver.backend)
    except UnknownNameError:
        return None
    return LoadedPreset(solver, where, backend, validate_options(backend.options, solver.options, where, "options"))
