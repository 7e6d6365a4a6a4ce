"""The tracked task (tip position, or tip pose as a dual quaternion) and the data every controller needs per step.

One CasADi Function, built from the arm's own ``fk_*`` / ``jac_*`` Functions and
called through a buffer (:mod:`optikin.fastcall`), returns for the measured
configuration ``q``, the measured task value ``x``, the reference ``x_ref`` and
its rate ``xdot_ref``, the feedback gains ``k`` (diagonal of ``K``) and the
damping ``lambda``:

* ``J``: the task Jacobian (``m x n``; Seleem et al. 2020 eq. 33 for the pose task),
* ``e = x_ref - x`` (Seleem et al. 2020 eq. 34),
* ``v = xdot_ref + K e``, the task velocity every controller asks for (eq. 34),
* ``H = J'J + lambda I`` and ``g = -J'v``: the QP ``min 1/2 qdot'H qdot + g'qdot``
  equivalent to ``min ||J qdot - v||^2 + lambda ||qdot||^2``, with ``H``'s upper
  triangle also given in compressed-column order (what OSQP stores).

A dual quaternion and its negative are the same pose. For the pose task the
reference (and its rate) is flipped into the hemisphere of the measurement
(``<x_ref,r, x_r> >= 0``) before ``e`` is formed, so ``e`` is the short way round.
"""

from __future__ import annotations

from typing import Literal

import casadi as ca
import numpy as np

from optikin.arms.base import ArmModel
from optikin.fastcall import BufferedFunction
from optikin.solvers.qp.common import upper_triangle_csc_indices

Task = Literal["pose", "position"]
TASK_FUNCTIONS = {"pose": ("fk_dq", "jac_dq"), "position": ("fk_position", "jac_position")}


def task_dimension(task: Task) -> int:
    return {"pose": 8, "position": 3}[_checked(task)]


def _checked(task: str) -> str:
    if task not in TASK_FUNCTIONS:
        raise ValueError(f"unknown task {task!r}; known: {', '.join(TASK_FUNCTIONS)}")
    return task


def task_step_function(arm: ArmModel, task: Task) -> ca.Function:
    """``(q, x, x_ref, xdot_ref, k, lambda) -> (J, e, v, H, H_upper, g)`` (see the module docstring)."""
    fk_name, jac_name = TASK_FUNCTIONS[_checked(task)]
    n, m = arm.n_config, task_dimension(task)
    q = ca.SX.sym("q", n)
    x, x_ref, xdot_ref, k = (ca.SX.sym(name, m) for name in ("x", "x_ref", "xdot_ref", "k"))
    damping = ca.SX.sym("damping")
    J = arm.function(jac_name)(q)
    sign: ca.SX | float
    if task == "pose":
        sign = ca.if_else(ca.dot(x_ref[:4], x[:4]) < 0, -1.0, 1.0)
    else:
        sign = 1.0
    e = sign * x_ref - x
    v = sign * xdot_ref + k * e
    H = J.T @ J + damping * ca.SX.eye(n)
    rows, cols = upper_triangle_csc_indices(n)
    H_upper = ca.vertcat(*[H[int(i), int(j)] for i, j in zip(rows, cols)])
    g = -J.T @ v
    return ca.Function(
        f"{arm.name}_{task}_step",
        [q, x, x_ref, xdot_ref, k, damping],
        [J, e, v, H, H_upper, g],
        ["q", "x", "x_ref", "xdot_ref", "k", "damping"],
        ["J", "e", "v", "H", "H_upper", "g"],
    )


class TaskModel:
    """The controller's model of the task: evaluates :func:`task_step_function` in place.

    After :meth:`evaluate`, the attributes ``J`` (``m x n``), ``e``, ``v`` (``m``),
    ``H`` (``n x n``), ``H_upper`` and ``g`` (``n``) are views of the buffers:
    valid until the next call, not to be kept. :attr:`q` is the Function's configuration
    input, holding the ``q`` of the last :meth:`evaluate` (a rate box may read it in place,
    :meth:`optikin.control.limits.RateBounds.read_configuration_from`).
    """

    def __init__(self, arm: ArmModel, task: Task = "pose", compiled: bool = False):
        self.arm, self.task = arm, _checked(task)
        self.n, self.m = arm.n_config, task_dimension(task)
        self.fk = arm.function(TASK_FUNCTIONS[task][0])
        self._f = BufferedFunction(task_step_function(arm, task), compiled=compiled)
        self.q, self._x, self._x_ref, self._xdot_ref, self._k, self._damping = self._f.inputs
        self.J = self._f.output_matrix(0)
        self.e, self.v = self._f.outputs[1], self._f.outputs[2]
        self.H = self._f.output_matrix(3)
        self.H_upper, self.g = self._f.outputs[4], self._f.outputs[5]

    def set_gains(self, gain: np.ndarray, damping: float = 0.0) -> None:
        """Feedback gains ``k`` (diagonal of ``K``) and damping ``lambda`` used by the next evaluations."""
        self._k[:] = gain
        self._damping[0] = damping

    def evaluate(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> None:
        """Refresh ``J, e, v, H, H_upper, g`` for this step (gains as last set)."""
        self.q[...] = q  # [...] = copies in place, cheaper than [:] = (no slice object, no view)
        self._x[...] = x
        self._x_ref[...] = x_ref
        self._xdot_ref[...] = xdot_ref
        self._f()
