"""Forward-kinematics throughput per evaluation path and arm (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    pytest tests/timing --benchmark-only

Each arm is one benchmark group, so pytest-benchmark's table compares the paths
side by side on the same configurations. ``extra_info`` holds the time per
sample and the speed-up against the numpy baseline measured in the same session
(numpy runs first in each group). The full-size figures (100,000
configurations) come from ``optikin bench``; see BENCHMARKS.md.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.bench import _configurations, _load_arm
from optikin.errors import SolverError
from optikin.problems.fk import numpy_tip_dq
from optikin.solvers.evaluation import CallEvaluator, CompiledEvaluator, MapEvaluator
from optikin.spec import SolverSpec

SAMPLES = 10_000
"""Configurations per call: small enough that the whole module runs within a minute on 2 busy cores."""
ROUNDS = {"numpy": 15, "casadi_call": 3, "casadi_map": 15, "casadi_compiled": 15}
EVALUATORS = {"casadi_call": CallEvaluator, "casadi_map": MapEvaluator, "casadi_compiled": CompiledEvaluator}
_numpy_per_sample: dict[str, float] = {}


@pytest.fixture(scope="module", params=["cc", "cbha"])
def case(request):
    arm, reason = _load_arm(request.param)
    if arm is None:
        pytest.skip(reason)
    Q = _configurations(arm, SAMPLES, np.random.default_rng(0))
    return arm, Q, numpy_tip_dq(arm, Q)


@pytest.mark.parametrize("path", list(ROUNDS))
def test_fk_tip_throughput(benchmark, case, path):
    arm, Q, reference = case
    if path == "numpy":

        def run():
            return numpy_tip_dq(arm, Q)
    else:
        evaluator = EVALUATORS[path](SolverSpec(name="timing", backend=path))
        try:
            evaluator.evaluate(arm, "fk_dq", Q[:1])  # build (and compile) outside the timing
        except SolverError as exc:
            pytest.skip(str(exc))

        def run():
            return evaluator.evaluate(arm, "fk_dq", Q)[:, :, 0]

    benchmark.group = f"fk_dq {arm.name}, {SAMPLES} configurations"
    result = benchmark.pedantic(run, rounds=ROUNDS[path], warmup_rounds=1, iterations=1)
    np.testing.assert_allclose(result, reference, rtol=0, atol=1e-12)

    per_sample = benchmark.stats.stats.median / SAMPLES
    benchmark.extra_info["samples"] = SAMPLES
    benchmark.extra_info["median per sample [ns]"] = round(per_sample * 1e9, 1)
    if path == "numpy":
        _numpy_per_sample[arm.name] = per_sample
    elif arm.name in _numpy_per_sample:
        benchmark.extra_info["speed-up vs numpy (median)"] = round(_numpy_per_sample[arm.name] / per_sample, 2)
