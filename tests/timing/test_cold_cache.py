"""Per-call times with warm and with cold caches: FK, PH shape, IK and DMP, side by side (one process).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_cold_cache.py --benchmark-only -s

Each operation is built and called once untimed, then :data:`ROUNDS` rounds each time
two calls, interleaved:

* **warm**: right after an untimed call of the same operation (code, data and the
  model's work arrays in the caches);
* **cold**: right after :func:`flush`, a read-modify-write sweep over 64 MB (twice the
  32 MB last-level cache of the 2-core machine this was written on), which evicts the
  operation's code and data from every cache level and its pages from the TLB.

Operations (the per-call paths of ``BENCHMARKS.md``):

* ``fk``: ``ArmModel.evaluate("fk_dq", Q)`` on 1,000 configurations of the two-section
  CC arm (the vectorised kernel of :mod:`optikin.fk_soa`), and on one configuration;
* ``ph``: the compiled given-speed Newton of the PH shape (``ShapeEnergyModel(compile=True)``)
  warm-started along the 100 postures of ``problems/cbha-ph-shape.yaml``, one posture per call;
* ``ik``: ``gauss-newton-compiled`` position IK of the two-section CC arm, one target per
  call, warm-started from the previous solution along a smooth 1,000-sample motion;
* ``dmp``: fit plus roll-out of the cartesian pose DMP (1,000 steps, 50 basis functions,
  the fast path of ``tests/timing/test_dmp_fast_timing.py``).

Printed per operation: medians of thread-CPU and wall time per call, warm and cold, and the
cold/warm ratio of the thread-CPU medians; with the load average.
"""

from __future__ import annotations

import os
import time
from typing import Callable

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

SWEEP_BYTES = 64 * 1024 * 1024
ROUNDS = {"fk 1000": 200, "fk 1": 200, "ph": 200, "ik": 200, "dmp": 30}
_sweep = np.zeros(SWEEP_BYTES // 8)


def flush() -> None:
    """Read and write every cache line of a 64 MB buffer."""
    np.add(_sweep, 1.0, out=_sweep)


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def _fk(batch: int) -> Callable[[], object]:
    from optikin.arms.constant_curvature import ConstantCurvatureArm

    arm = ConstantCurvatureArm()
    Q = np.random.default_rng(0).uniform(arm.lower, arm.upper, (batch, arm.n_config))
    q = Q[0] if batch == 1 else Q
    return lambda: arm.evaluate("fk_dq", q)


def _ph() -> Callable[[], object]:
    from optikin.curves import EnergySettings, ShapeEnergyModel
    from optikin.problems.ph_shared import backbone_lengths, end_data, recording_of

    recording = recording_of("cbha-ph-shape").with_fixed_base()
    samples = end_data(recording, backbone_lengths(recording, "arc", "timing"), "timing")
    model = ShapeEnergyModel(EnergySettings(), free_speeds=False, compile=True)
    state = {"k": 0, "x": None}

    def call():
        k = state["k"] % len(samples)
        state["k"] += 1
        sol = model.solve_newton(samples[k], state["x"] if k > 0 else None)
        state["x"] = sol.x if sol.status == "ok" else None
        return sol

    return call


def _ik() -> Callable[[], object]:
    from optikin.arms import ConstantCurvatureArm
    from optikin.data.configurations import TrajectoryParams, smooth_motion
    from optikin.ik.formulation import tip_residual
    from optikin.solvers import load_backends, preset_of
    from optikin.solvers.nonlinear import LeastSquaresProblem
    from optikin.spec import load_solver

    load_backends()
    arm = ConstantCurvatureArm()
    Q, _ = smooth_motion(arm, 1000, 2020, TrajectoryParams())
    P = arm.evaluate("fk_position", Q)
    problem = LeastSquaresProblem(
        tip_residual(arm, "position", 0.396),
        arm.lower,
        arm.upper,
        arm.periodic,
        tolerance=1e-10,
        weights=1.0 / (arm.upper - arm.lower),
        name="cold_cache_position",
        variable_names=arm.config_names,
    )
    preset, _ = load_solver("gauss-newton-compiled")
    solver = preset_of(preset).build()
    state = {"k": 0, "x": Q[0]}

    def call():
        k = state["k"] % len(P)
        state["k"] += 1
        report = solver.solve_many(problem, state["x"], P[k : k + 1], warm_start=True)
        state["x"] = report.x[0] if k < len(P) - 1 else Q[0]
        return report

    return call


def _dmp() -> Callable[[], object]:
    from optikin.data.demonstrations import smooth_pose_demonstration
    from optikin.dmp.pose import pose_dmp, to_variant

    demo = smooth_pose_demonstration(samples=1000, duration=10.0, seed=1)
    data = to_variant("cartesian", demo.dual_quaternion)

    def call():
        dmp = pose_dmp("cartesian", n_basis=50)
        dmp.imitate(demo.t, data)
        return dmp.rollout(engine="compiled")

    return call


BUILDERS: dict[str, Callable[[], Callable[[], object]]] = {
    "fk 1000": lambda: _fk(1000),
    "fk 1": lambda: _fk(1),
    "ph": _ph,
    "ik": _ik,
    "dmp": _dmp,
}


def _timed(call: Callable[[], object]) -> tuple[float, float]:
    c0, w0 = time.thread_time(), time.perf_counter()
    call()
    return time.thread_time() - c0, time.perf_counter() - w0


@pytest.mark.parametrize("operation", list(BUILDERS))
def test_warm_and_cold(benchmark, operation):
    call = BUILDERS[operation]()
    call()
    warm, cold = [], []
    load = [os.getloadavg()[0]]
    for _ in range(ROUNDS[operation]):
        call()
        warm.append(_timed(call))
        flush()
        cold.append(_timed(call))
    load.append(os.getloadavg()[0])
    w, c = np.median(warm, axis=0) * 1e6, np.median(cold, axis=0) * 1e6
    print(
        f"\n{operation:8s} warm cpu {w[0]:9.1f} us wall {w[1]:9.1f} us | cold cpu {c[0]:9.1f} us wall {c[1]:9.1f} us"
        f" | cold/warm x{c[0] / w[0]:.2f} (cpu)  [{ROUNDS[operation]} rounds, load {load[0]:.1f}-{load[1]:.1f}]"
    )
    benchmark.extra_info.update(
        {
            "warm cpu [us]": round(float(w[0]), 1),
            "warm wall [us]": round(float(w[1]), 1),
            "cold cpu [us]": round(float(c[0]), 1),
            "cold wall [us]": round(float(c[1]), 1),
            "cold/warm cpu": round(float(c[0] / w[0]), 2),
            "load": load,
        }
    )
    benchmark.group = "per call after a 64 MB cache flush"
    benchmark.pedantic(call, setup=flush, rounds=5, iterations=1)
