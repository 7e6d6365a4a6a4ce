"""An ``ik`` outcome as a :class:`~optikin.results.Result`: one comparison row per method, the arrays, the notes.

Each row reports the success rate on reachable targets, how unreachable targets
were flagged, residuals, the tip error recomputed with ``fk_dq`` (and how many
samples reach the target within ``tolerance``), the weighted distance from rest,
on a CBHA the margin of the legs to Table I and their deviation from the
elongation distribution, iterations and time per solve. Arrays per row (suffix
:func:`array_key` of the method): ``solutions``, ``status``, ``residual``,
``time``, ``iterations`` and every check of :func:`~optikin.problems.ik.run.answer_checks`.
"""

from __future__ import annotations

import re
from typing import Any, Callable

import numpy as np

from optikin.data.configurations import skipped_rows_notes
from optikin.data.targets import Targets
from optikin.ik.formulation import Formulation
from optikin.problems import ProblemContext
from optikin.problems.ik.run import IkOutcome, MethodRun
from optikin.results import SOLVED, MethodRow, Result
from optikin.solvers.base import SolutionBatch


def array_key(method: str) -> str:
    """A method's name as part of an array name: ``gauss-newton [penalty 1e-6]`` -> ``gauss-newton_penalty_1e-6``."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", method).strip("_")


def _stat(f: Callable[[np.ndarray], Any], values: np.ndarray) -> float:
    """``f`` over the finite values, NaN when there are none."""
    values = values[np.isfinite(values)]
    return float(f(values)) if values.size else float("nan")


def tip_metrics(
    targets: Targets, formulation: Formulation, checks: dict[str, np.ndarray], ok: np.ndarray
) -> dict[str, Any]:
    """Metrics of tip targets from the checks: tip and angle errors [m, rad], distance from rest, CBHA legs [mm]."""
    reachable = targets.reachable
    tip_error = checks["tip_error"]
    metrics: dict[str, Any] = {
        "max tip error ok [m]": _stat(np.max, tip_error[ok]),
        "median tip error [m]": _stat(np.median, tip_error),
    }
    within = reachable & (tip_error <= formulation.tolerance)
    metrics["tip within tolerance [%]"] = 100.0 * within.sum() / max(int(reachable.sum()), 1)
    if "angle_error" in checks:
        metrics["max angle error ok [rad]"] = _stat(np.max, checks["angle_error"][ok])
    metrics["median distance from rest"] = _stat(np.median, checks["rest_distance"])
    if "leg_margin" in checks:
        metrics["min leg margin [mm]"] = _stat(np.min, checks["leg_margin"]) * 1e3
        metrics["median leg margin [mm]"] = _stat(np.median, checks["leg_margin"]) * 1e3
        metrics["median deviation from distribution [mm]"] = _stat(np.median, checks["distribution_deviation"]) * 1e3
    return metrics


def point_metrics(checks: dict[str, np.ndarray]) -> dict[str, Any]:
    """Metrics of measured-point targets: the RMS point distance of every sample, whatever its status (median,
    95th percentile, max) [mm]: each posture has a residual, fitted or not."""
    rms = checks["rms_distance"] * 1e3
    rms = rms[np.isfinite(rms)]
    metrics: dict[str, Any] = {
        "median RMS point distance [mm]": _stat(np.median, rms),
        "95th percentile RMS point distance [mm]": _stat(lambda v: np.percentile(v, 95), rms),
        "max RMS point distance [mm]": _stat(np.max, rms),
    }
    return metrics


def method_metrics(run: MethodRun, targets: Targets) -> dict[str, Any]:
    """The comparison row of one method (module docstring)."""
    report, formulation, checks = run.report, run.method.formulation, run.checks
    status = np.array(report.status)
    ok = status == "ok"
    solved = np.isin(status, SOLVED)
    reachable = targets.reachable
    metrics: dict[str, Any] = {
        "formulation": formulation.label(),
        "success [%]": 100.0 * solved[reachable].mean() if reachable.any() else float("nan"),
        "median residual": _stat(np.median, report.residual[solved]),
        "max residual": _stat(np.max, report.residual[solved]),
    }
    if formulation.noise is not None:
        metrics["fit (within the noise)"] = int((status == "fit").sum())
    if targets.kind == "points":
        metrics.update(point_metrics(checks))
    elif targets.kind == "legs":
        metrics["max leg error ok, eqs. (7)-(9) [m]"] = _stat(np.max, checks["leg_error"][ok])
        metrics["ok within Table I"] = f"{int(checks['within_table_i'][ok].sum())}/{int(ok.sum())}"
    else:
        metrics.update(tip_metrics(targets, formulation, checks, ok))
    if (~reachable).any():
        metrics["unreachable flagged"] = f"{int((status[~reachable] == 'unreachable').sum())}/{int((~reachable).sum())}"
        metrics["unreachable reported ok"] = int(ok[~reachable].sum())
    metrics.update(
        {
            "median iterations": float(np.median(report.iterations)) if np.all(report.iterations >= 0) else None,
            "median time per solve [us]": float(np.median(report.seconds) * 1e6),
            "mean time per solve [us]": float(run.wall / len(report) * 1e6),
            "batched": report.batched,
            "statuses": ", ".join(f"{s}: {int((status == s).sum())}" for s in dict.fromkeys(report.status)),
        }
    )
    return metrics


def arrays_of(outcome: IkOutcome) -> dict[str, np.ndarray]:
    """The result's arrays (module docstring), plus what the figures draw: ``t`` along a trajectory and
    ``solution_tips`` for leg targets."""
    targets, main = outcome.targets, outcome.main
    error = main.checks[{"legs": "leg_error", "points": "rms_distance"}.get(targets.kind, "tip_error")]
    arrays = {
        "targets": targets.values,
        "reachable": targets.reachable,
        "true_configurations": targets.configurations,
        "solutions": main.report.x,
        "error": error,
    }
    for run in outcome.runs:
        key, r = array_key(run.method.name), run.report
        arrays |= {
            f"residual_{key}": r.residual,
            f"status_{key}": np.array(r.status),
            f"solutions_{key}": r.x,
            f"time_{key}": r.seconds,
            f"iterations_{key}": r.iterations,
        }
        arrays |= {f"{check}_{key}": values for check, values in run.checks.items()}
    if targets.points is not None:
        arrays["measured_points"] = measured_points(targets)
    if targets.t is not None:
        arrays["t"] = targets.t
    if outcome.solution_tips is not None:
        arrays["solution_tips"] = outcome.solution_tips
    return arrays


def measured_points(targets: Targets) -> np.ndarray:
    """``(N, k, 3)`` measured positions of the ``k`` points [m] (NaN for a point without a position)."""
    assert targets.points is not None
    out = np.full((len(targets), len(targets.points), 3), np.nan)
    for k, where in enumerate(targets.points.slices()):
        if "position" in where:
            out[:, k] = targets.values[:, where["position"]]
    return out


def notes_of(outcome: IkOutcome) -> list[str]:
    """One note per method and status ``failed`` or ``timeout``: how many, and the first sample's message."""
    notes = []
    for run in outcome.runs:
        r: SolutionBatch = run.report
        for status in ("failed", "timeout"):
            where = [i for i, s in enumerate(r.status) if s == status]
            if where:
                notes.append(
                    f"{run.method.name}: {len(where)} samples {status}, e.g. sample {where[0]}: {r.messages[where[0]]}"
                )
    return notes


def result_of(ctx: ProblemContext, outcome: IkOutcome) -> Result:
    """The :class:`~optikin.results.Result` of an ``ik`` run."""
    targets, main = outcome.targets, outcome.main.report
    formulation = outcome.setup.formulation
    metrics = {
        "targets": len(targets),
        "reachable targets": int(targets.reachable.sum()),
        "target": outcome.setup.target,
        "redundancy": formulation.redundancy,
        "trajectory (warm-started)": targets.trajectory,
        "tolerance [m]": formulation.tolerance,
    }
    if formulation.noise is not None:
        metrics["noise [m]"] = formulation.noise
    if targets.points is not None:
        metrics["points"] = ", ".join(f"{p.name} ({'+'.join(p.components)})" for p in targets.points.points)
    comparison = [MethodRow(run.method.name, run.method.role, method_metrics(run, targets)) for run in outcome.runs]
    comparison += [
        MethodRow(m.name, m.role, {"formulation": m.formulation.label(), "not applicable": m.not_applicable})
        for m in outcome.not_applicable
    ]
    return ctx.result(
        solver=outcome.main.method.name,
        status=list(main.status),
        iterations=main.iterations,
        residuals=main.residual,
        timings={"median per solve [us]": float(np.median(main.seconds) * 1e6)},
        metrics=metrics,
        comparison=comparison,
        arrays=arrays_of(outcome),
        notes=skipped_rows_notes(targets.skipped_rows, ctx.data_params) + notes_of(outcome),
    )
