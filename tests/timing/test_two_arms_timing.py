"""Time per control step of the joint two-arm QP of rope-skipping (pytest-benchmark), its Jacobians included.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_two_arms_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,rounds

The data: 400 consecutive control steps (both arms' configurations, the lowest point's reference and
its rate) recorded from the shipped ``rope-skipping`` run of the joint QP at 500 Hz, from the deep part
of the first loop, where the self-collision rows hold the tips apart: 12 rates, 3 task rows and 12
posture rows, the rate box, 4 collision rows and the rope's slack row. A step evaluates both arms
(41 backbone samples each and their Jacobians), the catenary's lowest point and its
implicit-function derivative, the nearest pairs of samples and the QP. Each benchmarked path steps
through the same sequence in order, one round per control step; the median is the time per step.
The comparison, measured first in the same session, is the same QP posed in cvxpy with Parameters
(:mod:`optikin.solvers.qp.qp_cvxpy`: DPP, canonicalised once, re-solved warm-started);
``extra_info`` holds each path's speed-up over it and its largest difference from the daqp path's
commands.
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.control.two_arm import TwoArmQP, qp_factory, simulate_two_arms
from optikin.problems.two_arms.run import setup
from optikin.runner import prepare

STEPS = 400
GROUP = "rope-skipping: time per control step of the joint QP, two 2-section CC arms, 500 Hz"
_medians: dict[str, float] = {}
_daqp_steps: list[np.ndarray] = []


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def built(compiled: bool):
    _, ctx = prepare("rope-skipping", overrides=[("options.compiled", compiled)])
    return ctx, setup(ctx)


def joint(compiled: bool, backend: str, **options) -> TwoArmQP:
    """The joint QP of rope-skipping with a step solver of ``backend``."""
    ctx, problem = built(compiled)
    o = ctx.options
    return TwoArmQP(
        problem.plant,
        problem.reference.dt,
        o.gain,
        factory=qp_factory(backend, **options),
        damping=o.damping,
        posture=problem.q0,
        posture_weight=o.posture_weight,
        posture_gain=o.posture_gain,
        rate_limits=o.rate_limits,
        limit_margin=o.limit_margin,
        tubes=problem.tubes,
        gamma=o.collision.gamma,
        margin=o.collision.margin,
    )


@pytest.fixture(scope="module")
def steps():
    _, problem = built(False)
    reference = problem.reference
    run = simulate_two_arms(problem.controllers["qp"], reference, problem.q0, problem.plant)
    first = int(0.25 / reference.dt)  # into the first loop's deep part, where the collision rows bite
    return [(run.q[k], reference.value[k], reference.rate[k]) for k in range(first, first + STEPS)]


def _bench(benchmark, name: str, controller: TwoArmQP, steps):
    cursor = iter(range(10**9))

    def step():
        q, x_ref, xdot_ref = steps[next(cursor) % len(steps)]
        return controller.command(q, x_ref, xdot_ref)

    commands, active, statuses = [], 0, set()
    for _ in range(len(steps)):  # one pass to record the commands (and warm everything up)
        commands.append(np.array(step()))
        active += bool(np.any(controller.data.A @ controller.qdot <= controller.data.b + 1e-6))
        statuses.add(controller.status)
    assert statuses == {"ok"}
    benchmark.extra_info["steps with an active row"] = active
    benchmark.group = GROUP
    benchmark.pedantic(step, rounds=len(steps), iterations=1, warmup_rounds=0)
    median = _medians[name] = benchmark.stats.stats.median
    benchmark.extra_info["median [us]"] = median * 1e6
    benchmark.extra_info["target 200 us met"] = bool(median <= 200e-6)
    if "cvxpy" in _medians and name != "cvxpy":
        benchmark.extra_info["speed-up over cvxpy Parameters"] = _medians["cvxpy"] / median
    if _daqp_steps:
        benchmark.extra_info["max |qdot - qdot_daqp|"] = float(np.abs(np.array(commands) - _daqp_steps).max())
    return commands


@pytest.mark.parametrize("solver", ["OSQP", "CLARABEL"])
def test_cvxpy_parameters(benchmark, steps, solver):
    name = "cvxpy" if solver == "OSQP" else f"cvxpy {solver}"
    _bench(benchmark, name, joint(False, "qp_cvxpy", solver=solver), steps[:100])


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi-vm", "compiled"])
def test_daqp_direct(benchmark, steps, compiled):
    commands = _bench(benchmark, f"daqp {compiled}", joint(compiled, "qp_qpsolvers", solver="daqp"), steps)
    if not _daqp_steps:
        _daqp_steps.extend(commands)


@pytest.mark.parametrize("compiled", [False, True], ids=["casadi-vm", "compiled"])
def test_active_set_warm_started(benchmark, steps, compiled):
    """The shipped preset qp-active-set: daqp on the controller's buffers, warm-started from the last active set."""
    _bench(benchmark, f"active set {compiled}", joint(compiled, "qp_daqp"), steps)


def test_osqp_updated_in_place(benchmark, steps):
    _bench(benchmark, "osqp", joint(True, "qp_osqp", eps_abs=1e-7, eps_rel=1e-7, rho=1.0, max_iter=4000), steps)
