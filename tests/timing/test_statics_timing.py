"""Inverse Cosserat statics: time per target, warm-started along a trajectory of targets (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_statics_timing.py --benchmark-only

The arm and targets of ``problems/cosserat-tendon-ik.yaml`` (two-segment tendon robot
of Rao et al. 2021, 20 RK4 steps per segment, compiled shooting): the tips of the
equilibria of a smooth tension trajectory, each target solved from the previous answer
by a ``nonlinear`` preset on the embedded equilibrium
(:mod:`optikin.problems.statics.equilibrium`). The target is at most 5 ms per target
for the solver preset. ``extra_info`` holds the mean time per target [ms], the
equilibria solved per target and the number solved.
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


@pytest.fixture(scope="module")
def setup():
    _, ctx = prepare("cosserat-tendon-ik")
    arm, options = ctx.arm, ctx.options
    solver = shooting_solver(arm, options)
    samples = ctx.data_source.load(arm, ctx.spec.data, ctx.data_params, ctx.path)
    fixed = fixed_loads(arm, options.loads)
    loads = [np.concatenate([fixed, a]) for a in samples.values[:TARGETS]]
    targets = np.array([solver.solve(P).tip_position for P in loads])
    return arm, options, solver, fixed, targets


@pytest.mark.parametrize("preset", ["gauss-newton", "lm", "trf"])
def test_inverse_statics_along_a_trajectory(benchmark, setup, preset):
    arm, options, solver, fixed, targets = setup
    adapter = build_preset(preset)
    equilibrium = TipEquilibrium(solver, fixed, options.flags)
    problem, _tip = inverse_problem(arm, equilibrium, options)
    start = 0.5 * (arm.lower + arm.upper)
    adapter.solve_many(problem, start, targets[:1])  # build the backend's Functions outside the timing
    reports = []

    def run():
        equilibrium.forget()
        count = equilibrium.equilibria
        began = time.perf_counter()
        reports[:] = [adapter.solve_many(problem, start, targets, warm_start=True)]
        benchmark.extra_info["ms_per_target"] = (time.perf_counter() - began) / len(targets) * 1e3
        benchmark.extra_info["equilibria_per_target"] = (equilibrium.equilibria - count) / len(targets)

    benchmark.group = f"inverse Cosserat statics, {TARGETS} targets along a trajectory"
    benchmark.pedantic(run, rounds=3, warmup_rounds=0, iterations=1)
    solved = int(np.sum(np.array(reports[0].status) == "ok"))
    benchmark.extra_info["solved"] = solved
    assert solved == len(targets)
