"""An ``fk`` outcome as a Result: per-sample status, tip ranges, the comparison with the baselines, the arrays."""

from __future__ import annotations

import numpy as np

from optikin.algebra import dq_translation
from optikin.data.configurations import skipped_rows_notes
from optikin.problems import ProblemContext
from optikin.problems.fk.run import FkOutcome
from optikin.results import MethodRow, Result
from optikin.status import Status

MM = 1e3

UNIT_TOLERANCE = 1e-9
"""A sample is ``ok`` when its tip is finite and a unit dual quaternion to within this."""

DIFFERENCE = "max |tip - numpy| [mm]"


def sample_status(outcome: FkOutcome) -> list[str]:
    """``ok`` for a finite tip and backbone with a unit tip dual quaternion, else ``failed``."""
    finite = np.isfinite(outcome.tip_dq).all(axis=1) & np.isfinite(outcome.backbone).all(axis=(1, 2))
    return [Status.OK if ok and e < UNIT_TOLERANCE else Status.FAILED for ok, e in zip(finite, outcome.unit_error)]


def comparison(ctx: ProblemContext, outcome: FkOutcome) -> list[MethodRow]:
    """The solver's row and one per baseline: time per sample and the largest tip distance from numpy's."""
    n = outcome.configurations.shape[0]
    position = dq_translation(outcome.tip_dq)
    numpy_run = next((b for b in outcome.baselines if b.name == "numpy"), None)
    reference = None if numpy_run is None else dq_translation(numpy_run.tip_dq)

    def distance(tip_position: np.ndarray) -> float:
        return 0.0 if reference is None else float(np.abs(reference - tip_position).max() * MM)

    solver = ctx.solver.name if ctx.solver is not None else "none"
    rows = [
        MethodRow(
            solver, "solver", {"time per sample [us]": outcome.tip_seconds / n * 1e6, DIFFERENCE: distance(position)}
        )
    ]
    for baseline in outcome.baselines:
        rows.append(
            MethodRow(
                baseline.name,
                "baseline",
                {
                    "time per sample [us]": baseline.seconds / n * 1e6,
                    DIFFERENCE: distance(position if baseline.name == "numpy" else dq_translation(baseline.tip_dq)),
                },
            )
        )
    return rows


def tip_metrics(outcome: FkOutcome) -> dict[str, float | list[float]]:
    """Ranges of the tip coordinates [mm], the largest base-tip distance [mm] and unit-norm error."""
    position = dq_translation(outcome.tip_dq)
    reach = np.linalg.norm(position, axis=1)
    ranges: dict[str, float | list[float]] = {
        f"tip {axis} range [mm]": [float(position[:, k].min() * MM), float(position[:, k].max() * MM)]
        for k, axis in enumerate("xyz")
    }
    return {
        **ranges,
        "max distance base-tip [mm]": float(reach.max() * MM),
        "max unit-norm error of tip dual quaternion": float(outcome.unit_error.max()),
    }


def report(ctx: ProblemContext, outcome: FkOutcome) -> Result:
    """The Result of an ``fk`` run (arrays: configurations, tip_dq, tip_position, section_dq, backbone, t)."""
    n = outcome.configurations.shape[0]
    arrays = {
        "configurations": outcome.configurations,
        "tip_dq": outcome.tip_dq,
        "tip_position": dq_translation(outcome.tip_dq),
        "section_dq": outcome.section_dq,
        "backbone": outcome.backbone,
    }
    if outcome.t is not None:
        arrays["t"] = outcome.t
    return ctx.result(
        status=sample_status(outcome),
        residuals=outcome.unit_error,
        timings={
            "build [s]": outcome.build_seconds,
            "fk_dq total [s]": outcome.tip_seconds,
            "per sample [us]": outcome.tip_seconds / n * 1e6,
        },
        metrics=tip_metrics(outcome),
        comparison=comparison(ctx, outcome),
        arrays=arrays,
        notes=skipped_rows_notes(outcome.skipped_rows, ctx.data_params),
    )
