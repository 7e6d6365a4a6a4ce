"""``nn_fkm``: train (or load) the forward networks of every variant and solve the same arms exactly."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from optikin.baselines.nn_database import split_tube_lengths
from optikin.baselines.nn_models import TrainedModel, TrainingSetting, forward_tasks, hybrid_forward_configurations
from optikin.ik.platform import linearised_start, platform_problems, solve_platforms
from optikin.problems import ProblemContext
from optikin.problems.nn_shared import (
    PLATFORM_TOLERANCE,
    NetworkRun,
    Prepared,
    SolverRun,
    constant_curvature_tips,
    direct_model,
    latency,
    obtain_models,
    prepare,
    section_tube_radii,
    time_network,
    timed,
)
from optikin.solvers import build_preset
from optikin.solvers.base import SolutionBatch
from optikin.solvers.nonlinear import LeastSquaresProblem

FIG9 = "-fig9"
"""Suffix of the rows whose legs come from the six tube lengths by the percentage split of Fig. 6."""


@dataclass
class PlatformSolverRun(SolverRun):
    """A solver preset on eqs. (7)-(9) of every platform, with its one-sample latency [s] and the
    platform variables of the database's arms it was given (``None`` when it was given split legs)."""

    latency: float
    truth_configurations: np.ndarray | None = None


@dataclass
class TableIVRun:
    """One of seed 004 Table IV's other FKM rows on the test postures: ``direct-mlp`` (the qualitative
    models of Melingui et al., an MLP from the six tube lengths to the tip trained on the Cosserat training
    postures) or ``constant-curvature`` (the quantitative model of Escande et al.,
    :func:`~optikin.problems.nn_shared.constant_curvature_tips`).

    Attributes
    ----------
    name:
        The row's method.
    tip, errors:
        ``(n, 3)`` tips and ``(n,)`` tip errors [m].
    seconds:
        Wall time of the whole test set [s].
    columns:
        The row's own columns.
    """

    name: str
    tip: np.ndarray
    errors: np.ndarray
    seconds: float
    columns: dict[str, Any]


@dataclass
class Inputs:
    """What every method is given on the test postures, and the truth it is scored on.

    Attributes
    ----------
    legs:
        ``(n, 48)`` leg lengths [m] (true, or split from the six tube lengths).
    tip:
        ``(n, 3)`` true tips [m].
    suffix:
        ``""`` for the true legs, :data:`FIG9` for split ones.
    configurations:
        ``(n, 48)`` true platform variables when the truth is the vertebra model and the legs are its own.
    """

    legs: np.ndarray
    tip: np.ndarray
    suffix: str
    configurations: np.ndarray | None = None


@dataclass
class FKMOutcome:
    """The networks and the exact solvers of ``nn_fkm`` on the test postures.

    Attributes
    ----------
    prep:
        The checked inputs and the database.
    networks, solvers:
        One run per variant and input, and per baseline and input (on the first ``exact_samples``
        test postures).
    exact_samples:
        Test postures given to the exact solvers.
    inputs:
        The inputs of the rows (true legs and / or Fig. 9's split legs).
    table_iv:
        Seed 004 Table IV's other FKM rows, from the six tube lengths.
    """

    prep: Prepared
    networks: list[NetworkRun]
    solvers: list[PlatformSolverRun]
    exact_samples: int
    inputs: list[Inputs]
    table_iv: list[TableIVRun]

    @property
    def test(self) -> np.ndarray:
        """Indices of the test postures (of the Cosserat postures with the ``cosserat`` source)."""
        return self.prep.truth.test if self.prep.truth is not None else self.prep.db.test


def test_inputs(prep: Prepared) -> list[Inputs]:
    """The inputs of the rows: the true legs of the database's test arms, and (``tube_sensors``) the legs
    Fig. 9 gets from their six tube lengths; only the latter on the Cosserat postures."""
    db, truth = prep.db, prep.truth
    if truth is not None:
        return [Inputs(split_tube_lengths(db.geometry, truth.tube_lengths[truth.test]), truth.tip[truth.test], FIG9)]
    out = [Inputs(db.leg_lengths[db.test], db.tip[db.test], "", db.configurations[db.test])]
    if prep.options.tube_sensors:
        out.append(Inputs(split_tube_lengths(db.geometry, db.tube_lengths[db.test]), db.tip[db.test], FIG9))
    return out


def run_network(
    prep: Prepared, setting: TrainingSetting, models: list[TrainedModel], trained: bool, given: Inputs
) -> NetworkRun:
    """The forward networks of ``setting`` (Fig. 9): configurations from the given legs, tips by eq. (5)."""
    arm = prep.arm

    def hybrid(L: np.ndarray) -> np.ndarray:
        return arm.evaluate("fk_position", hybrid_forward_configurations(models, L), check=False)

    Q = hybrid_forward_configurations(models, given.legs)
    tip = arm.evaluate("fk_position", Q, check=False)  # the networks' configurations, however far they extrapolate
    batch, one = time_network(hybrid, given.legs, prep.options.latency_repeats)
    label = f"{setting.name}{given.suffix}"
    return NetworkRun(
        setting,
        models,
        trained,
        np.linalg.norm(tip - given.tip, axis=1),
        batch,
        one,
        {f"tip_{label}": tip, f"configurations_{label}": Q},
        given.suffix,
    )


def run_solver(
    prep: Prepared, name: str, problems: list[LeastSquaresProblem], k: int, given: Inputs
) -> PlatformSolverRun:
    """Solver preset ``name`` on every platform of the first ``k`` given legs, from the linearised start."""
    arm = prep.arm
    legs = given.legs
    adapter = build_preset(name)

    def solve(L: np.ndarray) -> SolutionBatch:
        return solve_platforms(adapter, problems, L, linearised_start(arm, L))

    solve(legs[:1])  # build (and compile) before the clock starts
    report, seconds = timed(lambda: solve(legs[:k]))
    tip = arm.evaluate("fk_position", report.x)
    label = f"{name}{given.suffix}"
    return PlatformSolverRun(
        label,
        report,
        np.linalg.norm(tip - given.tip[:k], axis=1),
        seconds,
        {f"tip_{label}": tip},
        latency(solve, legs, prep.options.latency_repeats),
        None if given.configurations is None else given.configurations[:k],
    )


def table_iv_rows(prep: Prepared) -> list[TableIVRun]:
    """``constant-curvature`` on the six tube lengths of the test postures (when they are given,
    ``tube_sensors`` or the Cosserat postures), and ``direct-mlp`` on the Cosserat postures (``direct``)."""
    truth, db, o = prep.truth, prep.db, prep.options
    if truth is None and not o.tube_sensors:
        return []
    tubes = truth.tube_lengths[truth.test] if truth is not None else db.tube_lengths[db.test]
    tips = truth.tip[truth.test] if truth is not None else db.tip[db.test]
    radii = section_tube_radii(prep.arm)
    cc, seconds = timed(lambda: constant_curvature_tips(tubes, radii))
    rows = [
        TableIVRun(
            "constant-curvature",
            cc,
            np.linalg.norm(cc - tips, axis=1),
            seconds,
            {"tube offsets [mm]": (radii * 1e3).round(3).tolist()},
        )
    ]
    if truth is not None and o.direct:
        model = direct_model(prep, "direct_fkm")
        tip, seconds = timed(lambda: model.predict(tubes.reshape(len(tubes), -1)))
        columns = {
            "neurons": model.neurons,
            "Cosserat postures trained on": len(truth.train),
            "training time [s]": model.training_time,
        }
        rows.append(TableIVRun("direct-mlp", tip, np.linalg.norm(tip - tips, axis=1), seconds, columns))
    return rows


def run(ctx: ProblemContext) -> FKMOutcome:
    """Every variant's networks, then every baseline, on every input of the test postures."""
    prep = prepare(ctx)
    db, o = prep.db, prep.options
    inputs = test_inputs(prep)
    networks = []
    for setting in o.settings():
        models, trained = obtain_models(
            ctx.progress, db, forward_tasks(db), setting, 0.0, o.store, f"fkm-{setting.name}"
        )
        networks += [run_network(prep, setting, models, trained, given) for given in inputs]
    k = min(len(inputs[0].tip), o.exact_samples)
    problems = platform_problems(prep.arm, PLATFORM_TOLERANCE)
    solvers = [run_solver(prep, name, problems, k, given) for name in ctx.spec.baselines for given in inputs]
    return FKMOutcome(prep, networks, solvers, k, inputs, table_iv_rows(prep))
