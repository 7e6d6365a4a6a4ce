"""Problem file + solver preset -> Result (DESIGN.md data flow).

``solve("cc-two-section-fk")`` loads and validates the problem file, picks the
solver preset (the ``--solver`` argument, else the file's ``solver``, else the
kind's default), checks that the kind accepts that backend and every listed
baseline, builds the arm, runs the kind, and optionally writes the result.
"""

from __future__ import annotations

from pathlib import Path

from optikin.arms import build_arm
from optikin.errors import SpecError, UnknownNameError
from optikin.problems import ProblemContext, ProblemKind, load_kinds
from optikin.progress import SILENT, Progress
from optikin.registry import PROBLEM_KINDS
from optikin.results import Result, write_result
from optikin.solvers import load_backends, load_preset
from optikin.spec import ProblemSpec, available, load_problem


def _kind_of(spec: ProblemSpec, path: Path) -> ProblemKind:
    load_kinds()
    try:
        return PROBLEM_KINDS.get(spec.kind)
    except UnknownNameError as exc:
        raise SpecError(path, "kind", str(exc)) from None


def _check_baselines(spec: ProblemSpec, path: Path, kind: ProblemKind) -> None:
    """Each baseline is one the kind implements, or a solver preset of a backend family the kind accepts."""
    presets = available("solvers")
    for i, baseline in enumerate(spec.baselines):
        if baseline in kind.baselines:
            continue
        if baseline not in presets:
            raise SpecError(path, f"baselines.{i}",
                            f"{baseline!r} is neither a baseline of kind {kind.name!r} "
                            f"(known: {', '.join(kind.baselines) or 'none'}) nor a solver preset")
        family = load_preset(baseline)[2].family
        if family not in kind.backend_families:
            raise SpecError(path, f"baselines.{i}", f"solver preset {baseline!r} ({family}) cannot solve kind "
                                                    f"{kind.name!r}, which takes {' or '.join(kind.backend_families)}")


def solve(problem: str, solver: str | None = None, out: Path | None = None, figures: bool = True,
          progress: Progress = SILENT) -> tuple[Result, Path | None]:
    """Solve a named problem (or a path to one); returns the Result and where it was written."""
    load_backends()
    spec, path = load_problem(problem)
    kind = _kind_of(spec, path)
    _check_baselines(spec, path, kind)
    preset_name = solver or spec.solver or kind.default_solver
    preset, preset_path, adapter = None, None, None
    if preset_name is not None:
        preset, preset_path, backend = load_preset(preset_name)
        if backend.family not in kind.backend_families:
            raise SpecError(preset_path, "backend",
                            f"{preset.backend!r} ({backend.family}) cannot solve kind {kind.name!r}, "
                            f"which takes {' or '.join(kind.backend_families)} backends")
        adapter = backend.build(preset)
    arm = build_arm(spec.arm.type, spec.arm.params, path)
    ctx = ProblemContext(spec=spec, path=path, arm=arm, solver=preset, solver_path=preset_path,
                         progress=progress, adapter=adapter)
    result = kind.run(ctx)
    written = None
    if out is not None:
        written = write_result(result, Path(out), figures=figures and spec.outputs.figures,
                               arrays=spec.outputs.arrays)
    return result, written
