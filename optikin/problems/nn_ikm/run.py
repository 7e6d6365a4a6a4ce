"""``nn_ikm``: train (or load) NN1-NN4 of every variant and solve the same tips exactly; realise every answer.

With the ``cosserat`` source every method's leg lengths are also summed into the six tube
lengths (seed 004 section V) and driven on the Cosserat arm as in the seed's Fig. 14: a
length-pressure controller (an MLP from six tube lengths to six pressures trained on the
Cosserat training postures, :func:`~optikin.baselines.nn_models.direct_tasks`) gives the
pressures, clipped to the arm's range, and the arm's equilibrium gives the tip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optikin.baselines.nn_database import section_limits, section_tube_lengths
from optikin.baselines.nn_models import (
    GoalBabbling,
    TrainedModel,
    TrainingSetting,
    goal_babbling,
    hybrid_inverse_configurations,
    inverse_tasks,
)
from optikin.data.cosserat_nn import CosseratSensors, cosserat_postures
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
    constant_curvature_lengths,
    direct_model,
    obtain_models,
    prepare,
    section_tube_radii,
    time_network,
    timed,
)
from optikin.solvers import build_preset
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter


BABBLING_NOISE = 0.3
"""Exploratory perturbation of goal babbling, relative to the mid-range pressure."""


@dataclass
class Driven:
    """Tube lengths driven on the Cosserat arm through the length-pressure controller.

    Attributes
    ----------
    tube_lengths:
        ``(n, sections, 3)`` commanded [m].
    tube_errors:
        ``(n,)`` RMS over the six of ``commanded - true`` [m].
    pressures:
        ``(n, sections, 3)`` applied [Pa] (clipped to the arm's range).
    tip:
        ``(n, 3)`` the arm's tips [m]; not finite for lengths that are not.
    errors:
        ``(n,)`` distance to the target tips [m].
    """

    tube_lengths: np.ndarray
    tube_errors: np.ndarray
    pressures: np.ndarray
    tip: np.ndarray
    errors: np.ndarray


@dataclass
class InverseNetworkRun(NetworkRun):
    """A variant's networks with the realised lengths, the unclipped tip errors [m] of its poses and, on the
    Cosserat postures, their lengths driven on the arm (its ``errors`` are then the driven tip errors)."""

    realised: Realised
    unclipped: np.ndarray
    driven: Driven | None


@dataclass
class TipSolverRun(SolverRun):
    """A solver preset on the tip-position IK, with its realised lengths (and, on the Cosserat postures,
    driven on the arm)."""

    realised: Realised
    driven: Driven | None


@dataclass
class IKMOutcome:
    """The networks and the exact solvers of ``nn_ikm`` on the test tips.

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
    controller:
        The length-pressure controller (Cosserat postures only).
    floor:
        The true tube lengths driven through the controller: the error the controller alone makes.
    direct, direct_model:
        Seed 004 Table IV's qualitative IKM (Melingui et al.; tip -> six tube lengths, trained on the
        Cosserat training postures) driven on the arm, and its model.
    geometric:
        Seed 004 Table IV's quantitative IKM (Mahl et al.; constant-curvature sections,
        :func:`~optikin.problems.nn_shared.constant_curvature_lengths`) driven on the arm.
    babbling, babbled:
        Seed 004 Table IV's goal-babbling IKM (Rolf et al.; tip -> six pressures learned on the arm,
        :func:`~optikin.baselines.nn_models.goal_babbling`) executed on the arm, and its model.
    """

    prep: Prepared
    networks: list[InverseNetworkRun]
    solvers: list[TipSolverRun]
    exact_samples: int
    formulation: Formulation
    controller: TrainedModel | None = None
    floor: Driven | None = None
    direct: Driven | None = None
    direct_model: TrainedModel | None = None
    geometric: Driven | None = None
    babbling: Driven | None = None
    babbled: GoalBabbling | None = None

    @property
    def test(self) -> np.ndarray:
        """Indices of the test postures (of the Cosserat postures with the ``cosserat`` source)."""
        return self.prep.truth.test if self.prep.truth is not None else self.prep.db.test

    @property
    def targets(self) -> np.ndarray:
        """``(n, 3)`` test tips [m]."""
        return target_tips(self.prep)


@dataclass
class Realiser:
    """The platform problems and the adapter that realise commanded leg lengths (:func:`realise`)."""

    problems: list[LeastSquaresProblem]
    adapter: NonlinearAdapter


def target_tips(prep: Prepared) -> np.ndarray:
    """``(n, 3)`` test tips [m]: of the Cosserat postures, or of the database's test arms."""
    if prep.truth is not None:
        return prep.truth.tip[prep.truth.test]
    return prep.db.tip[prep.db.test]


def drive(prep: Prepared, controller: TrainedModel | None, tube_lengths: np.ndarray) -> Driven | None:
    """``tube_lengths`` ``(n, sections, 3)`` [m] for the first ``n`` test postures driven on the Cosserat arm
    (module docstring); ``None`` without Cosserat postures."""
    truth = prep.truth
    if truth is None or controller is None:
        return None
    n = len(tube_lengths)
    true = truth.tube_lengths[truth.test[:n]]
    low, high = truth.params.rod.pressure_range
    finite = np.all(np.isfinite(tube_lengths.reshape(n, -1)), axis=1)
    pressures = np.full(tube_lengths.shape, np.nan)
    tip = np.full((n, 3), np.nan)
    if finite.any():
        pressures[finite] = np.clip(controller.predict(tube_lengths[finite].reshape(-1, 6)), low, high).reshape(
            -1, *tube_lengths.shape[1:]
        )
        tip[finite] = cosserat_postures(truth.params.rod, pressures[finite], "controller pressures")["tip"]
    return Driven(
        tube_lengths=tube_lengths,
        tube_errors=np.sqrt(np.mean((tube_lengths - true).reshape(n, -1) ** 2, axis=1)),
        pressures=pressures,
        tip=tip,
        errors=np.linalg.norm(tip - target_tips(prep)[:n], axis=1),
    )


def babble(prep: Prepared) -> tuple[Driven, GoalBabbling]:
    """Goal babbling on the Cosserat arm towards its training tips from the mid-range pressures, then its
    pressures for the test tips executed (module docstring of :func:`~optikin.baselines.nn_models.goal_babbling`)."""
    truth = prep.truth
    assert truth is not None
    rod = truth.params.rod
    sensors = CosseratSensors(rod)
    low, high = rod.pressure_range
    shape = truth.pressures.shape[1:]

    def execute(p: np.ndarray) -> np.ndarray:
        return sensors(np.clip(p, low, high).reshape(1, *shape), "goal babbling")["tip"][0]

    steps = prep.options.goal_babbling // (4 if prep.options.setting == "small" else 1)
    home = np.full(int(np.prod(shape)), 0.5 * (low + high))
    rng = np.random.default_rng([truth.seed, 3])
    model = goal_babbling(execute, home, truth.tip[truth.train], rng, steps, noise=BABBLING_NOISE)
    targets = target_tips(prep)
    pressures = np.clip(model.predict(targets), low, high).reshape(len(targets), *shape)
    reached = sensors(pressures, "goal babbling")
    true = truth.tube_lengths[truth.test]
    driven = Driven(
        tube_lengths=reached["tube_lengths"],
        tube_errors=np.sqrt(np.mean((reached["tube_lengths"] - true).reshape(len(true), -1) ** 2, axis=1)),
        pressures=pressures,
        tip=reached["tip"],
        errors=np.linalg.norm(reached["tip"] - targets, axis=1),
    )
    return driven, model


def run_network(
    ctx: ProblemContext, prep: Prepared, setting: TrainingSetting, realiser: Realiser, controller: TrainedModel | None
) -> InverseNetworkRun:
    """NN1-NN4 of ``setting`` (Fig. 10) on the test tips, their lengths realised (and driven)."""
    arm, db, o = prep.arm, prep.db, prep.options
    targets = target_tips(prep)
    models, trained = obtain_models(
        ctx.progress, db, inverse_tasks(db), setting, o.penalty, o.store, f"ikm-{setting.name}"
    )

    def hybrid(P: np.ndarray) -> np.ndarray:
        return arm.evaluate("leg_lengths", hybrid_inverse_configurations(models, P), check=False)

    Q = hybrid_inverse_configurations(models, targets)
    realised = realise(arm, Q, realiser.adapter, realiser.problems)
    # the networks' configurations as predicted, however far they extrapolate: not checked for plausibility
    unclipped = np.linalg.norm(arm.evaluate("fk_position", Q, check=False) - targets, axis=1)
    driven = drive(prep, controller, section_tube_lengths(db.geometry, realised.commanded))
    batch, one = time_network(hybrid, targets, o.latency_repeats)
    s = setting.name
    arrays = {
        f"tip_{s}": realised.tip if driven is None else driven.tip,
        f"leg_lengths_{s}": realised.commanded,
        f"predicted_{s}": Q,
        f"configurations_{s}": realised.configurations,
    }
    errors = np.linalg.norm(realised.tip - targets, axis=1) if driven is None else driven.errors
    return InverseNetworkRun(setting, models, trained, errors, batch, one, arrays, "", realised, unclipped, driven)


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
    prep: Prepared,
    name: str,
    problem: LeastSquaresProblem,
    start: np.ndarray,
    k: int,
    realiser: Realiser,
    controller: TrainedModel | None,
) -> TipSolverRun:
    """Solver preset ``name`` on ``problem`` for the first ``k`` test tips from ``start``, its answers realised."""
    arm, targets = prep.arm, target_tips(prep)
    adapter = build_preset(name)
    adapter.solve(problem, start, targets[0])  # build before the clock starts
    report, seconds = timed(lambda: adapter.solve_many(problem, start, targets[:k]))
    realised = realise(arm, report.x, realiser.adapter, realiser.problems)
    driven = drive(prep, controller, section_tube_lengths(prep.db.geometry, realised.commanded))
    errors = np.linalg.norm(realised.tip - targets[:k], axis=1) if driven is None else driven.errors
    return TipSolverRun(
        name,
        report,
        errors,
        seconds,
        {
            f"tip_{name}": realised.tip if driven is None else driven.tip,
            f"configurations_{name}": realised.configurations,
        },
        realised,
        driven,
    )


def run(ctx: ProblemContext) -> IKMOutcome:
    """Every variant's networks, then every baseline, on the test tips of the ``data`` database."""
    prep = prepare(ctx)
    truth, o = prep.truth, prep.options
    controller = direct_model(prep, "controller") if truth is not None else None
    realiser = Realiser(platform_problems(prep.arm, PLATFORM_TOLERANCE), build_preset(REALISER))
    networks = [run_network(ctx, prep, setting, realiser, controller) for setting in o.settings()]
    k = min(len(target_tips(prep)), o.exact_samples)
    formulation = tip_formulation(prep)
    problem = build_problem(prep.arm, formulation)
    assert isinstance(problem, LeastSquaresProblem)  # one problem: the tip IK is not split by platform
    solvers = [
        run_solver(prep, name, problem, formulation.rest, k, realiser, controller) for name in ctx.spec.baselines
    ]
    outcome = IKMOutcome(prep, networks, solvers, k, formulation, controller)
    if truth is not None:
        outcome.floor = drive(prep, controller, truth.tube_lengths[truth.test])
        lower, upper = section_limits(prep.arm.geometry)
        lengths = constant_curvature_lengths(target_tips(prep), section_tube_radii(prep.arm), lower, upper)
        outcome.geometric = drive(prep, controller, lengths)
        if o.goal_babbling:
            outcome.babbling, outcome.babbled = babble(prep)
        if o.direct:
            model = direct_model(prep, "direct_ikm")
            lengths = model.predict(target_tips(prep)).reshape(len(truth.test), -1, 3)
            outcome.direct, outcome.direct_model = drive(prep, controller, lengths), model
    return outcome
