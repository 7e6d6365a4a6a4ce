"""``nn_ikm``: train (or load) NN1-NN4 of every variant and solve the same tips exactly; realise every answer."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optikin.baselines.nn_models import TrainingSetting, hybrid_inverse_configurations, inverse_tasks
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.platform import Realised, platform_problems, realise
from optikin.problems import ProblemContext
from optikin.problems.nn_shared import (
    PLATFORM_TOLERANCE,
    REALISER,
    TIP_TOLERANCE,
    NetworkRun,
    Prepared,
    SolverRun,
    obtain_models,
    prepare,
    time_network,
    timed,
)
from optikin.solvers import build_preset
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter


@dataclass
class InverseNetworkRun(NetworkRun):
    """A variant's networks with the realised lengths and the unclipped tip errors [m] of its poses."""

    realised: Realised
    unclipped: np.ndarray


@dataclass
class TipSolverRun(SolverRun):
    """A solver preset on the tip-position IK, with its realised lengths."""

    realised: Realised


@dataclass
class IKMOutcome:
    """The networks and the exact solvers of ``nn_ikm`` on the test split.

    Attributes
    ----------
    prep:
        The checked inputs and the database.
    networks, solvers:
        One run per variant, and per baseline (on the first ``exact_samples`` test tips).
    exact_samples:
        Test tips given to the exact solvers.
    formulation:
        The tip-position IK the solvers solve.
    """

    prep: Prepared
    networks: list[InverseNetworkRun]
    solvers: list[TipSolverRun]
    exact_samples: int
    formulation: Formulation

    @property
    def test(self) -> np.ndarray:
        """Row indices of the test split."""
        return self.prep.db.test


@dataclass
class Realiser:
    """The platform problems and the adapter that realise commanded leg lengths (:func:`realise`)."""

    problems: list[LeastSquaresProblem]
    adapter: NonlinearAdapter


def run_network(ctx: ProblemContext, prep: Prepared, setting: TrainingSetting, realiser: Realiser) -> InverseNetworkRun:
    """NN1-NN4 of ``setting`` (Fig. 10) on the test tips, their lengths realised."""
    arm, db, o = prep.arm, prep.db, prep.options
    targets = db.tip[db.test]
    models, trained = obtain_models(
        ctx.progress, db, inverse_tasks(db), setting, o.penalty, o.store, f"ikm-{setting.name}"
    )

    def hybrid(P: np.ndarray) -> np.ndarray:
        return arm.evaluate("leg_lengths", hybrid_inverse_configurations(models, P))

    Q = hybrid_inverse_configurations(models, targets)
    realised = realise(arm, Q, realiser.adapter, realiser.problems)
    unclipped = np.linalg.norm(arm.evaluate("fk_position", Q) - targets, axis=1)
    batch, one = time_network(hybrid, targets, o.latency_repeats)
    s = setting.name
    arrays = {
        f"tip_{s}": realised.tip,
        f"leg_lengths_{s}": realised.commanded,
        f"predicted_{s}": Q,
        f"configurations_{s}": realised.configurations,
    }
    return InverseNetworkRun(
        setting,
        models,
        trained,
        np.linalg.norm(realised.tip - targets, axis=1),
        batch,
        one,
        arrays,
        realised,
        unclipped,
    )


def tip_formulation(prep: Prepared) -> Formulation:
    """The tip-position IK for the admissible configuration nearest the straight mid-range pose."""
    arm = prep.arm
    return Formulation(
        target="position",
        redundancy="rest",
        rest=rest_configuration(arm),
        weights=1.0 / (arm.upper - arm.lower),
        tolerance=TIP_TOLERANCE,
    )


def run_solver(
    prep: Prepared, name: str, problem: LeastSquaresProblem, start: np.ndarray, k: int, realiser: Realiser
) -> TipSolverRun:
    """Solver preset ``name`` on ``problem`` for the first ``k`` test tips from ``start``, its answers realised."""
    arm, targets = prep.arm, prep.db.tip[prep.db.test]
    adapter = build_preset(name)
    adapter.solve(problem, start, targets[0])  # build before the clock starts
    report, seconds = timed(lambda: adapter.solve_many(problem, start, targets[:k]))
    realised = realise(arm, report.x, realiser.adapter, realiser.problems)
    return TipSolverRun(
        name,
        report,
        np.linalg.norm(realised.tip - targets[:k], axis=1),
        seconds,
        {f"tip_{name}": realised.tip, f"configurations_{name}": realised.configurations},
        realised,
    )


def run(ctx: ProblemContext) -> IKMOutcome:
    """Every variant's networks, then every baseline, on the test tips of the ``data`` database."""
    prep = prepare(ctx)
    realiser = Realiser(platform_problems(prep.arm, PLATFORM_TOLERANCE), build_preset(REALISER))
    networks = [run_network(ctx, prep, setting, realiser) for setting in prep.options.settings()]
    k = min(len(prep.db.test), prep.options.exact_samples)
    formulation = tip_formulation(prep)
    problem = build_problem(prep.arm, formulation)
    assert isinstance(problem, LeastSquaresProblem)  # one problem: the tip IK is not split by platform
    solvers = [run_solver(prep, name, problem, formulation.rest, k, realiser) for name in ctx.spec.baselines]
    return IKMOutcome(prep, networks, solvers, k, formulation)
