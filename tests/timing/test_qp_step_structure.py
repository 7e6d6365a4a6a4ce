"""QP tracking step by structure: the default dense active set against OSQP in place and cvxpy, 2 / 4 / 8 sections.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_qp_step_structure.py --benchmark-only -s

For each arm (2, 4 and 8 constant-curvature sections, 6 / 12 / 24 rates, pose task: 8 rows, so
the 4- and 8-section arms are redundant), :data:`STEPS` consecutive control steps are recorded from
a 1 kHz closed loop of the default controller along a pose reference that drives the first bend
and the last length past their limits, so rate bounds switch between active and inactive as in use.
Every contender is a :class:`~optikin.control.qp.QPController` with the compiled task Function and
steps through the same sequence in order (warm starts as in a real loop). One untimed pass steps
all contenders side by side (the commands compared, the iterations counted); then :data:`PASSES`
timed passes in one process, each running every contender through the whole sequence in turn, a
different contender first each pass. Whole sequences, not single steps, are interleaved: a control
loop runs one controller, and a cvxpy solve between two steps of another path evicts that path's
data from the caches (its steps then take several times as long).

* ``active set (default)``: ``solver=None``, i.e. daqp on the controller's buffers, warm-started,
  its C functions called directly (:class:`~optikin.solvers.qp.qp_daqp.DirectDaqp`);
* ``active set, daqp.Model``: the same, through daqp's Python class (``direct=False``: what a daqp
  release the direct calls are not written for gets), which copies its answer every step;
* ``osqp in place``: the ``qp_osqp`` backend at its defaults (eps 1e-7, rho 1);
* ``qpsolvers daqp``: ``qpsolvers``-style, daqp set up from scratch every step (the exactness reference);
* ``cvxpy Parameters``: the ``qp_cvxpy`` backend (DPP, Clarabel).

Each line printed: thread-CPU and wall medians per step [us], the solver's median iterations, the
largest difference of the commanded rates from ``qpsolvers daqp``, and the load average before and
after. The pytest-benchmark figure of each test is the default path.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.qp import QPController
from optikin.control.reference import minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import simulate
from optikin.solvers.qp import step_solver
from optikin.solvers.qp.qp_daqp import ActiveSetStepSolver

RATE, STEPS, PASSES = 1000.0, 400, 4
TASK_ROWS = 8


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def recorded_steps(arm: ConstantCurvatureArm) -> list[tuple[np.ndarray, ...]]:
    """Closed-loop steps (q, x, x_ref, xdot_ref) where the first bend and the last length cross their limits."""
    start = np.tile([0.0, 0.6, 0.3], arm.n_sections)
    start[0::3] = 0.5 * (arm.lower[0::3] + arm.upper[0::3])
    start[5::3] = -1.0
    beyond = start.copy()
    beyond[1], beyond[-3] = 1.3 * arm.theta_max, arm.upper[-3] + 0.2 * (arm.upper[-3] - start[-3])
    t, Q, Qdot = minimum_jerk_path(np.array([start, beyond]), 1.0, RATE)
    ref = reference_from_configurations(arm, t, Q, Qdot, "pose")
    run = simulate(QPController(arm, 1 / RATE, compiled=True), ref, start)
    pick = range(len(t) // 2 - STEPS // 2, len(t) // 2 + STEPS // 2)
    return [(run.q[k], run.x[k], ref.value[k], ref.rate[k]) for k in pick]


def contenders(arm: ConstantCurvatureArm) -> dict[str, QPController]:
    n, dt = arm.n_config, 1 / RATE

    def qp(solver=None):
        return QPController(arm, dt, compiled=True, solver=solver)

    return {
        "active set (default)": qp(),
        "active set, daqp.Model": qp(ActiveSetStepSolver(n, TASK_ROWS, direct=False)),
        "osqp in place": qp(step_solver("qp_osqp", n, TASK_ROWS)),
        "qpsolvers daqp": qp(step_solver("qp_qpsolvers", n, TASK_ROWS, solver="daqp")),
        "cvxpy Parameters": qp(step_solver("qp_cvxpy", n, TASK_ROWS, solver="CLARABEL")),
    }


@pytest.mark.parametrize("sections", [2, 4, 8])
def test_qp_step_by_structure(benchmark, sections):
    arm = ConstantCurvatureArm(section_lengths=(0.18,) * sections)
    steps = recorded_steps(arm)
    paths = contenders(arm)
    for controller in paths.values():
        controller.reset(steps[0][0], steps[0][1])
    commands = {name: np.empty((STEPS, arm.n_config)) for name in paths}
    iterations: dict[str, list[int]] = {name: [] for name in paths}
    bounded = 0
    for k, step in enumerate(steps):  # the untimed pass: the commands, the iterations, warm-up
        for name, controller in paths.items():
            commands[name][k] = controller.command(*step)
            assert controller.solution is not None
            iterations[name].append(controller.solution.iterations)
        lb, ub = paths["qpsolvers daqp"].bounds.lb, paths["qpsolvers daqp"].bounds.ub
        bounded += bool(
            np.any((commands["qpsolvers daqp"][k] <= lb + 1e-12) | (commands["qpsolvers daqp"][k] >= ub - 1e-12))
        )
    cpu: dict[str, list[int]] = {name: [] for name in paths}
    wall: dict[str, list[int]] = {name: [] for name in paths}
    load = [os.getloadavg()[0]]
    names = list(paths)
    for turn in range(PASSES):
        for name in names[turn % len(names) :] + names[: turn % len(names)]:  # a different one first each pass
            controller = paths[name]
            controller.reset(steps[0][0], steps[0][1])
            for step in steps:
                c0, w0 = time.thread_time_ns(), time.perf_counter_ns()
                controller.command(*step)
                cpu[name].append(time.thread_time_ns() - c0)
                wall[name].append(time.perf_counter_ns() - w0)
    load.append(os.getloadavg()[0])
    reference = commands["qpsolvers daqp"]
    print(
        f"\nQP tracking step, {sections} CC sections ({arm.n_config} rates, pose task), {STEPS} steps x {PASSES}"
        f" passes, {bounded} steps with an active rate bound,"
        f" load {load[0]:.1f}-{load[1]:.1f} on {os.cpu_count()} cores"
    )
    for name in paths:
        differences = float(np.abs(commands[name] - reference).max())
        per_cpu, per_wall = np.median(cpu[name]) / 1e3, np.median(wall[name]) / 1e3
        print(
            f"  {name:22s} cpu {per_cpu:8.1f} us  wall {per_wall:8.1f} us"
            f"  iterations {np.median(iterations[name]):5.0f}  max |qdot - daqp| {differences:.1e}"
        )
        benchmark.extra_info[f"{name} cpu [us]"] = round(float(per_cpu), 2)
        benchmark.extra_info[f"{name} wall [us]"] = round(float(per_wall), 2)
        benchmark.extra_info[f"{name} max diff"] = differences
    benchmark.extra_info["load"] = load
    benchmark.group = "QP tracking step by structure"
    default = paths["active set (default)"]
    cursor = iter(range(10**9))
    benchmark.pedantic(lambda: default.command(*steps[next(cursor) % STEPS]), rounds=STEPS, iterations=1)
    assert np.abs(commands["active set (default)"] - reference).max() <= 1e-9
