"""Run a ``calibrate`` problem: read the recording, calibrate, measure the held-out error, compare with any truth."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optikin.algebra import matrix_from_quat, rotation_vector_from_matrix
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.calibration.calibrate import (
    SCREENING_ITERATIONS,
    Calibration,
    HeldOut,
    calibrate,
    fit_postures,
    folds_of,
    held_out,
    initial_base,
    reference_orientation,
)
from optikin.calibration.export import (
    arm_section,
    base_frame_points,
    calibration_facts,
    marker_recording,
    write_arm_file,
    write_folds_csv,
    write_points_csv,
    write_target_csv,
)
from optikin.calibration.synthetic import CalibrationTruth
from optikin.data.markers import write_marker_csv
from optikin.data.recording import FrameOptions, Recording, frame_matrix
from optikin.errors import InputDataError
from optikin.problems import ProblemContext
from optikin.problems.calibrate.options import BaseOptions, CalibrateOptions


@dataclass(eq=False)
class CalibrateOutcome:
    """What a ``calibrate`` run produced."""

    recording: Recording
    marker_names: list[str]
    measured: np.ndarray
    calibration: Calibration
    held_out: HeldOut
    arm: dict
    facts: dict
    truth: CalibrationTruth | None
    truth_held_out: np.ndarray | None
    seconds: float
    held_out_seconds: float
    written: dict[str, Path]
    candidates: list["Candidate"]
    chosen: str


def tracks_of(recording: Recording) -> dict[str, np.ndarray]:
    """Every tracked point of a recording by name: its markers, then the positions of its rigid bodies."""
    tracks = dict(recording.markers)
    for name, body in recording.bodies.items():
        tracks.setdefault(name, body.positions)
    return tracks


def markers_of(ctx: ProblemContext, recording: Recording, n_sections: int) -> tuple[list[str], list[int], np.ndarray]:
    """The points used, the section end of each and their positions ``(N, M, 3)``: ``options.markers`` (markers
    or rigid bodies by name), else the recording's markers, else its rigid bodies, when one per section."""
    options: CalibrateOptions = ctx.options
    tracks = tracks_of(recording)
    if options.markers is not None:
        names = list(options.markers)
        sections = [options.markers[n] for n in names]
        for name, section in zip(names, sections):
            if name not in tracks:
                raise ctx.error(
                    f"options.markers.{name}", f"no such marker or rigid body; the recording has {sorted(tracks)}"
                )
            if not 1 <= section <= n_sections:
                raise ctx.error(f"options.markers.{name}", f"section {section} outside 1..{n_sections}")
    elif len(recording.markers) == n_sections:
        names, sections = list(recording.markers), list(range(1, n_sections + 1))
    elif len(recording.bodies) == n_sections:
        names, sections = list(recording.bodies), list(range(1, n_sections + 1))
    else:
        raise ctx.error(
            "options.markers",
            f"the recording has {len(recording.markers)} markers and {len(recording.bodies)} rigid bodies for "
            f"{n_sections} sections: say which disk carries each",
        )
    return names, sections, np.stack([tracks[n] for n in names], axis=1)


def truth_beta(calibration: Calibration, truth: CalibrationTruth) -> np.ndarray:
    """The true geometry in the calibration's parameters (the rotation about its reference orientation)."""
    lay = calibration.layout
    beta = np.zeros(lay.n_beta)
    beta[lay.lengths] = truth.section_lengths[lay.lengths]
    beta[lay.position] = truth.base_position
    beta[lay.rotation] = rotation_vector_from_matrix(calibration.problem.ref.T @ truth.base_rotation)
    sections = np.array(lay.marker_sections) - 1
    beta[lay.offsets] = truth.marker_offsets[sections].ravel()
    return beta


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation nearest (Frobenius) to the mean of rotations ``R (N, 3, 3)``: the polar factor by SVD."""
    U, _, Vt = np.linalg.svd(np.mean(R, axis=0))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


DEFAULT_LENGTH_BOUNDS = (0.5, 2.0)
"""Bounds of the estimated section lengths, as fractions of the nominal ones, when the arm gives no
``length_range``: a section is not half or twice the length it was built with."""
HYPOTHESES = (("from the data", None), ("hanging", (0.0, 0.0, -1.0)), ("standing", (0.0, 0.0, 1.0)))
"""The starts of an estimated base: the base axis from the chords between disks (:func:`initial_base`), straight
down and straight up in optikin's z-up frame (each with its position on that axis behind the first disks)."""


PRUNE = 2.0
"""Several starts are first run for the screening fit's steps alone (:data:`SCREENING_ITERATIONS`); one whose
in-sample error (median largest-marker error, least squares) then exceeds this many times the best start's is
not run on, and one whose converged in-sample error does is reported without a held-out test: it cannot win
(a held-out error is not below the in-sample one of the same geometry by that much)."""


@dataclass(eq=False)
class Candidate:
    """One start of the base and where it led (``held_out`` None: pruned, :data:`PRUNE`; a start that reached
    the geometry of an earlier one, :func:`same_geometry`, shares its held-out test)."""

    name: str
    calibration: Calibration
    held_out: HeldOut | None
    seconds: float
    held_out_seconds: float


def length_bounds_of(ctx: ProblemContext) -> tuple[float, float]:
    """The arm's ``length_range`` where the problem file gives one, else :data:`DEFAULT_LENGTH_BOUNDS`."""
    arm = ctx.arm
    if ctx.spec.arm is not None and "length_range" in ctx.spec.arm.params and isinstance(arm, ConstantCurvatureArm):
        return arm.length_range
    return DEFAULT_LENGTH_BOUNDS


def recording_axes(ctx: ProblemContext) -> np.ndarray:
    """``A`` taking the recording's axes to optikin's (its source's ``frame``), the identity without one."""
    frame = getattr(ctx.data_params, "frame", None)
    return frame_matrix(frame) if isinstance(frame, FrameOptions) else np.eye(3)


def mount_of(ctx: ProblemContext, base: BaseOptions) -> tuple[tuple[int, float] | None, np.ndarray | None]:
    """``options.base.plane`` and ``direction`` in optikin's frame: ``(axis index, value [m])`` and ``(3,)``."""
    A = recording_axes(ctx)
    plane = None
    if base.plane is not None:
        if len(base.plane) != 1:
            raise ctx.error(
                "options.base.plane", f"give one coordinate of the mount plane, e.g. {{y: 0.0}}, got {base.plane}"
            )
        ((axis, value),) = base.plane.items()
        image = A @ np.eye(3)["xyz".index(axis)]
        k = int(np.argmax(np.abs(image)))
        plane = (k, float(np.sign(image[k]) * value))
    direction = None
    if base.direction is not None:
        d = np.asarray(base.direction, dtype=float)
        if not np.linalg.norm(d) > 0:
            raise ctx.error("options.base.direction", "the exit direction must not be zero")
        direction = A @ (d / np.linalg.norm(d))
    return plane, direction


def solve(ctx: ProblemContext) -> CalibrateOutcome:
    """Calibrate the arm of ``ctx`` on the recording of ``data``."""
    options: CalibrateOptions = ctx.options
    arm = ctx.arm
    if not isinstance(arm, ConstantCurvatureArm):
        raise ctx.error("arm.type", f"kind calibrate calibrates constant_curvature arms, not {ctx.arm_type!r}")
    recording: Recording = ctx.load_data()
    names, sections, measured = markers_of(ctx, recording, arm.n_sections)
    seen = np.all(np.isfinite(measured), axis=2)
    if not seen.any():
        raise InputDataError("no marker is ever seen: nothing to calibrate", source=ctx.spec.data.source)
    readings = None
    if options.actuator_map == "linear":
        channels = list(recording.actuators) if options.actuators is None else options.actuators
        missing = [c for c in channels if c not in recording.actuators]
        if missing or not channels:
            raise ctx.error(
                "options.actuators" if missing else "options.actuator_map",
                f"no actuator channel {missing[0]!r}; the recording has {sorted(recording.actuators)}"
                if missing
                else "the recording has no actuator channels",
            )
        readings = np.column_stack([recording.actuators[c] for c in channels])
        bad = ~np.all(np.isfinite(readings), axis=1)
        if bad.any():
            raise InputDataError(
                "actuator readings must be finite", source=ctx.spec.data.source, sample=int(np.argmax(bad))
            )
    base = options.base
    rotation = None
    position = base.position
    if base.body is not None:
        if base.position is not None or base.orientation is not None:
            raise ctx.error("options.base.body", "give the base as a rigid body or as position and orientation")
        if base.body not in recording.bodies:
            raise ctx.error("options.base.body", f"no such rigid body; the recording has {sorted(recording.bodies)}")
        track = recording.bodies[base.body]
        seen = np.all(np.isfinite(track.positions), axis=1) & np.all(np.isfinite(track.quaternions), axis=1)
        if not seen.any():
            raise InputDataError("the base body is never tracked", source=ctx.spec.data.source, field=base.body)
        position = np.mean(track.positions[seen], axis=0).tolist()
        rotation = mean_rotation(matrix_from_quat(track.quaternions[seen], check=False))
    elif base.orientation is not None:
        q = np.array(base.orientation)
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            raise ctx.error("options.base.orientation", "expected a unit quaternion (w, x, y, z)")
        rotation = matrix_from_quat(q / np.linalg.norm(q))
    plane, direction = mount_of(ctx, base)
    if direction is not None and (base.body is not None or base.orientation is not None):
        raise ctx.error(
            "options.base.direction", "give the base axis once: as the exit direction, or by a body or orientation"
        )
    estimated = (
        base.starts == "several"
        and base.body is None
        and base.position is None
        and base.orientation is None
        and plane is None
        and direction is None
        and not base.fix
    )
    starts = HYPOTHESES if estimated else HYPOTHESES[:1]
    sigma_deg = base.orientation_sigma_deg
    bounds = length_bounds_of(ctx) if options.lengths == "estimate" else None
    h = options.holdout
    fold = folds_of(len(measured), h.method, h.folds, h.test_fraction, ctx.rng(1))

    def run_start(axis: tuple[float, float, float] | None, iterations: int) -> tuple[Calibration, float]:
        start_position, start_rotation = position, rotation
        if axis is not None:
            start_position = initial_base(measured, sections, float(arm.section_lengths[0]), np.array(axis))[0].tolist()
            start_rotation = reference_orientation(np.array(axis))
        started = time.perf_counter()
        calibration = calibrate(
            measured,
            arm.section_lengths.tolist(),
            sections,
            names,
            base_position=start_position,
            base_rotation=start_rotation,
            position_sigma=base.position_sigma,
            orientation_sigma=None if sigma_deg is None else float(np.radians(sigma_deg)),
            fix=base.fix,
            plane=plane,
            direction=None if direction is None else direction.tolist(),
            estimate_yaw=base.estimate_yaw,
            fix_lengths=options.lengths == "fixed",
            length_bounds=bounds,
            offsets=options.offsets == "per_marker",
            offset_sigma=options.offset_sigma,
            extensible=options.lengths == "extensible",
            actuators=readings,
            loss=options.loss,
            loss_scale=options.loss_scale,
            marker_noise=options.marker_noise,
            outlier_threshold=options.outlier_threshold,
            max_iterations=iterations,
            tolerance=options.tolerance,
            max_std=options.identifiability.max_std * 1e-3,
        )
        return calibration, time.perf_counter() - started

    calibrations: list[tuple[str, Calibration, float]] = []
    task = f"calibrate: {len(measured)} postures x {len(names)} markers, {len(starts)} start(s)"
    with ctx.progress.task(task, total=2 * len(starts)) as advance:
        short = [run_start(axis, min(SCREENING_ITERATIONS, options.max_iterations)) for _, axis in starts]
        best_short = min(in_sample_median(c) for c, _ in short) if len(starts) > 1 else np.inf
        for (label, axis), (quick, quick_seconds) in zip(starts, short):
            if in_sample_median(quick) <= PRUNE * best_short:
                calibrations.append((label, *run_start(axis, options.max_iterations)))
            else:
                calibrations.append((label, quick, quick_seconds))
            advance()
        best_in_sample = min(in_sample_median(c) for _, c, _ in calibrations)
        candidates: list[Candidate] = []
        for label, calibration, seconds in calibrations:
            started = time.perf_counter()
            same = next((c for c in candidates if c.held_out and same_geometry(c.calibration, calibration)), None)
            test: HeldOut | None = same.held_out if same is not None else None
            if same is None and in_sample_median(calibration) <= PRUNE * best_in_sample:
                test = held_out(calibration, fold=fold)
            candidates.append(Candidate(label, calibration, test, seconds, time.perf_counter() - started))
            advance()
    tested = [c for c in candidates if c.held_out is not None]
    best = min(tested, key=lambda c: _finite_or_inf(c.held_out.headline()["median"]) if c.held_out else np.inf)
    calibration = best.calibration
    assert best.held_out is not None
    test = best.held_out
    truth = getattr(recording, "truth", None)
    truth_errors = None
    lay = calibration.layout
    if isinstance(truth, CalibrationTruth) and not lay.extensible and not lay.actuated:
        assert calibration.full is not None
        rows = np.flatnonzero(test.tested)
        truth_errors = np.full(test.errors.shape, np.nan)
        X0 = calibration.X_all[rows]
        subset = calibration.full.subset(rows)
        truth_errors[rows] = fit_postures(subset, truth_beta(calibration, truth), X0, loss="linear").errors
    section = arm_section(calibration, arm)
    facts = calibration_facts(calibration, test)
    written: dict[str, Path] = {}
    try:
        if options.arm_file is not None:
            written["arm_file"] = (ctx.path.parent / options.arm_file).resolve()
            write_arm_file(written["arm_file"], section, facts, ctx.path.name)
        if options.targets_file is not None:
            written["targets_file"] = (ctx.path.parent / options.targets_file).resolve()
            points = base_frame_points(calibration, measured[calibration.kept, int(np.argmax(sections))])
            postures = np.arange(len(measured))[calibration.kept]
            write_target_csv(written["targets_file"], recording.time[calibration.kept], points, postures)
        if options.points_file is not None:
            written["points_file"] = (ctx.path.parent / options.points_file).resolve()
            postures = np.arange(len(measured))[calibration.kept]
            write_points_csv(written["points_file"], names, measured[calibration.kept], postures)
        if options.folds_file is not None:
            written["folds_file"] = (ctx.path.parent / options.folds_file).resolve()
            write_folds_csv(written["folds_file"], test.fold)
        if options.markers_file is not None:
            written["markers_file"] = (ctx.path.parent / options.markers_file).resolve()
            tip = names[int(np.argmax(sections))]
            others = [n for n in names if n != tip]
            if not others:
                raise ctx.error("options.markers_file", "needs a marker besides the tip's to check the backbone")
            intermediate = measured[:, [names.index(n) for n in others]]
            write_marker_csv(marker_recording(calibration, recording, intermediate), written["markers_file"])
    except OSError as exc:
        field = next(reversed(written))
        raise ctx.error(f"options.{field}", f"cannot write {written[field]}: {exc.strerror or exc}") from None
    return CalibrateOutcome(
        recording,
        names,
        measured,
        calibration,
        test,
        section,
        facts,
        truth if isinstance(truth, CalibrationTruth) else None,
        truth_errors,
        best.seconds,
        best.held_out_seconds,
        written,
        candidates,
        best.name,
    )


def _finite_or_inf(x: float) -> float:
    return x if np.isfinite(x) else np.inf


def in_sample_median(calibration: Calibration) -> float:
    """The median over the postures of each one's largest least-squares marker error in sample [m]."""
    errors = calibration.least_squares.errors if calibration.least_squares is not None else calibration.fit.errors
    finite = np.isfinite(errors)
    largest = np.max(np.where(finite, errors, -np.inf), axis=1)[finite.any(axis=1)]
    return _finite_or_inf(float(np.median(largest))) if len(largest) else np.inf


def same_geometry(a: Calibration, b: Calibration) -> bool:
    """Two starts that reached the same geometry (section lengths, base position, base axis, offsets: to 1e-6 m
    or rad; the rotation about the base axis, held at each start's reference, is not compared) and kept the
    same postures."""
    if not np.array_equal(a.kept, b.kept) or a.layout != b.layout:
        return False
    pairs = [
        (a.lengths, b.lengths),
        (a.base_position, b.base_position),
        (a.base_rotation[:, 2], b.base_rotation[:, 2]),
        (a.offsets, b.offsets),
    ]
    return all(np.max(np.abs(x - y), initial=0.0) <= 1e-6 for x, y in pairs)
