"""What every tracking controller offers the closed-loop simulator.

A controller maps, once per control step of length ``dt``, the measured
configuration ``q``, the measured task value ``x`` (tip position, or tip pose
as a dual quaternion), the reference ``x_ref`` and its rate ``xdot_ref`` to a
commanded configuration rate ``qdot`` held over the step. After each
:meth:`Controller.command` it states how the step went in :attr:`Controller.status`
(``"ok"``, or ``"fallback: <reason>"`` when its solver failed and a stated
safe command was applied instead).

A controller that knows no limits can be given some (:meth:`Controller.saturate_at`): its command is then
clipped into the box of :class:`~optikin.control.limits.RateBounds` -- the rate limits, and the
configuration limits reached after the step -- the box the QP's solution is kept in, so a comparison
with the QP is not one between a controller inside the limits and others outside them by construction.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.limits import RateBounds
from optikin.control.task import Task, TaskModel, task_dimension
from optikin.status import Status


def gain_vector(gain, m: int, what: str = "gain") -> np.ndarray:
    """A scalar or ``m`` values as a positive vector of length ``m``."""
    k = np.asarray(gain, dtype=float)
    if k.ndim == 0:
        k = np.full(m, float(k))
    if k.shape != (m,):
        raise ValueError(f"{what} needs 1 or {m} values, got {np.shape(gain)}")
    if np.any(~np.isfinite(k)) or np.any(k < 0):
        raise ValueError(f"{what} must be finite and non-negative, got {k}")
    return k


class Controller(ABC):
    """A Jacobian-based tracking controller on ``arm`` for ``task`` at control period ``dt``."""

    name = "controller"
    limits: RateBounds | None = None
    """The box its commands are clipped into (:meth:`saturate_at`); ``None``: none."""

    def __init__(self, arm: ArmModel, dt: float, task: Task = "pose", gain=10.0, compiled: bool = False):
        if not dt > 0:
            raise ValueError(f"dt must be positive, got {dt}")
        self.arm, self.dt, self.task = arm, float(dt), task
        self.model = TaskModel(arm, task, compiled=compiled)
        self.gain = gain_vector(gain, task_dimension(task))
        self.model.set_gains(self.gain)
        self.status: str = Status.OK

    def reset(self, q: np.ndarray, x: np.ndarray) -> None:
        """Start a new run from measured configuration ``q`` and task value ``x``."""
        self.status = Status.OK

    def saturate_at(self, limits: RateBounds) -> None:
        """Clip every later command into ``limits``' box at the configuration the command was computed at;
        the controller's :attr:`name` says so (``"<name> (saturated)"``)."""
        limits.read_configuration_from(self.model.q)
        self.limits = limits
        self.name = f"{self.name} (saturated)"

    def saturated_command(self, qdot: np.ndarray) -> np.ndarray:
        """``qdot`` clipped (in place) into the box of :attr:`limits` at the configuration the task model
        last evaluated; unchanged without limits."""
        if self.limits is None:
            return qdot
        self.limits.refresh()
        return np.clip(qdot, self.limits.lb, self.limits.ub, out=qdot)

    @abstractmethod
    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        """The configuration rate to hold over the next step."""
