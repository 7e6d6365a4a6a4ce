"""An ``actuation`` outcome as a :class:`~optikin.results.Result`.

The headline is, for every method at every share of the training folds, each held-out posture's largest marker
error (median / p95 / max [mm]) over every posture of the recording (a posture the physics model gives no
equilibrium for counts as an infinite error). The comparison has one row per method, its metrics at every share;
the metrics say whether the physics model beats the best regressor at the smallest share and at the full one.

Arrays: ``fold`` ``(N,)`` (the test fold of every posture: score another model on it), ``postures`` ``(N,)`` (the
recording's index of each), ``fractions`` ``(F,)``, ``training`` ``(folds, F)`` (postures trained on),
``errors_<method>`` ``(F, N)`` [m], ``predicted_<method>`` ``(N, 3, 3)`` [m] at the full share, ``measured``
``(N, 3, 3)`` [m], ``inputs`` ``(N, 6)`` [N], ``physics_parameters`` ``(folds, F, 13)`` (EI [N m^2] x 3, motor
offsets [N] x 6, payload [kg], section lengths [m] x 3) and, for a recording with truth, ``truth_errors`` ``(N,)``
[m] (the noise-free markers' error: the floor no model passes).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems import ProblemContext
from optikin.problems.actuation.run import PHYSICS, ActuationOutcome
from optikin.results import MethodRow, Result

MM = 1e3


def summary_of(errors: np.ndarray) -> dict[str, float]:
    """Median / p95 / max [mm] of posture errors ``(N,)`` [m] (NaN: no marker seen, left out; ``inf``: no
    prediction, counted; the order statistic at or above each share, no interpolation)."""
    e = errors[~np.isnan(errors)] * MM
    return {
        "median": float(np.percentile(e, 50, method="higher")),
        "p95": float(np.percentile(e, 95, method="higher")),
        "max": float(np.max(e)),
    }


def claims(outcome: ActuationOutcome) -> dict[str, Any]:
    """Whether the physics model's median beats the best regressor's at the smallest and at the full share."""
    out: dict[str, Any] = {}
    regressors = [m for m in outcome.methods if m != PHYSICS]
    if not regressors:
        return out
    for i, label in ((0, "smallest share"), (len(outcome.fractions) - 1, "full share")):
        medians = {m: summary_of(outcome.errors[m][i])["median"] for m in outcome.methods}
        best = min(regressors, key=lambda m: medians[m])
        out[f"{label} ({outcome.fractions[i]:g})"] = {
            "physics median [mm]": round(medians[PHYSICS], 3),
            "best regressor": best,
            "its median [mm]": round(medians[best], 3),
            "physics beats it": bool(medians[PHYSICS] < medians[best]),
        }
    return out


def result_of(ctx: ProblemContext, outcome: ActuationOutcome) -> Result:
    """The Result of an ``actuation`` run (module docstring)."""
    N = len(outcome.fold)
    rows = []
    curve: dict[str, Any] = {}
    for method, title in zip(outcome.methods, outcome.titles):
        row: dict[str, Any] = {}
        for i, share in enumerate(outcome.fractions):
            s = summary_of(outcome.errors[method][i])
            for key, value in s.items():
                row[f"{share:g}: {key} [mm]"] = round(value, 3)
            curve.setdefault(title, {})[f"{share:g}"] = {k: round(v, 3) for k, v in s.items()}
        row["time [s]"] = round(outcome.fit_time[method], 2)
        rows.append(MethodRow(title, "solver" if method == PHYSICS else "baseline", row))
    full = [fits[-1] for fits in outcome.physics_fits]
    estimates = {
        "EI [N m^2] per section": np.mean([f.params.stiffness for f in full], axis=0).round(5).tolist(),
        "motor offsets [N]": np.mean([f.params.motor_offsets for f in full], axis=0).round(3).tolist(),
        "payload [kg]": round(float(np.mean([f.params.payload for f in full])), 4),
        "section lengths [mm]": (np.mean([f.params.section_lengths for f in full], axis=0) * MM).round(2).tolist(),
    }
    metrics: dict[str, Any] = {
        "postures": N,
        "folds": len(outcome.training),
        "training postures per share (fold 1)": outcome.training[0].tolist(),
        "largest held-out marker error per posture [mm]": curve,
        "physics vs the best regressor": claims(outcome),
        "physics estimates (mean over folds, full share)": estimates,
        "physics model": "Kirchhoff rod per section, straight tendons as pure moments, payload and own weight, "
        "inputs read as tensions less a per-motor offset; geometry, stiffness, offsets and payload fitted "
        "on the training postures only (soft-L1 loss)",
    }
    if outcome.truth_errors is not None:
        metrics["noise-free markers' error [mm]"] = {
            k: round(v, 3) for k, v in summary_of(outcome.truth_errors).items()
        }
    converged = all(f.success for fits in outcome.physics_fits for f in fits)
    params = np.array(
        [
            [np.concatenate([f.params.stiffness, f.params.motor_offsets, [f.params.payload], f.params.section_lengths])]
            for fits in outcome.physics_fits
            for f in fits
        ]
    ).reshape(len(outcome.physics_fits), len(outcome.fractions), 13)
    arrays: dict[str, np.ndarray] = {
        "fold": outcome.fold,
        "postures": outcome.indices,
        "fractions": outcome.fractions,
        "training": outcome.training,
        "measured": outcome.measured,
        "inputs": outcome.inputs,
        "physics_parameters": params,
    }
    for method in outcome.methods:
        arrays[f"errors_{method}"] = outcome.errors[method]
        arrays[f"predicted_{method}"] = outcome.predicted[method]
    if outcome.truth_errors is not None:
        arrays["truth_errors"] = outcome.truth_errors
    notes = list(outcome.notes)
    if not converged:
        notes.append("physics: a least-squares fit stopped at its evaluation limit (options.max_evaluations)")
    per_posture = outcome.errors[PHYSICS][-1]
    return ctx.result(
        status=["ok" if np.isfinite(e) or np.isnan(e) else "failed" for e in per_posture],
        residuals=per_posture,
        metrics=metrics,
        comparison=rows,
        arrays=arrays,
        notes=notes,
        timings={m: t for m, t in outcome.fit_time.items()},
    )
