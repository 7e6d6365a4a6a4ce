"""Constrained tracking: one small QP per control step (issue 6; beyond seed 000 sections V-VI).

Each step solves

    min_qdot  ||J(q) qdot - (xdot_ref + K e)||^2 + lambda ||qdot||^2
    s.t.      lb <= qdot <= ub

where ``J`` is the task Jacobian of the arm's own model (seed 000 eq. 33 for the
dual-quaternion pose), ``e = x_ref - x`` and ``K = diag(k)`` as in seed 000
eq. (34), and the box (:class:`optikin.control.limits.RateBounds`) keeps every
configuration limit after integrating the rate over the step and respects the
rate limits, also when the arm starts outside a limit (it steers back at the
full rate; the box is never empty). Without active bounds the solution is the
damped least-squares step ``(J'J + lambda I)^-1 J' (xdot_ref + K e)``.

Failure handling. If the solver raises, returns nothing, or returns a
non-finite vector, the step is reported (:attr:`QPController.status` starts
with ``"fallback"``) and a safe command is applied instead:

* ``fallback="hold"`` (default): the smallest rate inside the box, i.e. stop
  (``qdot = 0``) inside the limits, steer back at the full rate outside;
* ``fallback="damped_least_squares"``: the unconstrained QP solution projected
  onto the box.

Both lie in the box, so a failing solver can never push a limit. A returned
solution is itself projected onto the box (a no-op for an exact solver); the
amount removed is kept in :attr:`QPController.slip`, the bound violation the
solver's tolerance would otherwise have let through.
"""

from __future__ import annotations

import math
from typing import Any, Literal, Mapping, Sequence

import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.control.limits import RateBounds
from optikin.control.qp_backends import QPData, make_qp_backend
from optikin.control.task import Task

Fallback = Literal["hold", "damped_least_squares"]
FALLBACKS = ("hold", "damped_least_squares")


class QPController(Controller):
    """Tracking by a bounded least-squares QP per step.

    Parameters
    ----------
    arm, dt, task, gain:
        See :class:`optikin.control.base.Controller`; ``gain`` is ``K`` (1/s).
    damping:
        ``lambda``, weight of ``||qdot||^2`` (keeps ``H`` positive definite at singular configurations).
    backend:
        ``"osqp"``, ``"qpsolvers"``, ``"cvxpy"``, ``"cvxpy_rebuild"``, or any object with
        ``solve(QPData) -> array | None`` and ``last_status``.
    solver, backend_options:
        The solver behind ``qpsolvers``/``cvxpy`` and options handed to the backend.
    rate_limits, margin, periodic, limit_gain:
        See :class:`optikin.control.limits.RateBounds` (``limit_gain`` is its ``gain``).
    fallback:
        What to command when the solver fails (see the module docstring).
    """

    name = "qp"

    def __init__(self, arm: ArmModel, dt: float, task: Task = "pose", gain=10.0, damping: float = 1e-4,
                 backend: Any = "osqp", solver: str | None = None, backend_options: Mapping[str, Any] | None = None,
                 rate_limits=None, margin: float | Sequence[float] = 1e-9, periodic: Sequence[str] | None = None,
                 limit_gain: float = 1.0, fallback: Fallback = "hold", compiled: bool = False):
        super().__init__(arm, dt, task, gain, compiled)
        if not damping >= 0:
            raise ValueError(f"damping must be non-negative, got {damping}")
        if fallback not in FALLBACKS:
            raise ValueError(f"unknown fallback {fallback!r}; known: {', '.join(FALLBACKS)}")
        self.damping, self.fallback = float(damping), fallback
        self.model.set_gains(self.gain, self.damping)
        self.bounds = RateBounds(arm, dt, rate_limits, margin, periodic, gain=limit_gain)
        m = self.model
        self.data = QPData(m.J, m.v, self.damping, m.H, m.H_upper, m.g, self.bounds.lb, self.bounds.ub)
        if isinstance(backend, str):
            backend = make_qp_backend(backend, arm.n_config, m.m, solver, backend_options)
        self.backend = backend
        self.name = f"qp ({getattr(backend, 'name', type(backend).__name__)})"
        self.qdot = np.zeros(arm.n_config)
        self.slip = 0.0

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.model.evaluate(q, x, x_ref, xdot_ref)
        self.bounds.update(q)
        lb, ub = self.bounds.lb, self.bounds.ub
        try:
            solution = self.backend.solve(self.data)
            failure = None if solution is not None else f"no solution ({self.backend.last_status})"
        except Exception as exc:  # noqa: BLE001 - a solver crash must stop neither the loop nor the arm
            solution, failure = None, f"solver raised {type(exc).__name__}: {exc}"
        if failure is None:
            qdot = self.qdot
            np.maximum(solution, lb, out=qdot)
            np.minimum(qdot, ub, out=qdot)
            removed = [abs(d) for d in (qdot - solution).tolist()]
            if math.isfinite(sum(removed)):  # NaN or inf anywhere in the solution makes the sum non-finite
                self.slip = max(removed)
                self.status = "ok"
                return qdot
            failure = "non-finite solution"
        self.slip = 0.0
        self._fall_back()
        self.status = f"fallback ({self.fallback}): {failure}"
        return self.qdot

    def _fall_back(self) -> None:
        if self.fallback == "hold":
            self.qdot[:] = 0.0
        else:
            self.qdot[:] = np.linalg.solve(self.model.H, -self.model.g)
        np.maximum(self.qdot, self.bounds.lb, out=self.qdot)
        np.minimum(self.qdot, self.bounds.ub, out=self.qdot)

