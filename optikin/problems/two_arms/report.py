"""The ``two_arms`` outcome as a Result: the joint QP's metrics, a comparison row per controller, arrays, notes."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.control.two_arm import TwoArmRun, limit_excess_two
from optikin.curves.catenary import catenary
from optikin.errors import InputDataError
from optikin.problems import ProblemContext
from optikin.problems.two_arms.run import TwoArmOutcome
from optikin.results import MethodRow, Result
from optikin.status import Status

MM, DEG = 1e3, 180.0 / np.pi

COMPARED = {
    "rms [mm]": "task error rms [mm]",
    "max [mm]": "task error max [mm]",
    "clearance [mm]": "tube clearance min [mm]",
    "collision steps": "collision steps",
    "depth [mm]": "deepest penetration [mm]",
    "outside limits": "samples outside limits",
    "step [us]": "step time median [us]",
    "obstacle [mm]": "obstacle clearance min [mm]",
    "obstacle steps": "steps inside an obstacle",
}
"""Columns of the comparison table: short name -> metric of :func:`run_metrics`."""


def run_metrics(outcome: TwoArmOutcome, name: str) -> dict[str, Any]:
    """Task errors, the tubes' clearance (sampled, and its bound between samples), limits, step times of run ``name``.

    ``tube clearance bound`` is the least sampled clearance less ``(h_1 + h_2) / 2``: the least distance of
    any two points of the continuous tubes (:mod:`optikin.control.self_collision`). A collision step is one
    whose least sampled clearance is negative (the tubes interpenetrate there).
    """
    tracked = outcome.runs[name]
    error = tracked.error * MM
    clearance = outcome.clearances[name]
    excess = limit_excess_two(outcome.model, tracked.q)
    after = limit_excess_two(outcome.model, tracked.q + outcome.reference.dt * tracked.qdot)
    controller_made = (after > 0) & (after >= excess)
    names = [*outcome.model.arms[0].arm.config_names, *outcome.model.arms[1].arm.config_names]
    us = tracked.step_time[np.isfinite(tracked.step_time)] * 1e6
    out: dict[str, Any] = {
        "task error rms [mm]": float(np.sqrt(np.mean(error**2))),
        "task error max [mm]": float(error.max()),
        "task error final [mm]": float(error[-1]),
        "tube clearance min [mm]": float(clearance.min() * MM),
        "tube clearance bound [mm]": float((clearance.min() - outcome.tubes.between_samples) * MM),
        "collision steps": int(np.sum(clearance < 0)),
        "deepest penetration [mm]": float(max(0.0, -clearance.min()) * MM),
        "steps within margin": int(np.sum(clearance < outcome.tubes.margin - 1e-6)),
        "samples outside limits": int(np.any(excess > 0, axis=1).sum()),
        "steps the controller kept or took outside": int(np.any(controller_made, axis=1).sum()),
        "fallback steps": sum(1 for s in tracked.status if s.startswith("fallback")),
        "step time median [us]": float(np.median(us)),
        "step time p95 [us]": float(np.percentile(us, 95)),
    }
    for prefix, unit, scale in (("S", "mm", MM), ("theta", "deg", DEG)):
        cols = [i for i, n in enumerate(names) if n.startswith(prefix)]
        if cols:
            out[f"max limit excess {prefix} [{unit}]"] = float(excess[:, cols].max() * scale)
    rope = outcome.model.rope
    if rope is not None:
        chord = np.linalg.norm(tracked.tips[:, 1] - tracked.tips[:, 0], axis=1)
        out["rope slack min [mm]"] = float((rope.sensitivity.length - chord.max()) * MM)
        if rope.floor is not None:
            height = tracked.x @ rope.sensitivity.up - rope.floor
            out["lowest point above the floor min [mm]"] = float(height.min() * MM)
        out["rope to the arms' tubes min [mm]"] = float(rope_clearance(outcome, tracked) * MM)
    if outcome.obstacle_clearances is not None and outcome.obstacles is not None:
        near = outcome.obstacle_clearances[name]
        out["obstacle clearance min [mm]"] = float(np.nanmin(near) * MM)
        out["obstacle clearance bound [mm]"] = float(np.nanmin(near - 0.5 * body_spacings(outcome)) * MM)
        out["steps inside an obstacle"] = int(np.sum(np.any(near < 0, axis=1)))
        for body, least in zip(outcome.obstacles.bodies, np.nanmin(near, axis=0)):
            out[f"{body} to obstacles min [mm]"] = float(least * MM)
    return out


def body_spacings(outcome: TwoArmOutcome) -> np.ndarray:
    """The sample spacing of each body of the obstacle rows (arm 1, arm 2, rope) [m]: between samples a body
    comes at most half of it closer to an obstacle (signed distances are 1-Lipschitz)."""
    first, second = outcome.model.arms
    spacings = [first.spacing, second.spacing]
    rope = outcome.model.rope
    if rope is not None and rope.samples is not None:
        spacings.append(float(np.diff(rope.samples.arc_lengths).max(initial=0.0)))
    return np.array(spacings)


def rope_clearance(outcome: TwoArmOutcome, tracked: TwoArmRun, every: int = 10, count: int = 60) -> float:
    """The least distance of the hanging rope to either arm's tube on every ``every``-th step [m]: the rope
    sampled at ``count`` points, those within arc length ``exclusion`` of a grip left out (the rope leaves the
    holding tube there; the QP's rope rows exclude the same)."""
    rope = outcome.model.rope
    assert rope is not None
    first, second = outcome.model.arms
    n1, L = outcome.model.n1, rope.sensitivity.length
    s = np.linspace(0.0, L, count)
    keep = (s >= rope.exclusion) & (s <= L - rope.exclusion)
    least = np.inf
    for k in range(0, len(tracked.t), every):
        points = _rope_points(outcome, tracked, k, count)[keep]
        if np.isnan(points).any():
            continue
        for placed, q in ((first, tracked.q[k, :n1]), (second, tracked.q[k, n1:])):
            gaps = points[:, None, :] - placed.points_at(q)[None, :, :]
            least = min(least, float(np.sqrt(np.einsum("ijk,ijk->ij", gaps, gaps)).min()) - placed.radius)
    return least


def result(ctx: ProblemContext, outcome: TwoArmOutcome) -> Result:
    """The Result: per-step status of the joint QP (``ok``, or ``failed`` where it fell back to holding)."""
    summaries = {name: run_metrics(outcome, name) for name in outcome.runs}
    comparison = [
        MethodRow(
            r.controller,
            "solver" if name == "qp" else "baseline",
            {k: summaries[name][v] for k, v in COMPARED.items() if v in summaries[name]},
        )
        for name, r in outcome.runs.items()
    ]
    qp = summaries["qp"]
    criteria = {
        "no collision": qp["tube clearance bound [mm]"] > 0,
        "within limits": qp["samples outside limits"] == 0,
    }
    missed = []
    if not criteria["no collision"]:
        missed.append(
            f"criterion no collision not met: the QP's tubes came within {qp['tube clearance bound [mm]']:.3g} mm "
            "of each other (bound between samples)"
        )
    if outcome.obstacles is not None:
        criteria["no obstacle penetration"] = qp["obstacle clearance bound [mm]"] > 0
        if not criteria["no obstacle penetration"]:
            missed.append(
                "criterion no obstacle penetration not met: the QP came within "
                f"{qp['obstacle clearance bound [mm]']:.3g} mm of an obstacle (bound between samples)"
            )
    if not criteria["within limits"]:
        missed.append(f"criterion within limits not met: {qp['samples outside limits']} steps outside the limits")
    timings = {f"{name} run [s]": value for name, value in outcome.wall.items()} | {
        "qp step median [us]": qp["step time median [us]"],
        "qp step p95 [us]": qp["step time p95 [us]"],
    }
    return ctx.result(
        status=[Status.OK if s == Status.OK else Status.FAILED for s in outcome.runs["qp"].status],
        residuals=outcome.runs["qp"].error,
        timings=timings,
        metrics=qp | {"samples per section": outcome.model.arms[0].points_per_section},
        comparison=comparison,
        arrays=arrays(outcome),
        notes=missed + notes(outcome, summaries),
        criteria=criteria,
    )


def notes(outcome: TwoArmOutcome, summaries: dict[str, dict[str, Any]]) -> list[str]:
    """Collisions of every run (the baselines' too), fallbacks, limit excursions, runs stopped by a taut rope."""
    tubes = outcome.tubes
    out = [
        f"tubes sampled every {tubes.first.spacing * MM:.3g} / {tubes.second.spacing * MM:.3g} mm of arc: "
        f"between samples they come at most {tubes.between_samples * MM:.3g} mm closer than the sampled pairs "
        f"(margin {tubes.margin * MM:.3g} mm, {tubes.pairs} pairs in the QP)"
    ]
    for name, tracked in outcome.runs.items():
        m = summaries[name]
        out += [f"{tracked.controller}: {note}" for note in tracked.notes]
        if m["collision steps"]:
            first = outcome.reference.t[int(np.argmax(outcome.clearances[name] < 0))]
            out.append(
                f"{tracked.controller}: the arms interpenetrate on {m['collision steps']} steps (first at "
                f"t = {first:.3g} s), {m['deepest penetration [mm]']:.3g} mm deep at most"
            )
        if m.get("steps inside an obstacle"):
            out.append(
                f"{tracked.controller}: inside an obstacle on {m['steps inside an obstacle']} steps, "
                f"{-m['obstacle clearance min [mm]']:.3g} mm deep at most"
            )
        if m["fallback steps"]:
            out.append(f"{tracked.controller}: {m['fallback steps']} steps without a QP solution (held)")
        if m["samples outside limits"]:
            out.append(f"{tracked.controller}: outside the configuration limits on {m['samples outside limits']} steps")
    return out


def _rope_points(outcome: TwoArmOutcome, tracked: TwoArmRun, k: int, count: int = 40) -> np.ndarray:
    """The hanging rope at step ``k`` of a run, ``(count, 3)`` [m] (NaN when it cannot hang)."""
    rope = outcome.model.rope
    assert rope is not None
    A, B = tracked.tips[k]
    try:
        hanging = catenary(A, B, rope.sensitivity.length, -rope.sensitivity.up)
    except InputDataError:
        return np.full((count, 3), np.nan)
    return hanging.points(np.linspace(0.0, rope.sensitivity.length, count))


def arrays(outcome: TwoArmOutcome, snapshots: int = 5) -> dict[str, np.ndarray]:
    """The reference; per run its configurations, task value, tips, clearance and step times; backbones
    (and the rope) at a few instants, evenly spread and the closest approach of any run among them."""
    t = outcome.reference.t
    closest = min(outcome.clearances.values(), key=lambda c: float(c.min()))  # the closest approach of any run
    picks = np.unique(np.r_[np.linspace(0, len(t) - 1, snapshots - 1).round().astype(int), np.argmin(closest)])
    out: dict[str, np.ndarray] = {
        "t": t,
        "reference": outcome.reference.value,
        "collision_margin": np.array([outcome.tubes.margin]),
        "snapshot_t": t[picks],
    }
    first, second = outcome.model.arms
    n1 = outcome.model.n1
    for name, tracked in outcome.runs.items():
        out |= {
            f"q_{name}": tracked.q,
            f"x_{name}": tracked.x,
            f"tips_{name}": tracked.tips,
            f"clearance_{name}": outcome.clearances[name],
            f"step_time_{name}": tracked.step_time,
            f"snapshot_arm1_{name}": np.stack([first.points_at(tracked.q[k, :n1]) for k in picks]),
            f"snapshot_arm2_{name}": np.stack([second.points_at(tracked.q[k, n1:]) for k in picks]),
        }
        if outcome.model.rope is not None:
            out[f"snapshot_rope_{name}"] = np.stack([_rope_points(outcome, tracked, k) for k in picks])
    return out
