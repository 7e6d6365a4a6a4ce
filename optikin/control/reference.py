"""References for the tip: a task value and its rate at every control instant.

Until the DMP roll-outs exist, references are made by forward kinematics of a
smooth configuration path: minimum-jerk segments (Flash & Hogan 1985,
``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5``) between waypoints written in the
problem file. The task value is ``fk(q(t))`` and its rate ``J(q(t)) qdot(t)``, both
from the arm's Functions, so the reference is exactly reachable by the model
wherever the path stays inside the limits, and drives into a limit wherever a
waypoint lies outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optikin.algebra import dq_rotation, dq_translation
from optikin.arms.base import ArmModel
from optikin.control.task import TASK_FUNCTIONS, Task, task_dimension


@dataclass(frozen=True)
class Reference:
    """Reference samples at the control instants ``t`` (uniform spacing ``dt``).

    ``value``/``rate`` are ``(N, m)``: tip positions (m, m/s) or tip dual
    quaternions and their derivatives. ``configurations`` is the path they were
    made from, when there is one.
    """

    t: np.ndarray
    value: np.ndarray
    rate: np.ndarray
    task: Task
    configurations: np.ndarray | None = None

    def __post_init__(self):
        m = task_dimension(self.task)
        n = len(self.t)
        if n < 2 or self.value.shape != (n, m) or self.rate.shape != (n, m):
            raise ValueError(
                f"reference needs t (N >= 2,), value and rate (N, {m}); got {self.t.shape}, "
                f"{self.value.shape}, {self.rate.shape}"
            )
        steps = np.diff(self.t)
        if np.any(steps <= 0) or np.ptp(steps) > 1e-9 * steps[0]:
            raise ValueError("reference times must be uniformly spaced and increasing")

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def position(self) -> np.ndarray:
        """Reference tip positions ``(N, 3)``."""
        return self.value if self.task == "position" else dq_translation(self.value)

    @property
    def orientation(self) -> np.ndarray | None:
        """Reference tip quaternions ``(N, 4)`` (pose task only)."""
        return dq_rotation(self.value) if self.task == "pose" else None


def minimum_jerk_path(waypoints: np.ndarray, durations, rate: float, hold: float = 0.0):
    """Configurations and rates along minimum-jerk segments through ``waypoints`` (K, n).

    ``durations`` gives each segment's length in seconds (one value for all);
    ``hold`` seconds at the last waypoint are appended. Returns ``(t, Q, Qdot)``
    sampled at ``rate`` Hz.
    """
    W = np.atleast_2d(np.asarray(waypoints, dtype=float))
    if W.shape[0] < 2:
        raise ValueError("a path needs at least two waypoints")
    d = np.broadcast_to(np.asarray(durations, dtype=float), (W.shape[0] - 1,))
    if np.any(d <= 0) or rate <= 0 or hold < 0:
        raise ValueError("durations and rate must be positive, hold non-negative")
    ends = np.concatenate([[0.0], np.cumsum(d)])
    t = np.arange(int(round((ends[-1] + hold) * rate)) + 1) / rate
    segment = np.clip(np.searchsorted(ends, t, side="right") - 1, 0, len(d) - 1)
    tau = np.clip((t - ends[segment]) / d[segment], 0.0, 1.0)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    sdot = 30 * tau**2 * (1 - tau) ** 2 / d[segment]
    sdot[t > ends[-1]] = 0.0
    delta = W[segment + 1] - W[segment]
    return t, W[segment] + s[:, None] * delta, sdot[:, None] * delta


def reference_from_configurations(
    arm: ArmModel, t: np.ndarray, Q: np.ndarray, Qdot: np.ndarray, task: Task = "pose"
) -> Reference:
    """The tip reference ``x = fk(q(t))``, ``xdot = J(q(t)) qdot(t)`` of a configuration path."""
    fk_name, jac_name = TASK_FUNCTIONS[task]
    value = arm.evaluate(fk_name, Q)
    rate = np.einsum("kij,kj->ki", arm.evaluate(jac_name, Q), Qdot)
    return Reference(np.asarray(t, dtype=float), value, rate, task, np.asarray(Q, dtype=float))
