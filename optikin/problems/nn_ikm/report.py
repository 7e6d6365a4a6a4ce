"""``nn_ikm``: the outcome as a Result (model metrics beside Table III, one row per variant and solver)."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems.nn_ikm.run import Driven, IKMOutcome
from optikin.problems.nn_shared import (
    annotate_fairness,
    MM,
    comparison_result,
    coverage_metrics,
    error_stats,
    network_row,
    solver_row,
)
from optikin.results import MethodRow, Result


def driven_columns(driven: Driven | None) -> dict[str, Any]:
    """The tube-length error of lengths driven on the Cosserat arm (empty without Cosserat postures)."""
    if driven is None:
        return {}
    finite = driven.tube_errors[np.isfinite(driven.tube_errors)]
    return {"tube length error RMS, median [mm]": float(np.median(finite) * MM) if finite.size else None}


def driven_row(name: str, driven: Driven, extra: dict[str, Any]) -> MethodRow:
    """The row of tube lengths driven on the Cosserat arm that no vertebra-model method produced."""
    return MethodRow(
        name,
        "baseline",
        {"samples": len(driven.errors), **error_stats(driven.errors), **driven_columns(driven), **extra},
    )


def report(outcome: IKMOutcome) -> Result:
    """The result of ``nn_ikm``: the first variant is the method, every variant and solver a row.

    Arrays: per variant ``tip_<setting>`` (the Cosserat arm's, on the ``cosserat`` source),
    ``leg_lengths_<setting>`` (commanded, before the clip), ``predicted_<setting>`` and
    ``configurations_<setting>`` (realised on the vertebra model), per solver ``tip_<preset>`` and
    ``configurations_<preset>``, on the ``cosserat`` source ``tip_direct-mlp``,
    ``tip_constant-curvature`` and ``tip_goal-babbling`` (Table IV's other rows), the test postures'
    ``test_rows``, ``targets``, ``configurations`` (vertebra-model truth only), and the figures'
    ``search_<setting>_<task>`` and ``tip_errors_<method>``.
    """
    prep, test, k = outcome.prep, outcome.test, outcome.exact_samples
    db, truth = prep.db, prep.truth
    metrics: dict[str, Any] = {
        "database": db.summary() if truth is None else truth.summary(),
        "database time [s]": prep.seconds,
        "test samples": len(test),
        "penalty (eq. 11)": prep.options.penalty,
        **coverage_metrics(prep, outcome.targets),
    }
    comparison: list[MethodRow] = []
    errors: dict[str, np.ndarray] = {}
    arrays: dict[str, np.ndarray] = {}
    for net in outcome.networks:
        extra = {
            "tip error of the predicted pose, unclipped, median [mm]": float(np.median(net.unclipped) * MM),
            "lengths clipped to Table I [%]": float(100 * net.realised.clipped.mean()),
        }
        if net.driven is not None:
            extra["vertebra-model tip error, median [mm]"] = float(
                np.nanmedian(np.linalg.norm(net.realised.tip - outcome.targets, axis=1)) * MM
            )
        comparison.append(network_row(net, db, metrics, extra | driven_columns(net.driven)))
        errors[net.label] = net.errors
        arrays |= net.arrays
    for solver in outcome.solvers:
        iterations = solver.report.iterations
        comparison.append(
            solver_row(
                solver,
                {
                    "lengths clipped to Table I [%]": float(100 * solver.realised.clipped.mean()),
                    "median iterations": float(np.median(iterations)) if np.all(iterations >= 0) else None,
                    **driven_columns(solver.driven),
                },
            )
        )
        errors[solver.name] = solver.errors
        arrays |= solver.arrays
    if outcome.direct is not None and outcome.direct_model is not None:
        model = outcome.direct_model
        comparison.append(
            driven_row(
                "direct-mlp", outcome.direct, {"neurons": model.neurons, "training time [s]": model.training_time}
            )
        )
        errors["direct-mlp"] = outcome.direct.errors
        arrays["tip_direct-mlp"] = outcome.direct.tip
    if outcome.geometric is not None:
        comparison.append(driven_row("constant-curvature", outcome.geometric, {}))
        errors["constant-curvature"] = outcome.geometric.errors
        arrays["tip_constant-curvature"] = outcome.geometric.tip
    if outcome.babbling is not None and outcome.babbled is not None:
        extra = {"commands executed while learning": outcome.babbled.samples}
        comparison.append(driven_row("goal-babbling", outcome.babbling, extra))
        errors["goal-babbling"] = outcome.babbling.errors
        arrays["tip_goal-babbling"] = outcome.babbling.tip
    if outcome.floor is not None and outcome.controller is not None:
        comparison.append(driven_row("true-lengths", outcome.floor, {"controller neurons": outcome.controller.neurons}))
        errors["true-lengths"] = outcome.floor.errors
        metrics["controller (length -> pressure) setting"] = outcome.controller.setting.description
    arrays |= {"test_rows": test, "targets": outcome.targets}
    if truth is None:
        arrays["configurations"] = db.configurations[test]
        note = (
            "Every MSE is on the test split; each method's leg lengths are clipped to Table I and realised through "
            "the exact platform and chain kinematics before its tip error is measured; exact solvers on the first "
            f"{k} test tips, from the straight mid-range pose, for the admissible configuration nearest it "
            f"({outcome.formulation.label()})."
        )
    else:
        note = (
            "Targets: tips of Cosserat postures. Every method's leg lengths are summed into the six tube lengths "
            "and driven on the Cosserat arm through a length-pressure controller (an MLP trained on the Cosserat "
            "training postures, pressures clipped to the arm's range) as in seed 004 Fig. 14; the tip error is "
            "the arm's. true-lengths drives the postures' own tube lengths: the controller's share of every "
            "error. Seed 004 Table IV's other rows: direct-mlp, the qualitative IKM (Melingui et al.), tip -> six "
            "tube lengths, trained on the Cosserat training postures; constant-curvature, the quantitative IKM "
            "(Mahl et al.), the lengths of constant-curvature sections reaching the tip nearest the mid lengths; "
            "goal-babbling (Rolf et al.), pressures from an inverse model learned by goal babbling on the arm "
            "towards its training tips (tube lengths: those the arm then has). "
            f"Exact solvers on the first {k} test tips ({outcome.formulation.label()})."
        )
    fairness = annotate_fairness(prep, comparison, metrics)
    return comparison_result(prep, outcome.networks, comparison, errors, metrics, arrays, note, fairness)
