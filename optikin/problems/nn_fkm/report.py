"""``nn_fkm``: the outcome as a Result (model metrics beside Table II, one row per variant, input and solver)."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems.nn_fkm.run import FKMOutcome
from optikin.problems.nn_shared import (
    annotate_fairness,
    comparison_result,
    coverage_metrics,
    error_stats,
    network_row,
    solver_row,
)
from optikin.results import MethodRow, Result


def report(outcome: FKMOutcome) -> Result:
    """The result of ``nn_fkm``: the first variant is the method, every variant, input and solver a row.

    Arrays: per variant and input ``tip_<setting>[-fig9]`` and ``configurations_<setting>[-fig9]``,
    per solver ``tip_<preset>[-fig9]``, per Table IV row ``tip_constant-curvature`` and
    ``tip_direct-mlp``, the test postures' ``test_rows``, ``leg_lengths`` (those given, first input),
    ``tip`` (true), ``configurations`` (true, vertebra-model truth only), and the figures'
    ``search_<setting>_<task>`` and ``tip_errors_<method>``.
    """
    prep, test, k = outcome.prep, outcome.test, outcome.exact_samples
    db, truth = prep.db, prep.truth
    first = outcome.inputs[0]
    metrics: dict[str, Any] = {
        "database": db.summary() if truth is None else truth.summary(),
        "database time [s]": prep.seconds,
        "test samples": len(test),
        **coverage_metrics(prep, first.tip),
    }
    comparison: list[MethodRow] = []
    errors: dict[str, np.ndarray] = {}
    arrays: dict[str, np.ndarray] = {}
    for net in outcome.networks:
        comparison.append(network_row(net, db, metrics))
        errors[net.label] = net.errors
        arrays |= net.arrays
    for solver in outcome.solvers:
        extra: dict[str, Any] = {"max leg residual [m]": float(np.max(solver.report.residual))}
        if solver.truth_configurations is not None:
            extra["max |platform variables - truth|"] = float(
                np.max(np.abs(solver.report.x - solver.truth_configurations))
            )
        extra["latency, one sample [us]"] = solver.latency * 1e6
        comparison.append(solver_row(solver, extra))
        errors[solver.name] = solver.errors
        arrays |= solver.arrays
    for extra_row in outcome.table_iv:
        row = {
            "samples": len(extra_row.errors),
            **error_stats(extra_row.errors),
            **extra_row.columns,
            "time per sample [us]": extra_row.seconds / len(extra_row.errors) * 1e6,
        }
        comparison.append(MethodRow(extra_row.name, "baseline", row))
        errors[extra_row.name] = extra_row.errors
        arrays[f"tip_{extra_row.name}"] = extra_row.tip
    arrays |= {"test_rows": test, "leg_lengths": first.legs, "tip": first.tip}
    if first.configurations is not None:
        arrays["configurations"] = first.configurations
    given = "the six tube lengths of the Cosserat postures, split over the legs as in Fig. 6 (Fig. 9)"
    if truth is None:
        given = "the true legs of the test arms" + (
            ", and (-fig9 rows) the legs split from their six tube lengths" if len(outcome.inputs) > 1 else ""
        )
    note = (
        f"Every MSE is on the test split of the vertebra-model database; methods given {given}; tip errors "
        f"through the exact chain of eq. (5); exact solvers on the first {k} test postures, every platform from "
        "eqs. (7)-(9) linearised."
    )
    names = [r.name for r in outcome.table_iv]
    if "constant-curvature" in names:
        note += (
            " constant-curvature: seed 004 Table IV's quantitative FKM (Escande et al.), each section an arc "
            "from its three tube lengths."
        )
    if "direct-mlp" in names:
        note += (
            " direct-mlp: seed 004 Table IV's qualitative FKM (Melingui et al.), an MLP from the six tube "
            "lengths to the tip trained on the Cosserat training postures."
        )
    fairness = annotate_fairness(prep, comparison, metrics)
    return comparison_result(prep, outcome.networks, comparison, errors, metrics, arrays, note, fairness)
