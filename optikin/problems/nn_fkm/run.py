"""``nn_fkm``: train (or load) the forward networks of every variant and solve the same arms exactly."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optikin.baselines.nn_models import TrainingSetting, forward_tasks, hybrid_forward_configurations
from optikin.ik.platform import linearised_start, platform_problems, solve_platforms
from optikin.problems import ProblemContext
from optikin.problems.nn_shared import (
    PLATFORM_TOLERANCE,
    NetworkRun,
    Prepared,
    SolverRun,
    latency,
    obtain_models,
    prepare,
    time_network,
    timed,
)
from optikin.solvers import build_preset
from optikin.solvers.base import SolutionBatch
from optikin.solvers.nonlinear import LeastSquaresProblem


@dataclass
class PlatformSolverRun(SolverRun):
    """A solver preset on eqs. (7)-(9) of every platform, with its one-sample latency [s]."""

    latency: float


@dataclass
class FKMOutcome:
    """The networks and the exact solvers of ``nn_fkm`` on the test split.

    Attributes
    ----------
    prep:
        The checked inputs and the database.
    networks, solvers:
        One run per variant, and per baseline (on the first ``exact_samples`` test arms).
    exact_samples:
        Test arms given to the exact solvers.
    """

    prep: Prepared
    networks: list[NetworkRun]
    solvers: list[PlatformSolverRun]
    exact_samples: int

    @property
    def test(self) -> np.ndarray:
        """Row indices of the test split."""
        return self.prep.db.test


def run_network(ctx: ProblemContext, prep: Prepared, setting: TrainingSetting) -> NetworkRun:
    """The forward networks of ``setting`` (Fig. 9): configurations from the test arms' legs, tips by eq. (5)."""
    arm, db = prep.arm, prep.db
    legs, truth_tip = db.leg_lengths[db.test], db.tip[db.test]
    models, trained = obtain_models(
        ctx.progress, db, forward_tasks(db), setting, 0.0, prep.options.store, f"fkm-{setting.name}"
    )

    def hybrid(L: np.ndarray) -> np.ndarray:
        return arm.evaluate("fk_position", hybrid_forward_configurations(models, L))

    Q = hybrid_forward_configurations(models, legs)
    tip = arm.evaluate("fk_position", Q)
    batch, one = time_network(hybrid, legs, prep.options.latency_repeats)
    return NetworkRun(
        setting,
        models,
        trained,
        np.linalg.norm(tip - truth_tip, axis=1),
        batch,
        one,
        {f"tip_{setting.name}": tip, f"configurations_{setting.name}": Q},
    )


def run_solver(prep: Prepared, name: str, problems: list[LeastSquaresProblem], k: int) -> PlatformSolverRun:
    """Solver preset ``name`` on every platform of the first ``k`` test arms, from the linearised start."""
    arm, db = prep.arm, prep.db
    legs, truth_tip = db.leg_lengths[db.test], db.tip[db.test]
    adapter = build_preset(name)

    def solve(L: np.ndarray) -> SolutionBatch:
        return solve_platforms(adapter, problems, L, linearised_start(arm, L))

    solve(legs[:1])  # build (and compile) before the clock starts
    report, seconds = timed(lambda: solve(legs[:k]))
    tip = arm.evaluate("fk_position", report.x)
    return PlatformSolverRun(
        name,
        report,
        np.linalg.norm(tip - truth_tip[:k], axis=1),
        seconds,
        {f"tip_{name}": tip},
        latency(solve, legs, prep.options.latency_repeats),
    )


def run(ctx: ProblemContext) -> FKMOutcome:
    """Every variant's networks, then every baseline, on the test split of the ``data`` database."""
    prep = prepare(ctx)
    networks = [run_network(ctx, prep, setting) for setting in prep.options.settings()]
    k = min(len(prep.db.test), prep.options.exact_samples)
    problems = platform_problems(prep.arm, PLATFORM_TOLERANCE)
    solvers = [run_solver(prep, name, problems, k) for name in ctx.spec.baselines]
    return FKMOutcome(prep, networks, solvers, k)
