"""A ``ph_chain`` outcome as a Result: marker and ground-truth distances per link, every method's rows."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems import ProblemContext
from optikin.problems.ph_chain.run import LINKS, ChainOutcome
from optikin.problems.ph_shared import MM, distances_to_curves, method_rows
from optikin.results import MethodRow, Result
from optikin.status import Status

SEED_MEAN_ERRORS_MM = (2.8, 8.0, 3.1)
"""Singh et al. 2018, section V.C: average error from the tracked markers for CBHA 1, the rope and CBHA 2."""
KEYS = {"CBHA 1": "arm1", "rope": "rope", "CBHA 2": "arm2"}
"""Array name prefix of each link."""


def chain_rows(outcome: ChainOutcome) -> list[MethodRow]:
    """One row per link and method: ``"<method> (<link>)"``."""
    comparison = []
    for name in LINKS:
        extra = {}
        for method, r in outcome.runs[name].items():
            d = distances_to_curves(r.curves, outcome.markers[name]) * MM
            extra[method] = {"mean marker distance [mm]": float(np.nanmean(d))}
        for row in method_rows(outcome.runs[name], extra):
            row.method = f"{row.method} ({name})"
            comparison.append(row)
    return comparison


def chain_metrics(outcome: ChainOutcome, marker_distance: dict[str, np.ndarray]) -> dict[str, Any]:
    """Marker and ground-truth distances per link [mm], time per sample, the rope's chord."""
    main, curves = outcome.main, {name: run.curves for name, run in outcome.main.items()}
    truth = {k: distances_to_curves(curves[k], outcome.truths[k]).max(axis=1) * MM for k in LINKS}
    chord = np.linalg.norm(outcome.arm2.tip_position - outcome.arm1.tip_position, axis=1)
    return {
        "mean marker distance per link [mm]": [float(np.nanmean(marker_distance[k])) for k in LINKS],
        "max marker distance per link [mm]": [float(np.nanmax(marker_distance[k])) for k in LINKS],
        "seed 002 V.C mean error per link [mm]": list(SEED_MEAN_ERRORS_MM),
        "truth: mean of the largest distance per link [mm]": [float(np.nanmean(truth[k])) for k in LINKS],
        "truth: largest distance per link [mm]": [float(np.nanmax(truth[k])) for k in LINKS],
        "median time per sample, all links [us]": float(np.median(sum(main[k].seconds for k in LINKS)) * 1e6),
        "rope chord / length min-max": [
            float(np.min(chord) / outcome.chain.rope_length),
            float(np.max(chord) / outcome.chain.rope_length),
        ],
    }


def chain_arrays(outcome: ChainOutcome, marker_distance: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays of the result (the figures draw from these)."""
    chain, t = outcome.chain, np.linspace(0, 1, 101)
    arrays = {"t": outcome.arm1.t, "rope_truth": chain.rope_truth, "rope_markers": chain.rope_markers}
    for name, key in KEYS.items():
        arrays[f"{key}_ph_points"] = outcome.main[name].curves.point(t)
        arrays[f"{key}_marker_distance"] = marker_distance[name] / MM
    arrays["arm1_markers"], arrays["arm2_markers"] = outcome.arm1.markers, outcome.arm2.markers
    arrays["arm1_vertebrae"], arrays["arm2_vertebrae"] = outcome.truths["CBHA 1"], outcome.truths["CBHA 2"]
    for name, key in KEYS.items():
        for method, r in outcome.runs[name].items():
            arrays[f"seconds_{key}_{method}"] = r.seconds
    return arrays


def sample_status(outcome: ChainOutcome) -> list[str]:
    """``ok`` where the solver solved all three links, else the first link's status that is not."""
    main = outcome.main
    return [
        Status.OK
        if all(main[name].status[i] == Status.OK for name in LINKS)
        else next(main[name].status[i] for name in LINKS if main[name].status[i] != Status.OK)
        for i in range(len(outcome.chain))
    ]


def report(ctx: ProblemContext, outcome: ChainOutcome) -> Result:
    """The Result of a ``ph_chain`` run."""
    main, options = outcome.main, outcome.options
    marker_distance = {k: distances_to_curves(main[k].curves, outcome.markers[k]) * MM for k in LINKS}
    metrics = chain_metrics(outcome, marker_distance)
    rope = "free, length held" if options.rope_free_speeds else "set to its length"
    return ctx.result(
        solver=outcome.solver,
        status=sample_status(outcome),
        iterations=np.sum([main[k].iterations for k in LINKS], axis=0),
        residuals=np.nanmax(np.column_stack([marker_distance[k].max(axis=1) for k in LINKS]), axis=1) / MM,
        timings={"median per sample, all links [us]": metrics["median time per sample, all links [us]"]},
        metrics=metrics,
        comparison=chain_rows(outcome),
        arrays=chain_arrays(outcome, marker_distance),
        notes=[
            f"{len(outcome.chain)} postures; rope {outcome.chain.rope_length} m; arms: backbone length "
            f"{options.length}, end speeds {'free' if options.free_speeds else 'set to the length'}; rope: end "
            f"speeds {rope}; residual = largest marker distance of the sample over the links [m]"
        ],
    )
