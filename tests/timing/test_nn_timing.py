"""Time per sample of the seed 004 networks against the exact solvers, on the same held-out arms.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_nn_timing.py --benchmark-only

Time per sample depends on the width, not on how well a network is trained, so the
networks here have the seed's width (18 neurons, Tables II-III) and a short Adam
training on a 400,000-draw database. Training time is measured by the command in
BENCHMARKS.md, not here.

* ``nn fkm`` group: leg lengths of ``N_FKM`` held-out arms -> tip. ``mlp`` = both section
  networks + the exact chain of eq. (5) (Fig. 9); ``newton`` = CasADi Newton on eqs.
  (7)-(9) for all 16 x N platforms in one mapped call + the same chain; ``least_squares``
  = scipy Levenberg-Marquardt, one call per arm, on ``N_SCIPY`` arms.
* ``nn ikm`` group: held-out tips -> leg lengths. ``mlp`` = NN1-NN4 + eqs. (7)-(9)
  (Fig. 10); ``ipopt`` and ``least_squares``, one call per tip, on fewer tips.
* ``one sample`` group: a single arm / tip per call, as a controller would call it.

``extra_info`` holds the median time per sample; the Newton and IPOPT rows also the
speed-up of the network over them (a value above 1: the network is faster).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from optikin.arms.cbha import CBHAGeometry
from optikin.baselines import nn_exact
from optikin.baselines.nn_database import DatabaseSpec, build_database
from optikin.baselines.nn_models import (
    SETTINGS, forward_tasks, hybrid_forward_configurations, hybrid_inverse_configurations, inverse_tasks,
    train_model)

N_FKM, N_SCIPY, N_IPOPT = 500, 20, 20
_per_sample: dict[str, float] = {}


@pytest.fixture(scope="module")
def trained():
    db = build_database(CBHAGeometry(), DatabaseSpec(candidates=400_000, seed=2016))
    setting = dataclasses.replace(SETTINGS["adam"], neurons=(18,), max_epochs=40, patience=10)
    forward = [train_model(t, db, setting) for t in forward_tasks(db)]
    inverse = [train_model(t, db, setting, penalty=1e-3) for t in inverse_tasks(db)]
    return db, forward, inverse, nn_exact.PlatformNewton(db.arm)


def record(benchmark, key: str, samples: int, reference: str | None = None) -> None:
    per_sample = benchmark.stats.stats.median / samples
    _per_sample[key] = per_sample
    benchmark.extra_info["median per sample [us]"] = round(per_sample * 1e6, 2)
    if reference in _per_sample:
        benchmark.extra_info[f"mlp speed-up over {key}"] = round(per_sample / _per_sample[reference], 1)


@pytest.mark.parametrize("method", ["mlp", "newton", "least_squares"])
def test_forward(benchmark, trained, method):
    db, forward, _, newton = trained
    arm = db.arm
    legs = db.leg_lengths[db.test][:N_FKM]
    if method == "mlp":
        def run(L=legs):
            return arm.evaluate("fk_position", hybrid_forward_configurations(forward, L))
    elif method == "newton":
        def run(L=legs):
            return arm.evaluate("fk_position", newton.solve(L)[0])
    else:
        legs = legs[:N_SCIPY]

        def run(L=legs):
            return arm.evaluate("fk_position", nn_exact.platform_least_squares(arm, L)[0])
    run(legs[:1])
    benchmark.group = f"nn fkm: leg lengths -> tip, {N_FKM} held-out arms (scipy: {N_SCIPY})"
    tip = benchmark.pedantic(run, rounds=3 if method == "least_squares" else 9, warmup_rounds=1, iterations=1)
    benchmark.extra_info["max tip error [mm]"] = float(1e3 * np.abs(tip - db.tip[db.test][:len(legs)]).max())
    record(benchmark, f"fkm {method}", len(legs), None if method == "mlp" else "fkm mlp")


@pytest.mark.parametrize("method", ["mlp", "ipopt", "least_squares"])
def test_inverse(benchmark, trained, method):
    db, _, inverse, _ = trained
    arm = db.arm
    tips = db.tip[db.test][:N_FKM]
    if method == "mlp":
        def run(P=tips):
            return arm.evaluate("leg_lengths", hybrid_inverse_configurations(inverse, P))
    elif method == "ipopt":
        tips, solver = tips[:N_IPOPT], nn_exact.TipIpopt(arm)

        def run(P=tips):
            return arm.evaluate("leg_lengths", solver.solve(P).configurations)
    else:
        tips = tips[:N_SCIPY // 4]

        def run(P=tips):
            return arm.evaluate("leg_lengths", nn_exact.tip_least_squares(arm, P).configurations)
    run(tips[:1])
    benchmark.group = f"nn ikm: tip -> leg lengths, {N_FKM} held-out tips (ipopt: {N_IPOPT}, scipy: {N_SCIPY // 4})"
    benchmark.pedantic(run, rounds=1 if method != "mlp" else 9, warmup_rounds=0, iterations=1)
    record(benchmark, f"ikm {method}", len(tips), None if method == "mlp" else "ikm mlp")


@pytest.mark.parametrize("method", ["fkm mlp", "fkm newton", "ikm mlp", "ikm ipopt"])
def test_one_sample(benchmark, trained, method):
    db, forward, inverse, newton = trained
    arm = db.arm
    legs, tip = db.leg_lengths[db.test][:1], db.tip[db.test][:1]
    ipopt = nn_exact.TipIpopt(arm)
    run = {
        "fkm mlp": lambda: arm.evaluate("fk_position", hybrid_forward_configurations(forward, legs)),
        "fkm newton": lambda: arm.evaluate("fk_position", newton.solve(legs)[0]),
        "ikm mlp": lambda: arm.evaluate("leg_lengths", hybrid_inverse_configurations(inverse, tip)),
        "ikm ipopt": lambda: arm.evaluate("leg_lengths", ipopt.solve(tip).configurations),
    }[method]
    run()
    benchmark.group = "nn: one sample per call"
    benchmark.pedantic(run, rounds=50 if "ipopt" not in method else 10, warmup_rounds=2, iterations=1)
    reference = {"fkm newton": "one fkm mlp", "ikm ipopt": "one ikm mlp"}.get(method)
    record(benchmark, f"one {method}", 1, reference)
