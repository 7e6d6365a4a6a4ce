"""What the PH problem kinds share: options, end data from markers, the methods and their energy gaps.

The kinds ``ph_shape`` (Singh et al. 2018, section V.A), ``ph_ik`` (V.B, Tables
II-III) and ``ph_chain`` (V.C) all rebuild backbones as minimum-energy PH quintics
from end poses (:mod:`optikin.curves.min_energy`) with the ``ph`` backends
(:mod:`optikin.solvers.ph_backends`): the problem's solver and every ``ph`` preset
listed in ``baselines`` solve the same samples in the same run, and each method's
energy gap (to the lowest energy any method found for the sample) and time per
sample are reported.

Options shared by the three kinds (:class:`PHOptions`, all optional)::

    twist_weight: 0.0     # E = int kappa^2 ds + twist_weight int tau^2 ds
    nodes: 16             # Gauss-Legendre nodes of the energy
    free_speeds: false    # false: end speeds = backbone length (the seed's setting);
                          # true: speeds free, arc length held to the backbone length
    length: arc           # backbone length: arc | markers | model | a number (metres)
    fixed_base: false     # true: average the base pose over the recording (a base known to be fixed, as
                          # the seed's); false: each posture's own measured base pose

``length``: the seed builds the PH curve from the end poses alone, so the default
estimates the length from them: ``arc`` is the circular arc leaving ``p0`` along
``t0`` and reaching ``p1`` along ``t1`` in the plane of the chord
(:func:`optikin.curves.arc_length_estimate`); ``markers`` the polyline through all
markers (a lower bound; uses the intermediate markers); ``model`` the vertebra
model's true backbone length (an oracle, synthetic recordings only).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import yaml
from pydantic import Field, field_validator

from optikin.arms import build_arm
from optikin.curves import EnergySettings, PHQuintic, ShapeData, ShapeEnergyModel, ShapeSolution, arc_length_estimate
from optikin.curves.bernstein import bernstein_basis
from optikin.curves.energy import DEFAULT_NODES
from optikin.curves.tubes import TubeLayout, tube_points
from optikin.data.cosserat_markers import CosseratRecording
from optikin.data.markers import MarkerRecording
from optikin.data.sources import source_of
from optikin.errors import InputDataError
from optikin.options import Options, validate_options
from optikin.problems import ProblemContext, load_kinds
from optikin.registry import PROBLEM_KINDS
from optikin.results import MethodRow
from optikin.solvers import build_preset
from optikin.solvers.ph_backends import PHAdapter
from optikin.spec import load_problem
from optikin.status import Status

LENGTH_MODES = ("arc", "markers", "model")
MM = 1e3


# ------------------------------------------------------------------------------ options
class PHOptions(Options):
    """The options every PH kind takes (module docstring)."""

    twist_weight: float = Field(0.0, ge=0, description="weight of the twist energy int tau^2 ds")
    nodes: int = Field(DEFAULT_NODES, ge=2, le=200, strict=True, description="Gauss-Legendre nodes of the energy")
    free_speeds: bool = Field(
        False, strict=True, description="false: end speeds = backbone length; true: free, arc length held"
    )
    length: str | float = Field("arc", description="backbone length: arc | markers | model | a length [m]")
    fixed_base: bool = Field(
        False,
        strict=True,
        description="true: average the base pose over the recording (a fixed base); false: each posture's own",
    )

    @field_validator("length", mode="before")
    @classmethod
    def _length_mode(cls, value: Any) -> Any:
        if isinstance(value, str) and value in LENGTH_MODES:
            return value
        if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0:
            return float(value)
        raise ValueError(f"must be one of {', '.join(LENGTH_MODES)} or a positive length in metres, got {value!r}")

    @property
    def energy(self) -> EnergySettings:
        """What is minimised."""
        return EnergySettings(float(self.twist_weight), self.nodes)

    def speeds_note(self) -> str:
        """How the end speeds are chosen, for the notes of a result."""
        return "free, length held" if self.free_speeds else "set to the length"


# ------------------------------------------------------------------------------ data
def recording_of(problem: str, samples: int | None = None) -> Any:
    """The recording a problem file's ``data`` describes (its source, params and arm), ``samples`` postures.

    For notebooks and tests that look at a shipped problem's data without solving it.
    """
    spec, path = load_problem(problem)
    load_kinds()
    family = PROBLEM_KINDS.get(spec.kind).data_family
    if family is None:
        raise ValueError(f"kind {spec.kind!r} of {problem!r} has no data family")
    source = source_of(family, spec.data.source, path)
    params = validate_options(source.params, spec.data.params, path, "data.params")
    data = spec.data if samples is None else spec.data.model_copy(update={"samples": int(samples)})
    arm = None if spec.arm is None else build_arm(spec.arm.type, spec.arm.params, path)
    return source.load(arm, data, params, path)


# ------------------------------------------------------------------------------ end data
def shape_samples(
    recording: MarkerRecording, options: PHOptions, source: str
) -> tuple[MarkerRecording, np.ndarray, list[ShapeData]]:
    """The recording (base pose averaged with ``fixed_base``), its backbone lengths and end data."""
    if options.fixed_base:
        recording = recording.with_fixed_base()
    lengths = backbone_lengths(recording, options.length, source)
    return recording, lengths, end_data(recording, lengths, source)


def backbone_lengths(recording: MarkerRecording, mode: str | float, source: str) -> np.ndarray:
    """One backbone length per posture by ``mode`` (module docstring)."""
    n = len(recording)
    if not isinstance(mode, str):
        return np.full(n, float(mode))
    if mode == "arc":
        return arc_length_estimate(
            recording.base_position, recording.base_direction, recording.tip_position, recording.tip_direction
        )
    if mode == "markers":
        points = np.concatenate(
            [recording.base_position[:, None], recording.markers, recording.tip_position[:, None]], 1
        )
        return np.linalg.norm(np.diff(points, axis=1), axis=2).sum(axis=1)
    if recording.truth is None:
        raise InputDataError(
            "length 'model' needs a synthetic recording (the vertebra model's backbone length)",
            source=source,
            field="length",
        )
    return recording.truth.backbone_length.copy()


def end_data(recording: MarkerRecording, lengths: np.ndarray, source: str) -> list[ShapeData]:
    """One :class:`ShapeData` per posture: base pose to tip pose, backbone length ``lengths``.

    A length shorter than the chord is raised to it (an estimate cannot be shorter than the chord).
    """
    chord = np.linalg.norm(recording.tip_position - recording.base_position, axis=1)
    lengths = np.maximum(lengths, chord * (1.0 + 1e-9))
    return [
        ShapeData.checked(
            recording.base_position[i],
            recording.base_direction[i],
            recording.tip_position[i],
            recording.tip_direction[i],
            length=lengths[i],
            source=source,
            sample=i,
        )
        for i in range(len(recording))
    ]


# ------------------------------------------------------------------------------ methods
@dataclass
class MethodRun:
    """One ``ph`` method over all samples."""

    name: str
    role: str
    solutions: Sequence[ShapeSolution]
    build_seconds: float
    adapter: PHAdapter
    model: ShapeEnergyModel
    samples: list[ShapeData]

    @property
    def curves(self) -> PHQuintic:
        """The solutions' curves as one batch (NaN coefficients where a sample has no point)."""
        return self.model.curves(self.solutions, self.samples)

    @property
    def compiled(self) -> bool:
        return self.model.compile

    @property
    def energies(self) -> np.ndarray:
        return np.array([s.energy for s in self.solutions])

    @property
    def seconds(self) -> np.ndarray:
        return np.array([s.seconds for s in self.solutions])

    @property
    def iterations(self) -> np.ndarray:
        return np.array([s.iterations for s in self.solutions])

    @property
    def status(self) -> list[str]:
        return [s.status for s in self.solutions]


def solver_name(ctx: ProblemContext) -> str:
    """The solver preset's name (every PH kind has a default solver, so there is one)."""
    if ctx.solver is None:
        raise ctx.error("solver", f"kind {ctx.spec.kind!r} needs a ph solver preset")
    return ctx.solver.name


def ph_methods(ctx: ProblemContext, others: tuple[str, ...] = ()) -> list[tuple[str, str, PHAdapter]]:
    """``(preset name, role, adapter)``: the problem's solver, then every baseline not already listed.

    ``others`` are baseline names the kind runs itself (not ``ph`` presets).
    """
    methods = [(solver_name(ctx), "solver", ctx.backend(PHAdapter))]
    for name in ctx.spec.baselines:
        if name in [m[0] for m in methods] or name in others:
            continue
        methods.append((name, "baseline", build_preset(name)))  # the runner checked its family
    return methods


def solve_methods(
    ctx: ProblemContext,
    energy: EnergySettings,
    free_speeds: bool,
    samples: list[ShapeData],
    label: str = "",
    others: tuple[str, ...] = (),
) -> dict[str, MethodRun]:
    """Every ``ph`` method on ``samples`` (in order); models are built (and compiled) before the clock starts."""
    runs: dict[str, MethodRun] = {}
    methods = ph_methods(ctx, others)
    with ctx.progress.task(
        f"{ctx.spec.kind}{label}: {len(samples)} samples x {len(methods)} methods", total=len(methods)
    ) as advance:
        for name, role, adapter in methods:
            tic = time.perf_counter()
            model = adapter.model(energy, free_speeds)
            adapter.solve(model, samples[:1])  # build nlpsol / compile Newton outside the timing
            build = time.perf_counter() - tic
            runs[name] = MethodRun(name, role, adapter.solve(model, samples), build, adapter, model, samples)
            advance()
    return runs


def energy_gaps(runs: dict[str, MethodRun]) -> dict[str, np.ndarray]:
    """Per method, ``E - E_best`` per sample (``E_best``: the lowest energy any method found), NaN where failed."""
    E = np.array([[e if s == Status.OK else np.nan for e, s in zip(r.energies, r.status)] for r in runs.values()])
    with np.errstate(all="ignore"):
        best = np.nanmin(np.where(np.isfinite(E), E, np.nan), axis=0)
    return {name: E[k] - best for k, name in enumerate(runs)}


def method_rows(runs: dict[str, MethodRun], extra: dict[str, dict[str, Any]] | None = None) -> list[MethodRow]:
    """One comparison row per method: statuses, energy gap, iterations, time per sample (+ ``extra`` metrics)."""
    gaps = energy_gaps(runs)
    rows = []
    for name, run in runs.items():
        gap, E = gaps[name], run.energies
        relative = gap / np.where(np.abs(E) > 0, np.abs(E), 1.0)
        finite = np.isfinite(gap)
        status = np.array(run.status)
        metrics: dict[str, Any] = {
            "ok": f"{int((status == 'ok').sum())}/{len(status)}",
            "max energy gap": float(np.max(gap[finite])) if finite.any() else math.nan,
            "samples with relative gap > 1e-6": int(np.sum(relative[finite] > 1e-6)),
            "median iterations": float(np.median(run.iterations)),
            "median time per sample [us]": float(np.median(run.seconds) * 1e6),
            "mean time per sample [us]": float(np.mean(run.seconds) * 1e6),
            "fallbacks": int(sum(bool(s.notes) and s.method == "newton" for s in run.solutions)),
        }
        metrics.update((extra or {}).get(name, {}))
        rows.append(MethodRow(name, run.role, metrics))
    return rows


# ------------------------------------------------------------------------------ curves and distances
def distances_to_curves(curves: PHQuintic, points: np.ndarray, coarse: int = 401, refine: int = 10) -> np.ndarray:
    """Distance of each point ``(N, K, 3)`` to curve ``n`` of the batch: ``(N, K)``.

    The closest of ``coarse`` samples, then Newton on ``(r(t) - p) . r'(t) = 0`` kept
    within ``[0, 1]`` (end points included); curves and derivatives in Bernstein form.
    """
    P = np.stack(curves.control_points(), axis=1)  # (N, 6, 3)
    W = np.stack(curves.hodograph_coefficients(), axis=1)  # (N, 5, 3): r' (quartic)
    dW = 4.0 * (W[:, 1:] - W[:, :-1])  # (N, 4, 3): r'' (cubic)

    def at(coefficients, t):
        basis = np.stack(bernstein_basis(coefficients.shape[1] - 1, t), axis=-1)  # (N, K, degree + 1)
        return np.einsum("nkj,njc->nkc", basis, coefficients)

    t = np.linspace(0.0, 1.0, coarse)
    samples = curves.point(t)  # (N, T, 3)
    d2 = np.sum((points[:, :, None, :] - samples[:, None, :, :]) ** 2, axis=-1)  # (N, K, T)
    tk = t[np.argmin(d2, axis=-1)]  # (N, K)
    for _ in range(refine):
        diff, d1 = at(P, tk) - points, at(W, tk)
        g = np.sum(diff * d1, axis=-1)
        h = np.sum(d1 * d1, axis=-1) + np.sum(diff * at(dW, tk), axis=-1)
        step = np.where(h > 0, g / np.where(h > 0, h, 1.0), 0.0)
        tk = np.clip(tk - step, 0.0, 1.0)
        if not np.any(np.abs(step) > 1e-15):
            break
    return np.linalg.norm(at(P, tk) - points, axis=-1)


def distances_to_polylines(points: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Distance of each point ``(..., S, 3)`` to the polyline ``(..., T, 3)`` of the same batch: ``(..., S)``."""
    out = np.empty(points.shape[:-1])
    for i in np.ndindex(points.shape[:-2]):  # one line at a time: (S, T) pairs
        a, ab = lines[i][None, :-1], np.diff(lines[i], axis=0)[None]  # (1, T - 1, 3)
        p = points[i][:, None]  # (S, 1, 3)
        t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-300), 0.0, 1.0)
        out[i] = np.min(np.linalg.norm(a + t[..., None] * ab - p, axis=-1), axis=-1)
    return out


def tube_marker_distances(
    curves: PHQuintic, recording: MarkerRecording, markers: np.ndarray, frame: str = "rmf", points: int = 1001
) -> np.ndarray | None:
    """Distance of tube markers ``(N, M, S, 3)`` to the PH tube curves at their offset: ``(N, M, S)`` [m].

    For a recording with tube markers (:class:`optikin.data.cosserat_markers.CosseratRecording`):
    tube ``m`` of each curve is the offset curve of :func:`optikin.curves.tubes.tube_points` at the
    recording's tube radii and angles, carried by ``frame`` from the base x axis, sampled at
    ``points`` parameters (a polyline: its chord error is ``kappa h^2 / 8``, 0.3 um at 10 / m over 0.5 m); ``None``
    for a recording without tube markers.
    """
    if not isinstance(recording, CosseratRecording):
        return None
    layout = TubeLayout(*recording.tube_radius, recording.tube_angles, frame)
    lines = tube_points(curves, recording.base_normal, np.linspace(0.0, 1.0, points), layout)  # (N, M, T, 3)
    return distances_to_polylines(markers, lines)


def summary_of(values_mm: np.ndarray) -> dict[str, float]:
    """Min / mean / max of finite values (Table II style)."""
    v = values_mm[np.isfinite(values_mm)]
    if v.size == 0:
        return {"min": math.nan, "avg": math.nan, "max": math.nan}
    return {"min": float(v.min()), "avg": float(v.mean()), "max": float(v.max())}


# ------------------------------------------------------------------------------ smaller runs of shipped problems
def problem_variant(
    name: str,
    directory: Path,
    *,
    samples: int | None = None,
    solver: str | None = None,
    baselines: list[str] | None = None,
    options: dict[str, Any] | None = None,
    data_params: dict[str, Any] | None = None,
) -> Path:
    """A copy of problem ``name`` in ``directory`` with fewer samples, another solver, baselines or options.

    For notebooks and tests that run a shipped problem on a small setting; the copy
    keeps the name (the file stem must equal it). Returns the new file's path.
    """
    _, path = load_problem(name)
    raw = yaml.safe_load(path.read_text())
    if samples is not None:
        raw["data"]["samples"] = int(samples)
    if solver is not None:
        raw["solver"] = solver
    if baselines is not None:
        raw["baselines"] = list(baselines)
    raw["options"] = {**raw.get("options", {}), **(options or {})}
    raw["data"]["params"] = {**raw["data"].get("params", {}), **(data_params or {})}
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out = directory / f"{raw['name']}.yaml"
    out.write_text(yaml.safe_dump(raw, sort_keys=False))
    return out
