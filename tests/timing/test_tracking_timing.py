"""Time per control step of every tracking controller and QP backend (pytest-benchmark), Jacobian included.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_tracking_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,rounds

The data: 400 consecutive control steps (measured configuration, tip pose,
reference and its rate) recorded from a 1 kHz closed-loop run of the QP on the
two-section arm along a pose reference that drives into the limits, so bounds
switch between active and inactive as in use. Each benchmarked controller steps
through the same sequence in order (warm starts as in a real loop), one round
per control step; the median is the time per step. The baseline, measured
first in the same session, is cvxpy rebuilding its problem every step;
``extra_info`` holds each path's speed-up over it and whether the step agrees
with the OSQP path (max |difference| of the commanded rates).
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.baselines.mrac import MRACController
from optikin.baselines.pseudo_inverse import DampedLeastSquaresController, PseudoInverseController
from optikin.control.qp import QPController
from optikin.control.reference import minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import simulate
from optikin.solvers.qp import step_solver
from optikin.solvers.qp.qp_qpsolvers import installed_solvers

RATE, STEPS = 1000.0, 400
ARM = ConstantCurvatureArm()
GROUP = f"tracking: time per control step, two-section CC arm, pose task, {RATE:.0f} Hz"
_medians: dict[str, float] = {}
_osqp_steps: list[np.ndarray] = []


def qp(backend="qp_osqp", compiled=False, **options):
    """The QP controller at the benchmark's rate with a step solver of ``backend``."""
    return QPController(ARM, 1 / RATE, compiled=compiled, solver=step_solver(backend, ARM.n_config, 8, **options))


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


@pytest.fixture(scope="module")
def steps():
    start = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0])
    beyond = start.copy()
    beyond[1], beyond[3] = 1.3 * ARM.theta_max, 1.2 * ARM.upper[3]
    t, Q, Qdot = minimum_jerk_path(np.array([start, beyond]), 1.0, RATE)
    ref = reference_from_configurations(ARM, t, Q, Qdot, "pose")
    run = simulate(qp(), ref, start)
    pick = range(len(t) // 2 - STEPS // 2, len(t) // 2 + STEPS // 2)  # where the limits start to bite
    return [(run.q[k], run.x[k], ref.value[k], ref.rate[k]) for k in pick]


def _bench(benchmark, name, controller, steps):
    controller.reset(steps[0][0], steps[0][1])
    commands = []
    cursor = iter(range(10**9))

    def step():
        q, x, x_ref, xdot_ref = steps[next(cursor) % len(steps)]
        return controller.command(q, x, x_ref, xdot_ref)

    def recorded():
        commands.append(np.array(step()))

    for _ in range(len(steps)):  # one pass to record the commands (and warm everything up)
        recorded()
    benchmark.group = GROUP
    benchmark.pedantic(step, rounds=len(steps), iterations=1, warmup_rounds=0)
    _medians[name] = benchmark.stats.stats.median
    if "cvxpy rebuild" in _medians:
        benchmark.extra_info["speed-up over cvxpy rebuild"] = _medians["cvxpy rebuild"] / _medians[name]
    if _osqp_steps and isinstance(controller, QPController):
        benchmark.extra_info["max |qdot - qdot_osqp|"] = float(np.abs(np.array(commands) - _osqp_steps).max())
    return commands


def test_cvxpy_rebuilt_every_step(benchmark, steps):
    _bench(benchmark, "cvxpy rebuild", qp("qp_cvxpy_rebuild"), steps[:100])


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi-vm", "compiled"])
def test_osqp_updated_in_place(benchmark, steps, compiled):
    commands = _bench(benchmark, f"osqp {compiled}", qp(compiled=compiled), steps)
    if not _osqp_steps:
        _osqp_steps.extend(commands)


@pytest.mark.parametrize("solver", installed_solvers())
def test_qpsolvers(benchmark, steps, solver):
    _bench(benchmark, f"qpsolvers {solver}", qp("qp_qpsolvers", solver=solver), steps)


@pytest.mark.parametrize("solver", ["CLARABEL", "OSQP"])
def test_cvxpy_parameters(benchmark, steps, solver):
    _bench(benchmark, f"cvxpy {solver}", qp("qp_cvxpy", solver=solver), steps)


@pytest.mark.parametrize(
    "Controller",
    [MRACController, PseudoInverseController, DampedLeastSquaresController],
    ids=["mrac", "pseudo-inverse", "damped-least-squares"],
)
def test_unconstrained_baselines(benchmark, steps, Controller):
    _bench(benchmark, Controller.name, Controller(ARM, 1 / RATE, "pose"), steps)


OBSTACLE_GROUP = (
    f"tracking with 3 obstacles on the backbone: time per control step, two-section CC arm, pose, {RATE:.0f} Hz"
)
_obstacle_medians: dict[str, float] = {}


def obstacle_qp(backend="qp_osqp", compiled=False, **options):
    """The barrier QP (3 obstacles: sphere on the reference, capsule, box) with a step solver of ``backend``."""
    from optikin.control.obstacles import BarrierRows, Obstacle
    from optikin.solvers import preset_of
    from optikin.spec import SolverSpec

    obstacles = [
        Obstacle("sphere", center=(0.1554, 0.1544, 0.2668), radius=0.02),
        Obstacle("capsule", a=(-0.1, 0.05, 0.1), b=(-0.1, -0.05, 0.3), radius=0.02),
        Obstacle("box", center=(0.0, -0.15, 0.2), half_extents=(0.03, 0.03, 0.05)),
    ]
    barrier = BarrierRows(ARM, 1 / RATE, obstacles, margin=0.01, gamma=20.0, compiled=compiled)
    factory = preset_of(SolverSpec(name=backend, backend=backend, options=options)).build()
    solver = factory.create(ARM.n_config, 8, rows=barrier.rows)
    return QPController(ARM, 1 / RATE, compiled=compiled, solver=solver, barrier=barrier)


@pytest.fixture(scope="module")
def obstacle_steps():
    start, end = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0]), np.array([0.17, 1.0, 0.8, 0.19, -0.4, -0.5])
    t, Q, Qdot = minimum_jerk_path(np.array([start, end]), 1.5, RATE)
    ref = reference_from_configurations(ARM, t, Q, Qdot, "pose")
    run = simulate(obstacle_qp(), ref, start)
    pick = range(len(t) // 2 - STEPS // 2, len(t) // 2 + STEPS // 2)  # where the sphere blocks the reference
    return [(k, run.q[k], run.x[k], ref.value[k], ref.rate[k]) for k in pick]


def _bench_obstacles(benchmark, name, controller, steps):
    controller.reset(steps[0][1], steps[0][2])
    cursor = iter(range(10**9))

    def step():
        k, q, x, x_ref, xdot_ref = steps[next(cursor) % len(steps)]
        controller.barrier.step = k  # the barrier's clock at the recorded instant
        return controller.command(q, x, x_ref, xdot_ref)

    solves, rows = [], []
    for _ in range(len(steps)):
        step()
        solves.append(controller.solution.seconds)
        rows.append(int(np.sum(controller.barrier.A @ controller.qdot <= controller.barrier.b + 1e-6)))
    benchmark.extra_info["solver's own time median [us]"] = float(np.median(solves) * 1e6)
    benchmark.extra_info["steps with an active barrier row"] = int(np.count_nonzero(rows))
    benchmark.group = OBSTACLE_GROUP
    benchmark.pedantic(step, rounds=len(steps), iterations=1, warmup_rounds=0)
    _obstacle_medians[name] = benchmark.stats.stats.median
    if "cvxpy" in _obstacle_medians and name != "cvxpy":
        benchmark.extra_info["speed-up over cvxpy Parameters"] = _obstacle_medians["cvxpy"] / _obstacle_medians[name]


def test_obstacles_cvxpy_parameters(benchmark, obstacle_steps):
    _bench_obstacles(benchmark, "cvxpy", obstacle_qp("qp_cvxpy", solver="OSQP"), obstacle_steps[:100])


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi-vm", "compiled"])
def test_obstacles_osqp_updated_in_place(benchmark, obstacle_steps, compiled):
    _bench_obstacles(benchmark, f"osqp {compiled}", obstacle_qp(compiled=compiled), obstacle_steps)


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi-vm", "compiled"])
def test_obstacles_daqp_direct(benchmark, obstacle_steps, compiled):
    controller = obstacle_qp("qp_qpsolvers", compiled=compiled, solver="daqp")
    _bench_obstacles(benchmark, f"daqp {compiled}", controller, obstacle_steps)


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi-vm", "compiled"])
def test_obstacles_active_set(benchmark, obstacle_steps, compiled):
    controller = obstacle_qp("qp_daqp", compiled=compiled)
    _bench_obstacles(benchmark, f"active set {compiled}", controller, obstacle_steps)
