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
