"""Unconstrained Jacobian tracking baselines: the plain pseudo-inverse and damped least squares.

Both command ``qdot = J^+ (xdot_ref + K e)`` with ``e = x_ref - x`` (Seleem et al. 2020
eq. 34 with a constant gain ``K``):

* :class:`PseudoInverseController`: ``J^+`` the Moore-Penrose pseudo-inverse
  (Seleem et al. 2020 eq. 32). Singular values below ``rcond`` times the largest count as
  zero: the dual-quaternion Jacobian of a two-section constant-curvature arm is
  8 x 6 of rank 5 everywhere (its tip pose has five independent directions;
  finite differences agree), and at a straight section (``theta_i = 0``) the
  ``phi_i`` column vanishes.
* :class:`DampedLeastSquaresController`: ``qdot = (J'J + lambda I)^-1 J' (xdot_ref + K e)``,
  the minimiser of ``||J qdot - v||^2 + lambda ||qdot||^2`` (Wampler 1986;
  Nakamura & Hanafusa 1986), i.e. the QP of :mod:`optikin.control.qp` without bounds.

Neither knows the configuration or rate limits: on a reference that drives the
arm into a limit they go through it (the tracking tests report how far). Saturated
(:meth:`~optikin.control.base.Controller.saturate_at`), their command is clipped into the QP's box.
"""

from __future__ import annotations

import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.control.task import Task

PINV_RCOND = 1e-10
"""Relative cut-off of singular values in the pseudo-inverse."""


class PseudoInverseController(Controller):
    """``qdot = J^+ (xdot_ref + K e)`` (Seleem et al. 2020 eqs. 32, 34) with a constant ``K``."""

    name = "pseudo-inverse"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain=10.0,
        rcond: float = PINV_RCOND,
        compiled: bool = False,
    ):
        super().__init__(arm, dt, task, gain, compiled)
        self.rcond = float(rcond)

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.model.evaluate(q, x, x_ref, xdot_ref)
        return self.saturated_command(np.linalg.pinv(self.model.J, rcond=self.rcond) @ self.model.v)


class DampedLeastSquaresController(Controller):
    """``qdot = (J'J + lambda I)^-1 J' (xdot_ref + K e)`` with a constant ``K``."""

    name = "damped least squares"

    def __init__(
        self, arm: ArmModel, dt: float, task: Task = "pose", gain=10.0, damping: float = 1e-4, compiled: bool = False
    ):
        super().__init__(arm, dt, task, gain, compiled)
        if not damping > 0:
            raise ValueError(f"damping must be positive, got {damping}")
        self.damping = float(damping)
        self.model.set_gains(self.gain, self.damping)

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.model.evaluate(q, x, x_ref, xdot_ref)
        return self.saturated_command(np.linalg.solve(self.model.H, -self.model.g))
