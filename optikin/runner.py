"""Problem file + solver preset -> Result.

``solve("cc-two-section-fk")`` loads and validates the problem file, picks the
solver preset (the ``--solver`` argument, else the file's ``solver``, else the
kind's default), checks that the kind accepts that backend, resolves every listed
baseline to the one the kind runs (:func:`resolve_baselines`), validates ``options``
and ``data.params`` against the kind's and the data source's models, builds the
arm, refuses a run whose estimated memory passes the limit (:mod:`optikin.resources`),
runs the kind, records on the result its size setting and the verdict the file expects
(:func:`label`), and optionally writes the result. Every error found before the run names the file and the dotted field;
a run that runs out of memory all the same is a :class:`~optikin.errors.SpecError`
on ``data.samples`` too (exit 2), not a traceback.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

from optikin.arms import build_arm
from optikin.arms.base import ArmModel
from optikin.data.sources import DATA_SOURCES, DataSource, source_of
from optikin.errors import SpecError, UnknownNameError
from optikin.options import validate_options
from optikin.problems import Baseline, ProblemContext, ProblemKind, load_kind, load_kinds
from optikin.progress import SILENT, Progress
from optikin.provenance import now, provenance_of
from optikin.resources import check_memory
from optikin.results import Result, check_output_folder, write_result
from optikin.solvers import LoadedPreset, load_preset
from optikin.spec import ProblemSpec, available, load_problem, provenance

if TYPE_CHECKING:
    from optikin.sweep.chunks import Chunks

logger = logging.getLogger(__name__)


def kind_of(spec: ProblemSpec, path: Path) -> ProblemKind:
    """The registered kind a problem file names, importing that kind's package only (:func:`load_kind`);
    an unknown one names the file's ``kind`` field."""
    try:
        return load_kind(spec.kind)
    except UnknownNameError as exc:
        raise SpecError(path, "kind", str(exc)) from None


def _data_source(kind: ProblemKind, name: str, path: Path) -> DataSource:
    """The kind's data source ``name``; one the kind's own modules do not register may be registered by a
    module another kind imports, so an unknown one is looked for again with every kind imported."""
    sources = DATA_SOURCES.get(kind.data_family)
    if sources is None or name not in sources:
        load_kinds()
    return source_of(kind.data_family, name, path)


def resolve_baselines(spec: ProblemSpec, path: Path, kind: ProblemKind) -> tuple[Baseline[Any, Any], ...]:
    """Every name of ``baselines:``, in order, as the :class:`~optikin.problems.Baseline` the kind runs.

    A name is the kind's own baseline, else a solver preset of a backend family the kind accepts, which
    the kind's :attr:`~optikin.problems.ProblemKind.preset_baseline` turns into its baseline. A name given
    twice, an unknown one, a preset of another family and a preset of a kind that runs none are
    :class:`SpecError` on ``baselines.<i>``.
    """
    presets = available("solvers")
    resolved: list[Baseline[Any, Any]] = []
    for i, name in enumerate(spec.baselines):
        if name in spec.baselines[:i]:
            first = spec.baselines.index(name)
            raise SpecError(path, f"baselines.{i}", f"{name!r} is listed twice (first as baselines.{first})")
        if name in kind.baselines:
            resolved.append(kind.baselines[name])
            continue
        if name not in presets:
            raise SpecError(
                path,
                f"baselines.{i}",
                f"{name!r} is neither a baseline of kind {kind.name!r} "
                f"(known: {', '.join(kind.baselines) or 'none'}) nor a solver preset",
            )
        preset = load_preset(name)
        family = preset.backend.family
        if family not in kind.backend_families or kind.preset_baseline is None:
            takes = " or ".join(kind.backend_families) if kind.preset_baseline is not None else ""
            raise SpecError(
                path,
                f"baselines.{i}",
                f"solver preset {name!r} ({family}) cannot be a baseline of kind {kind.name!r}, which runs "
                f"{f'presets of {takes}' if takes else 'no solver presets'} as baselines "
                f"(its own: {', '.join(kind.baselines) or 'none'})",
            )
        resolved.append(kind.preset_baseline(name, preset))
    return tuple(resolved)


def _preset(name: str | None, kind: ProblemKind) -> LoadedPreset | None:
    if name is None:
        return None
    preset = load_preset(name)
    if preset.backend.family not in kind.backend_families:
        raise SpecError(
            preset.path,
            "backend",
            f"{preset.spec.backend!r} ({preset.backend.family}) cannot solve kind {kind.name!r}, "
            f"which takes {' or '.join(kind.backend_families) or 'no'} backends",
        )
    return preset


def _check_arrays(spec: ProblemSpec, path: Path, result: Result) -> None:
    """``outputs.arrays`` names arrays this result has."""
    for i, name in enumerate(spec.outputs.arrays or []):
        if name not in result.arrays:
            raise SpecError(
                path,
                f"outputs.arrays.{i}",
                f"no array {name!r} in this result; known: {', '.join(sorted(result.arrays)) or 'none'}",
            )


def prepare(
    problem: str,
    solver: str | None = None,
    progress: Progress = SILENT,
    notify: Callable[[str], None] | None = None,
    overrides: Sequence[tuple[str, Any]] = (),
    arms: Callable[[str, dict[str, Any], Path], ArmModel] = build_arm,
) -> tuple[ProblemKind, ProblemContext]:
    """Everything :func:`solve` checks and builds before the run: the kind and its context.

    ``notify`` receives one line for each file used that is not one of optikin's own
    (:func:`optikin.spec.provenance`); ``overrides`` are ``(dotted field, value)`` pairs set in the
    problem file before it is validated (:func:`optikin.spec.apply_overrides`); ``arms`` builds the arm
    as :func:`optikin.arms.build_arm` does (a sweep worker's cache: :func:`optikin.sweep.cell.cached_arm`).
    Only the problem's own kind and the modules of the backends its presets name are imported
    (:func:`optikin.problems.load_kind`, :func:`optikin.solvers.load_backend`).
    """
    spec, path = load_problem(problem, overrides)
    _tell(notify, provenance(problem, path, "problems"))
    return prepare_spec(spec, path, solver, progress, notify, arms)


def prepare_spec(
    spec: ProblemSpec,
    path: Path,
    solver: str | None = None,
    progress: Progress = SILENT,
    notify: Callable[[str], None] | None = None,
    arms: Callable[[str, dict[str, Any], Path], ArmModel] = build_arm,
    run: bool = True,
) -> tuple[ProblemKind, ProblemContext]:
    """:func:`prepare` of a problem file already read (:func:`optikin.spec.load_problem`) from ``path``.

    ``run=False`` builds a context that is not run (an export, :mod:`optikin.export.context`): the
    baselines and the memory of the run are not checked, and no baseline's backend is imported.
    """
    kind = kind_of(spec, path)
    baselines = resolve_baselines(spec, path, kind) if run else ()
    options = validate_options(kind.options, spec.options, path, "options")
    data_source = _data_source(kind, spec.data.source, path)
    data_params = validate_options(data_source.params, spec.data.params, path, "data.params")
    preset_name = solver or spec.solver or kind.default_solver
    preset = _preset(preset_name, kind)
    if preset is not None and preset_name is not None:
        _tell(notify, provenance(preset_name, preset.path, "solvers"))
    adapter = None if preset is None else preset.build()
    if spec.arm is None and not kind.arm_optional:
        raise SpecError(path, "arm", f"missing: kind {kind.name!r} needs an arm (arm: {{type: ..., params: ...}})")
    arm = None if spec.arm is None else arms(spec.arm.type, spec.arm.params, path)
    if run:
        check_memory(kind.name, arm, 1 + len(spec.baselines), spec.data.samples, path)
    ctx = ProblemContext(
        spec=spec,
        path=path,
        arm_model=arm,
        progress=progress,
        options=options,
        data_source=data_source,
        data_params=data_params,
        preset=preset,
        adapter=adapter,
        baselines=baselines,
    )
    return kind, ctx


def label(result: Result, ctx: ProblemContext) -> None:
    """Record on ``result`` the size setting the run used (``options.setting`` of a kind that has one) and
    the verdict the problem file expects (``expect:``), so that both are printed and written with it."""
    setting = getattr(ctx.options, "setting", None)
    result.setting = None if setting is None else str(setting)
    expect = ctx.spec.expect
    result.expect = None if expect is None else expect.model_dump(mode="json")


def _tell(notify: Callable[[str], None] | None, line: str | None) -> None:
    if notify is not None and line is not None:
        notify(line)


def solve(
    problem: str,
    solver: str | None = None,
    out: Path | None = None,
    figures: bool = True,
    progress: Progress = SILENT,
    notify: Callable[[str], None] | None = None,
    overrides: Sequence[tuple[str, Any]] = (),
    arms: Callable[[str, dict[str, Any], Path], ArmModel] = build_arm,
    chunks: "Chunks | None" = None,
) -> tuple[Result, Path | None]:
    """Solve a named problem (or a path to one); returns the Result and where it was written.

    Parameters
    ----------
    problem:
        A problem name (looked up as :func:`optikin.spec.resolve` says) or a path to a problem file.
    solver:
        A preset name or path replacing the file's ``solver``.
    out:
        Folder to write ``<problem>/`` into (nothing is written when None).
    figures:
        Draw the figures (when the file's ``outputs.figures`` allows).
    progress:
        Progress reporter for long runs.
    notify:
        Receives one line per file used that is not one of optikin's own.
    overrides:
        ``(dotted field, value)`` pairs set in the problem file before validation (``--set``).
    arms:
        Builds the arm (:func:`prepare`).
    chunks:
        Splits the samples of a kind that allows it across worker processes
        (:class:`optikin.sweep.chunks.Chunks`; ``--jobs`` / ``--dask``).
    """
    clock = time.perf_counter()
    kind, ctx = prepare(problem, solver, progress, notify, overrides, arms)
    preset = ctx.preset.spec.name if ctx.preset is not None else "none"
    logger.debug("%s: kind %s, preset %s, prepared in %.3g s", ctx.path, kind.name, preset, time.perf_counter() - clock)
    if out is not None:
        check_output_folder(Path(out), ctx.spec.name)
    try:
        started, clock = now(), time.perf_counter()
        result = kind.run(ctx) if chunks is None else chunks.run(kind, ctx, overrides)
        result.provenance = provenance_of(ctx, started, time.perf_counter() - clock)
        label(result, ctx)
        logger.debug("%s: ran in %.3g s", ctx.spec.name, time.perf_counter() - clock)
        _check_arrays(ctx.spec, ctx.path, result)
        written = None
        if out is not None:
            written = write_result(
                result,
                Path(out),
                figures=figures and ctx.spec.outputs.figures,
                arrays=ctx.spec.outputs.arrays,
                figure_builder=kind.figures,
            )
            logger.debug("%s: written to %s", ctx.spec.name, written)
    except MemoryError:
        raise SpecError(
            ctx.path,
            "data.samples",
            f"the run ran out of memory with {ctx.spec.data.samples} samples; use fewer samples",
        ) from None
    return result, written
