"""Inverse-kinematics solve time per backend, warm-started along a trajectory, and batched throughput.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_ik_timing.py --benchmark-only

Targets: two-section CC tip-position IK under 100 us per warm-started
solve from Python, and a batched path of at least 20,000 solves per second, both
against scipy ``least_squares`` measured in the same session.

* ``warm`` groups: one round solves every target of a 10 s, 100 Hz smooth
  trajectory (the targets of ``problems/cc-ik-trajectory.yaml``) in order, each from
  the previous solution. scipy ``lm`` runs first in each group; ``extra_info`` holds
  the median time per solve (round median / targets), the success count and the
  speed-up over scipy ``lm``.
* ``batched`` group: independent random reachable targets, cold-started from the
  home configuration, Gauss-Newton over all of them at once (CasADi VM and
  compiled C), against a Python loop of scipy ``lm`` over a tenth of them.
* ``cbha`` groups (seed 004): the 16 platforms of 200 random admissible postures
  from their leg lengths (eqs. (7)-(9)), and the whole CBHA's tip position -> 48
  variables closest to rest with every leg within Table I, cold-started from rest
  (scipy ``lm`` first; IPOPT on a quarter of the targets).
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms import ConstantCurvatureArm
from optikin.arms.cbha import CBHAArm
from optikin.data.configurations import TrajectoryParams, smooth_motion
from optikin.ik.formulation import Formulation, build_problem, rest_configuration, tip_residual
from optikin.ik.platform import platform_problems, solve_platforms
from optikin.solvers import load_backends, preset_of
from optikin.solvers.nonlinear import LeastSquaresProblem
from optikin.spec import load_solver

load_backends()
HOME = np.array([0.18, 0.6, 0.0, 0.18, 0.6, np.pi / 2])
TRAJECTORY_SAMPLES, BATCH = 1000, 20_000
WARM = ("lm", "gauss-newton", "gauss-newton-compiled", "newton", "sqpmethod", "ipopt", "trf")
ROUNDS = {"lm": 3, "gauss-newton": 7, "gauss-newton-compiled": 7, "newton": 5, "sqpmethod": 3, "ipopt": 1, "trf": 1}
_lm_per_solve: dict[str, float] = {}


def adapter(preset_name: str):
    preset, _ = load_solver(preset_name)
    return preset_of(preset).build()


@pytest.fixture(scope="module")
def arm():
    return ConstantCurvatureArm()


def problem_of(arm, target: str) -> LeastSquaresProblem:
    return LeastSquaresProblem(
        tip_residual(arm, target, 0.396),
        arm.lower,
        arm.upper,
        arm.periodic,
        tolerance=1e-10,
        weights=1.0 / (arm.upper - arm.lower),
        name=f"timing_{target}",
        variable_names=arm.config_names,
    )


@pytest.fixture(scope="module", params=["position", "pose"])
def trajectory(request, arm):
    Q, _ = smooth_motion(arm, TRAJECTORY_SAMPLES, 2020, TrajectoryParams())
    name = "fk_position" if request.param == "position" else "fk_dq"
    return request.param, problem_of(arm, request.param), Q, arm.evaluate(name, Q)


@pytest.mark.parametrize("preset", WARM)
def test_warm_started_trajectory(benchmark, trajectory, preset):
    target, problem, Q, P = trajectory
    solver = adapter(preset)
    solver.solve_many(problem, Q[0], P[:3], warm_start=True)  # build (and compile) outside the timing

    def run():
        return solver.solve_many(problem, Q[0], P, warm_start=True)

    benchmark.group = f"ik warm-started, {target}, {len(P)} targets per round"
    report = benchmark.pedantic(run, rounds=ROUNDS[preset], warmup_rounds=0, iterations=1)
    per_solve = benchmark.stats.stats.median / len(P)
    ok = report.status.count("ok")
    benchmark.extra_info.update(
        {
            "median per solve [us]": round(per_solve * 1e6, 1),
            "solved": f"{ok}/{len(P)}",
            "median iterations": float(np.median(report.iterations)),
        }
    )
    if preset == "lm":
        _lm_per_solve[target] = per_solve
    elif target in _lm_per_solve:
        benchmark.extra_info["speed-up vs scipy lm"] = round(_lm_per_solve[target] / per_solve, 1)
    if preset.startswith("gauss-newton"):
        assert ok == len(P)


@pytest.fixture(scope="module")
def independent(arm):
    Q = arm.sample_configurations(BATCH, np.random.default_rng(7))
    return problem_of(arm, "position"), arm.evaluate("fk_position", Q)


@pytest.mark.parametrize("preset", ["lm", "gauss-newton", "gauss-newton-compiled"])
def test_batched_throughput(benchmark, independent, preset):
    problem, P = independent
    if preset == "lm":
        P = P[: BATCH // 10]
    solver = adapter(preset)
    solver.solve_many(problem, HOME, P[:10])

    def run():
        return solver.solve_many(problem, HOME, P)

    benchmark.group = "ik independent targets, position, cold start"
    report = benchmark.pedantic(run, rounds=3 if preset == "lm" else 5, warmup_rounds=0, iterations=1)
    rate = len(P) / benchmark.stats.stats.median
    benchmark.extra_info.update(
        {
            "targets": len(P),
            "solves per second": round(rate),
            "solved": f"{report.status.count('ok')}/{len(P)}",
            "batched": report.batched,
        }
    )
    if preset == "lm":
        _lm_per_solve["batch"] = 1.0 / rate
    elif "batch" in _lm_per_solve:
        benchmark.extra_info["speed-up vs scipy lm loop"] = round(rate * _lm_per_solve["batch"], 1)
    assert report.status.count("ok") >= 0.999 * len(P)


CBHA_TARGETS = 200


@pytest.fixture(scope="module")
def cbha():
    arm = CBHAArm()
    Q = arm.sample_configurations(CBHA_TARGETS, np.random.default_rng(5))
    rest = rest_configuration(arm)
    tip = build_problem(arm, Formulation("position", "rest", rest, 1.0 / (arm.upper - arm.lower), 1e-10))
    return arm, rest, tip, arm.evaluate("fk_position", Q), arm.evaluate("leg_lengths", Q).reshape(len(Q), -1)


@pytest.mark.parametrize("preset", ["lm", "gauss-newton", "gauss-newton-compiled"])
def test_cbha_platforms(benchmark, cbha, preset):
    arm, rest, _, _, legs = cbha
    problems, solver = platform_problems(arm, 1e-12), adapter(preset)
    solve_platforms(solver, problems, legs[:2], rest)

    def run():
        return solve_platforms(solver, problems, legs, rest)

    benchmark.group = f"ik cbha platforms (16 per posture), {len(legs)} postures"
    report = benchmark.pedantic(run, rounds=3, warmup_rounds=0, iterations=1)
    per_posture = benchmark.stats.stats.median / len(legs)
    benchmark.extra_info.update(
        {
            "median per posture [us]": round(per_posture * 1e6, 1),
            "solved": f"{report.status.count('ok')}/{len(legs)}",
            "batched": report.batched,
        }
    )
    if preset == "lm":
        _lm_per_solve["cbha platforms"] = per_posture
    elif "cbha platforms" in _lm_per_solve:
        benchmark.extra_info["speed-up vs scipy lm"] = round(_lm_per_solve["cbha platforms"] / per_posture, 1)
    assert report.status.count("ok") == len(legs)


@pytest.mark.parametrize("preset", ["lm", "gauss-newton", "ipopt"])
def test_cbha_tip(benchmark, cbha, preset):
    arm, rest, problem, tips, _ = cbha
    solver = adapter(preset)
    P = tips[: CBHA_TARGETS // 4] if preset == "ipopt" else tips
    solver.solve_many(problem, rest, P[:2], x_ref=rest)

    def run():
        return solver.solve_many(problem, rest, P, x_ref=rest)

    benchmark.group = "ik cbha tip position -> 48 variables, closest to rest, cold start"
    report = benchmark.pedantic(run, rounds=3 if preset != "ipopt" else 1, warmup_rounds=0, iterations=1)
    per_solve = benchmark.stats.stats.median / len(P)
    benchmark.extra_info.update(
        {
            "median per solve [us]": round(per_solve * 1e6, 1),
            "targets": len(P),
            "solved": f"{report.status.count('ok')}/{len(P)}",
            "batched": report.batched,
        }
    )
    if preset == "lm":
        _lm_per_solve["cbha tip"] = per_solve
    elif "cbha tip" in _lm_per_solve:
        benchmark.extra_info["speed-up vs scipy lm"] = round(_lm_per_solve["cbha tip"] / per_solve, 1)
