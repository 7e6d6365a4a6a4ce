"""A ``statics`` outcome as a Result: per-sample status, the comparison of the methods, the arrays.

Forward mode
    Status per sample from the shooting equilibrium's tip residual (``failed`` with the
    residual when the BVP did not converge). Comparison rows: compiled shooting and, as
    baseline, collocation (IPOPT): time per equilibrium [ms] and the largest distance
    between their tips and their backbones at shared arc lengths [mm]. Arrays
    ``actuation (N, n_act)``, ``s (K,)``, ``backbone (N, K, 3)``, ``tip_position (N, 3)``,
    ``tip_orientation (N, 4)``, ``base_wrench (N, 6)``, ``residual (N,)``, ``time (N,)``,
    ``iterations (N,)``, ``t`` for a trajectory, and ``tip_position_collocation``,
    ``residual_collocation``, ``time_collocation``, ``status_collocation`` with the baseline.
Inverse mode
    Status per target from the solver preset (``ok`` only when the recomputed equilibrium
    reaches the target). Per method: success rate, tip errors [m], time per target [ms],
    equilibria solved per target and, for targets made from actuations, the largest
    difference from those actuations. Arrays ``targets``, ``target_actuation`` and per
    method ``actuation_<m>``, ``tip_error_<m>``, ``residual_<m>``, ``status_<m>``, ``time_<m>``.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from optikin.problems import ProblemContext
from optikin.problems.statics.run import ForwardOutcome, ForwardRun, InverseOutcome
from optikin.results import MethodRow, Result
from optikin.status import Status

MM = 1e3
MS = 1e3


def array_key(method: str) -> str:
    """A method's name as part of an array name (``gauss-newton`` stays, spaces become ``_``)."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", method).strip("_")


def _finite(f: Any, values: np.ndarray) -> float:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    return float(f(values)) if values.size else float("nan")


def _stack(run: ForwardRun, what: str) -> np.ndarray:
    return np.array([getattr(s, what) for s in run.solutions])


def agreement(shooting: ForwardRun, collocation: ForwardRun) -> tuple[np.ndarray, float]:
    """Tip distances per sample [m] and the largest backbone distance at the arc lengths both grids share [m]."""
    tips = np.linalg.norm(
        np.array([s.tip_position for s in shooting.solutions])
        - np.array([c.tip_position for c in collocation.solutions]),
        axis=1,
    )
    s_a, s_b = shooting.solutions[0].s, collocation.solutions[0].s
    shared = [(i, int(np.argmin(np.abs(s_a - v)))) for i, v in enumerate(s_b) if np.min(np.abs(s_a - v)) < 1e-12]
    both = [k for k, (a, b) in enumerate(zip(shooting.solutions, collocation.solutions)) if a.ok and b.ok]
    if not shared or not both:
        return tips, float("nan")
    ib, ia = (np.array(v) for v in zip(*shared))
    gaps = [np.abs(shooting.solutions[k].positions[ia] - collocation.solutions[k].positions[ib]).max() for k in both]
    return tips, float(max(gaps))


def forward_result(ctx: ProblemContext, outcome: ForwardOutcome) -> Result:
    """The Result of a forward run (module docstring)."""
    run = outcome.shooting
    n = len(run.solutions)
    status: list[str] = [s.status for s in run.solutions]
    residual = np.array([s.residual_norm for s in run.solutions])
    tips = np.array([s.tip_position for s in run.solutions])
    arrays: dict[str, np.ndarray] = {
        "actuation": outcome.actuations,
        "s": run.solutions[0].s,
        "backbone": _stack(run, "positions"),
        "tip_position": tips,
        "tip_orientation": np.array([s.orientations[-1] for s in run.solutions]),
        "base_wrench": _stack(run, "base_wrench"),
        "residual": residual,
        "time": run.seconds,
        "iterations": np.array([s.iterations for s in run.solutions]),
    }
    if outcome.t is not None:
        arrays["t"] = outcome.t
    ok = np.array(status) == Status.OK
    rows = [
        MethodRow(
            run.name,
            "solver",
            {
                "median time per equilibrium [ms]": _finite(np.median, run.seconds) * MS,
                "max time per equilibrium [ms]": _finite(np.max, run.seconds) * MS,
                "ok": int(ok.sum()),
                "build [s]": run.build_seconds,
            },
        )
    ]
    notes = []
    metrics: dict[str, Any] = {
        f"tip {axis} range [mm]": [_finite(np.min, tips[ok, k]) * MM, _finite(np.max, tips[ok, k]) * MM]
        for k, axis in enumerate("xyz")
    }
    metrics["max tip residual of ok samples"] = _finite(np.max, residual[ok])
    if outcome.collocation is not None:
        c = outcome.collocation
        tip_gap, backbone_gap = agreement(run, c)
        c_ok = np.array([s.ok for s in c.solutions])
        arrays["tip_position_collocation"] = np.array([s.tip_position for s in c.solutions])
        arrays["residual_collocation"] = np.array([s.residual_norm for s in c.solutions])
        arrays["time_collocation"] = c.seconds
        arrays["status_collocation"] = np.array([s.status for s in c.solutions])
        both = ok & c_ok
        rows.append(
            MethodRow(
                c.name,
                "baseline",
                {
                    "median time per equilibrium [ms]": _finite(np.median, c.seconds) * MS,
                    "max time per equilibrium [ms]": _finite(np.max, c.seconds) * MS,
                    "ok": int(c_ok.sum()),
                    "build [s]": c.build_seconds,
                    "max |tip - shooting| [mm]": _finite(np.max, tip_gap[both]) * MM,
                    "max |backbone - shooting| [mm]": backbone_gap * MM,
                },
            )
        )
        metrics["max tip distance shooting-collocation [mm]"] = _finite(np.max, tip_gap[both]) * MM
    failed = [i for i, s in enumerate(run.solutions) if not s.ok]
    if failed:
        first = run.solutions[failed[0]]
        notes.append(f"{len(failed)} equilibria failed; first: sample {failed[0]}: {first.message}")
    if outcome.skipped_rows:
        notes.append(f"{outcome.skipped_rows} rows of {ctx.data_params.file} skipped (data.samples)")
    return ctx.result(
        solver=run.name,
        status=status,
        iterations=arrays["iterations"],
        residuals=residual,
        timings={
            "build [s]": run.build_seconds,
            "equilibria total [s]": float(run.seconds.sum()),
            "per equilibrium [ms]": float(run.seconds.sum()) / n * MS,
        },
        metrics=metrics,
        comparison=rows,
        arrays=arrays,
        notes=notes,
    )


def inverse_result(ctx: ProblemContext, outcome: InverseOutcome) -> Result:
    """The Result of an inverse run (module docstring)."""
    arrays: dict[str, np.ndarray] = {"targets": outcome.targets, "target_actuation": outcome.target_actuations}
    if outcome.t is not None:
        arrays["t"] = outcome.t
    rows = []
    for run in outcome.runs:
        key = array_key(run.name)
        report = run.report
        status = np.array(report.status)
        arrays[f"actuation_{key}"] = report.x
        arrays[f"tip_error_{key}"] = run.tip_error
        arrays[f"residual_{key}"] = report.residual
        arrays[f"status_{key}"] = status
        arrays[f"time_{key}"] = report.seconds
        metrics = {
            "success rate": float(np.mean(status == Status.OK)) if len(status) else float("nan"),
            "median tip error [m]": _finite(np.median, run.tip_error),
            "max tip error [m]": _finite(np.max, run.tip_error),
            "median time per target [ms]": _finite(np.median, report.seconds) * MS,
            "mean time per target [ms]": _finite(np.mean, report.seconds) * MS,
            "mean iterations": _finite(np.mean, report.iterations),
            "equilibria per target": run.equilibria_per_target,
        }
        if run.angle_error is not None:
            metrics["max angle error [rad]"] = _finite(np.max, run.angle_error)
        if np.isfinite(outcome.target_actuations).all() and len(status):
            metrics["max |actuation - generating actuation|"] = _finite(
                np.max, np.abs(report.x - outcome.target_actuations)
            )
        rows.append(MethodRow(run.name, run.role, metrics))
    main = outcome.runs[0]
    notes = []
    if outcome.dropped:
        notes.append(f"{outcome.dropped} targets dropped: the equilibrium of their actuation did not converge")
    if outcome.skipped_rows:
        notes.append(f"{outcome.skipped_rows} rows of {ctx.data_params.file} skipped (data.samples)")
    bad = [i for i, s in enumerate(main.report.status) if s != Status.OK]
    if bad:
        notes.append(f"{len(bad)} targets not solved by {main.name}; first: {bad[0]}: {main.report.messages[bad[0]]}")
    return ctx.result(
        solver=main.name,
        status=list(main.report.status),
        iterations=np.asarray(main.report.iterations),
        residuals=np.asarray(main.report.residual),
        timings={"per target [ms]": _finite(np.mean, main.report.seconds) * MS},
        metrics=dict(rows[0].metrics),
        comparison=rows,
        arrays=arrays,
        notes=notes,
    )


def result_of(ctx: ProblemContext, outcome: ForwardOutcome | InverseOutcome) -> Result:
    """The Result of either mode."""
    if isinstance(outcome, ForwardOutcome):
        return forward_result(ctx, outcome)
    return inverse_result(ctx, outcome)
