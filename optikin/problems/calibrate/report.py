"""A ``calibrate`` outcome as a :class:`~optikin.results.Result`.

Metrics: the estimates with their standard deviations (section lengths [mm], base
position [mm], base axis and tilt, marker offsets [mm], the actuator map ``K``, ``k0``
of bending vectors ``K (a - mean a) + k0``), the marker errors of the
fit and the held-out error (median and RMS [mm]), the rejected postures, the time of
the calibration and of the held-out test, the calibrated ``arm:`` section and, for a
synthetic recording, the errors of the estimates against the truth and the held-out
error that the true geometry gives on the same postures.

Arrays: ``measured`` and ``fitted`` ``(N, M, 3)`` [m], ``errors`` (final fit; the screening
fit's for rejected postures) and ``held_out_errors`` ``(N, M)`` [m], ``weights`` ``(N, M)`` (robust), ``outlier``
``(N,)``, ``configurations`` ``(N, 3 m)`` ``(S, theta, phi)`` per section,
``backbone`` ``(N, 3, K)`` [m] in the recording frame, ``parameters`` and ``std``
(shared parameters in the solver's units), and ``truth_held_out_errors`` for a
synthetic recording.

Every posture's status is ``ok`` when the final fit converged (``not_converged``
otherwise); a rejected posture is counted, flagged in ``outlier`` and its reason is a note, after
the reader's notes on the recording (dropped frames, gaps, swapped labels).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.problems import ProblemContext
from optikin.problems.calibrate.run import CalibrateOutcome
from optikin.results import MethodRow, Result

MAX_OUTLIER_NOTES = 20
"""Rejected postures listed one by one in the notes (the rest are counted)."""


def all_configurations(outcome: CalibrateOutcome) -> np.ndarray:
    """``(N, n_x)`` per-posture variables of every posture: the final fit's, the screening fit's for rejected ones."""
    cal = outcome.calibration
    X = cal.robust.X.copy()
    X[cal.kept] = cal.fit.X
    return X


def backbones(outcome: CalibrateOutcome, Q: np.ndarray) -> np.ndarray:
    """``(N, 3, K)`` backbone points [m] of the calibrated arm in the recording frame."""
    cal = outcome.calibration
    params = outcome.arm["params"]
    lo, hi = params["length_range"]
    arm = ConstantCurvatureArm(tuple(params["section_lengths"]), (lo, hi), np.pi, "calibrated", 12)
    points = arm.evaluate("backbone", Q)
    if points.ndim == 2:
        points = points[None]
    return cal.base_position[None, :, None] + np.einsum("ij,njk->nik", cal.base_rotation, points)


def estimates(outcome: CalibrateOutcome) -> dict[str, Any]:
    """The estimates with their standard deviations, in mm and degrees."""
    cal = outcome.calibration
    lay = cal.layout
    std = cal.fit.std
    out: dict[str, Any] = {}
    if lay.extensible:
        out["section lengths, median [mm]"] = (cal.lengths * 1e3).round(3).tolist()
        out["section length ranges [mm]"] = (cal.length_ranges * 1e3).round(3).tolist()
    else:
        out["section lengths [mm]"] = (cal.lengths * 1e3).round(3).tolist()
        out["section lengths std [mm]"] = (std[lay.lengths] * 1e3).round(4).tolist()
    out["base position [mm]"] = (cal.base_position * 1e3).round(3).tolist()
    out["base position std [mm]"] = (std[lay.position] * 1e3).round(4).tolist()
    out["base axis (z) in the recording frame"] = cal.base_rotation[:, 2].round(6).tolist()
    out["base tilt std [deg]"] = np.degrees(std[lay.rotation][:2]).round(4).tolist()
    if lay.actuated:
        K, k0 = cal.actuator_map
        out["actuator map K [rad per reading unit]"] = K.round(4).tolist()
        out["actuator map k0 [rad]"] = k0.round(5).tolist()
    if cal.problem.free[lay.offsets].any():
        out["marker offsets [mm]"] = {n: (o * 1e3).round(3).tolist() for n, o in zip(cal.marker_names, cal.offsets)}
        out["marker offsets std [mm]"] = (std[lay.offsets].reshape(-1, 3) * 1e3).round(4).tolist()
    return out


def truth_metrics(outcome: CalibrateOutcome) -> dict[str, Any]:
    """Errors of the estimates against a synthetic recording's truth."""
    truth, cal = outcome.truth, outcome.calibration
    if truth is None:
        return {}
    out: dict[str, Any] = {}
    if not cal.layout.extensible:
        out["max section length error [mm]"] = float(np.max(np.abs(cal.lengths - truth.section_lengths)) * 1e3)
    out["base position error [mm]"] = float(np.linalg.norm(cal.base_position - truth.base_position) * 1e3)
    cosine = float(np.clip(cal.base_rotation[:, 2] @ truth.base_rotation[:, 2], -1.0, 1.0))
    out["base tilt error [deg]"] = float(np.degrees(np.arccos(cosine)))
    if cal.problem.free[cal.layout.offsets].any():
        sections = np.array(cal.layout.marker_sections) - 1
        out["max marker offset error [mm]"] = float(np.max(np.abs(cal.offsets - truth.marker_offsets[sections])) * 1e3)
    rejected = np.zeros(len(outcome.measured), dtype=bool)
    rejected[[o.posture for o in cal.outliers]] = True
    out["corrupted postures rejected"] = f"{int((rejected & truth.corrupted).sum())}/{int(truth.corrupted.sum())}"
    out["clean postures rejected"] = int((rejected & ~truth.corrupted).sum())
    if outcome.truth_held_out is not None:
        true_rms = float(np.sqrt(np.nanmean(outcome.truth_held_out**2)))
        out["held-out RMS with the true geometry [mm]"] = true_rms * 1e3
        out["held-out RMS / true geometry's"] = outcome.held_out.rms / true_rms
    return out


def result_of(ctx: ProblemContext, outcome: CalibrateOutcome) -> Result:
    """The :class:`~optikin.results.Result` of a ``calibrate`` run (module docstring)."""
    cal, test = outcome.calibration, outcome.held_out
    N = len(outcome.measured)
    kept_errors = cal.robust.errors.copy()
    kept_errors[cal.kept] = cal.fit.errors
    held = np.full_like(kept_errors, np.nan)
    held[cal.kept] = test.errors
    weights = np.zeros_like(kept_errors)
    weights[cal.kept] = cal.fit.weights
    outlier = np.zeros(N, dtype=bool)
    outlier[[o.posture for o in cal.outliers]] = True
    X = all_configurations(outcome)
    Q = cal.configurations(X)
    fitted = cal.problem.model.evaluate(X, cal.fit.beta, cal.problem.ref, False, cal.actuators)[0].reshape(N, -1, 3)
    metrics: dict[str, Any] = {
        "postures": N,
        "markers": ", ".join(f"{n} (section {s})" for n, s in zip(outcome.marker_names, cal.layout.marker_sections)),
        "postures rejected": len(cal.outliers),
        **estimates(outcome),
        "median marker error [mm]": float(np.nanmedian(cal.fit.errors) * 1e3),
        "RMS marker error [mm]": float(np.sqrt(np.nanmean(cal.fit.errors**2)) * 1e3),
        "residual sigma per coordinate [mm]": cal.fit.sigma * 1e3,
        f"held-out median marker error ({test.method}) [mm]": test.median * 1e3,
        f"held-out RMS marker error ({test.method}) [mm]": test.rms * 1e3,
        "calibration time [s]": outcome.seconds,
        "held-out test time [s]": outcome.held_out_seconds,
        "iterations (screening, final)": [cal.robust.iterations, cal.fit.iterations],
        **truth_metrics(outcome),
        "calibrated arm": outcome.arm,
        "calibration": outcome.facts,
    }
    for option, file in outcome.written.items():
        metrics[option.replace("_", " ")] = str(file)
    reader = outcome.recording.notes
    notes = [f"reader: {n}" for n in reader[:MAX_OUTLIER_NOTES]]
    if len(reader) > MAX_OUTLIER_NOTES:
        notes.append(f"reader: ... and {len(reader) - MAX_OUTLIER_NOTES} more notes")
    notes += [f"posture {o.posture} rejected: {o.reason}" for o in cal.outliers[:MAX_OUTLIER_NOTES]]
    if len(cal.outliers) > MAX_OUTLIER_NOTES:
        notes.append(f"... and {len(cal.outliers) - MAX_OUTLIER_NOTES} more rejected postures (array outlier)")
    if not cal.problem.free[cal.layout.rotation][2]:
        notes.append(
            "the rotation of the base about its own axis is not observable from marker positions on a "
            "torsion-free arm: it is held at the reference orientation (options.base.orientation, else the "
            "recording's x axis across the base axis)"
        )
    status = "ok" if cal.fit.converged else "not_converged"
    comparison = [
        MethodRow(
            "levenberg-marquardt-schur",
            "solver",
            {
                "loss": cal.problem.loss,
                "converged": cal.fit.converged,
                "iterations": cal.fit.iterations,
                "calibration time [s]": outcome.seconds,
                "median marker error [mm]": float(np.nanmedian(cal.fit.errors) * 1e3),
                "held-out RMS [mm]": test.rms * 1e3,
            },
        )
    ]
    arrays = {
        "measured": outcome.measured,
        "fitted": fitted,
        "errors": kept_errors,
        "held_out_errors": held,
        "weights": weights,
        "outlier": outlier,
        "configurations": Q,
        "backbone": backbones(outcome, Q),
        "parameters": cal.fit.beta,
        "std": cal.fit.std,
    }
    if outcome.truth_held_out is not None:
        truth_held = np.full_like(held, np.nan)
        truth_held[cal.kept] = outcome.truth_held_out
        arrays["truth_held_out_errors"] = truth_held
    return ctx.result(
        solver="levenberg-marquardt-schur",
        status=[status] * N,
        iterations=np.full(N, cal.fit.iterations),
        residuals=np.max(np.where(np.isfinite(kept_errors), kept_errors, 0.0), axis=1),
        timings={"calibration [s]": outcome.seconds, "held-out test [s]": outcome.held_out_seconds},
        metrics=metrics,
        comparison=comparison,
        arrays=arrays,
        notes=notes,
        criteria={"converged": bool(cal.fit.converged)},
    )
