"""Batched CC tip pose: the vectorised SoA kernel against the compiled CasADi loop and numpy (one process).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_fk_soa_timing.py --benchmark-only -s

For 1, 2 and 4 sections, the same 100,000 uniformly drawn configurations go through
every contender once per round, the contenders interleaved, :data:`ROUNDS` rounds
after one untimed call that builds (and compiles) them:

* ``numpy``: :func:`optikin.problems.fk.numpy_tip_dq` (the arm's formula vectorised in numpy);
* ``casadi compiled``: the ``casadi_compiled`` backend (CasADi's generated C, a C loop over
  the samples, one C call per batch);
* ``soa via evaluate``: ``ArmModel.evaluate("fk_dq", Q)`` on row-major ``(N, 3m)`` input,
  which now takes :mod:`optikin.fk_soa` (transposing through the stack in C);
* ``soa kernel``: the SoA entry on ``(3m, N)`` input into a preallocated ``(8, N)``
  output (no copies at all).

Each line printed: medians per sample of thread-CPU and wall time [ns], speed-up over
numpy (thread-CPU), largest difference from the CasADi Function, and the load average.
The pytest-benchmark figure of each test is the ``soa via evaluate`` call.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from optikin import fk_soa
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.batch import batch_evaluate
from optikin.errors import SolverError
from optikin.problems.fk import numpy_tip_dq
from optikin.solvers.evaluation import CompiledEvaluator
from optikin.spec import SolverSpec

SAMPLES = 100_000
ROUNDS = 15


def _median_ns(values: list[float]) -> float:
    return float(np.median(values)) / SAMPLES * 1e9


@pytest.mark.parametrize("m", [1, 2, 4])
def test_soa_kernel_throughput(benchmark, m):
    arm = ConstantCurvatureArm(section_lengths=(0.18,) * m)
    runner = fk_soa.kernel(m)
    if runner is None:
        pytest.skip("no C compiler")
    Q = np.random.default_rng(0).uniform(arm.lower, arm.upper, (SAMPLES, arm.n_config))
    reference = batch_evaluate(arm.fk_dq, Q)[..., 0]
    compiled = CompiledEvaluator(SolverSpec(name="timing", backend="casadi_compiled"))
    try:
        compiled.evaluate(arm, "fk_dq", Q[:1])
    except SolverError as exc:
        pytest.skip(str(exc))
    Qs, out = np.ascontiguousarray(Q.T), np.empty((8, SAMPLES))
    contenders = {
        "numpy": lambda: numpy_tip_dq(arm, Q),
        "casadi compiled": lambda: compiled.evaluate(arm, "fk_dq", Q)[:, :, 0],
        "soa via evaluate": lambda: arm.evaluate("fk_dq", Q),
        "soa kernel": lambda: runner.soa("fk_dq", Qs, out).T,
    }
    errors = {name: float(np.abs(run() - reference).max()) for name, run in contenders.items()}
    cpu: dict[str, list[float]] = {name: [] for name in contenders}
    wall: dict[str, list[float]] = {name: [] for name in contenders}
    load = [os.getloadavg()[0]]
    for _ in range(ROUNDS):
        for name, run in contenders.items():
            c0, w0 = time.thread_time(), time.perf_counter()
            run()
            cpu[name].append(time.thread_time() - c0)
            wall[name].append(time.perf_counter() - w0)
    load.append(os.getloadavg()[0])
    base = _median_ns(cpu["numpy"])
    print(f"\nCC fk_dq, {m} section(s), {SAMPLES} samples, {ROUNDS} rounds, load {load[0]:.1f}-{load[1]:.1f}")
    print(f"flags of the SoA kernel: {' '.join(runner.flags)}")
    for name in contenders:
        per_cpu, per_wall = _median_ns(cpu[name]), _median_ns(wall[name])
        print(
            f"  {name:18s} cpu {per_cpu:9.1f} ns  wall {per_wall:9.1f} ns  x{base / per_cpu:6.1f}"
            f"  max diff {errors[name]:.1e}"
        )
        benchmark.extra_info[f"{name} per sample cpu [ns]"] = round(per_cpu, 1)
        benchmark.extra_info[f"{name} per sample wall [ns]"] = round(per_wall, 1)
        benchmark.extra_info[f"{name} max diff"] = errors[name]
    benchmark.extra_info["load"] = load
    benchmark.group = "CC fk_dq batched, SoA kernel"
    benchmark.pedantic(contenders["soa via evaluate"], rounds=5, iterations=1)
    assert errors["soa via evaluate"] <= 1e-14 and errors["soa kernel"] <= 1e-14
