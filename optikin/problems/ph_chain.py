"""Problem kind ``ph_chain``: two CBHAs holding a rope, each link a PH quintic (seed 002 IV.B and V.C).

Seed 002 closes a kinematic chain ABCD: CBHA 1 from its base A to its tip B, a rope
hanging under its own weight from B to C, CBHA 2 from its tip C to its base D.
Each link is rebuilt by a PH quintic from the positions and orientations at its two
ends (the seed's Table I), with C0 joints (eqs. 19-22), and compared with the
tracked markers: 2.8, 8 and 3.1 mm average error for CBHA 1, the rope and CBHA 2.

Here (:func:`optikin.data.markers.synthetic_rope_chain`) both arms are the CBHA
vertebra model driven by their tubes, upright, ``base_distance`` apart and facing
each other; the rope is the exact inextensible catenary of ``rope_length`` between
the true tips; markers (0.3 mm noise) sit on each arm (end rigid bodies and three
intermediate markers) and on the rope (three intermediate markers, and one
``end_offset`` from each end, which gives the rope's end directions). The arm links
take the options of :mod:`optikin.problems.ph_common`; the rope's length is known,
so by default its end speeds are free and its arc length is held to it
(``rope_free_speeds``).

Data (``data.source: synthetic``), params: ``rope_length`` (0.65 m), ``base_distance``
(0.25 m), ``end_offset`` (0.02 m), ``rope_markers`` (fractions of the rope length,
``[0.25, 0.5, 0.75]``), ``noise``, ``stride``, ``frequency``, ``amplitude`` (as the
``synthetic`` marker source). Options: those of :mod:`optikin.problems.ph_common`,
and ``rope_free_speeds`` (true).

Per-sample status: ``ok`` when the solver solved all three links. Per link and
method: energy gap, time per sample; per link: marker distances and the largest
distance of the ground truth (vertebra centres, dense catenary) to the PH curve.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from optikin.curves.chain import check_joints
from optikin.curves.min_energy import ShapeData
from optikin.data.markers import RopeChainRecording
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.problems import ph_figures as figures
from optikin.problems.ph_common import (
    COMMON_DEFAULTS,
    MM,
    backbone_lengths,
    check_options,
    distances_to_curves,
    end_data,
    method_rows,
    ph_settings,
    solve_methods,
)
from optikin.results import Result

LINKS = ("CBHA 1", "rope", "CBHA 2")
SEED_MEAN_ERRORS_MM = (2.8, 8.0, 3.1)
"""Seed 002 section V.C: average error from the tracked markers for CBHA 1, the rope and CBHA 2."""
DEFAULTS: dict[str, Any] = {**COMMON_DEFAULTS, "rope_free_speeds": True}


def load_chain(ctx: ProblemContext) -> RopeChainRecording:
    """The chain of ``data.source`` (family ``rope_chains``, :mod:`optikin.data.markers`)."""
    return ctx.load_data()


def reversed_data(data: ShapeData) -> ShapeData:
    """The same backbone traversed from its end (CBHA 2 runs from its tip C to its base D)."""
    return ShapeData(data.p1, -data.t1, data.p0, -data.t0, None if data.speeds is None else data.speeds[::-1],
                     data.length)


def run(ctx: ProblemContext) -> Result:
    spec = ctx.spec
    options = check_options(ctx, DEFAULTS)
    if not isinstance(options["rope_free_speeds"], bool):
        raise ctx.error("options.rope_free_speeds", f"must be true or false, got {options['rope_free_speeds']!r}")
    settings = ph_settings(ctx, {k: v for k, v in options.items() if k != "rope_free_speeds"})
    chain = load_chain(ctx)
    arm1, arm2 = chain.arm1, chain.arm2
    if settings.fixed_base:
        arm1, arm2 = arm1.with_fixed_base(), arm2.with_fixed_base()
    source = f"{ctx.path.name}: data"
    n = len(chain)
    links = {
        "CBHA 1": end_data(arm1, backbone_lengths(arm1, settings.length, source), source),
        "rope": [ShapeData.checked(arm1.tip_position[i], chain.rope_directions[i, 0], arm2.tip_position[i],
                                   chain.rope_directions[i, 1], length=chain.rope_length, source=source, sample=i)
                 for i in range(n)],
        "CBHA 2": [reversed_data(d) for d in end_data(arm2, backbone_lengths(arm2, settings.length, source), source)],
    }
    for i in range(n):
        check_joints([links[name][i] for name in LINKS], "C0", source=f"{source}: sample {i}")
    rope_settings = replace(settings, free_speeds=options["rope_free_speeds"])
    runs = {name: solve_methods(ctx, rope_settings if name == "rope" else settings, links[name], f" ({name})")
            for name in LINKS}

    markers = {"CBHA 1": arm1.markers, "rope": chain.rope_markers, "CBHA 2": arm2.markers}
    truths = {"CBHA 1": arm1.truth.vertebrae, "rope": chain.rope_truth, "CBHA 2": arm2.truth.vertebrae}
    main = {name: runs[name][ctx.solver.name] for name in LINKS}
    curves = {name: main[name].curves for name in LINKS}
    marker_distance = {name: distances_to_curves(curves[name], markers[name]) * MM for name in LINKS}
    truth_distance = {name: distances_to_curves(curves[name], truths[name]).max(axis=1) * MM for name in LINKS}

    comparison = []
    for name in LINKS:
        extra = {}
        for method, r in runs[name].items():
            d = distances_to_curves(r.curves, markers[name]) * MM
            extra[method] = {"mean marker distance [mm]": float(np.nanmean(d))}
        for row in method_rows(runs[name], extra):
            row.method = f"{row.method} ({name})"
            comparison.append(row)
    status = ["ok" if all(main[name].status[i] == "ok" for name in LINKS) else
              next(main[name].status[i] for name in LINKS if main[name].status[i] != "ok") for i in range(n)]
    metrics: dict[str, Any] = {
        "mean marker distance per link [mm]": [float(np.nanmean(marker_distance[k])) for k in LINKS],
        "max marker distance per link [mm]": [float(np.nanmax(marker_distance[k])) for k in LINKS],
        "seed 002 V.C mean error per link [mm]": list(SEED_MEAN_ERRORS_MM),
        "truth: mean of the largest distance per link [mm]": [float(np.nanmean(truth_distance[k])) for k in LINKS],
        "truth: largest distance per link [mm]": [float(np.nanmax(truth_distance[k])) for k in LINKS],
        "median time per sample, all links [us]": float(np.median(sum(main[k].seconds for k in LINKS)) * 1e6),
        "rope chord / length min-max": [float(np.min(np.linalg.norm(arm2.tip_position - arm1.tip_position, axis=1))
                                              / chain.rope_length),
                                        float(np.max(np.linalg.norm(arm2.tip_position - arm1.tip_position, axis=1))
                                              / chain.rope_length)],
    }
    t = np.linspace(0, 1, 101)
    arrays = {"t": arm1.t, "rope_truth": chain.rope_truth, "rope_markers": chain.rope_markers}
    for key, name in (("arm1", "CBHA 1"), ("rope", "rope"), ("arm2", "CBHA 2")):
        arrays[f"{key}_ph_points"] = curves[name].point(t)
        arrays[f"{key}_marker_distance"] = marker_distance[name] / MM
    arrays["arm1_markers"], arrays["arm2_markers"] = arm1.markers, arm2.markers

    def draw_shapes(path):
        figures.chains_3d(path, [arrays[f"{k}_ph_points"] for k in ("arm1", "rope", "arm2")],
                          [markers[k] for k in LINKS], [truths[k] for k in LINKS],
                          f"{spec.name}: CBHA 1, rope, CBHA 2 ({ctx.solver.name})")

    def draw_errors(path):
        figures.per_sample(path, {k: marker_distance[k] for k in LINKS}, "marker distance [mm]",
                           f"{spec.name}: marker distance per link")

    def draw_times(path):
        figures.times_per_sample(path, {f"{m} ({k})": runs[k][m].seconds for k in LINKS for m in runs[k]},
                                 f"{spec.name}: time per sample and link")

    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=ctx.arm.describe(),
        status=status, iterations=sum(main[k].iterations for k in LINKS),
        residuals=np.nanmax(np.column_stack([marker_distance[k].max(axis=1) for k in LINKS]), axis=1) / MM,
        timings={"median per sample, all links [us]": metrics["median time per sample, all links [us]"]},
        metrics=metrics, comparison=comparison, arrays=arrays,
        figures={"shapes": draw_shapes, "errors": draw_errors, "times": draw_times},
        notes=[f"{n} postures; rope {chain.rope_length} m; arms: backbone length {settings.length}, end speeds "
               f"{'free' if settings.free_speeds else 'set to the length'}; rope: end speeds "
               f"{'free, length held' if rope_settings.free_speeds else 'set to its length'}; residual = largest "
               f"marker distance of the sample over the links [m]"],
    )


register_kind(ProblemKind(
    options=None,
    data_family="rope_chains",
    name="ph_chain",
    summary="two CBHAs and a hanging rope, each link a PH quintic from its end poses (seed 002 IV.B, V.C)",
    run=run,
    backend_families=("ph",),
    default_solver="ph-newton",
    baselines=(),
))
