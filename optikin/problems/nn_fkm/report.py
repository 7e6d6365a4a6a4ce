"""``nn_fkm``: the outcome as a Result (model metrics beside Table II, one row per variant and solver)."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems.nn_fkm.run import FKMOutcome
from optikin.problems.nn_shared import comparison_result, network_row, solver_row
from optikin.results import MethodRow, Result


def report(outcome: FKMOutcome) -> Result:
    """The result of ``nn_fkm``: the first variant is the method, every variant and solver a row.

    Arrays: per variant ``tip_<setting>`` and ``configurations_<setting>``, per solver
    ``tip_<preset>``, the test split's ``test_rows``, ``leg_lengths``, ``configurations``,
    ``tip``, and the figures' ``search_<setting>_<task>`` and ``tip_errors_<method>``.
    """
    prep, test, k = outcome.prep, outcome.test, outcome.exact_samples
    db = prep.db
    metrics: dict[str, Any] = {"database": db.summary(), "database time [s]": prep.seconds, "test samples": len(test)}
    comparison: list[MethodRow] = []
    errors: dict[str, np.ndarray] = {}
    arrays: dict[str, np.ndarray] = {}
    for net in outcome.networks:
        comparison.append(network_row(net, db, metrics))
        errors[net.label] = net.errors
        arrays |= net.arrays
    for solver in outcome.solvers:
        comparison.append(
            solver_row(
                solver,
                {
                    "max |platform variables - truth|": float(
                        np.max(np.abs(solver.report.x - db.configurations[test[:k]]))
                    ),
                    "max leg residual [m]": float(np.max(solver.report.residual)),
                    "latency, one sample [us]": solver.latency * 1e6,
                },
            )
        )
        errors[solver.name] = solver.errors
        arrays |= solver.arrays
    arrays |= {
        "test_rows": test,
        "leg_lengths": db.leg_lengths[test],
        "configurations": db.configurations[test],
        "tip": db.tip[test],
    }
    note = (
        "Every MSE is on the test split; tip errors through the exact chain of eq. (5); "
        f"exact solvers on the first {k} test arms, every platform from eqs. (7)-(9) linearised."
    )
    return comparison_result(prep, outcome.networks, comparison, errors, metrics, arrays, note)
