"""``nn_ikm``: the outcome as a Result (model metrics beside Table III, one row per variant and solver)."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems.nn_ikm.run import IKMOutcome
from optikin.problems.nn_shared import MM, comparison_result, network_row, solver_row
from optikin.results import MethodRow, Result


def report(outcome: IKMOutcome) -> Result:
    """The result of ``nn_ikm``: the first variant is the method, every variant and solver a row.

    Arrays: per variant ``tip_<setting>``, ``leg_lengths_<setting>`` (commanded, before the clip),
    ``predicted_<setting>`` and ``configurations_<setting>`` (realised), per solver ``tip_<preset>``
    and ``configurations_<preset>``, the test split's ``test_rows``, ``targets``,
    ``configurations``, and the figures' ``search_<setting>_<task>`` and ``tip_errors_<method>``.
    """
    prep, test, k = outcome.prep, outcome.test, outcome.exact_samples
    db = prep.db
    metrics: dict[str, Any] = {
        "database": db.summary(),
        "database time [s]": prep.seconds,
        "test samples": len(test),
        "penalty (eq. 11)": prep.options.penalty,
    }
    comparison: list[MethodRow] = []
    errors: dict[str, np.ndarray] = {}
    arrays: dict[str, np.ndarray] = {}
    for net in outcome.networks:
        comparison.append(
            network_row(
                net,
                db,
                metrics,
                {
                    "tip error of the predicted pose, unclipped, median [mm]": float(np.median(net.unclipped) * MM),
                    "lengths clipped to Table I [%]": float(100 * net.realised.clipped.mean()),
                },
            )
        )
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
                },
            )
        )
        errors[solver.name] = solver.errors
        arrays |= solver.arrays
    arrays |= {"test_rows": test, "targets": db.tip[test], "configurations": db.configurations[test]}
    note = (
        "Every MSE is on the test split; each method's leg lengths are clipped to Table I and realised through "
        "the exact platform and chain kinematics before its tip error is measured; exact solvers on the first "
        f"{k} test tips, from the straight mid-range pose, for the admissible configuration nearest it "
        f"({outcome.formulation.label()})."
    )
    return comparison_result(prep, outcome.networks, comparison, errors, metrics, arrays, note)
