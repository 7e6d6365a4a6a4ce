"""Run a ``calibrate`` problem: read the recording, calibrate, measure the held-out error, compare with any truth."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optikin.algebra import matrix_from_quat
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.calibration.calibrate import Calibration, HeldOut, calibrate, fit_postures, held_out
from optikin.calibration.export import (
    arm_section,
    base_frame_points,
    calibration_facts,
    marker_recording,
    write_arm_file,
    write_points_csv,
    write_target_csv,
)
from optikin.data.markers import write_marker_csv
from optikin.calibration.model import vector_from_rotation_np
from optikin.calibration.synthetic import CalibrationTruth
from optikin.data.recording import Recording
from optikin.errors import InputDataError
from optikin.problems import ProblemContext
from optikin.problems.calibrate.options import CalibrateOptions


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
    beta[lay.rotation] = vector_from_rotation_np(calibration.problem.ref.T @ truth.base_rotation)
    sections = np.array(lay.marker_sections) - 1
    beta[lay.offsets] = truth.marker_offsets[sections].ravel()
    return beta


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation nearest (Frobenius) to the mean of rotations ``R (N, 3, 3)``: the polar factor by SVD."""
    U, _, Vt = np.linalg.svd(np.mean(R, axis=0))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def solve(ctx: ProblemContext) -> CalibrateOutcome:
    """Calibrate the arm of ``ctx`` on the recording of ``data``."""
    options: CalibrateOptions = ctx.options
    arm = ctx.arm
    if not isinstance(arm, ConstantCurvatureArm):
        raise ctx.error("arm.type", f"kind calibrate calibrates constant_curvature arms, not {ctx.arm_type!r}")
    recording: Recording = ctx.load_data()
    names, sections, measured = markers_of(ctx, recording, arm.n_sections)
    seen = np.all(np.isfinite(measured), axis=2)
    if seen.sum() * 3 <= 2 * arm.n_sections * len(measured) + arm.n_sections + 5:
        raise InputDataError(
            f"{int(seen.sum())} marker samples in {len(measured)} postures are too few to calibrate",
            source=ctx.spec.data.source,
        )
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
    sigma_deg = base.orientation_sigma_deg
    started = time.perf_counter()
    with ctx.progress.task(f"calibrate: {len(measured)} postures x {len(names)} markers", total=2) as advance:
        calibration = calibrate(
            measured,
            arm.section_lengths.tolist(),
            sections,
            names,
            base_position=position,
            base_rotation=rotation,
            position_sigma=base.position_sigma,
            orientation_sigma=None if sigma_deg is None else float(np.radians(sigma_deg)),
            fix=base.fix,
            estimate_yaw=base.estimate_yaw,
            fix_lengths=options.lengths == "fixed",
            offsets=options.offsets == "per_marker",
            offset_sigma=options.offset_sigma,
            extensible=options.lengths == "extensible",
            actuators=readings,
            loss=options.loss,
            loss_scale=options.loss_scale,
            marker_noise=options.marker_noise,
            outlier_threshold=options.outlier_threshold,
            max_iterations=options.max_iterations,
            tolerance=options.tolerance,
        )
        seconds = time.perf_counter() - started
        advance()
        h = options.holdout
        started = time.perf_counter()
        test = held_out(
            calibration, h.method, h.folds, h.test_fraction, ctx.rng(1), options.max_iterations, options.tolerance
        )
        held_out_seconds = time.perf_counter() - started
        advance()
    truth = getattr(recording, "truth", None)
    truth_errors = None
    lay = calibration.layout
    if isinstance(truth, CalibrationTruth) and not lay.extensible and not lay.actuated:
        tested = test.fold >= 0
        subset = calibration.problem.subset(np.flatnonzero(tested))
        truth_errors = np.full(test.errors.shape, np.nan)
        X0 = calibration.fit.X[tested]
        truth_errors[tested] = fit_postures(subset, truth_beta(calibration, truth), X0).errors
    section = arm_section(calibration, arm)
    facts = calibration_facts(calibration, test.median)
    written: dict[str, Path] = {}
    try:
        if options.arm_file is not None:
            written["arm_file"] = (ctx.path.parent / options.arm_file).resolve()
            write_arm_file(written["arm_file"], section, facts, ctx.path.name)
        if options.targets_file is not None:
            written["targets_file"] = (ctx.path.parent / options.targets_file).resolve()
            tip = names[int(np.argmax(sections))]
            points = base_frame_points(calibration, measured[calibration.kept, int(np.argmax(sections))])
            write_target_csv(written["targets_file"], recording.time[calibration.kept], points)
        if options.points_file is not None:
            written["points_file"] = (ctx.path.parent / options.points_file).resolve()
            write_points_csv(written["points_file"], names, measured[calibration.kept])
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
        seconds,
        held_out_seconds,
        written,
    )
