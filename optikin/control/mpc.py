"""Model predictive tracking: a horizon of ``N`` control steps, one sparse QP per step, warm-started.

The model. The configuration is integrated from the commanded rates, ``q_{j+1} = q_j + dt u_j``
(zero-order hold, as the plant of :mod:`optikin.control.simulate`), and the task by the same
forward-Euler step through the task Jacobian, ``x_{j+1} = x_j + dt J(qbar_j) u_j``, from the
measured ``x_0 = x``. The Jacobians are taken along ``qbar``: the previous step's plan shifted by
one step (its last rate repeated) and rolled out from the measured configuration,
``qbar_0 = q``, ``qbar_{j+1} = qbar_j + dt ubar_j`` (zero rates at the first step).

The target. The predicted tip follows the reference trajectory of predictive functional control
(Richalet et al. 1978): the reference, Euler-integrated from its rates, minus the present error
decaying at the task gain ``K``,

    w_j = x_ref + dt sum_{i<j} xdot_ref(t_{k+i}) - (I - dt K)^j e,    e = x_ref - x,

the discretisation of the QP controller's error dynamics ``e_dot = -K e``. The rates are the
reference's own ahead of the present instant when the controller is handed the reference
(``preview``), else the present rate held; the pose task's reference is flipped into the
measurement's hemisphere first, as in :mod:`optikin.control.task`.

The QP. With the task slacks ``s_j = (w_j - x_j) / dt`` (a task velocity) and the displacements
``y_j = (q_j - q) / dt`` (a rate) as variables, so that every matrix entry is of order one, the
step's QP over ``z = (u_0..u_{N-1}, y_1..y_N, s_1..s_N)`` is

    min  1/2 sum_{j=1..N} ||s_j||^2 + 1/2 lambda sum_{j=0..N-1} ||u_j||^2
    s.t. y_{j+1} - y_j - u_j = 0                                        (dynamics, y_0 = 0)
         s_{j+1} - s_j + J(qbar_j) u_j = xdot_ref(t_{k+j}) + K (I - dt K)^j e     (task, s_0 = 0)
         lb <= u_0 <= ub,  -r <= u_j <= r                               (rate box)
         (lo_j - q) / dt <= y_j <= (hi_j - q) / dt,  j >= 2             (configuration limits)
         D u_j + gamma dt D y_j >= b_j                                  (backbone barrier)

``lb, ub`` is the QP controller's box (:class:`optikin.control.limits.RateBounds`), which also
keeps ``q_1`` inside the limits; ``lo_j, hi_j`` are the limits, widened where the arm starts
outside them to what the full rate can recover by step ``j``, so the box stays non-empty.
``D, b_0`` are the rows :class:`optikin.control.obstacles.BarrierRows` writes at the present
step (``D u >= b_0`` is ``d_dot >= -gamma (d - d_safe)``, moving obstacles included), carried
along the horizon (:class:`HorizonBarrier`): ``gamma dt D y_j = gamma D (q_j - q)`` moves the
distance ``d(q)`` to the predicted ``d(q_j)`` to first order, and ``b_j`` adds a moving
obstacle's own translation. At ``j = 0`` the rows are exactly the QP controller's. The task
enters only through its slacks (free, penalised); the barrier and the boxes are hard.

Reduction to the QP step. With ``N = 1`` and no barrier, ``s_1 = v - J u_0`` with
``v = xdot_ref + K e``, so the QP is ``min 1/2 ||J u_0 - v||^2 + 1/2 lambda ||u_0||^2`` over the
rate box: the QP controller's step (:mod:`optikin.control.qp`) with ``damping = lambda``
(``effort_weight`` here) and the same gain ``K``, command for command.

The solver. OSQP (Stellato et al. 2020), set up once: ``P`` is constant and diagonal, ``A`` keeps
its pattern, and per step only ``A``'s values (the ``J`` and ``D`` blocks), ``l`` and ``u`` are
written in place before a solve warm-started from the previous step's primal and dual solution
(OSQP's own warm start: the answer of the last step as it is; shifting it by one step, as the
linearisation is, took more ADMM iterations in the benchmark of ``tests/timing``). OSQP takes the
sparse matrices as they are (a horizon's KKT system is banded), it detects primal infeasibility, and
its per-step cost is one factorisation and a few dozen ADMM iterations; the per-step overhead of a
modelling layer (cvxpy, qpsolvers' conversions) would exceed the solve. The defaults
(``eps = 1e-3``, ``rho = 0.1``, no polishing) are ADMM's usual accuracy: the applied rate is projected onto
the box (:attr:`HorizonController.slip`), and a barrier row may be missed by about ``eps`` [m/s],
which the row's own feedback ``-gamma (d - d_safe)`` turns into at most about ``eps / gamma`` of the
margin (0.05 mm at the defaults), never into a penetration. Tighter tolerances with ``polishing``
give the exact QP solution (the tests compare it with a dense solve).

Infeasible horizon. If the solve fails (OSQP reports the horizon infeasible, or runs out of
iterations), the step is solved again with the configuration limits and barrier rows of the
later steps dropped; that QP keeps the rate box and the barrier of the applied step, i.e. the QP
controller's step with the horizon's task cost. Its status says so (``"fallback (first step):
horizon ..."``). Should that fail too, the arm holds (the smallest rate in the box), ``"fallback
(hold): ..."``: then not even the present step's rows can be kept (an obstacle faster than the
rates allow), and the status says that too. No step passes an obstacle silently.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import casadi as ca
import numpy as np
import scipy.sparse as sp

from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.control.limits import RateBounds
from optikin.control.obstacles import BarrierRows
from optikin.control.reference import Reference
from optikin.control.task import TASK_FUNCTIONS, Task
from optikin.fastcall import BufferedFunction
from optikin.status import Status

_INFINITY = 1e30
"""OSQP's ``OSQP_INFTY``: a bound at or beyond it is no bound."""


class HorizonController(Controller):
    """What the MPC's QP path and its nonlinear reference share: horizon, target, bounds, barrier clock.

    Parameters
    ----------
    arm, dt, task, gain:
        See :class:`optikin.control.base.Controller`; ``gain`` is ``K`` [1/s], ``0 <= K dt <= 1``.
    effort_weight:
        ``lambda``, the weight of ``||u_j||^2`` (the QP controller's ``damping`` for ``N = 1``).
    horizon:
        ``N``, the control steps predicted, at least 1.
    rate_limits, margin, periodic, limit_gain:
        See :class:`optikin.control.limits.RateBounds`.
    barrier:
        The backbone barrier; ``None``: no obstacles.
    preview:
        The reference the run tracks: its rates ahead of the present step enter the target;
        ``None``: the present rate is held over the horizon.
    compiled:
        Compile the per-step CasADi Functions with a C compiler.
    """

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain: float | Sequence[float] = 10.0,
        effort_weight: float = 1e-4,
        *,
        horizon: int = 20,
        rate_limits=None,
        margin: float | Sequence[float] = 1e-9,
        periodic: Sequence[str] | None = None,
        limit_gain: float = 1.0,
        barrier: BarrierRows | None = None,
        preview: Reference | None = None,
        compiled: bool = False,
    ):
        super().__init__(arm, dt, task, gain, compiled)
        if int(horizon) != horizon or horizon < 1:
            raise ValueError(f"horizon must be a whole number of steps, at least 1, got {horizon}")
        if not effort_weight >= 0:
            raise ValueError(f"effort_weight must be non-negative, got {effort_weight}")
        if np.any(self.gain * self.dt > 1):
            raise ValueError(f"gain dt must be at most 1 (the target's error decays by 1 - K dt per step), got {gain}")
        if preview is not None and (preview.task != task or abs(preview.dt - self.dt) > 1e-9 * self.dt):
            raise ValueError("the preview reference must be of the controller's task and period")
        self.N, self.effort_weight = int(horizon), float(effort_weight)
        self.model.set_gains(self.gain, self.effort_weight)
        self.bounds = RateBounds(arm, dt, rate_limits, margin, periodic, gain=limit_gain)
        self.barrier, self.preview = barrier, preview
        n, m, N = arm.n_config, self.model.m, self.N
        self.decay = (1.0 - self.dt * self.gain)[None, :] ** np.arange(N)[:, None]  # (I - dt K)^j, (N, m)
        self.plan = np.zeros((N, n))  # the last solution's rates u_0..u_{N-1}
        self.qbar = np.zeros((N, n))  # the linearisation configurations qbar_0..qbar_{N-1}
        self.increments = np.zeros((N, m))  # right-hand sides of the task rows
        self.lower = np.zeros((N, n))  # bounds of q_1..q_N (q_1: +-inf, kept by the rate box of u_0)
        self.upper = np.zeros((N, n))
        self.qdot = np.zeros(n)
        self.slip = 0.0
        self.k = 0
        self.shifted = False

    def reset(self, q: np.ndarray, x: np.ndarray) -> None:
        super().reset(q, x)
        self.k, self.shifted = 0, False
        self.plan[:] = 0.0
        if self.barrier is not None:
            self.barrier.reset()

    def prepare(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> None:
        """The step's linearisation configurations, task right-hand sides and configuration bounds."""
        N, dt = self.N, self.dt
        self.model.evaluate(q, x, x_ref, xdot_ref)
        self.bounds.update(q)
        ubar = np.concatenate([self.plan[1:], self.plan[-1:]]) if self.shifted else self.plan
        self.qbar[0] = q
        np.cumsum(dt * ubar[:-1], axis=0, out=self.qbar[1:])
        self.qbar[1:] += q
        e, v = self.model.e, self.model.v
        rates = self._rates(xdot_ref)
        if self.task == "pose" and float(np.dot(x_ref[:4], x[:4])) < 0:
            rates = -rates
        self.increments[:] = rates + (self.gain * e)[None, :] * self.decay
        self.increments[0] = v
        b = self.bounds
        steps = np.arange(1, N)[:, None]  # q_{j+1} for j = 1..N-1
        self.lower[0], self.upper[0] = -np.inf, np.inf
        reach_up = q + dt * b.ub + (steps - 1) * dt * b.rate  # the highest q_{j+1} any plan reaches
        reach_down = q + dt * b.lb - (steps - 1) * dt * b.rate
        self.lower[1:] = np.minimum(b.lower, reach_up)
        self.upper[1:] = np.maximum(b.upper, reach_down)

    def _rates(self, xdot_ref: np.ndarray) -> np.ndarray:
        """Reference rates at ``t_k .. t_{k+N-1}`` (``(N, m)``), the last one held beyond the reference's end."""
        if self.preview is None:
            return np.broadcast_to(xdot_ref, (self.N, len(xdot_ref))).copy()
        rows = np.minimum(self.k + np.arange(self.N), len(self.preview.t) - 1)
        out = self.preview.rate[rows].copy()
        out[0] = xdot_ref
        return out

    def finish(self, u0: np.ndarray) -> np.ndarray:
        """Project the first rate onto the rate box (the amount removed is :attr:`slip`), advance the clocks."""
        lb, ub = self.bounds.lb, self.bounds.ub
        np.minimum(np.maximum(u0, lb), ub, out=self.qdot)
        removed = float(np.max(np.abs(self.qdot - u0)))
        self.slip = removed if math.isfinite(removed) else 0.0
        self.k += 1
        if self.barrier is not None:
            self.barrier.step = self.k
        return self.qdot

    def hold(self) -> np.ndarray:
        """The smallest rate in the box (stop inside the limits, steer back outside), as the QP's ``hold``."""
        self.plan[:] = 0.0
        self.shifted = False
        return self.finish(np.zeros(self.arm.n_config))


class HorizonBarrier:
    """The barrier rows of :class:`BarrierRows` at the present step, carried along the horizon.

    The rows of the present step (the nearest samples, their distance Jacobian ``D`` and
    ``b = -gamma (d - d_safe) + G' dc_k / dt``) hold for every step of the horizon with the
    distances moved to first order: by ``D (q_j - q)`` through the arm (a term of the QP, see
    :class:`HorizonQP`) and by ``-G' (c_{k+j} - c_k)`` through a moving obstacle's own
    translation ``c``, whose step ``c_{k+j+1} - c_{k+j}`` enters as in :class:`BarrierRows`:

        D u_j + gamma D (q_j - q) >= -gamma (d - d_safe - G' (c_{k+j} - c_k)) + G' (c_{k+j+1} - c_{k+j}) / dt.

    Parameters
    ----------
    barrier:
        The rows of one step.
    horizon:
        ``N``.

    Attributes
    ----------
    D, b:
        ``(p, n)`` and ``(N, p)``: the rows ``D u_j + gamma D (q_j - q) >= b_j``.
    """

    def __init__(self, barrier: BarrierRows, horizon: int):
        self.barrier, self.N = barrier, horizon
        self.D = barrier.A
        self.b = np.zeros((horizon, barrier.rows))

    def update(self, q: np.ndarray) -> None:
        """Rows for the horizon from ``q`` at the barrier's present step (its clock then counts the step)."""
        barrier, N = self.barrier, self.N
        t = barrier.step * barrier.dt
        barrier.update(q)
        self.b[:] = barrier.b
        distances = barrier.distances
        if not distances.moving:
            return
        k = barrier.points_per_obstacle
        G = distances.G_rows[barrier.selected]  # the rows' samples, as BarrierRows chose them at q
        offsets = np.stack([distances.offsets(t + j * barrier.dt) for j in range(N + 1)])  # (N + 1, 3, count)
        moved = np.repeat(offsets - offsets[:1], k, axis=2)  # c_{k+j} - c_k per row
        step = np.repeat(np.diff(offsets, axis=0), k, axis=2)  # c_{k+j+1} - c_{k+j} per row
        along = np.einsum("ri,jir->jr", G, moved[:N])
        self.b[:] = (
            self.b
            - np.einsum("ri,ir->r", G, step[0])[None, :] / barrier.dt
            + barrier.gamma * along
            + np.einsum("ri,jir->jr", G, step) / barrier.dt
        )


class HorizonQP:
    """The sparse QP of one MPC step (module docstring), its pattern fixed, its values refreshed in place.

    Parameters
    ----------
    n, m, N, p:
        Rates, task rows, horizon, barrier rows per step.
    dt:
        Control period [s].
    effort_weight:
        ``lambda``.
    gamma:
        The barrier rate [1/s] (unused without rows).

    Attributes
    ----------
    P, A:
        ``(nz, nz)`` upper-triangular diagonal and ``(rows, nz)`` constraint matrix (CSC);
        ``A.data`` is rewritten by :meth:`set_matrix`.
    l, u:
        ``(rows,)`` bounds of ``A z``, written by the controller (OSQP's infinity for none).
    """

    def __init__(self, n: int, m: int, N: int, p: int, dt: float, effort_weight: float, gamma: float = 0.0):
        self.n, self.m, self.N, self.p, self.gamma, self.dt = n, m, N, p, float(gamma), float(dt)
        nu, ne = N * n, N * m
        self.nz = 2 * nu + ne
        iu, iq, ie = 0, nu, 2 * nu  # variable offsets: u_0.., y_1.., s_1..
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        vals: list[np.ndarray] = []

        def add(r, c, v):
            rows.append(np.asarray(r).ravel())
            cols.append(np.asarray(c).ravel())
            vals.append(np.broadcast_to(np.asarray(v, dtype=float), np.shape(r)).ravel())

        eye_n, eye_m = np.arange(n), np.arange(m)
        self.row_dynamics, self.row_task = 0, nu
        self.row_rates, self.row_limits = nu + ne, 2 * nu + ne
        self.row_barrier = 3 * nu + ne
        self.rows = self.row_barrier + N * p
        for j in range(N):
            r = self.row_dynamics + j * n + eye_n
            add(r, iq + j * n + eye_n, 1.0)
            if j:
                add(r, iq + (j - 1) * n + eye_n, -1.0)
            add(r, iu + j * n + eye_n, -1.0)
            r = self.row_task + j * m + eye_m
            add(r, ie + j * m + eye_m, 1.0)
            if j:
                add(r, ie + (j - 1) * m + eye_m, -1.0)
        add(self.row_rates + np.arange(nu), iu + np.arange(nu), 1.0)
        add(self.row_limits + np.arange(nu), iq + np.arange(nu), 1.0)
        static = sum(len(r) for r in rows)
        # Dynamic entries in the order of the value stacks: J_j (N, m, n), D on u_j, gamma dt D on y_j (j >= 1).
        j_, a_, c_ = np.meshgrid(np.arange(N), eye_m, eye_n, indexing="ij")
        add(self.row_task + j_ * m + a_, iu + j_ * n + c_, 0.0)
        if p:
            j_, r_, c_ = np.meshgrid(np.arange(N), np.arange(p), eye_n, indexing="ij")
            add(self.row_barrier + j_ * p + r_, iu + j_ * n + c_, 0.0)
            j_, r_, c_ = np.meshgrid(np.arange(1, N), np.arange(p), eye_n, indexing="ij")
            add(self.row_barrier + j_ * p + r_, iq + (j_ - 1) * n + c_, 0.0)
        r_all, c_all = np.concatenate(rows), np.concatenate(cols)
        self._values = np.concatenate(vals)
        tags = sp.csc_matrix((np.arange(1, len(r_all) + 1, dtype=float), (r_all, c_all)), shape=(self.rows, self.nz))
        tags.sort_indices()
        self._order = tags.data.astype(np.int64) - 1  # CSC position -> entry of the value stacks
        self.A = sp.csc_matrix((self._values[self._order], tags.indices.copy(), tags.indptr.copy()), tags.shape)
        self._jac = slice(static, static + N * m * n)
        self._du = slice(self._jac.stop, self._jac.stop + N * p * n)
        self._dq = slice(self._du.stop, self._du.stop + (N - 1) * p * n)
        diagonal = np.concatenate([np.full(nu, float(effort_weight)), np.zeros(nu), np.ones(ne)])
        self.P = sp.diags(diagonal, format="csc")
        self.l = np.zeros(self.rows)
        self.u = np.zeros(self.rows)

    def set_matrix(self, J: np.ndarray, D: np.ndarray | None = None) -> None:
        """Write the task Jacobians ``J`` ``(N, m, n)`` and the barrier rows' ``D`` ``(p, n)`` into ``A``."""
        self._values[self._jac] = J.ravel()
        if self.p and D is not None:
            rows = D.ravel()
            self._values[self._du] = np.tile(rows, self.N)
            self._values[self._dq] = np.tile(self.gamma * self.dt * rows, self.N - 1)
        np.take(self._values, self._order, out=self.A.data)

    def dense(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(P, A, l, u)`` as dense arrays with ``+-inf`` for missing bounds (for checks)."""
        lower = np.where(self.l <= -_INFINITY, -np.inf, self.l)
        upper = np.where(self.u >= _INFINITY, np.inf, self.u)
        return self.P.toarray(), self.A.toarray(), lower, upper


def shifted_blocks(blocks: list[tuple[int, int]], N: int) -> np.ndarray:
    """Indices taking every ``(start, size)`` block of ``N`` steps one step forward (the last step repeated)."""
    total = max(start + N * size for start, size in blocks)
    index = np.arange(total)
    for start, size in blocks:
        steps = np.minimum(np.arange(N) + 1, N - 1)
        index[start : start + N * size] = (start + steps[:, None] * size + np.arange(size)[None, :]).ravel()
    return index


class MPCController(HorizonController):
    """MPC tracking by one sparse OSQP solve per step (module docstring).

    Parameters
    ----------
    arm, dt, task, gain, effort_weight:
        See :class:`HorizonController`.
    eps_abs, eps_rel, max_iter, rho, polishing:
        OSQP's tolerances, iteration limit per step, ADMM step size and active-set polishing.
    settings:
        Further OSQP settings (``osqp.OSQP.setup`` keywords).
    **horizon:
        The keywords of :class:`HorizonController`: ``horizon``, ``rate_limits``, ``margin``,
        ``periodic``, ``limit_gain``, ``barrier``, ``preview``, ``compiled``.

    Attributes
    ----------
    qp:
        The step's :class:`HorizonQP` (its values are those of the last solve).
    z:
        The last solution ``(u_0..u_{N-1}, y_1..y_N, s_1..s_N)``.
    iterations:
        OSQP's ADMM iterations of the last step.
    """

    name = "mpc (osqp)"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain: float | Sequence[float] = 10.0,
        effort_weight: float = 1e-4,
        *,
        eps_abs: float = 1e-3,
        eps_rel: float = 1e-3,
        max_iter: int = 4000,
        rho: float = 0.1,
        polishing: bool = False,
        settings: dict[str, Any] | None = None,
        **horizon: Any,
    ):
        super().__init__(arm, dt, task, gain, effort_weight, **horizon)
        import osqp

        n, m, N = arm.n_config, self.model.m, self.N
        p = 0 if self.barrier is None else self.barrier.rows
        self.horizon_barrier = None if self.barrier is None else HorizonBarrier(self.barrier, N)
        gamma = 0.0 if self.barrier is None else self.barrier.gamma
        self.qp = HorizonQP(n, m, N, p, self.dt, self.effort_weight, gamma)
        jac = arm.function(TASK_FUNCTIONS[task][1])
        Q = ca.SX.sym("Q", n, N)
        jacobians = jac.map(N)(Q)  # (m, N n): J(qbar_j) side by side
        # Output transposed blocks so the column-major buffer reads as a row-major (N, m, n) array.
        stacked = ca.horzcat(*[jacobians[:, j * n : (j + 1) * n].T for j in range(N)])
        self._jacobians = BufferedFunction(
            ca.Function("horizon_jacobians", [Q], [stacked]), compiled=bool(horizon.get("compiled", False))
        )
        self._J = self._jacobians.outputs[0].reshape(N, m, n)
        self._Qbar = self._jacobians.inputs[0]
        qp = self.qp
        self.problem = osqp.OSQP()
        self.problem.setup(
            qp.P,
            np.zeros(qp.nz),
            qp.A,
            -np.ones(qp.rows),
            np.ones(qp.rows),
            eps_abs=eps_abs,
            eps_rel=eps_rel,
            max_iter=max_iter,
            rho=rho,
            polishing=polishing,
            warm_starting=True,
            verbose=False,
            **(settings or {}),
        )
        self._solver = self.problem._solver
        self._solved = osqp.SolverStatus.OSQP_SOLVED
        self._interrupted = osqp.SolverStatus.OSQP_SIGINT
        self.z = np.zeros(qp.nz)
        self.iterations = 0
        self._zeros = np.zeros(qp.nz)
        self._no_duals = np.zeros(qp.rows)

    def reset(self, q: np.ndarray, x: np.ndarray) -> None:
        super().reset(q, x)
        self.z[:] = 0.0

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.prepare(q, x, x_ref, xdot_ref)
        qp = self.qp
        self._Qbar[:] = self.qbar.ravel()
        self._jacobians()
        hb = self.horizon_barrier
        if hb is not None:
            hb.update(q)
        qp.set_matrix(self._J, None if hb is None else hb.D)
        self._bounds(q, hb)
        solver = self._solver
        solver.update_data_mat(P_x=None, P_i=None, A_x=qp.A.data, A_i=None)
        solver.update_data_vec(q=self._zeros, l=qp.l, u=qp.u)
        if not self.shifted:  # a new run, or the arm held: start from zero, not from the last answer
            solver.warm_start(x=self._zeros, y=self._no_duals)
        failure = self._solve()
        if failure is None:
            self.status = Status.OK
            return self._accept()
        # The first step alone: the later steps' limits and barrier rows dropped (module docstring).
        qp.l[qp.row_limits : qp.row_barrier] = -_INFINITY
        qp.u[qp.row_limits : qp.row_barrier] = _INFINITY
        qp.l[qp.row_barrier + qp.p :] = -_INFINITY
        solver.update_data_vec(q=self._zeros, l=qp.l, u=qp.u)
        second = self._solve()
        if second is None:
            self.status = f"fallback (first step): horizon {failure}"
            return self._accept()
        self.status = f"fallback (hold): horizon {failure}; first step {second}"
        return self.hold()

    def _bounds(self, q: np.ndarray, hb: HorizonBarrier | None) -> None:
        """``l, u`` of every row block of the step."""
        qp, n, b = self.qp, self.arm.n_config, self.bounds
        qp.l[qp.row_dynamics : qp.row_task] = 0.0
        qp.u[qp.row_dynamics : qp.row_task] = 0.0
        task = slice(qp.row_task, qp.row_rates)
        qp.l[task] = self.increments.ravel()
        qp.u[task] = qp.l[task]
        rates = qp.l[qp.row_rates : qp.row_limits].reshape(self.N, n)
        rates[:] = -b.rate
        rates[0] = b.lb
        rates = qp.u[qp.row_rates : qp.row_limits].reshape(self.N, n)
        rates[:] = b.rate
        rates[0] = b.ub
        np.clip(((self.lower - q) / self.dt).ravel(), -_INFINITY, _INFINITY, out=qp.l[qp.row_limits : qp.row_barrier])
        np.clip(((self.upper - q) / self.dt).ravel(), -_INFINITY, _INFINITY, out=qp.u[qp.row_limits : qp.row_barrier])
        if hb is not None:
            np.clip(hb.b.ravel(), -_INFINITY, _INFINITY, out=qp.l[qp.row_barrier :])
            qp.u[qp.row_barrier :] = _INFINITY

    def _solve(self) -> str | None:
        """One OSQP solve; ``None`` when solved, else OSQP's status."""
        solver = self._solver
        solver.solve()
        info = solver.info
        self.iterations = info.iter
        if info.status_val == self._interrupted:
            raise KeyboardInterrupt  # OSQP catches SIGINT itself during a solve; honour it once it returned
        if info.status_val != self._solved:
            return f"{info.status} after {info.iter} iterations"
        x = solver.solution.x
        if not np.all(np.isfinite(x)):
            return "non-finite solution"
        self.z[:] = x
        return None

    def _accept(self) -> np.ndarray:
        n, N = self.arm.n_config, self.N
        self.plan[:] = self.z[: N * n].reshape(N, n)
        self.shifted = True
        return self.finish(self.plan[0])
