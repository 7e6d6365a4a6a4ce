"""The nonlinear reference of the MPC: the same horizon, target and limits, solved by IPOPT through CasADi.

Where :mod:`optikin.control.mpc` linearises, this keeps the model exact, to show what the
linearisation costs (it is a reference, not a fast path). Over the rates ``u_0..u_{N-1}`` and the
configurations ``q_1..q_N`` (multiple shooting: ``q_{j+1} = q_j + dt u_j``, ``q_0 = q``):

    min  1/2 sum_{j=1..N} ||(w_j - fk(q_j) - (x - fk(q))) / dt||^2 + 1/2 lambda sum_j ||u_j||^2
    s.t. lb <= u_0 <= ub,  -r <= u_j <= r,  lo_j <= q_j <= hi_j  (j >= 2),
         d_i(q_{j+1}, t_{k+j+1}) - d_safe >= (1 - gamma dt) (d_i(q_j, t_{k+j}) - d_safe)

for every obstacle and every backbone sample ``i`` (not only the nearest), ``j = 0..N-1``: the
discrete-time barrier of :mod:`optikin.control.obstacles` without its linearisation. ``w_j`` is
the MPC's target, ``x - fk(q)`` the measured tip's offset from the model, held over the horizon
(zero on the model's own plant). The NLP is built once (``nlpsol``, IPOPT, exact Hessian), its
data are parameters; each step starts from the previous solution (primal and multipliers)
shifted by one step, with IPOPT's warm-start settings and its adaptive barrier parameter update
(from a warm start it takes a few iterations where the monotone update takes several times more). A step
IPOPT does not solve is reported (``"fallback (hold): ipopt <status>"``) and the arm holds.
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.mpc import HorizonController, shifted_blocks
from optikin.control.task import TASK_FUNCTIONS, Task
from optikin.interrupt import calls_casadi
from optikin.status import Status


class NonlinearMPCController(HorizonController):
    """The MPC's nonlinear reference, one IPOPT solve per step (module docstring).

    Parameters
    ----------
    arm, dt, task, gain, effort_weight:
        See :class:`optikin.control.mpc.HorizonController`.
    tolerance, max_iter:
        IPOPT's ``tol`` and iteration limit per step.
    ipopt_options:
        Further IPOPT options (they override the warm-start settings).
    **horizon:
        The keywords of :class:`optikin.control.mpc.HorizonController`: ``horizon``, ``rate_limits``,
        ``margin``, ``periodic``, ``limit_gain``, ``barrier``, ``preview``, ``compiled`` (not used:
        IPOPT calls the CasADi VM).

    Attributes
    ----------
    iterations:
        IPOPT's iterations of the last step.
    """

    name = "mpc (ipopt)"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain: float | Sequence[float] = 10.0,
        effort_weight: float = 1e-4,
        *,
        tolerance: float = 1e-8,
        max_iter: int = 200,
        ipopt_options: dict[str, Any] | None = None,
        **horizon: Any,
    ):
        super().__init__(arm, dt, task, gain, effort_weight, **horizon)
        n, m, N = arm.n_config, self.model.m, self.N
        fk = arm.function(TASK_FUNCTIONS[task][0])
        # Multiple shooting: the configurations are variables too, so every term's Hessian is one block.
        U, Qv = ca.SX.sym("U", n, N), ca.SX.sym("Q", n, N)
        q0 = ca.SX.sym("q0", n)
        offset = ca.SX.sym("offset", m)  # x - fk(q)
        W = ca.SX.sym("W", m, N)  # w_1..w_N
        Q = [q0] + [Qv[:, j] for j in range(N)]
        cost = 0.5 * self.effort_weight * ca.sumsqr(U)
        for j in range(1, N + 1):
            cost += 0.5 * ca.sumsqr((W[:, j - 1] - fk(Q[j]) - offset) / self.dt)
        g = [ca.vec(Qv - ca.horzcat(*Q[:N]) - self.dt * U)]
        parameters = [q0, offset, ca.vec(W)]
        self.samples = 0
        if self.barrier is not None:
            barrier = self.barrier
            count = len(barrier.distances.obstacles)
            C = ca.SX.sym("C", 3 * count, N + 1)  # obstacle offsets at t_k .. t_{k+N}
            distance = barrier.distances.function
            h = [ca.vec(distance(Q[j], ca.reshape(C[:, j], 3, count))[0]) - barrier.margin for j in range(N + 1)]
            decay = 1.0 - barrier.gamma * self.dt
            g += [h[j + 1] - decay * h[j] for j in range(N)]
            parameters.append(ca.vec(C))
            self.samples = count * barrier.distances.samples
        nlp = {"x": ca.vertcat(ca.vec(U), ca.vec(Qv)), "p": ca.vertcat(*parameters), "f": cost, "g": ca.vertcat(*g)}
        options: dict[str, Any] = {
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "tol": tolerance,
                "max_iter": max_iter,
                "warm_start_init_point": "yes",
                "mu_init": 1e-5,
                "warm_start_bound_push": 1e-9,
                "warm_start_mult_bound_push": 1e-9,
                "mu_strategy": "adaptive",
            }
            | (ipopt_options or {}),
            "print_time": False,
        }
        self.solver = ca.nlpsol("mpc_ipopt", "ipopt", nlp, options)
        self.iterations = 0
        rows = [(0, n)] + ([(N * n, self.samples)] if self.samples else [])
        self._shift_x = shifted_blocks([(0, n), (N * n, n)], N)
        self._shift_g = shifted_blocks(rows, N)
        self._lam_x = np.zeros(2 * N * n)
        self._lam_g = np.zeros(N * (n + self.samples))

    @calls_casadi
    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.prepare(q, x, x_ref, xdot_ref)
        n, N, dt = self.arm.n_config, self.N, self.dt
        fk_q = np.asarray(self.model.fk(q)).ravel()
        targets = x + dt * np.cumsum(self.increments, axis=0)  # w_1..w_N, (N, m)
        p = [q, x - fk_q, targets.ravel()]  # vec(W) of (m, N) is targets row by row
        lbg, ubg = [np.zeros(N * n)], [np.zeros(N * n)]
        if self.barrier is not None:
            distances = self.barrier.distances
            t0 = self.k * dt
            p.append(np.concatenate([distances.offsets(t0 + j * dt).ravel(order="F") for j in range(N + 1)]))
            lbg.append(np.zeros(N * self.samples))
            ubg.append(np.full(N * self.samples, np.inf))
        lbu, ubu = np.tile(-self.bounds.rate, (N, 1)), np.tile(self.bounds.rate, (N, 1))
        lbu[0], ubu[0] = self.bounds.lb, self.bounds.ub
        lbx = np.concatenate([lbu.ravel(), self.lower.ravel()])
        ubx = np.concatenate([ubu.ravel(), self.upper.ravel()])
        start = np.concatenate([self.plan[1:], self.plan[-1:]]) if self.shifted else self.plan
        rolled = q + dt * np.cumsum(start, axis=0)
        warm = self.shifted
        result = self.solver(
            x0=np.clip(np.concatenate([start.ravel(), rolled.ravel()]), lbx, ubx),
            lam_x0=self._lam_x[self._shift_x] if warm else np.zeros_like(self._lam_x),
            lam_g0=self._lam_g[self._shift_g] if warm else np.zeros_like(self._lam_g),
            p=np.concatenate(p),
            lbx=lbx,
            ubx=ubx,
            lbg=np.concatenate(lbg),
            ubg=np.concatenate(ubg),
        )
        stats = self.solver.stats()
        self.iterations = int(stats.get("iter_count", 0))
        U = np.asarray(result["x"]).ravel()[: N * n]
        if not stats["success"] or not np.all(np.isfinite(U)):
            self.status = f"fallback (hold): ipopt {stats['return_status']}"
            return self.hold()
        self.status = Status.OK
        self._lam_x[:] = np.asarray(result["lam_x"]).ravel()
        self._lam_g[:] = np.asarray(result["lam_g"]).ravel()
        self.plan[:] = U.reshape(N, n)
        self.shifted = True
        return self.finish(self.plan[0])
