"""A ``dynamics`` outcome as a Result: one status per time step, the traces, the speed.

Status per planned step: ``ok`` when its BVP converged; the step that did not and every
step after it (never computed) are ``failed``, and a note names the step, its time and its
residual: the arrays then hold the partial trajectory up to the last converged step
(metric ``partial``).

Arrays: ``t (n,)`` [s], ``tip_position (n, 3)``, ``tip_orientation (n, 4)``, ``energy (n, 3)``
(kinetic, elastic, gravitational [J]), ``actuation (n, n_act)`` (applied), ``command (n, n_act)``
(commanded: the chamber pressures lag it with ``options.pressure_time_constant``), ``tip_force (n, 3)``,
``residual (n,)``, ``iterations (n,)``, ``step_time (n - 1,)`` [s], ``backbone (n, K, 3)`` (every
step, so ``optikin view`` animates it), ``s (K,)``, ``static_backbone (K, 3)`` (the static equilibrium under the last
loads, when the run completed).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.physics.dynamics_equations import ENERGY_NAMES
from optikin.problems import ProblemContext
from optikin.problems.dynamics.options import DynamicsKindOptions
from optikin.problems.dynamics.run import DynamicsOutcome
from optikin.results import MethodRow, Result

MM = 1e3
US = 1e6


def dominant_frequency(t: np.ndarray, tips: np.ndarray) -> float:
    """Frequency [Hz] of the tip coordinate that moves most, from its upward crossings of its late mean.

    NaN with fewer than two crossings.
    """
    if t.size < 4:
        return float("nan")
    axis = int(np.argmax(tips.std(axis=0)))
    y = tips[:, axis] - tips[t.size // 2 :, axis].mean()
    up = np.nonzero((y[:-1] < 0) & (y[1:] >= 0))[0]
    if up.size < 2:
        return float("nan")
    times = t[up] - y[up] * (t[up + 1] - t[up]) / (y[up + 1] - y[up])
    return float((up.size - 1) / (times[-1] - times[0]))


def result_of(ctx: ProblemContext, outcome: DynamicsOutcome) -> Result:
    """The Result (module docstring)."""
    options: DynamicsKindOptions = ctx.options
    states = outcome.states
    n, planned = len(states), outcome.t.size - 1
    status = ["ok"] * (n - 1) + ["failed"] * (planned - n + 1)
    t = np.array([s.t for s in states])
    tips = np.array([s.tip_position for s in states])
    energy = np.array([s.energy for s in states])
    residual = np.array([s.residual for s in states])
    iterations = np.array([s.iterations for s in states])
    arrays: dict[str, np.ndarray] = {
        "t": t,
        "tip_position": tips,
        "tip_orientation": np.array([s.tip_orientation for s in states]),
        "energy": energy,
        "actuation": outcome.actuation[:n],
        "command": outcome.command[:n],
        "tip_force": outcome.tip_force[:n],
        "residual": residual,
        "iterations": iterations,
        "step_time": outcome.step_seconds,
        "backbone": np.array([s.positions for s in states]),
        "s": outcome.s,
    }
    if outcome.static_positions is not None:
        arrays["static_backbone"] = outcome.static_positions
    seconds = outcome.step_seconds
    mean_step = float(seconds.mean()) if seconds.size else float("nan")
    total = energy.sum(axis=1)
    scale = float(np.abs(energy).sum(axis=1).max()) or 1.0
    metrics: dict[str, Any] = {
        "steps": n - 1,
        "partial": outcome.failure is not None,
        "simulated [s]": float(t[-1]),
        "dt [s]": options.dt,
        "alpha": options.alpha,
        "points": int(outcome.s.size),
        "median step [us]": float(np.median(seconds)) * US if seconds.size else float("nan"),
        "mean step [us]": mean_step * US,
        "real-time factor": options.dt / mean_step if seconds.size else float("nan"),
        "mean Newton iterations": float(iterations[1:].mean()) if n > 1 else float("nan"),
        "max step residual": float(residual.max()),
        "tip displacement max [mm]": float(np.linalg.norm(tips - tips[0], axis=1).max()) * MM,
        "energy change / max energy": float((total[-1] - total[0]) / scale),
        "first bending period, Euler-Bernoulli [s]": outcome.first_period,
        "tip frequency [Hz]": dominant_frequency(t, tips),
    }
    for name, value in zip(ENERGY_NAMES, energy[-1]):
        metrics[f"final {name} energy [J]"] = float(value)
    if outcome.static_positions is not None:
        metrics["final distance to the static equilibrium [mm]"] = (
            float(np.abs(states[-1].positions - outcome.static_positions).max()) * MM
        )
    method = "bdf-alpha shooting" + (" (compiled)" if options.compiled else "")
    rows = [
        MethodRow(
            method,
            "solver",
            {
                "step [us]": metrics["median step [us]"],
                "real-time factor": metrics["real-time factor"],
                "Newton iterations": metrics["mean Newton iterations"],
                "steps ok": n - 1,
                "build [s]": outcome.build_seconds,
            },
        )
    ]
    notes = []
    if outcome.failure is not None:
        notes.append(
            f"partial trajectory: {outcome.failure}; the arrays stop at step {n - 1} (t = {t[-1]:.6g} s), "
            f"{planned - n + 1} steps not computed"
        )
    return ctx.result(
        solver=method,
        status=status,
        iterations=iterations[1:],
        residuals=residual[1:],
        timings={"build [s]": outcome.build_seconds, "steps [s]": float(seconds.sum())},
        metrics=metrics,
        comparison=rows,
        arrays=arrays,
        notes=notes,
    )
