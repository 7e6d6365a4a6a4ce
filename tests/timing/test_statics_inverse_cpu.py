"""Inverse Cosserat statics with gauss-newton: wall and thread-CPU time per target along a trajectory.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest -o addopts="" tests/timing/test_statics_inverse_cpu.py --benchmark-only

The targets of ``problems/cosserat-tendon-ik.yaml`` (as in ``test_statics_timing.py``), solved
in order by the solver preset, five rounds. The benchmark's timer is the wall clock;
``extra_info`` holds the medians over the rounds of the wall and thread-CPU time per target
[ms] (thread CPU is what one core spends, the measure that a loaded machine disturbs least),
the equilibria solved per target, and the number solved.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from optikin.problems.statics.equilibrium import TipEquilibrium
from optikin.problems.statics.run import fixed_loads, inverse_problem, shooting_solver
from optikin.runner import prepare
from optikin.solvers import build_preset

TARGETS = 100
ROUNDS = 5


@pytest.fixture(scope="module")
def setup():
    _, ctx = prepare("cosserat-tendon-ik")
    arm, options = ctx.arm, ctx.options
    solver = shooting_solver(arm, options)
    samples = ctx.data_source.load(arm, ctx.spec.data, ctx.data_params, ctx.path)
    fixed = fixed_loads(arm, options.loads)
    targets = np.array([solver.solve(np.concatenate([fixed, a])).tip_position for a in samples.values[:TARGETS]])
    return arm, options, solver, fixed, targets


def test_inverse_statics_wall_and_thread_cpu_per_target(benchmark, setup):
    arm, options, solver, fixed, targets = setup
    adapter = build_preset("gauss-newton")
    equilibrium = TipEquilibrium(solver, fixed, options.flags)
    problem, _tip = inverse_problem(arm, equilibrium, options)
    start = 0.5 * (arm.lower + arm.upper)
    adapter.solve_many(problem, start, targets[:1])  # build the backend's Functions outside the timing
    wall, cpu, reports = [], [], []

    def run():
        equilibrium.forget()
        count = equilibrium.equilibria
        began, began_cpu = time.perf_counter(), time.thread_time()
        reports[:] = [adapter.solve_many(problem, start, targets, warm_start=True)]
        cpu.append((time.thread_time() - began_cpu) / len(targets) * 1e3)
        wall.append((time.perf_counter() - began) / len(targets) * 1e3)
        benchmark.extra_info["equilibria_per_target"] = (equilibrium.equilibria - count) / len(targets)

    benchmark.group = f"inverse Cosserat statics (gauss-newton), {TARGETS} targets, wall and thread CPU"
    benchmark.pedantic(run, rounds=ROUNDS, warmup_rounds=0, iterations=1)
    benchmark.extra_info["wall_ms_per_target_median"] = float(np.median(wall))
    benchmark.extra_info["thread_cpu_ms_per_target_median"] = float(np.median(cpu))
    solved = int(np.sum(np.array(reports[0].status) == "ok"))
    benchmark.extra_info["solved"] = solved
    assert solved == len(targets)
