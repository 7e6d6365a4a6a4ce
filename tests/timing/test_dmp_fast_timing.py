"""DMP fit + roll-out, fast path (Cholesky fit, roll-out as generated C) against the reference (one process).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_dmp_fast_timing.py --benchmark-only -s

The demonstration and sizes of ``tests/timing/test_dmp_timing.py``: a smooth
rest-to-rest pose motion, 1,000 samples over 10 s, 50 basis functions per gap
component, rolled out over the same 10 s (1,000 steps). For the ``cartesian`` and
``dual-quaternion`` pose DMPs, three contenders, interleaved, :data:`ROUNDS` rounds
after one untimed round that builds (and compiles) everything:

* ``reference``: ``imitate(factorisation="svd", engine="numpy")`` (the gaps in numpy,
  ``numpy.linalg.lstsq``) and ``rollout(engine="casadi")`` (the ``mapaccum`` in CasADi's
  virtual machine);
* ``fast``: ``imitate(engine="compiled")`` (the gaps in one C call; the design matrix and
  its Cholesky factor from the per-process caches, one refinement step) and
  ``rollout(engine="compiled")`` (the features of every step from the per-process cache);
* ``fast, cold``: the same with those three caches emptied first (a demonstration of a new
  length or step, or a new roll-out length).

Printed: medians of thread-CPU and wall time [ms] of the fit (``imitate``, which
includes building the regression problem), of the roll-out and of both, and the
largest difference between the two contenders' poses; with the load average.
BLAS runs on one thread.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.data.demonstrations import smooth_pose_demonstration
from optikin.dmp import basis, imitation, regression
from optikin.dmp.compiled import compiled_rollout
from optikin.dmp.pose import pose_dmp, to_variant

SAMPLES, DURATION, BASIS = 1000, 10.0, 50
ROUNDS = 21
CONTENDERS = {
    "reference": ("svd", "numpy", "casadi", False),
    "fast": ("cholesky", "compiled", "compiled", False),
    "fast, cold": ("cholesky", "compiled", "compiled", True),
}


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def _one(variant: str, t: np.ndarray, data: np.ndarray, factorisation: str, gaps: str, engine: str, cold: bool):
    """One fit plus roll-out; thread-CPU and wall seconds of each part, and the poses."""
    if cold:
        for cache in (imitation._DESIGNS, regression._FACTORS, basis._TABLES):
            cache.clear()
    c0, w0 = time.thread_time(), time.perf_counter()
    dmp = pose_dmp(variant, n_basis=BASIS)
    dmp.imitate(t, data, factorisation=factorisation, engine=gaps)
    c1, w1 = time.thread_time(), time.perf_counter()
    y = dmp.rollout(engine=engine).y
    c2, w2 = time.thread_time(), time.perf_counter()
    return (c1 - c0, w1 - w0, c2 - c1, w2 - w1, c2 - c0, w2 - w0), y


@pytest.mark.parametrize("variant", ["cartesian", "dual-quaternion"])
def test_fast_fit_and_rollout(benchmark, variant):
    demo = smooth_pose_demonstration(samples=SAMPLES, duration=DURATION, seed=1)
    data = to_variant(variant, demo.dual_quaternion)
    if compiled_rollout(pose_dmp(variant, n_basis=BASIS).space, BASIS) is None:
        pytest.skip("no C compiler")
    poses = {name: _one(variant, demo.t, data, *how)[1] for name, how in CONTENDERS.items()}
    times: dict[str, list] = {name: [] for name in CONTENDERS}
    load = [os.getloadavg()[0]]
    for _ in range(ROUNDS):
        for name, how in CONTENDERS.items():
            times[name].append(_one(variant, demo.t, data, *how)[0])
    load.append(os.getloadavg()[0])
    difference = float(np.abs(poses["fast"] - poses["reference"]).max())
    print(
        f"\nDMP {variant}, {SAMPLES} steps, {BASIS} basis functions, {ROUNDS} rounds, load {load[0]:.1f}-{load[1]:.1f}"
    )
    print(
        f"  {'':12s} {'fit cpu':>9s} {'fit wall':>9s} {'roll cpu':>9s} {'roll wall':>9s} {'cpu':>9s} {'wall':>9s}  [ms]"
    )
    for name in CONTENDERS:
        medians = np.median(np.array(times[name]), axis=0) * 1e3
        print(f"  {name:12s} " + " ".join(f"{v:9.3f}" for v in medians))
        for label, value in zip(("fit cpu", "fit wall", "rollout cpu", "rollout wall", "cpu", "wall"), medians):
            benchmark.extra_info[f"{name} {label} [ms]"] = round(float(value), 3)
    print(f"  largest pose difference fast - reference: {difference:.1e}")
    print(
        f"  median wall of fast fit + roll-out: {np.median(np.array(times['fast'])[:, 5]) * 1e3:.3f} ms (target 2 ms)"
    )
    benchmark.extra_info["load"] = load
    benchmark.extra_info["pose difference"] = difference
    benchmark.group = "DMP fit + roll-out, fast path"
    benchmark.pedantic(lambda: _one(variant, demo.t, data, *CONTENDERS["fast"]), rounds=5, iterations=1)
    assert difference <= 1e-10
