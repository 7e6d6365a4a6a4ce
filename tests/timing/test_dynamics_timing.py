"""Implicit Cosserat-rod dynamics: wall time of one warm-started time step (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_dynamics_timing.py --benchmark-only

The soft rod of the PyElastica comparisons (0.3 m, r = 10 mm, E = 1 MPa, G = E / 3,
1000 kg/m^3) clamped horizontally under gravity, released from a 20 mN tip load and
vibrating: N = 40 points, dt = 2 ms, BDF2, the shape compiled to C
(:class:`optikin.physics.dynamics.RodDynamics`). One round is 100 consecutive steps
from the same state 50 steps after the release, each warm-started from the two before
(the kept Jacobian carries over between rounds, as along a run). The target of the issue
is 20 us per step (100x real time). ``test_till_cantilever_step`` times the dynamic
cantilever of Till et al.'s C++ examples the same way (steel, 0.5 m, r = 1 mm, alpha = -0.2;
tests/test_dynamics_till.py), whose readable C++ takes about 60-70 us per step at its 40
points (Euler in ``s``: 0.6 mm of grid error at the tip, 0.04 mm at 640 points and 1 ms per step).
``extra_info`` holds the time per step [us] and the real-time factor (of the last round), the
shape evaluations and Newton iterations per step, and the shooting intervals.
``test_pyelastica_real_time_factor`` runs the PyElastica comparison of
tests/test_dynamics_pyelastica.py (the soft rod, a 5 mN tip-force step, 1 s simulated):
PyElastica at 50 elements (PositionVerlet, dt = 0.01 L / n) and optikin at 40 points and
2 ms BDF2 steps in the same process, one round each, their real-time factors and tip
distance from PyElastica's Richardson extrapolation in ``extra_info``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from optikin.physics import Loads, Rod, RodArm
from optikin.physics.dynamics import DynamicsOptions, RodDynamics

STEPS = 100
DT = 0.002


def timed(benchmark, dyn: RodDynamics, state, loads: np.ndarray):
    """Benchmark :data:`STEPS` steps from ``state``; extra_info as the module docstring says."""
    evaluations = [0]
    evaluate = dyn._evaluate_packed

    def counted(*args, **kwargs):
        evaluations[0] += 1
        return evaluate(*args, **kwargs)

    dyn._evaluate_packed = counted

    def run():
        x = state
        iterations = 0
        began = time.perf_counter()
        for _ in range(STEPS):
            x = dyn.step(x, loads)
            iterations += x.iterations
        per_step = (time.perf_counter() - began) / STEPS
        benchmark.extra_info["us_per_step"] = per_step * 1e6
        benchmark.extra_info["real_time_factor"] = DT / per_step
        benchmark.extra_info["newton_iterations_per_step"] = iterations / STEPS
        return x

    final = benchmark.pedantic(run, rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info["evaluations_per_step"] = evaluations[0] / (6 * STEPS)
    benchmark.extra_info["intervals"] = dyn.intervals
    assert final.step == state.step + STEPS


@pytest.fixture(scope="module")
def setup():
    rod = Rod(
        length=0.3, radius=0.01, youngs_modulus=1e6, shear_modulus=1e6 / 3, density=1000.0, gravity=(0.0, 0.0, -9.81)
    )
    arm = RodArm.single(rod, base_orientation=(np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0))
    dyn = RodDynamics(arm, DynamicsOptions(dt=DT, steps_per_segment=39))
    start = dyn.rest(Loads(tip_force=(0.0, 0.0, -0.02)))
    free = dyn.load_vector(Loads())
    state = dyn.simulate(start, np.tile(free, (50, 1)), keep_shapes=False).final
    return dyn, state, free


def test_one_time_step_at_40_points(benchmark, setup):
    dyn, state, free = setup
    timed(benchmark, dyn, state, free)


def test_till_cantilever_step(benchmark):
    rod = Rod(
        length=0.5, radius=0.001, youngs_modulus=200e9, shear_modulus=80e9, density=8000.0, gravity=(-9.81, 0.0, 0.0)
    )
    dyn = RodDynamics(RodArm.single(rod), DynamicsOptions(dt=DT, alpha=-0.2, steps_per_segment=39))
    start = dyn.rest(Loads(tip_force=(-0.02 * 9.81, 0.0, 0.0)))
    free = dyn.load_vector(Loads())
    state = dyn.simulate(start, np.tile(free, (50, 1)), keep_shapes=False).final
    timed(benchmark, dyn, state, free)


def test_pyelastica_real_time_factor(benchmark):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from test_dynamics_pyelastica import DURATION, FORCE, RAMP, SAMPLE, pyelastica_tip, rms

    pyelastica_tip(10)  # numba compiles here, outside the timing
    began = time.perf_counter()
    coarse = pyelastica_tip(50)
    pyelastica_seconds = time.perf_counter() - began
    reference = 2 * pyelastica_tip(100) - coarse
    rod = Rod(length=0.3, radius=0.01, youngs_modulus=1e6, shear_modulus=1e6 / 3, density=1000.0, gravity=(0, 0, 0))
    dyn = RodDynamics(RodArm.single(rod), DynamicsOptions(dt=DT, steps_per_segment=39))
    n = int(round(DURATION / DT))
    loads = np.zeros((n, dyn.n_loads))
    loads[:, 0:3] = FORCE[None, :] * np.clip(DT * np.arange(1, n + 1) / RAMP, 0.0, 1.0)[:, None]
    start = dyn.rest(Loads())
    trajectory = benchmark.pedantic(lambda: dyn.simulate(start, loads, keep_shapes=False), rounds=3, iterations=1)
    times = SAMPLE * np.arange(reference.shape[0])
    tip = np.array([np.interp(times, trajectory.t, trajectory.tip[:, k]) for k in range(3)]).T
    benchmark.extra_info["pyelastica_50_real_time_factor"] = DURATION / pyelastica_seconds
    benchmark.extra_info["pyelastica_50_rms_mm"] = rms(coarse, reference) * 1e3
    benchmark.extra_info["optikin_real_time_factor"] = DURATION / benchmark.stats.stats.min
    benchmark.extra_info["optikin_rms_mm"] = rms(tip, reference) * 1e3
