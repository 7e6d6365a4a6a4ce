"""Cosserat-rod equilibria along a slowly varying load sequence, VM vs compiled (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    pytest tests/timing/test_cosserat_timing.py --benchmark-only

One equilibrium of the 0.3 m rod of the PyElastica cases (100 RK4 steps, gravity
on) per tip load, for 100 tip loads (force and couple) varying slowly, each solve
warm-started from the ones before (:meth:`ShootingSolver.solve_sequence`).
``extra_info`` holds the time per equilibrium and the mean iterations.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from optikin.errors import SolverError
from optikin.physics import Loads, Rod, RodArm, ShootingOptions, ShootingSolver

SEQUENCE = 100


def loads() -> list[Loads]:
    t = np.linspace(0.0, 1.0, SEQUENCE)
    return [
        Loads(tip_force=(0.05 * np.sin(2 * np.pi * ti), 0.02 * ti, -0.03), tip_couple=(0.0, 0.001 * ti, 0.0))
        for ti in t
    ]


@pytest.mark.parametrize("compiled", [False, True], ids=["vm_rootfinder", "compiled_newton"])
def test_equilibrium_sequence(benchmark, compiled):
    rod = Rod(
        length=0.3, radius=0.01, youngs_modulus=1e6, shear_modulus=1e6 / 3, density=1000.0, gravity=(0.0, 0.0, -9.81)
    )
    try:
        solver = ShootingSolver(RodArm.single(rod), ShootingOptions(steps_per_segment=100, compiled=compiled))
    except SolverError as exc:
        pytest.skip(str(exc))
    sequence = loads()
    solver.solve_sequence(sequence[:3])  # build (and compile) outside the timing
    results = []

    def run():
        start = time.perf_counter()
        results[:] = solver.solve_sequence(sequence)
        benchmark.extra_info["ms_per_equilibrium"] = (time.perf_counter() - start) / SEQUENCE * 1e3

    benchmark.group = f"cosserat equilibria, {SEQUENCE} slowly varying tip loads"
    benchmark.pedantic(run, rounds=3, warmup_rounds=0, iterations=1)
    benchmark.extra_info["mean_iterations"] = float(np.mean([r.iterations for r in results]))
    assert all(r.ok for r in results)
