"""Problem kinds: each reads a validated problem spec, builds its problem, solves it, returns a Result.

Each kind is a package ``optikin/problems/<kind>/``:

``run.py``
    builds and solves the problem from a :class:`ProblemContext`, returning the
    kind's own typed outcome;
``report.py``
    turns that outcome into a :class:`~optikin.results.Result` (metrics, the
    comparison table, arrays, notes);
``figures.py``
    draws from the result's arrays and summary alone
    (:data:`~optikin.results.FigureBuilder`), so ``optikin plot RESULT_DIR``
    redraws a written result without solving again;
``__init__.py``
    registers a :class:`ProblemKind` under the name used in the ``kind`` field of
    problem files, with its options model, data family and baselines (:class:`Baseline`).

The runner validates ``options`` and ``data.params`` against the kind's models
before the run, and hands the kind a :class:`ProblemContext` holding the spec,
the typed options, the data source, the solver preset and its adapter, the arm
model, a progress reporter and every baseline the file lists, resolved once (:class:`Baseline`: the
kind's own, or a solver preset of a family the kind runs).
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Generic, Mapping, Protocol, Sequence, TypeVar

import numpy as np

from optikin.arms.base import ArmModel
from optikin.data.sources import DataSource
from optikin.errors import SolverError, SpecError
from optikin.options import NoOptions, Options
from optikin.progress import Progress
from optikin.registry import PROBLEM_KINDS
from optikin.results import Drawer, FigureBuilder, Result
from optikin.solvers.base import Adapter
from optikin.spec import ProblemSpec, SolverSpec

if TYPE_CHECKING:
    from optikin.solvers import LoadedPreset

A = TypeVar("A")
S = TypeVar("S")
M = TypeVar("M")


@dataclass(frozen=True)
class Baseline(Generic[S, M]):
    """A method a kind compares its solver with, listed by :attr:`name` in a problem's ``baselines:``.

    Attributes
    ----------
    name:
        The name in ``baselines:`` (a kind's own, or a solver preset's).
    title:
        The label of its comparison row (and of its curves).
    role:
        The row's role: ``baseline`` (a method compared with), ``solver`` (optikin's own, e.g. the MPC).
    build:
        ``build(ctx, setup) -> method``: the method, made from the context and what the kind's run
        prepared for every method (``setup``: the kind's own type). ``None``: the kind's run solves the
        baseline by its name.
    preset:
        The loaded solver preset of a preset baseline (:func:`optikin.runner.resolve_baselines`); ``None``
        for the kind's own.
    """

    name: str
    title: str
    role: str = "baseline"
    build: Callable[["ProblemContext", S], M] | None = None
    preset: "LoadedPreset | None" = None

    def method(self, ctx: "ProblemContext", setup: S) -> M:
        """:attr:`build` of ``ctx`` and ``setup``; a baseline without one is a :class:`SolverError`."""
        if self.build is None:
            raise SolverError(f"baseline {self.name!r} of kind {ctx.spec.kind!r} has no builder")
        return self.build(ctx, setup)


def baselines_of(*baselines: Baseline[Any, Any]) -> dict[str, Baseline[Any, Any]]:
    """``baselines`` by name, in order (a name given twice is a ``ValueError``)."""
    out: dict[str, Baseline[Any, Any]] = {}
    for baseline in baselines:
        if baseline.name in out:
            raise ValueError(f"baseline {baseline.name!r} is declared twice")
        out[baseline.name] = baseline
    return out


@dataclass
class ProblemContext:
    """Everything a kind's ``run`` needs, validated.

    Attributes
    ----------
    spec, path:
        The problem file and where it came from.
    arm_model:
        The arm model built from ``arm:``; None for a kind that needs no arm when the file has none
        (:attr:`ProblemKind.arm_optional`). :attr:`arm` gives it to kinds that need one.
    options:
        ``options:`` validated against the kind's options model.
    data_source, data_params:
        The source named by ``data.source`` (in the kind's data family) and its
        ``data.params`` validated against the source's params model; ``None`` for
        kinds without a data family.
    preset:
        The solver preset (spec, file, backend, typed options), or ``None``.
    adapter:
        The preset's adapter, keeping its family's protocol (:mod:`optikin.solvers.base`);
        :meth:`backend` gives it with the type a kind expects.
    baselines:
        Every name of ``baselines:``, in order, resolved by the runner (:func:`optikin.runner.resolve_baselines`):
        the kind's own :class:`Baseline` or the one it makes of a solver preset. Empty for a context that
        is not run (an export).
    """

    spec: ProblemSpec
    path: Path
    arm_model: ArmModel | None
    progress: Progress
    options: Any = None
    data_source: DataSource | None = None
    data_params: Any = None
    preset: "LoadedPreset | None" = None
    adapter: Adapter | None = None
    baselines: tuple[Baseline[Any, Any], ...] = ()

    @property
    def arm(self) -> ArmModel:
        """The arm; a :class:`SpecError` on ``arm`` when the file gives none."""
        if self.arm_model is None:
            raise SpecError(self.path, "arm", f"kind {self.spec.kind!r} needs an arm here: give arm: {{type: ...}}")
        return self.arm_model

    @property
    def arm_type(self) -> str:
        """The file's ``arm.type``, or ``none`` without an arm (for messages)."""
        return "none" if self.spec.arm is None else self.spec.arm.type

    @property
    def solver(self) -> SolverSpec | None:
        """The solver preset's spec, or None."""
        return None if self.preset is None else self.preset.spec

    def backend(self, expected: type[A]) -> A:
        """The preset's adapter as ``expected`` (a family protocol of :mod:`optikin.solvers.base`, or an
        adapter class); a kind run without a preset, or with one of another family, is a :class:`SolverError`."""
        if not isinstance(self.adapter, expected):
            got = "no solver preset" if self.adapter is None else type(self.adapter).__name__
            raise SolverError(f"kind {self.spec.kind!r} needs a {getattr(expected, '__name__', expected)}, got {got}")
        return self.adapter

    def rng(self, stream: int = 0) -> np.random.Generator:
        """A generator seeded from ``data.seed`` (``stream`` separates independent draws)."""
        return np.random.default_rng([self.spec.data.seed, stream])

    def load_data(self) -> Any:
        """The samples of ``data:``, from the kind's data source with its validated params."""
        if self.data_source is None:
            raise SpecError(self.path, "data.source", f"kind {self.spec.kind!r} has no data sources")
        return self.data_source.load(self.arm_model, self.spec.data, self.data_params, self.path)

    def result(self, **fields: Any) -> Result:
        """A :class:`~optikin.results.Result` of this problem.

        ``problem``, ``kind`` and ``title`` come from the file; ``arm`` (the arm's
        :meth:`describe`) and ``solver`` (the preset's name) unless ``fields`` give them.
        """
        fields.setdefault("solver", None if self.solver is None else self.solver.name)
        fields.setdefault("arm", {} if self.arm_model is None else self.arm_model.describe())
        return Result(problem=self.spec.name, kind=self.spec.kind, title=self.spec.title, **fields)

    def error(self, field_path: str, message: str) -> SpecError:
        return SpecError(self.path, field_path, message)


ChunkWork = Callable[[ProblemContext, dict[str, Any], Any], Any]
"""``work(ctx, memo, piece) -> answer``: a module-level function solving one piece of a run's samples in a
worker process, where ``ctx`` is built from the same problem file and ``memo`` is a dict kept with it in that
process across the pieces of one run (for the models a worker builds once)."""


class ChunkEngine(Protocol):
    """What :attr:`ProblemKind.run_chunked` receives: the pieces of a run's samples and the engine solving them
    (:mod:`optikin.sweep.chunks`)."""

    def split(self, n: int) -> list[slice]:
        """Contiguous slices covering samples ``0 .. n - 1``, one per piece (one slice: solve them here)."""
        ...

    def map(self, work: ChunkWork, pieces: Sequence[Any]) -> list[Any]:
        """``work(ctx, memo, piece)`` of every piece, in the order of ``pieces``, on the engine's workers."""
        ...


@dataclass(frozen=True)
class ProblemKind:
    """What a kind accepts and how it runs.

    Attributes
    ----------
    name, summary:
        The ``kind:`` of problem files, and one line for ``optikin list --kinds``.
    run:
        ``run(ctx) -> Result``.
    backend_families, default_solver:
        The backend families whose presets may solve it, and the preset used when
        the file names none.
    baselines:
        The baselines the kind implements itself, by name (:func:`baselines_of`).
    preset_baseline:
        ``preset_baseline(name, preset) -> Baseline``: how the kind runs a solver preset of one of its
        :attr:`backend_families` listed in ``baselines:``. ``None``: it runs none, and a file listing one
        is refused when it is validated.
    data_family:
        The family of :data:`optikin.data.sources.DATA_SOURCES` that ``data.source`` names.
    options:
        The model of ``options:``.
    figures:
        Draws the result's figures from its arrays and summary.
    headline:
        The comparison columns a compact table shows (``optikin solve`` without ``--wide``); empty:
        chosen by :func:`optikin.tables.compact_columns`.
    arm_optional:
        Whether a problem file may leave out ``arm:`` (the data carry everything, e.g. the end poses
        of a shape reconstruction); the data source then receives ``arm=None``.
    run_chunked:
        ``run_chunked(ctx, engine) -> Result``: :attr:`run` with the independent samples split in pieces
        across worker processes (``optikin solve --jobs N`` or ``--dask``). The kind draws its samples once,
        here, hands slices of them to ``engine.map`` and merges the answers, which equal :attr:`run`'s
        sample for sample. None: the kind runs as one piece.
    """

    name: str
    summary: str
    run: Callable[[ProblemContext], Result]
    backend_families: tuple[str, ...]
    default_solver: str | None
    data_family: str
    baselines: Mapping[str, Baseline[Any, Any]] = field(default_factory=dict)
    preset_baseline: Callable[[str, "LoadedPreset"], Baseline[Any, Any]] | None = None
    options: type[Options] = NoOptions
    figures: FigureBuilder | None = None
    headline: tuple[str, ...] = ()
    arm_optional: bool = False
    run_chunked: Callable[[ProblemContext, ChunkEngine], Result] | None = None


def figures_of(module: str) -> FigureBuilder:
    """The :data:`~optikin.results.FigureBuilder` ``figures`` of ``module``, imported at the first drawing.

    A kind's figures need matplotlib (about half a second to import); a solve without figures, an
    export or a listing never imports it.
    """

    def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
        builder: FigureBuilder = importlib.import_module(module).figures
        return builder(arrays, summary)

    figures.__doc__ = f"The figures of :mod:`{module}` (imported when first drawn)."
    return figures


def preset_row(name: str, preset: "LoadedPreset") -> Baseline[Any, Any]:
    """A solver preset run as a baseline by the kind's own code, its row labelled with the preset's name."""
    return Baseline(name, name, preset=preset)


def register_kind(kind: ProblemKind) -> ProblemKind:
    """Register ``kind`` under its name.

    Raises
    ------
    TypeError
        ``kind.baselines`` is not a mapping of :class:`Baseline` (names alone, as a tuple: :func:`baselines_of`).
    ValueError
        A baseline declared under another name than its own.
    """
    if not isinstance(kind.baselines, Mapping) or not all(isinstance(b, Baseline) for b in kind.baselines.values()):
        raise TypeError(
            f"kind {kind.name!r}: baselines must map names to Baseline (optikin.problems.baselines_of), "
            f"got {type(kind.baselines).__name__}"
        )
    for key, baseline in kind.baselines.items():
        if key != baseline.name:
            raise ValueError(f"kind {kind.name!r} declares baseline {baseline.name!r} under the name {key!r}")
    PROBLEM_KINDS.register(kind.name)(kind)
    return kind


def load_kind(name: str) -> ProblemKind:
    """The kind registered as ``name``, importing its package ``optikin.problems.<name>`` only.

    A kind no package of that name registers is looked for among every kind (:func:`load_kinds`).

    Raises
    ------
    UnknownNameError
        No module registers ``name``; the message lists every kind.
    """
    if name not in PROBLEM_KINDS and name.isidentifier() and not name.startswith("_"):
        if importlib.util.find_spec(f"{__name__}.{name}") is not None:
            importlib.import_module(f"{__name__}.{name}")
    if name not in PROBLEM_KINDS:
        load_kinds()
    return PROBLEM_KINDS.get(name)


def load_kinds() -> None:
    """Import every problem-kind module and package here so it is registered."""
    from optikin.solvers import import_all

    import_all(__name__, __path__)
