"""A ``calibrate`` outcome as a :class:`~optikin.results.Result`.

The verdict first: ``ok`` or ``not_identifiable`` (:mod:`optikin.calibration.identifiability`: the reasons,
the parameters and the options that would determine them, with the report at the start and at the solution).
The headline error is each posture's largest marker error held out (median / p95 / max [mm]) over every posture
tested, from least-squares fits of the test postures with the geometry of the folds that left them out; the
postures beyond their training fold's outlier rule are counted and listed apart, and stay in the headline.
Every reported error is a least-squares one; the robust loss is used only where the geometry is estimated.

Metrics: the estimates with their standard deviations (section lengths [mm], base
position [mm], base axis and tilt, marker offsets [mm], the actuator map ``K``, ``k0``
of bending vectors ``K (a - mean a) + k0``), the in-sample least-squares errors, the rejected postures, the
starts of the base tried (each with its held-out error), the time of the calibration and of the held-out
test, the calibrated ``arm:`` section and, for a synthetic recording, the errors of the estimates against
the truth and the held-out error that the true geometry gives on the same postures.

Arrays: ``measured`` and ``fitted`` ``(N, M, 3)`` [m], ``errors`` (least squares with the final geometry)
and ``held_out_errors`` ``(N, M)`` [m], ``held_out_posture_errors`` ``(N,)`` [m], ``fold`` ``(N,)`` (the test
fold of each posture, ``-1`` never tested: score another model on it), ``screened`` ``(N,)`` (beyond the
training fold's rule), ``weights`` ``(N, M)`` (robust), ``outlier`` ``(N,)`` (rejected from the geometry's fit),
``configurations`` ``(N, 3 m)`` ``(S, theta, phi)`` per section, ``backbone`` ``(N, 3, K)`` [m] in the
recording frame, ``parameters`` and ``std`` (shared parameters in the solver's units), ``singular_values``,
and ``truth_held_out_errors`` for a synthetic recording.

Every posture's status is ``ok`` when the final fit converged and the geometry is identifiable,
``not_converged`` when the fit did not converge, and ``failed`` when the geometry is not identifiable (the
criterion ``identifiable`` is then unmet and the run exits 1); a rejected posture is counted, flagged in
``outlier`` and its reason is a note, after the reader's notes on the recording (dropped frames, gaps, swapped
labels).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.problems import ProblemContext
from optikin.problems.calibrate.run import PRUNE, CalibrateOutcome, in_sample_median
from optikin.results import MethodRow, Result
from optikin.status import Status

MAX_OUTLIER_NOTES = 20
"""Rejected postures listed one by one in the notes (the rest are counted)."""


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
    std = cal.fit.std
    lay = cal.layout
    if not lay.extensible:
        error = cal.lengths - truth.section_lengths
        out["max section length error [mm]"] = float(np.max(np.abs(error)) * 1e3)
        with np.errstate(divide="ignore", invalid="ignore"):
            out["section length errors / std"] = (error / std[lay.lengths]).round(2).tolist()
    out["base position error [mm]"] = float(np.linalg.norm(cal.base_position - truth.base_position) * 1e3)
    cosine = float(np.clip(cal.base_rotation[:, 2] @ truth.base_rotation[:, 2], -1.0, 1.0))
    out["base tilt error [deg]"] = float(np.degrees(np.arccos(cosine)))
    if cal.problem.free[lay.offsets].any():
        sections = np.array(lay.marker_sections) - 1
        # the disks' frames turn with the rotation about the base axis, held at a reference: compare what that
        # rotation keeps, each offset's component along its disk's axis and its distance from that axis
        true = truth.marker_offsets[sections]
        axial = np.abs(cal.offsets[:, 2] - true[:, 2])
        radial = np.abs(np.hypot(cal.offsets[:, 0], cal.offsets[:, 1]) - np.hypot(true[:, 0], true[:, 1]))
        out["max marker offset error, axial and radial [mm]"] = [float(axial.max() * 1e3), float(radial.max() * 1e3)]
    rejected = np.zeros(len(outcome.measured), dtype=bool)
    rejected[[o.posture for o in cal.outliers]] = True
    out["corrupted postures rejected"] = f"{int((rejected & truth.corrupted).sum())}/{int(truth.corrupted.sum())}"
    out["clean postures rejected"] = int((rejected & ~truth.corrupted).sum())
    if outcome.truth_held_out is not None:
        true_rms = float(np.sqrt(np.nanmean(outcome.truth_held_out**2)))
        finite = np.isfinite(outcome.truth_held_out)
        true_posture = np.where(
            finite.any(axis=1), np.max(np.where(finite, outcome.truth_held_out, -1), axis=1), np.nan
        )
        true_median = float(np.nanmedian(true_posture))
        out["held-out RMS with the true geometry [mm]"] = true_rms * 1e3
        out["held-out RMS / true geometry's"] = outcome.held_out.rms / true_rms
        out["held-out median largest-marker error with the true geometry [mm]"] = true_median * 1e3
        out["held-out median largest-marker error / true geometry's"] = (
            outcome.held_out.headline()["median"] / true_median
        )
    return out


def mm(values: dict[str, float]) -> dict[str, float]:
    return {k: float(f"{v * 1e3:.4g}") if np.isfinite(v) else float("nan") for k, v in values.items()}


def screening_metrics(outcome: CalibrateOutcome) -> dict[str, Any]:
    """The held-out test's screening: the rule, how many test postures it flags, which, and their errors."""
    test = outcome.held_out
    flagged = np.flatnonzero(test.screened)
    return {
        "rule": f"a test posture whose largest marker error exceeds {test.threshold:g} x its training fold's median "
        "marker error (the rule that rejects training postures from that fold's fit)",
        "training fold limits [mm]": (np.asarray(test.limits) * 1e3).round(4).tolist(),
        "postures flagged": int(len(flagged)),
        "flagged postures": flagged.tolist()[:200],
        "largest-marker error of the flagged [mm]": mm(test.headline(screened=True)),
        "largest-marker error of the others [mm]": mm(test.headline(screened=False)),
        "postures rejected from the training folds": [len(r) for r in test.training_outliers],
    }


def result_of(ctx: ProblemContext, outcome: CalibrateOutcome) -> Result:
    """The :class:`~optikin.results.Result` of a ``calibrate`` run (module docstring)."""
    cal, test = outcome.calibration, outcome.held_out
    N = len(outcome.measured)
    ls = cal.least_squares if cal.least_squares is not None else cal.fit
    errors = ls.errors
    weights = np.zeros_like(errors)
    weights[cal.kept] = cal.fit.weights
    outlier = np.zeros(N, dtype=bool)
    outlier[[o.posture for o in cal.outliers]] = True
    X = ls.X
    Q = cal.configurations(X)
    fitted = cal.problem.model.evaluate(X, cal.fit.beta, cal.problem.ref, False, cal.actuators)[0].reshape(N, -1, 3)
    report = cal.identifiability
    verdict = cal.verdict
    identifiability = {} if report is None else report.summary()
    start = {} if cal.identifiability_start is None else cal.identifiability_start.summary()
    finite = np.where(np.isfinite(errors), errors, -1.0)
    largest = np.where(np.isfinite(errors).any(axis=1), finite.max(axis=1), np.nan)
    tested = int(test.tested.sum())
    headline_name = f"held-out largest-marker error per posture, {tested} of {N} postures ({test.method}) [mm]"
    metrics: dict[str, Any] = {
        "verdict": verdict,
        "postures": N,
        "markers": ", ".join(f"{n} (section {s})" for n, s in zip(outcome.marker_names, cal.layout.marker_sections)),
        headline_name: mm(test.headline()),
        "held-out screening": screening_metrics(outcome),
        "losses": f"geometry estimated with loss {cal.problem.loss} (scale {cal.problem.loss_scale * 1e3:g} mm); "
        "every reported error from least-squares fits",
        "base start chosen": outcome.chosen,
        "postures rejected": len(cal.outliers),
        **estimates(outcome),
        "identifiability": identifiability,
        "identifiability at the start": start,
        "largest-marker error per posture, in sample [mm]": mm(
            {
                "median": float(np.nanmedian(largest)),
                "p95": float(np.nanpercentile(largest, 95)),
                "max": float(np.nanmax(largest)),
            }
        ),
        "median marker error [mm]": float(np.nanmedian(errors) * 1e3),
        "RMS marker error [mm]": float(np.sqrt(np.nanmean(errors**2)) * 1e3),
        "residual sigma per coordinate [mm]": cal.fit.sigma * 1e3,
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
    notes = []
    if report is not None and verdict != Status.OK:
        notes.append("not identifiable: " + "; ".join(report.reasons))
        notes += [f"to determine it: {r}" for r in identifiability.get("remedies", [])]
    reader = outcome.recording.notes
    notes += [f"reader: {n}" for n in reader[:MAX_OUTLIER_NOTES]]
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
    status = Status.FAILED if verdict != Status.OK else Status.OK if cal.fit.converged else Status.NOT_CONVERGED
    comparison = [
        MethodRow(
            f"start: {c.name}" if len(outcome.candidates) > 1 else "levenberg-marquardt-schur",
            "solver" if c.name == outcome.chosen else "variant",
            {
                "verdict": c.calibration.verdict,
                "loss": c.calibration.problem.loss,
                "converged": c.calibration.fit.converged,
                "iterations": c.calibration.fit.iterations,
                "section lengths [mm]": (c.calibration.lengths * 1e3).round(2).tolist(),
                "in-sample median [mm]": in_sample_median(c.calibration) * 1e3,
                **{
                    f"held-out {k} [mm]": (v * 1e3 if c.held_out is not None else float("nan"))
                    for k, v in (c.held_out or test).headline().items()
                },
                "calibration time [s]": c.seconds,
            },
        )
        for c in outcome.candidates
    ]
    pruned = [c.name for c in outcome.candidates if c.held_out is None]
    if pruned:
        notes.append(
            f"start(s) {', '.join(pruned)}: in-sample error above {PRUNE:g} x the best start's, no held-out test "
            "(it cannot win)"
        )
    arrays = {
        "measured": outcome.measured,
        "fitted": fitted,
        "errors": errors,
        "held_out_errors": test.errors,
        "held_out_posture_errors": test.posture_errors,
        "fold": test.fold,
        "screened": test.screened,
        "weights": weights,
        "outlier": outlier,
        "configurations": Q,
        "backbone": backbones(outcome, Q),
        "parameters": cal.fit.beta,
        "std": cal.fit.std,
        "singular_values": np.zeros(0) if report is None else report.singular_values,
    }
    if outcome.truth_held_out is not None:
        arrays["truth_held_out_errors"] = outcome.truth_held_out
    return ctx.result(
        solver="levenberg-marquardt-schur",
        status=[status] * N,
        iterations=np.full(N, cal.fit.iterations),
        residuals=np.where(np.isfinite(largest), largest, 0.0),
        timings={"calibration [s]": outcome.seconds, "held-out test [s]": outcome.held_out_seconds},
        metrics=metrics,
        comparison=comparison,
        arrays=arrays,
        notes=notes,
        criteria={"converged": bool(cal.fit.converged), "identifiable": verdict == Status.OK},
    )
