"""``optikin bench`` runs on a tiny batch and reports every path with results equal to numpy's.

No timing assertions here: speed is measured by ``optikin bench`` itself and by
``pytest tests/timing --benchmark-only``. Also checks that the evaluation
backends the bench measures return exactly the numbers of a plain ``f.map``.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from optikin import bench
from optikin.arms.base import FUNCTION_NAMES
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.batch import BatchFunction, batch_evaluate
from optikin.solvers.evaluation import CallEvaluator, CompiledEvaluator, MapEvaluator
from optikin.spec import SolverSpec

TINY = ["--samples", "64", "--call-samples", "8", "--repeats", "2", "--json"]


def run_bench(argv: list[str], capsys) -> tuple[int, dict]:
    parser = argparse.ArgumentParser(prog="optikin bench")
    bench.add_arguments(parser)
    code = bench.main(parser.parse_args(argv))
    return code, json.loads(capsys.readouterr().out)


def test_bench_json_reports_every_path_agreeing_with_numpy(capsys):
    code, report = run_bench(TINY + ["--arm", "cc"], capsys)
    assert code == bench.EXIT_OK and report["ok"]
    assert report["command"].startswith("optikin bench --samples 64")
    assert report["machine"]["nproc"] >= 1 and report["machine"]["casadi"]
    paths = {r["path"]: r for r in report["arms"]["cc"]["paths"]}
    assert list(paths) == list(bench.PATH_NAMES)
    assert paths["numpy"]["speedup_vs_numpy"] == pytest.approx(1.0)
    assert paths["casadi call"]["samples"] == 8
    for name, r in paths.items():
        if name == "compiled" and r["skipped"]:  # no working C compiler: said, not hidden
            continue
        assert not r["skipped"], name
        assert len(r["times_ms"]) == 2 and r["median_ms"] > 0 and r["per_sample_ns"] > 0
        assert r["speedup_vs_numpy"] > 0
        if name != "numpy":
            assert r["agrees"] and r["max_abs_diff"] <= 1e-12, name


def test_bench_exits_1_when_a_path_disagrees(capsys):
    code, report = run_bench(TINY + ["--arm", "cc", "--no-compiled", "--tolerance", "-1"], capsys)
    assert code == bench.EXIT_DISAGREE and not report["ok"]
    paths = {r["path"]: r for r in report["arms"]["cc"]["paths"]}
    assert paths["compiled"]["skipped"] == "disabled by --no-compiled"
    assert paths["casadi map"]["agrees"] is False


def test_bench_cbha_is_measured_or_skipped_with_a_reason(capsys):
    code, report = run_bench(TINY + ["--arm", "cbha", "--no-compiled"], capsys)
    assert code == bench.EXIT_OK
    if report["skipped"]:
        assert report["skipped"][0]["arm"] == "cbha" and report["skipped"][0]["reason"]
    else:
        paths = report["arms"]["cbha"]["paths"]
        assert all(r["agrees"] for r in paths if r["path"] not in ("numpy", "compiled"))


def test_bench_tables_print(capsys):
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    assert (
        bench.main(
            parser.parse_args(
                ["--samples", "16", "--call-samples", "4", "--repeats", "1", "--arm", "cc", "--no-compiled"]
            )
        )
        == bench.EXIT_OK
    )
    out = capsys.readouterr().out
    assert "casadi map" in out and "vs numpy" in out


def test_bench_is_wired_into_the_cli(capsys):
    from optikin.cli import build_parser, main

    try:
        build_parser().parse_args(["bench", "--samples", "1"])
    except SystemExit:
        pytest.skip("optikin bench is not wired into optikin.cli yet")
    assert main(["bench", *TINY, "--arm", "cc", "--no-compiled"]) == 0
    assert json.loads(capsys.readouterr().out)["ok"]


# --------------------------------------------------------------------------- the backends the bench measures


@pytest.fixture(scope="module")
def arm():
    return ConstantCurvatureArm()


def reference(f, Q):
    """The plain DM route: ``f.map(N)`` on ``Q.T``, reshaped to ``(N, rows, cols)``."""
    rows, cols = f.size_out(0)
    out = np.asarray(f.map(Q.shape[0])(Q.T))
    return out.reshape(rows, cols, Q.shape[0], order="F").transpose(2, 0, 1)


@pytest.mark.parametrize("backend", [MapEvaluator, CallEvaluator, CompiledEvaluator])
def test_backends_equal_plain_map_bit_for_bit(arm, backend):
    evaluator = backend(SolverSpec(name="t", backend="x"))
    Q = arm.sample_configurations(37, np.random.default_rng(5))
    Q[0] = arm.straight_configuration()  # the series branch
    names = FUNCTION_NAMES if backend is not CompiledEvaluator else ("fk_dq", "jac_dq")  # jac_dq: sparse output
    for name in names:
        f = arm.function(name)
        out = evaluator.evaluate(arm, name, Q)
        np.testing.assert_array_equal(out, reference(f, Q), err_msg=name)
        assert evaluator.evaluate(arm, name, Q[:0]).shape == (0, *f.size_out(0))


def test_batch_chunks_and_remainders(arm):
    f = arm.function("jac_dq")  # sparse output: scattered into the dense block
    runner = BatchFunction(f, chunk=7, max_sizes=3)
    for n in (1, 6, 7, 8, 14, 15, 30, 3, 30):
        Q = arm.sample_configurations(n, np.random.default_rng(n))
        np.testing.assert_array_equal(runner(Q), reference(f, Q), err_msg=str(n))
    assert len(runner._maps) <= 3 and 7 in runner._maps


def test_batch_evaluate_accepts_views_and_rejects_wrong_shapes(arm):
    Q = arm.sample_configurations(10, np.random.default_rng(1))
    f = arm.fk_dq
    np.testing.assert_array_equal(batch_evaluate(f, np.asfortranarray(Q)), reference(f, Q))
    np.testing.assert_array_equal(batch_evaluate(f, Q[::2]), reference(f, Q[::2]))
    np.testing.assert_array_equal(batch_evaluate(f, Q.astype(np.float32)), reference(f, Q.astype(np.float32)))
    with pytest.raises(ValueError, match="shape"):
        batch_evaluate(f, Q[:, :5])
