"""IK to three measured points per posture (a three-section trunk's disks), warm-started along a motion.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_ik_points_timing.py --benchmark-only

Target: at most 50 us per warm-started solve from Python, against scipy ``lm`` (the
``lm`` preset) measured in the same session. The targets are the three disk centres of
1000 postures of a smooth motion with 0.3 mm Gaussian noise per coordinate, fitted with
fixed section lengths (6 bending variables, 9 rows): every solve is a least-squares fit.
``extra_info`` holds the median time per solve (round median / targets), the number of
fits and the speed-up over ``lm``.

:func:`test_trunk_ik_problem` runs the shipped ``trunk-ik`` problem (``optikin solve trunk-ik``: the
calibrated arm, its recording's three disks, fits within the noise) cold from rest and warm-started along
the recording (``data.params.trajectory``), and holds the kind's own time per posture to
:data:`POSTURE_BUDGET`.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms import ConstantCurvatureArm
from optikin.data.configurations import TrajectoryParams, smooth_motion
from optikin.ik.formulation import Formulation, build_problem
from optikin.ik.points import MeasuredPoint, PointSet
from optikin.runner import solve
from optikin.solvers import load_backends, preset_of
from optikin.spec import load_solver

load_backends()
SAMPLES = 1000
PRESETS = ("lm", "gauss-newton", "gauss-newton-compiled")
_lm_per_solve: dict[str, float] = {}
POSTURE_BUDGET = 0.5e-3
"""Largest median time per posture [s] of ``trunk-ik`` (the kind's per-posture solve time, retries included)."""


@pytest.fixture(scope="module")
def trunk():
    arm = ConstantCurvatureArm(section_lengths=(0.1058, 0.0949, 0.1144), length_range=(1.0, 1.0), theta_max=1.5)
    points = PointSet(tuple(MeasuredPoint(f"disk{k + 1}", k) for k in range(3)))
    Q, _ = smooth_motion(arm, SAMPLES, 7, TrajectoryParams())
    targets = points.forward(arm, Q) + np.random.default_rng(1).normal(0.0, 3e-4, (SAMPLES, 9))
    span = arm.upper - arm.lower
    formulation = Formulation(
        target="points",
        redundancy="previous",
        rest=arm.straight_configuration(),
        weights=1.0 / np.where(span > 0, span, 1.0),
        tolerance=1e-10,
        orientation_length=0.3,
        points=points,
        noise=1e-3,
    )
    return build_problem(arm, formulation), Q, targets


@pytest.mark.parametrize("preset", PRESETS)
def test_points_warm_started(benchmark, trunk, preset):
    problem, Q, P = trunk
    spec, _ = load_solver(preset)
    solver = preset_of(spec).build()
    solver.solve_many(problem, Q[0], P[:5], warm_start=True)  # build (and compile) outside the timing
    report = benchmark.pedantic(lambda: solver.solve_many(problem, Q[0], P, warm_start=True), rounds=5, iterations=1)
    per_solve = benchmark.stats.stats.median / SAMPLES
    if preset == "lm":
        _lm_per_solve["lm"] = per_solve
    benchmark.extra_info["median per solve [us]"] = per_solve * 1e6
    benchmark.extra_info["stationary (fits)"] = int(sum(s == "ok" for s in report.status))
    if "lm" in _lm_per_solve:
        benchmark.extra_info["speed-up over lm"] = _lm_per_solve["lm"] / per_solve
    assert sum(s == "ok" for s in report.status) >= 0.99 * SAMPLES


@pytest.mark.parametrize("trajectory", [False, True])
def test_trunk_ik_problem(benchmark, trajectory):
    overrides = [("data.params.trajectory", trajectory)]
    solve("trunk-ik", figures=False, overrides=overrides)  # build outside the timing
    result, _ = benchmark.pedantic(
        lambda: solve("trunk-ik", figures=False, overrides=overrides), rounds=3, iterations=1
    )
    seconds = np.asarray(result.arrays["time_gauss-newton"])
    iterations = np.asarray(result.arrays["iterations_gauss-newton"])
    benchmark.extra_info["median per posture [us]"] = float(np.median(seconds) * 1e6)
    benchmark.extra_info["median / max iterations"] = [float(np.median(iterations)), int(iterations.max())]
    benchmark.extra_info["statuses"] = result.status_counts()
    assert np.median(seconds) <= POSTURE_BUDGET
