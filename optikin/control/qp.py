"""Constrained tracking: one small QP per control step (beyond the MRAC of Seleem et al. 2020, sections V-VI).

Each step solves

    min_qdot  ||J(q) qdot - (xdot_ref + K e)||^2 + lambda ||qdot||^2
    s.t.      lb <= qdot <= ub,   A qdot >= b  (optional: the backbone barrier)

where ``J`` is the task Jacobian of the arm's own model (Seleem et al. 2020 eq. 33 for the
dual-quaternion pose), ``e = x_ref - x`` and ``K = diag(k)`` as in Seleem et al. 2020
eq. (34), and the box (:class:`optikin.control.limits.RateBounds`) keeps every
configuration limit after integrating the rate over the step and respects the
rate limits, also when the arm starts outside a limit (it steers back at the
full rate; the box is never empty). Without active bounds the solution is the
damped least-squares step ``(J'J + lambda I)^-1 J' (xdot_ref + K e)``.

With obstacles (``barrier``, :class:`optikin.control.obstacles.BarrierRows`) the rows
``A qdot >= b`` are the discrete-time barrier of the backbone samples nearest to each
obstacle; the task stays a least-squares objective (its slack is free), the barrier is hard.

Which QP method. The QP is solved by a step solver (``solve(QPData) -> Solution``): a ``qp``
backend's (:mod:`optikin.solvers.qp`) when a preset names one, e.g. ``qp-osqp``; otherwise
(``solver=None``) it is chosen by the QP's structure (:func:`default_step_solver`). These QPs are
small and dense (``n`` rates, ``H`` full, the box plus a few rows), so for ``n <=``
:data:`ACTIVE_SET_MAX_RATES` and at most :data:`ACTIVE_SET_MAX_ROWS` rows the default is a
dual active-set method (DAQP, Arnstrom, Bemporad and Axehill 2022,
:class:`~optikin.solvers.qp.qp_daqp.ActiveSetStepSolver`, backend ``qp_daqp``, preset
``qp-active-set``): exact up to rounding once the active set is found, warm-started with the previous
step's active set (consecutive steps rarely change it: often one iteration), one
dense Cholesky factorisation of ``H`` per step. ADMM (OSQP) stops at its tolerance, and on the
redundant arms (more rates than task rows: the null space of ``J`` is held by ``lambda`` alone) its
error there is about the tolerance over ``lambda``; it is the default only beyond those sizes, where
a dense factorisation per step grows as ``n^3`` and OSQP's sparse one pays.

Failure handling. If the solver raises, answers with a status other than
``"ok"``, or returns a non-finite vector, the step is reported (:attr:`QPController.status` starts
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
from typing import Literal, Sequence

import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.control.limits import RateBounds
from optikin.control.obstacles import BarrierRows
from optikin.control.task import Task
from optikin.solvers.base import QPStepSolver, Solution
from optikin.solvers.qp.common import QPData
from optikin.solvers.qp.qp_daqp import ActiveSetStepSolver

Fallback = Literal["hold", "damped_least_squares"]
FALLBACKS = ("hold", "damped_least_squares")

ACTIVE_SET_MAX_RATES = 24
"""Up to this many rates (8 three-variable sections) the default QP method is the dense active set."""
ACTIVE_SET_MAX_ROWS = 96
"""Up to this many rows ``A qdot >= b`` besides the box the default QP method is the dense active set."""


def default_step_solver(n: int, m: int, rows: int = 0) -> QPStepSolver:
    """The QP method chosen by structure (module docstring): dense active set when small, else OSQP.

    Parameters
    ----------
    n, m, rows:
        Rates, task rows and rows ``A qdot >= b`` of the per-step QP.

    Returns
    -------
    QPStepSolver
        :class:`~optikin.solvers.qp.qp_daqp.ActiveSetStepSolver` for ``n <=`` :data:`ACTIVE_SET_MAX_RATES`
        and ``rows <=`` :data:`ACTIVE_SET_MAX_ROWS`; otherwise the ``qp_osqp`` backend's step solver at its defaults.
    """
    if n <= ACTIVE_SET_MAX_RATES and rows <= ACTIVE_SET_MAX_ROWS:
        return ActiveSetStepSolver(n, m, rows=rows)
    from optikin.solvers import preset_of
    from optikin.spec import SolverSpec

    factory = preset_of(SolverSpec(name="qp-osqp", backend="qp_osqp", options={})).build()
    return factory.create(n, m, rows)


class QPController(Controller):
    """Tracking by a bounded least-squares QP per step.

    Parameters
    ----------
    arm, dt, task, gain:
        See :class:`optikin.control.base.Controller`; ``gain`` is ``K`` (1/s).
    damping:
        ``lambda``, weight of ``||qdot||^2`` (keeps ``H`` positive definite at singular configurations).
    solver:
        The step solver (``solve(QPData) -> Solution``), e.g. a ``qp`` preset's
        ``create(arm.n_config, task rows)`` or :func:`optikin.solvers.qp.step_solver`;
        ``None``: chosen by the QP's structure (:func:`default_step_solver`, module docstring).
    rate_limits, margin, periodic, limit_gain:
        See :class:`optikin.control.limits.RateBounds` (``limit_gain`` is its ``gain``).
    fallback:
        What to command when the solver fails (see the module docstring).
    compiled:
        Compile the per-step CasADi Function with a C compiler.
    barrier:
        The backbone barrier rows (its step solver must be created for ``barrier.rows`` rows); ``None``: no obstacles.
    """

    name = "qp"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain: float | Sequence[float] = 10.0,
        damping: float = 1e-4,
        *,
        solver: QPStepSolver | None = None,
        rate_limits=None,
        margin: float | Sequence[float] = 1e-9,
        periodic: Sequence[str] | None = None,
        limit_gain: float = 1.0,
        fallback: Fallback = "hold",
        compiled: bool = False,
        barrier: BarrierRows | None = None,
    ):
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
        self.barrier = barrier
        if barrier is not None:
            self.data.A, self.data.b = barrier.A, barrier.b
        if solver is None:
            solver = default_step_solver(arm.n_config, m.m, 0 if barrier is None else barrier.rows)
        self.solver = solver
        self.name = f"qp ({getattr(solver, 'name', type(solver).__name__)})"
        self.qdot = np.zeros(arm.n_config)
        self._removed = np.zeros(arm.n_config)
        self.slip = 0.0
        self.solution: Solution | None = None

    def reset(self, q: np.ndarray, x: np.ndarray) -> None:
        super().reset(q, x)
        if self.barrier is not None:
            self.barrier.reset()

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.model.evaluate(q, x, x_ref, xdot_ref)
        self.bounds.update(q)
        if self.barrier is not None:
            self.barrier.update(q)
        lb, ub = self.bounds.lb, self.bounds.ub
        try:
            solution = self.solution = self.solver.solve(self.data)
            failure = None if solution.status == "ok" else f"no solution ({solution.message})"
        except Exception as exc:  # noqa: BLE001 - a solver crash must stop neither the loop nor the arm
            self.solution, failure = None, f"solver raised {type(exc).__name__}: {exc}"
        if failure is None:
            qdot, removed = self.qdot, self._removed
            np.maximum(solution.x, lb, out=qdot)
            np.minimum(qdot, ub, out=qdot)
            np.subtract(qdot, solution.x, out=removed)
            amounts = np.abs(removed, out=removed).tolist()  # n floats: quicker than a numpy reduction
            if math.isfinite(sum(amounts)):  # NaN or inf anywhere in the solution makes the sum non-finite
                self.slip = max(amounts)
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
