"""The ``tracking`` outcome as a Result: the QP's metrics, a comparison row per controller, the arrays, notes."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.control.simulate import DEG, MM, TrackingRun
from optikin.problems import ProblemContext
from optikin.problems.tracking.options import ToleranceOptions
from optikin.problems.tracking.run import TrackingOutcome
from optikin.results import MethodRow, Result

COMPARED = {
    "rms [mm]": "position error rms [mm]",
    "final [mm]": "position error final [mm]",
    "final [deg]": "orientation error final [deg]",
    "outside limits": "samples outside limits",
    "excess S [mm]": "max limit excess S [mm]",
    "excess theta [deg]": "max limit excess theta [deg]",
    "step [us]": "step time median [us]",
    "settle [s]": "settling time [s]",
}
"""Columns of the comparison table: short name -> metric of :meth:`TrackingRun.metrics`."""


def result(ctx: ProblemContext, outcome: TrackingOutcome) -> Result:
    """The Result of ``outcome``: per-step status of the QP (``ok``, or ``failed`` where its fallback acted)."""
    runs = outcome.runs
    qp_run = runs["qp"]
    summaries = {name: tracking.metrics() for name, tracking in runs.items()}
    if outcome.settle_after is not None:
        for name, tracking in runs.items():
            summaries[name]["settling time [s]"] = settling_time(tracking, outcome.settle_after, outcome.tolerance)
    comparison = [_row(name, tracking, summaries[name], outcome.tolerance) for name, tracking in runs.items()]
    metrics = summaries["qp"] | {"converged": comparison[0].metrics["converged"]}
    for name, tracking in runs.items():
        if summaries[name].get("gain saturation steps") is not None:
            metrics[f"{tracking.controller}: gain saturation steps"] = summaries[name]["gain saturation steps"]
    timings = {f"{name} run [s]": value for name, value in outcome.wall.items()} | {
        "qp step median [us]": float(metrics["step time median [us]"]),
        "qp step p95 [us]": float(metrics["step time p95 [us]"]),
    }
    criteria, missed = success_criteria(summaries["qp"], outcome.tolerance)
    return ctx.result(
        status=["ok" if s == "ok" else "failed" for s in qp_run.status],
        residuals=qp_run.position_error,
        timings=timings,
        metrics=metrics,
        comparison=comparison,
        arrays=arrays(outcome),
        notes=missed + notes(runs, summaries, outcome.settle_after),
        criteria=criteria,
    )


def _row(name: str, tracking: TrackingRun, full: dict[str, Any], tolerance: ToleranceOptions) -> MethodRow:
    row = {short: full[key] for short, key in COMPARED.items() if key in full}
    row["converged"] = converged(full, tolerance)
    return MethodRow(tracking.controller, "solver" if name == "qp" else "baseline", row)


def settling_time(tracking: TrackingRun, after: float, tolerance: ToleranceOptions) -> float | None:
    """Seconds from ``after`` until the errors stay within ``options.tolerance`` to the end; ``None``: never."""
    return tracking.settling_time(after, tolerance.position_mm / MM, tolerance.orientation_deg / DEG)


def converged(metrics: dict[str, Any], tolerance: ToleranceOptions) -> bool:
    """Whether the final position (and orientation) errors are below the tolerance."""
    ok = metrics["position error final [mm]"] < tolerance.position_mm
    if "orientation error final [deg]" in metrics:
        ok = ok and metrics["orientation error final [deg]"] < tolerance.orientation_deg
    return bool(ok)


def success_criteria(metrics: dict[str, Any], tolerance: ToleranceOptions) -> tuple[dict[str, bool], list[str]]:
    """The run-level criteria of the solver under study (the QP), and a note for each one missed.

    ``converged``: :func:`converged` (the final errors, means over the last 10 % of the run,
    below ``options.tolerance``). ``within limits``: on no step did the QP's own command keep
    or take the arm outside the configuration limits (a start outside them or a disturbance
    does not count while the command leads back).

    Parameters
    ----------
    metrics:
        :meth:`~optikin.control.simulate.TrackingRun.metrics` of the QP's run.
    tolerance:
        ``options.tolerance``.

    Returns
    -------
    tuple
        ``{name: met}`` and the notes saying by how much each missed criterion failed.
    """
    missed = []
    ok = converged(metrics, tolerance)
    if not ok:
        position = metrics["position error final [mm]"]
        errors = [f"final position error {position:.4g} mm (tolerance {tolerance.position_mm:g} mm)"]
        if "orientation error final [deg]" in metrics:
            errors.append(
                f"final orientation error {metrics['orientation error final [deg]']:.4g} deg "
                f"(tolerance {tolerance.orientation_deg:g} deg)"
            )
        missed.append(f"criterion converged not met: {', '.join(errors)}")
    steps = metrics["steps the controller kept or took outside"]
    if steps:
        worst = ", ".join(
            f"{variable} {metrics[key]:.3g} {unit}"
            for variable, unit in (("S", "mm"), ("theta", "deg"))
            if metrics.get(key := f"max limit excess {variable} [{unit}]", 0) > 0
        )
        missed.append(
            f"criterion within limits not met: the QP's command kept or took the arm outside the "
            f"configuration limits on {steps} steps; farthest: {worst}"
        )
    return {"converged": ok, "within limits": not steps}, missed


def arrays(outcome: TrackingOutcome) -> dict[str, np.ndarray]:
    """The reference and, per controller name, its configurations, rates, tip, ``V(e)`` and step times."""
    reference = outcome.reference
    out: dict[str, np.ndarray] = {
        "t": reference.t,
        "reference": reference.value,
        "reference_position": reference.position,
    }
    for name, tracking in outcome.runs.items():
        out |= {
            f"q_{name}": tracking.q,
            f"qdot_{name}": tracking.qdot,
            f"x_{name}": tracking.x,
            f"V_{name}": tracking.lyapunov,
            f"step_time_{name}": tracking.step_time,
        }
        if tracking.gains is not None:
            out[f"gains_{name}"] = tracking.gains
    return out


def notes(
    runs: dict[str, TrackingRun], summaries: dict[str, dict[str, Any]], settle_after: float | None = None
) -> list[str]:
    """QP failures, rod-plant notes, excursions outside the limits, MRAC gain saturation, settling, in words."""
    out = []
    qp_run = runs["qp"]
    failed = [(t, s) for t, s in zip(qp_run.t, qp_run.status) if s != "ok"]
    if failed:
        out.append(f"QP solver failed on {len(failed)} steps; first at t = {failed[0][0]:.4g} s: {failed[0][1]}")
    for name, tracking in runs.items():
        m = summaries[name]
        out += [f"{tracking.controller}: {note}" for note in tracking.notes]
        if m.get("plant equilibrium failures"):
            out.append(
                f"{tracking.controller}: the rod plant's equilibrium did not converge on "
                f"{m['plant equilibrium failures']} steps"
            )
        if m["samples outside limits"]:
            worst = ", ".join(
                f"{variable} {m[f'max limit excess {variable} [{unit}]']:.3g} {unit}"
                for variable, unit in (("S", "mm"), ("theta", "deg"))
                if m.get(f"max limit excess {variable} [{unit}]", 0) > 0
            )
            out.append(
                f"{tracking.controller}: outside the configuration limits on {m['samples outside limits']} "
                f"steps ({m['steps the controller kept or took outside']} by its own command); "
                f"farthest: {worst}"
            )
        if settle_after is not None and m.get("settling time [s]") is None:
            out.append(
                f"{tracking.controller}: not settled within the tolerance by the end of the run, "
                f"{tracking.t[-1] - settle_after:.3g} s after the disturbance ended"
            )
        if m.get("gain saturation steps"):
            out.append(
                f"{tracking.controller}: adaptive gain saturated on {m['gain saturation steps']} steps, "
                f"first at t = {m['first gain saturation [s]']:.4g} s"
            )
    return out
