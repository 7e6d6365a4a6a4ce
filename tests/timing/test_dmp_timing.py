"""Fit plus roll-out of a pose DMP against movement_primitives' CartesianDMP (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_dmp_timing.py --benchmark-only

The demonstration is a smooth rest-to-rest pose motion, 1,000 samples over
10 s; every method learns it with 50 basis functions per dimension and rolls
it out over the same 10 s. BLAS runs on one thread (threadpoolctl, in
case the variable was not set). movement_primitives runs first in the group;
``extra_info`` holds each method's reproduction error and its speed-up over
movement_primitives measured in the same session. optikin's roll-out Function
is built before the timing (once per process; its build time is in
``extra_info`` too).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.algebra import quat_angle, quat_conjugate, quat_multiply
from optikin.data.demonstrations import smooth_pose_demonstration
from optikin.dmp.pose import from_variant, pose_dmp, to_variant

SAMPLES, DURATION, BASIS = 1000, 10.0, 50
ROUNDS = 7
_seconds: dict[str, float] = {}


@pytest.fixture(scope="module")
def demo():
    return smooth_pose_demonstration(samples=SAMPLES, duration=DURATION, seed=1)


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def _errors(demo, position: np.ndarray, quaternion: np.ndarray) -> dict[str, float]:
    return {
        "position error [mm]": float(np.abs(position - demo.position).max() * 1e3),
        "orientation error [mrad]": float(
            quat_angle(quat_multiply(quaternion, quat_conjugate(demo.quaternion))).max() * 1e3
        ),
    }


def test_movement_primitives_cartesian_dmp(benchmark, demo):
    from movement_primitives.dmp import CartesianDMP

    def run():
        dmp = CartesianDMP(execution_time=DURATION, dt=demo.t[1], n_weights_per_dim=BASIS)
        dmp.imitate(demo.t, demo.pose)
        return dmp.open_loop()[1][:SAMPLES]

    benchmark.group = f"pose DMP fit + roll-out, {SAMPLES} steps, {BASIS} basis functions per dimension"
    Y = benchmark.pedantic(run, rounds=ROUNDS, warmup_rounds=1, iterations=1)
    _seconds["movement_primitives"] = benchmark.stats.stats.median
    benchmark.extra_info.update(_errors(demo, Y[:, :3], Y[:, 3:]))


@pytest.mark.parametrize("variant", ["cartesian", "dual-quaternion"])
def test_optikin_pose_dmp(benchmark, demo, variant):
    data = to_variant(variant, demo.dual_quaternion)
    start = time.perf_counter()
    warm = pose_dmp(variant, n_basis=BASIS)
    warm.imitate(demo.t, data)
    warm.rollout()
    build = time.perf_counter() - start

    def run():
        dmp = pose_dmp(variant, n_basis=BASIS)
        dmp.imitate(demo.t, data)
        return dmp.rollout().y

    benchmark.group = f"pose DMP fit + roll-out, {SAMPLES} steps, {BASIS} basis functions per dimension"
    Y = benchmark.pedantic(run, rounds=ROUNDS, warmup_rounds=1, iterations=1)
    position, quaternion = from_variant(variant, Y)
    errors = _errors(demo, position, quaternion)
    benchmark.extra_info.update(errors)
    benchmark.extra_info["first call incl. building the roll-out Function [s]"] = build
    reference = _seconds.get("movement_primitives")
    if reference is not None:
        benchmark.extra_info["speed-up over movement_primitives"] = reference / benchmark.stats.stats.median
    assert errors["position error [mm]"] < 0.1 and errors["orientation error [mrad]"] < 0.1
