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
:class:`ActiveSetStepSolver`): exact up to rounding once the active set is found, warm-started
with the previous step's active set (consecutive steps rarely change it: often one iteration), one
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
import time
from typing import Literal, Sequence

import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.control.limits import RateBounds
from optikin.control.obstacles import BarrierRows
from optikin.control.task import Task
from optikin.solvers.base import QPStepSolver, Solution
from optikin.solvers.qp.common import QPData

Fallback = Literal["hold", "damped_least_squares"]
FALLBACKS = ("hold", "damped_least_squares")

ACTIVE_SET_MAX_RATES = 24
"""Up to this many rates (8 three-variable sections) the default QP method is the dense active set."""
ACTIVE_SET_MAX_ROWS = 96
"""Up to this many rows ``A qdot >= b`` besides the box the default QP method is the dense active set."""

_DAQP_INFINITY = 1e30
"""daqp's ``DAQP_INF``: a bound at or beyond it is no bound."""


class ActiveSetStepSolver:
    """The per-step QP by DAQP's dual active-set method on the controller's own buffers, warm-started.

    DAQP (Arnstrom, Bemporad and Axehill 2022, "A dual active-set solver for embedded
    quadratic programming using recursive LDL' updates", IEEE TAC 67(8), doi:10.1109/TAC.2022.3176430)
    solves ``min 1/2 x'Hx + g'x`` s.t. ``lb <= x <= ub`` (simple bounds) and ``b <= A x``.
    One ``daqp.Model`` is set up at the first :meth:`solve` on the arrays of that
    :class:`~optikin.solvers.qp.common.QPData`: ``H`` (its transpose, the same symmetric
    matrix, C-ordered), ``g``, ``lb``, ``ub`` and ``A`` are handed over without a copy (daqp copies
    only arrays that are not contiguous ``float64``), so daqp reads the buffers the task Function
    writes. Each step then refreshes the model (``update``: the Cholesky factor of the new ``H``,
    the new bounds) and solves from the previous step's active set. With rows, the bounds go
    through two buffers ``[lb; b]``, ``[ub; inf]`` filled in place (``b`` clipped at daqp's
    infinity). After a failed solve the next one starts from the empty active set.

    The answer (:meth:`solve`) is one :class:`~optikin.solvers.base.Solution` updated in place
    every step: ``x`` a preallocated array, overwritten by the next call (copy what you keep);
    ``status`` ``"ok"`` or ``"failed"`` (``message`` daqp's exit flag, e.g. ``-1`` infeasible).

    Parameters
    ----------
    n:
        Number of rates.
    m:
        Number of task rows (unused; the signature of a ``qp`` step-solver factory).
    rows:
        Number of rows ``A qdot >= b``.
    """

    name = "daqp-active-set"

    def __init__(self, n: int, m: int = 0, rows: int = 0):
        import daqp

        self.n, self.rows = n, rows
        self._model = daqp.Model()
        self._update, self._solve = self._model.update, self._model.solve
        self._data: QPData | None = None
        self._sense = np.zeros(n + rows, dtype=np.intc)
        self._x = np.full(n, np.nan)
        self.solution = Solution(self._x, "ok")
        if rows:
            self._lower, self._upper = np.empty(n + rows), np.full(n + rows, _DAQP_INFINITY)
            self._lower_box, self._lower_rows, self._upper_box = self._lower[:n], self._lower[n:], self._upper[:n]

    def _setup(self, data: QPData) -> int:
        """Bind a daqp model to ``data``'s arrays; its exit flag (negative on failure)."""
        if data.H.shape != (self.n, self.n) or data.A.shape[0] != self.rows:
            raise ValueError(
                f"{self.name}: QP of {data.n} rates and {data.A.shape[0]} rows, set up for {self.n}, {self.rows}"
            )
        self._H = data.H.T  # H is symmetric and column-major: its transpose is the same matrix, C-ordered, no copy
        self._A = data.A if self.rows else np.zeros((0, self.n))
        if self.rows:
            self._fill_bounds(data)
            upper, lower = self._upper, self._lower
        else:
            upper, lower = data.ub, data.lb
        self._data, self._upper_now, self._lower_now = data, upper, lower
        self._sense.fill(0)  # no constraint assumed active
        flag, _ = self._model.setup(self._H, data.g, self._A, upper, lower, self._sense)
        return int(flag)

    def _fill_bounds(self, data: QPData) -> None:
        np.copyto(self._lower_box, data.lb)
        np.copyto(self._upper_box, data.ub)
        np.maximum(data.b, -_DAQP_INFINITY, out=self._lower_rows)

    def solve(self, data: QPData) -> Solution:
        """One warm-started solve of this step's QP (``data`` the same object every step)."""
        start = time.perf_counter()
        solution = self.solution
        if data is not self._data:
            flag = self._setup(data)
        elif self.rows:
            self._fill_bounds(data)
            flag = self._update(H=self._H, f=data.g, A=self._A, bupper=self._upper, blower=self._lower)
        else:
            flag = self._update(H=self._H, f=data.g, bupper=self._upper_now, blower=self._lower_now)
        iterations = -1
        if flag >= 0:  # set up or updated (the factorisation of H succeeded)
            x, _, flag, info = self._solve()
            iterations = info["iterations"]
        if flag == 1:
            np.copyto(self._x, x)
            solution.status, solution.message = "ok", ""
        else:
            self._x.fill(np.nan)
            solution.status, solution.message = "failed", f"daqp exit flag {flag}"
            self._data = None  # the next step sets the model up afresh: empty active set, new factorisation
        solution.iterations, solution.seconds = iterations, time.perf_counter() - start
        return solution


def default_step_solver(n: int, m: int, rows: int = 0) -> QPStepSolver:
    """The QP method chosen by structure (module docstring): dense active set when small, else OSQP.

    Parameters
    ----------
    n, m, rows:
        Rates, task rows and rows ``A qdot >= b`` of the per-step QP.

    Returns
    -------
    QPStepSolver
        :class:`ActiveSetStepSolver` for ``n <=`` :data:`ACTIVE_SET_MAX_RATES` and ``rows <=``
        :data:`ACTIVE_SET_MAX_ROWS`; otherwise the ``qp_osqp`` backend's step solver at its defaults.
    """
    if n <= ACTIVE_SET_MAX_RATES and rows <= ACTIVE_SET_MAX_ROWS:
        return ActiveSetStepSolver(n, m, rows)
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
