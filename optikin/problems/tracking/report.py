"""The ``tracking`` outcome as a Result: the QP's metrics, a comparison row per controller, the arrays, notes."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from optikin.control.obstacles import Obstacle
from optikin.control.simulate import DEG, MM, TrackingRun
from optikin.problems import ProblemContext
from optikin.problems.tracking.options import ToleranceOptions
from optikin.problems.tracking.run import BASELINES, MPC_NAMES, ObstacleOutcome, TrackingOutcome
from optikin.results import MethodRow, Result
from optikin.status import Status

COMPARED = {
    "rms [mm]": "position error rms [mm]",
    "final [mm]": "position error final [mm]",
    "final [deg]": "orientation error final [deg]",
    "outside limits": "samples outside limits",
    "excess S [mm]": "max limit excess S [mm]",
    "excess theta [deg]": "max limit excess theta [deg]",
    "step [us]": "step time median [us]",
    "settle [s]": "settling time [s]",
    "clearance [mm]": "backbone clearance min [mm]",
    "penetrations": "penetrating samples",
    "depth [mm]": "penetration depth max [mm]",
    "fallbacks": "fallback steps",
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
    if outcome.obstacles is not None:
        for name in runs:
            summaries[name] |= obstacle_metrics(outcome.obstacles, name)
        summaries["qp"] |= reference_inside_metrics(outcome.obstacles, runs["qp"])
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
    if outcome.obstacles is not None:
        for name in ("qp", *(name for name in MPC_NAMES if name in runs)):
            clear = summaries[name]["backbone clearance bound [mm]"] > 0
            criteria["no penetration" if name == "qp" else f"no penetration ({name})"] = bool(clear)
            if not clear:
                missed.append(
                    f"criterion no penetration not met: the backbone of {runs[name].controller} came within "
                    f"{summaries[name]['backbone clearance bound [mm]']:.3g} mm of an obstacle (bound between samples)"
                )
    return ctx.result(
        status=[Status.OK if s == Status.OK else Status.FAILED for s in qp_run.status],
        residuals=qp_run.position_error,
        timings=timings,
        metrics=metrics,
        comparison=comparison,
        arrays=arrays(outcome),
        notes=missed + notes(runs, summaries, outcome.settle_after) + obstacle_notes(runs, summaries, outcome),
        criteria=criteria,
    )


def obstacle_metrics(obstacles: ObstacleOutcome, name: str) -> dict[str, Any]:
    """Backbone clearance of run ``name``: least sample distance, penetrations, the bound between samples.

    ``backbone clearance bound`` is the least sample distance less half the sample spacing:
    the least distance of any point of the continuous backbone (signed distances are 1-Lipschitz).
    """
    d = obstacles.distances[name]
    half = 0.5 * obstacles.barrier.spacing
    least = float(d.min())
    return {
        "backbone clearance min [mm]": least * MM,
        "backbone clearance bound [mm]": (least - half) * MM,
        "penetrating samples": int(np.sum(d < 0)),
        "penetration depth max [mm]": float(max(0.0, -least) * MM),
        "steps with penetration": int(np.sum(np.any(d < 0, axis=(1, 2)))),
        "steps within margin": int(np.sum(np.any(d < obstacles.barrier.margin - 1e-6, axis=(1, 2)))),
    }


def reference_inside_metrics(obstacles: ObstacleOutcome, qp_run: TrackingRun) -> dict[str, Any]:
    """How far the QP's tip stays from the reference while the reference lies within the margin of an obstacle."""
    inside = obstacles.reference_distance < obstacles.barrier.margin
    out: dict[str, Any] = {"reference steps inside an obstacle or its margin": int(inside.sum())}
    if inside.any():
        error = qp_run.position_error[inside] * MM
        out |= {
            "tip from reference while inside, mean [mm]": float(error.mean()),
            "tip from reference while inside, max [mm]": float(error.max()),
            "reference depth inside, max [mm]": float(max(0.0, -obstacles.reference_distance.min()) * MM),
        }
    return out


def obstacle_notes(
    runs: dict[str, TrackingRun], summaries: dict[str, dict[str, Any]], outcome: TrackingOutcome
) -> list[str]:
    """Each run's penetrations (the baselines know no obstacles) and the QP's distance from a blocked reference."""
    if outcome.obstacles is None:
        return []
    out = []
    for name, tracking in runs.items():
        m = summaries[name]
        if m["penetrating samples"]:
            out.append(
                f"{tracking.controller}: backbone inside an obstacle on {m['steps with penetration']} steps "
                f"({m['penetrating samples']} samples), deepest {-m['backbone clearance min [mm]']:.3g} mm"
            )
    m = summaries["qp"]
    if m.get("reference steps inside an obstacle or its margin"):
        out.append(
            f"{runs['qp'].controller}: the reference lies in an obstacle or its margin on "
            f"{m['reference steps inside an obstacle or its margin']} steps; the tip then stays "
            f"{m['tip from reference while inside, mean [mm]']:.3g} mm (mean), "
            f"{m['tip from reference while inside, max [mm]']:.3g} mm (max) from it"
        )
    return out


def _row(name: str, tracking: TrackingRun, full: dict[str, Any], tolerance: ToleranceOptions) -> MethodRow:
    row = {short: full[key] for short, key in COMPARED.items() if key in full}
    row["converged"] = converged(full, tolerance)
    role = "solver" if name == "qp" else BASELINES[name].role if name in BASELINES else "baseline"
    return MethodRow(tracking.controller, role, row)


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
    if outcome.obstacles is not None:
        out |= obstacle_arrays(outcome)
    return out


def obstacle_arrays(outcome: TrackingOutcome, snapshots: int = 6) -> dict[str, np.ndarray]:
    """Per run the least backbone distance over time; backbones and obstacle surface points at a few instants."""
    obstacles = outcome.obstacles
    assert obstacles is not None
    t = outcome.reference.t
    picks = np.linspace(0, len(t) - 1, snapshots).round().astype(int)
    distances = obstacles.barrier.distances
    out: dict[str, np.ndarray] = {"barrier_margin": np.array([obstacles.barrier.margin]), "snapshot_t": t[picks]}
    for name, tracking in outcome.runs.items():
        out[f"clearance_{name}"] = obstacles.distances[name].min(axis=(1, 2))
        out[f"snapshot_backbone_{name}"] = np.stack([distances.points_at(tracking.q[k]) for k in picks])
    shells = [surface_points(distances.obstacles, float(t[k])) for k in picks]
    size = max(len(shell) for shell in shells)
    out["snapshot_obstacles"] = np.stack(
        [np.pad(s, ((0, size - len(s)), (0, 0)), constant_values=np.nan) for s in shells]
    )
    return out


def surface_points(obstacles: Sequence[Obstacle], t: float) -> np.ndarray:
    """Points on every obstacle's surface at ``t``, ``(M, 3)`` [m]."""
    return np.concatenate([ob.surface(t) for ob in obstacles])


def notes(
    runs: dict[str, TrackingRun], summaries: dict[str, dict[str, Any]], settle_after: float | None = None
) -> list[str]:
    """QP failures, rod-plant notes, excursions outside the limits, MRAC gain saturation, settling, in words."""
    out = []
    qp_run = runs["qp"]
    failed = [(t, s) for t, s in zip(qp_run.t, qp_run.status) if s != Status.OK]
    if failed:
        out.append(f"QP solver failed on {len(failed)} steps; first at t = {failed[0][0]:.4g} s: {failed[0][1]}")
    for name, tracking in runs.items():
        m = summaries[name]
        if name != "qp" and m["fallback steps"]:
            out.append(
                f"{tracking.controller}: fallback on {m['fallback steps']} steps; first at {m['first fallback']}"
            )
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
