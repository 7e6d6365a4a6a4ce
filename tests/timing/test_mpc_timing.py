"""Time per MPC step (N = 20) with the sparse OSQP path against the same QP through cvxpy with Parameters.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_mpc_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,rounds

The data: 200 consecutive control steps (measured configuration, tip pose, reference and its
rate, the step index) recorded from a 500 Hz closed-loop run of the MPC on the two-section arm
along the pose reference of ``problems/track-obstacle-sphere.yaml``, around the time the sphere
blocks it, so barrier rows switch between active and inactive as in use. Each benchmarked
controller steps through the same sequence in order (warm starts as in a real loop), one round
per control step; the benchmark's timer is the wall clock of a whole step (Jacobians along the
horizon and the barrier included). ``extra_info`` holds the medians of the wall and thread-CPU
time per step [us] (thread CPU: what one core spends, the measure that a loaded machine disturbs
least), the cvxpy path's ratio to the OSQP path and the largest difference of the commands.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.mpc import MPCController
from optikin.control.obstacles import BarrierRows, Obstacle
from optikin.control.reference import minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import simulate

RATE, HORIZON, STEPS = 500.0, 20, 200
ARM = ConstantCurvatureArm()
GROUP = f"MPC step, N = {HORIZON}, two-section CC arm, pose task, one sphere on the backbone, {RATE:.0f} Hz"
SPHERE = Obstacle("sphere", center=(0.1554, 0.1544, 0.2668), radius=0.02)
_medians: dict[str, float] = {}
_commands: dict[str, np.ndarray] = {}


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def reference():
    start, end = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0]), np.array([0.17, 1.0, 0.8, 0.19, -0.4, -0.5])
    t, Q, Qdot = minimum_jerk_path(np.array([start, end]), 1.5, RATE, hold=0.5)
    return start, reference_from_configurations(ARM, t, Q, Qdot, "pose")


def mpc(cls=MPCController, compiled=False):
    _, ref = reference()
    barrier = BarrierRows(ARM, 1 / RATE, [SPHERE], margin=0.01, gamma=20.0, compiled=compiled)
    return cls(ARM, 1 / RATE, "pose", 10.0, 1e-4, horizon=HORIZON, barrier=barrier, preview=ref, compiled=compiled)


class CvxpyMPC(MPCController):
    """The same horizon QP written in cvxpy with Parameters (built once), solved by cvxpy's OSQP each step."""

    name = "mpc (cvxpy Parameters, OSQP)"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        import cvxpy as cp

        n, m, N = self.arm.n_config, self.model.m, self.N
        p = self.qp.p
        big = 1e6  # stands for an infinite bound (cvxpy Parameters take finite values)
        self._big = big
        u, y, s = cp.Variable((N, n)), cp.Variable((N, n)), cp.Variable((N, m))
        self.J = [cp.Parameter((m, n)) for _ in range(N)]
        self.increments_p = cp.Parameter((N, m))
        self.lb0, self.ub0 = cp.Parameter(n), cp.Parameter(n)
        self.lo, self.hi = cp.Parameter((N, n)), cp.Parameter((N, n))
        self.D, self.b = cp.Parameter((p, n)), cp.Parameter((N, p))
        rate = self.bounds.rate
        constraints = [y[0] == u[0], s[0] == self.increments_p[0] - self.J[0] @ u[0]]
        constraints += [y[j] == y[j - 1] + u[j] for j in range(1, N)]
        constraints += [s[j] == s[j - 1] + self.increments_p[j] - self.J[j] @ u[j] for j in range(1, N)]
        constraints += [u[0] >= self.lb0, u[0] <= self.ub0, u[1:] >= -np.tile(rate, (N - 1, 1)), u[1:] <= rate]
        constraints += [y[1:] >= self.lo[1:], y[1:] <= self.hi[1:]]
        constraints += [self.D @ u[0] >= self.b[0]]
        gamma_dt = self.barrier.gamma * self.dt
        constraints += [self.D @ u[j] + gamma_dt * (self.D @ y[j]) >= self.b[j] for j in range(1, N)]
        cost = 0.5 * cp.sum_squares(s) + 0.5 * self.effort_weight * cp.sum_squares(u)
        self.problem = cp.Problem(cp.Minimize(cost), constraints)
        self.u = u

    def command(self, q, x, x_ref, xdot_ref):
        self.prepare(q, x, x_ref, xdot_ref)
        self._Qbar[:] = self.qbar.ravel()
        self._jacobians()
        self.horizon_barrier.update(q)
        for j, J in enumerate(self.J):
            J.value = self._J[j]
        self.increments_p.value = self.increments
        self.lb0.value, self.ub0.value = self.bounds.lb, self.bounds.ub
        self.lo.value = np.clip((self.lower - q) / self.dt, -self._big, self._big)
        self.hi.value = np.clip((self.upper - q) / self.dt, -self._big, self._big)
        self.D.value = self.horizon_barrier.D
        self.b.value = np.maximum(self.horizon_barrier.b, -self._big)
        self.problem.solve(solver="OSQP", warm_start=True, eps_abs=1e-3, eps_rel=1e-3, rho=0.1, max_iter=4000)
        self.status = "ok" if self.problem.status == "optimal" else f"fallback: {self.problem.status}"
        return self.finish(np.asarray(self.u.value[0]))


@pytest.fixture(scope="module")
def steps():
    start, ref = reference()
    run = simulate(mpc(), ref, start)
    pick = range(len(ref.t) // 3 - STEPS // 2, len(ref.t) // 3 + STEPS // 2)  # where the sphere blocks the path
    return [(k, run.q[k], run.x[k], ref.value[k], ref.rate[k]) for k in pick]


def _bench(benchmark, name, controller, steps):
    controller.reset(steps[0][1], steps[0][2])
    cursor = iter(range(10**9))
    wall: list[float] = []
    cpu: list[float] = []
    status: list[str] = []

    def step():
        k, q, x, x_ref, xdot_ref = steps[next(cursor) % len(steps)]
        controller.k = controller.barrier.step = k  # the controller's clock at the recorded instant
        began, began_cpu = time.perf_counter(), time.thread_time()
        out = controller.command(q, x, x_ref, xdot_ref)
        cpu.append(time.thread_time() - began_cpu)
        wall.append(time.perf_counter() - began)
        status.append(controller.status)
        return out

    commands = np.array([step().copy() for _ in range(len(steps))])  # one pass to record (and warm up)
    wall.clear()
    cpu.clear()
    status.clear()
    benchmark.group = GROUP
    benchmark.pedantic(step, rounds=len(steps), iterations=1, warmup_rounds=0)
    _medians[name] = float(np.median(wall))
    benchmark.extra_info["wall median [us]"] = float(np.median(wall) * 1e6)
    benchmark.extra_info["thread CPU median [us]"] = float(np.median(cpu) * 1e6)
    benchmark.extra_info["steps not ok"] = sum(s != "ok" for s in status)
    _commands[name] = commands
    if name != "osqp" and "osqp" in _medians:
        benchmark.extra_info["wall ratio to the OSQP path"] = _medians[name] / _medians["osqp"]
        benchmark.extra_info["max |u0 - u0_osqp|"] = float(np.abs(commands - _commands["osqp"][: len(commands)]).max())


def test_mpc_sparse_osqp_updated_in_place(benchmark, steps):
    _bench(benchmark, "osqp", mpc(), steps)


def test_mpc_sparse_osqp_compiled(benchmark, steps):
    _bench(benchmark, "osqp compiled", mpc(compiled=True), steps)


def test_mpc_cvxpy_parameters(benchmark, steps):
    pytest.importorskip("cvxpy")
    _bench(benchmark, "cvxpy", mpc(CvxpyMPC), steps[:50])
