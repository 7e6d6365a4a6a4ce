"""Problem kind ``ph_shape``: CBHA backbones rebuilt from end poses, checked against markers (seed 002 V.A).

Seed 002 (section V.A) builds one PH quintic per posture from the tracked start and
end poses and measures how far the three intermediate markers lie from it: 1.6,
4.2 and 3.8 mm for one posture, 1.2, 3.7 and 3.1 mm on average over a
100-posture trajectory. Here each posture's backbone is the minimum-energy PH
quintic of its end poses (:mod:`optikin.problems.ph_common` for the options and
the methods), and the distance of every intermediate marker to it is computed
(closest point, Newton-refined). On a synthetic recording the model's own
backbone (the vertebra centres) is also compared with the PH curve, noise-free:
the honest measure of how well a PH quintic can represent the vertebra model.

Per-sample status: the solver's (``ok``, ``not_converged``, ``failed``). The
comparison has one row per method (solver and ``ph`` baselines): energy gap to
the best energy found for the sample, time per sample, mean marker distance.
Figures: shapes against markers in 3-D, distances per sample, time per sample.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.problems import ph_figures as figures
from optikin.problems.ph_common import (
    COMMON_DEFAULTS,
    MM,
    backbone_lengths,
    check_options,
    distances_to_curves,
    end_data,
    load_recording,
    method_rows,
    ph_settings,
    solve_methods,
)
from optikin.results import Result

SEED_MEAN_DISTANCES_MM = (1.2, 3.7, 3.1)
"""Seed 002 section V.A: mean distance of the three intermediate markers over its 100-posture trajectory."""

CURVE_POINTS = 101


def run(ctx: ProblemContext) -> Result:
    spec = ctx.spec
    settings = ph_settings(ctx, check_options(ctx, dict(COMMON_DEFAULTS)))
    recording = load_recording(ctx)
    if settings.fixed_base:
        recording = recording.with_fixed_base()
    source = f"{ctx.path.name}: data"
    lengths = backbone_lengths(recording, settings.length, source)
    samples = end_data(recording, lengths, source)
    runs = solve_methods(ctx, settings, samples)

    distances, extra = {}, {}
    for name, method in runs.items():
        distances[name] = distances_to_curves(method.curves, recording.markers)
        extra[name] = {"mean marker distance [mm]": float(np.nanmean(distances[name]) * MM)}
    main = runs[ctx.solver.name]
    curves = main.curves
    distance = distances[ctx.solver.name] * MM  # (N, K)
    K = distance.shape[1]
    metrics: dict[str, Any] = {
        "mean distance per marker [mm]": np.nanmean(distance, axis=0),
        "max distance per marker [mm]": np.nanmax(distance, axis=0),
        "seed 002 V.A mean distance per marker [mm]": list(SEED_MEAN_DISTANCES_MM),
        "median time per sample [us]": float(np.median(main.seconds) * 1e6),
    }
    arrays: dict[str, np.ndarray] = {
        "t": recording.t, "markers": recording.markers, "marker_distance": distance / MM, "backbone_length": lengths,
        "ph_points": curves.point(np.linspace(0, 1, CURVE_POINTS)),
        "ph_p0": curves.p0, "ph_coefficients": np.stack([curves.A0, curves.A1, curves.A2], axis=1),
    }
    for name, method in runs.items():
        arrays[f"energy_{name}"] = method.energies
        arrays[f"seconds_{name}"] = method.seconds
    truth = recording.truth
    vertebra_distance = None
    if truth is not None:
        vertebra_distance = distances_to_curves(curves, truth.vertebrae) * MM  # (N, 17)
        clean = distances_to_curves(curves, truth.marker_truth) * MM
        metrics.update({
            "noise-free markers: mean distance per marker [mm]": np.nanmean(clean, axis=0),
            "model backbone: mean of the largest vertebra distance [mm]": float(np.nanmean(vertebra_distance.max(1))),
            "model backbone: largest vertebra distance [mm]": float(np.nanmax(vertebra_distance)),
            "backbone length estimate error mean / max [mm]": [
                float(np.mean(np.abs(lengths - truth.backbone_length)) * MM),
                float(np.max(np.abs(lengths - truth.backbone_length)) * MM)],
        })
        arrays["vertebrae"] = truth.vertebrae
        arrays["vertebra_distance"] = vertebra_distance / MM

    def draw_shapes(path):
        figures.shapes_3d(path, arrays["ph_points"], np.concatenate(
            [recording.base_position[:, None], recording.markers, recording.tip_position[:, None]], axis=1),
            f"{spec.name}: PH backbones ({ctx.solver.name}) and markers",
            None if truth is None else truth.vertebrae)

    def draw_errors(path):
        series = {"marker distance": distance}
        labels = {"marker distance": [f"marker {k + 1}" for k in range(K)]}
        if vertebra_distance is not None:
            series["model backbone"] = vertebra_distance.max(axis=1)
            labels["model backbone"] = ["largest vertebra distance"]
        figures.per_sample(path, series, "[mm]", f"{spec.name}: distance to the PH backbone", labels)

    def draw_times(path):
        figures.times_per_sample(path, {n: r.seconds for n, r in runs.items()}, f"{spec.name}: time per sample")

    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=ctx.arm.describe(),
        status=main.status, iterations=main.iterations, residuals=np.nanmax(distance, axis=1) / MM,
        timings={"median per sample [us]": float(np.median(main.seconds) * 1e6),
                 "mean per sample [us]": float(np.mean(main.seconds) * 1e6), "build [s]": main.build_seconds},
        metrics=metrics, comparison=method_rows(runs, extra), arrays=arrays,
        figures={"shapes": draw_shapes, "errors": draw_errors, "times": draw_times},
        notes=[f"{len(recording)} postures from {recording.source or spec.data.source}; residual = largest marker "
               f"distance of the sample [m]; backbone length: {settings.length}; end speeds "
               f"{'free, length held' if settings.free_speeds else 'set to the length'}"],
    )


register_kind(ProblemKind(
    options=None,
    data_family="markers",
    name="ph_shape",
    summary="CBHA backbones from end poses as minimum-energy PH quintics, against markers (seed 002 V.A)",
    run=run,
    backend_families=("ph",),
    default_solver="ph-newton",
    baselines=(),
))
