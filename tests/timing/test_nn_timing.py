"""Time per sample of the seed 004 networks against the exact solvers, on the same held-out arms.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_nn_timing.py --benchmark-only

Time per sample depends on the width, not on how well a network is trained, so the
networks here have the seed's width (18 neurons, Tables II-III) and a short Adam
training on a 400,000-draw database. Training time is measured by the command in
BENCHMARKS.md, not here.

The exact methods are the inverse-kinematics solver presets (``solvers/*.yaml``) on
the problems of :mod:`optikin.ik.platform` and :mod:`optikin.ik.formulation`,
exactly as ``optikin solve cbha-nn-fkm`` / ``cbha-nn-ikm`` run them:

* ``nn fkm`` group: leg lengths of ``N_FKM`` held-out arms -> tip. ``mlp`` = both section
  networks + the exact chain of eq. (5) (Fig. 9); ``newton`` (CasADi rootfinder mapped over
  the samples, one call per platform) and ``gauss-newton`` (batched) on eqs. (7)-(9) from
  their linearisation + the same chain; ``lm`` = scipy Levenberg-Marquardt, one call per
  platform and arm, on ``N_SCIPY`` arms.
* ``nn ikm`` group: held-out tips -> leg lengths. ``mlp`` = NN1-NN4 + eqs. (7)-(9)
  (Fig. 10); ``ipopt``, ``sqpmethod`` (Table I imposed), ``gauss-newton`` and ``lm`` (bounds
  only) for the configuration nearest the straight mid-range pose, one solve per tip, on
  ``N_TIP`` tips.
* ``one sample`` group: a single arm / tip per call, as a controller would call it.

``extra_info`` holds the median time per sample and, for the exact rows, the speed-up of
the network over them (a value above 1: the network is faster).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from optikin.arms.cbha import CBHAGeometry
from optikin.baselines.nn_database import DatabaseSpec, build_database
from optikin.baselines.nn_models import (
    SETTINGS,
    forward_tasks,
    hybrid_forward_configurations,
    hybrid_inverse_configurations,
    inverse_tasks,
    train_model,
)
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.platform import linearised_start, platform_problems, solve_platforms
from optikin.problems.nn_shared import PLATFORM_TOLERANCE, TIP_TOLERANCE
from optikin.solvers import build_preset

N_FKM, N_SCIPY, N_TIP = 500, 20, 20
_per_sample: dict[str, float] = {}


@pytest.fixture(scope="module")
def trained():
    db = build_database(CBHAGeometry(), DatabaseSpec(candidates=400_000, seed=2016))
    setting = dataclasses.replace(SETTINGS["adam"], neurons=(18,), max_epochs=40, patience=10)
    forward = [train_model(t, db, setting) for t in forward_tasks(db)]
    inverse = [train_model(t, db, setting, penalty=1e-3) for t in inverse_tasks(db)]
    return db, forward, inverse


def platform_solver(db, preset: str):
    """Leg lengths ``(N, 48)`` -> tips, by the preset on every platform (as ``nn_fkm``)."""
    arm, adapter, problems = db.arm, build_preset(preset), platform_problems(db.arm, PLATFORM_TOLERANCE)
    return lambda L: arm.evaluate("fk_position", solve_platforms(adapter, problems, L, linearised_start(arm, L)).x)


def tip_solver(db, preset: str):
    """Tips ``(N, 3)`` -> leg lengths, by the preset from the rest pose (as ``nn_ikm``)."""
    arm, adapter = db.arm, build_preset(preset)
    formulation = Formulation(
        target="position",
        redundancy="rest",
        rest=rest_configuration(arm),
        weights=1.0 / (arm.upper - arm.lower),
        tolerance=TIP_TOLERANCE,
    )
    problem = build_problem(arm, formulation)
    return lambda P: arm.evaluate("leg_lengths", adapter.solve_many(problem, formulation.rest, P).x)


def record(benchmark, key: str, samples: int, reference: str | None = None) -> None:
    per_sample = benchmark.stats.stats.median / samples
    _per_sample[key] = per_sample
    benchmark.extra_info["median per sample [us]"] = round(per_sample * 1e6, 2)
    if reference in _per_sample:
        benchmark.extra_info[f"mlp speed-up over {key}"] = round(per_sample / _per_sample[reference], 1)


@pytest.mark.parametrize("method", ["mlp", "newton", "gauss-newton", "lm"])
def test_forward(benchmark, trained, method):
    db, forward, _ = trained
    arm = db.arm
    legs = db.leg_lengths[db.test][:N_FKM]
    if method == "mlp":

        def run(L=legs):
            return arm.evaluate("fk_position", hybrid_forward_configurations(forward, L))
    else:
        legs = legs[:N_SCIPY] if method == "lm" else legs
        solve = platform_solver(db, method)

        def run(L=legs):
            return solve(L)

    run(legs[:1])
    benchmark.group = f"nn fkm: leg lengths -> tip, {N_FKM} held-out arms (lm: {N_SCIPY})"
    tip = benchmark.pedantic(run, rounds=3 if method == "lm" else 9, warmup_rounds=1, iterations=1)
    benchmark.extra_info["max tip error [mm]"] = float(1e3 * np.abs(tip - db.tip[db.test][: len(legs)]).max())
    record(benchmark, f"fkm {method}", len(legs), None if method == "mlp" else "fkm mlp")


@pytest.mark.parametrize("method", ["mlp", "ipopt", "sqpmethod", "gauss-newton", "lm"])
def test_inverse(benchmark, trained, method):
    db, _, inverse = trained
    arm = db.arm
    tips = db.tip[db.test][:N_FKM]
    if method == "mlp":

        def run(P=tips):
            return arm.evaluate("leg_lengths", hybrid_inverse_configurations(inverse, P))
    else:
        tips, solve = tips[:N_TIP], tip_solver(db, method)

        def run(P=tips):
            return solve(P)

    run(tips[:1])
    benchmark.group = f"nn ikm: tip -> leg lengths, {N_FKM} held-out tips (exact solvers: {N_TIP})"
    benchmark.pedantic(run, rounds=1 if method != "mlp" else 9, warmup_rounds=0, iterations=1)
    record(benchmark, f"ikm {method}", len(tips), None if method == "mlp" else "ikm mlp")


@pytest.mark.parametrize("method", ["fkm mlp", "fkm newton", "ikm mlp", "ikm ipopt"])
def test_one_sample(benchmark, trained, method):
    db, forward, inverse = trained
    arm = db.arm
    legs, tip = db.leg_lengths[db.test][:1], db.tip[db.test][:1]
    if method == "fkm newton":
        newton = platform_solver(db, "newton")
    if method == "ikm ipopt":
        ipopt = tip_solver(db, "ipopt")
    run = {
        "fkm mlp": lambda: arm.evaluate("fk_position", hybrid_forward_configurations(forward, legs)),
        "fkm newton": lambda: newton(legs),
        "ikm mlp": lambda: arm.evaluate("leg_lengths", hybrid_inverse_configurations(inverse, tip)),
        "ikm ipopt": lambda: ipopt(tip),
    }[method]
    run()
    benchmark.group = "nn: one sample per call"
    benchmark.pedantic(run, rounds=50 if "ipopt" not in method else 10, warmup_rounds=2, iterations=1)
    reference = {"fkm newton": "one fkm mlp", "ikm ipopt": "one ikm mlp"}.get(method)
    record(benchmark, f"one {method}", 1, reference)
