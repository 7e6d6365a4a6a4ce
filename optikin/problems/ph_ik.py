"""Problem kind ``ph_ik``: CBHA tube lengths from the PH backbone of the end poses (seed 002 V.B, Tables II-III).

Seed 002 (section V.B) computes the lengths ``L1, L2, L3`` of the CBHA's three
tubes from the PH backbone of each posture and compares them with the wire
potentiometers: Table II gives the min / max / mean absolute error per tube along
a trajectory (PH: 2.8, 2.2 and 1.0 mm on average), Table III the time per sample
(PH 0.27 ms, Newton-Raphson 233 ms, hybrid 12 ms). Here the backbone is the
minimum-energy PH quintic of the end poses (:mod:`optikin.problems.ph_common`),
the tubes are offset curves carried by a rotation-minimising frame
(:mod:`optikin.curves.tubes`), and the reference lengths are the recording's
(``L1, L2, L3``: the vertebra model's leg sums for a synthetic recording).

The time per sample of a method is its shape solve plus one call of the tube-length
Function (CasADi, compiled when the method's preset compiles), as the seed's PH row.

Options (besides those of :mod:`optikin.problems.ph_common`)::

    frame: rmf            # rmf | euler_rodrigues: the frame that carries the tubes
    tube_radius: null     # [base, tip] offset radius in metres; default: the CBHA's r_max, r_min

Baselines: any ``ph`` preset, and the comparators of Tables II-III
(:mod:`optikin.baselines.ph_comparators`): ``newton-raphson`` (Newton on the section
end positions and seed 004's elongation distribution), ``newton-raphson-pose`` (the
same on the tip pose, the PH rows' data) and ``hybrid`` (seed 004's networks from the
tip position). A comparator's postures that are not ``ok`` are counted, never dropped.

The other frame's tube lengths (same curves) are reported as an extra row, to show
what the choice of frame is worth.
"""

from __future__ import annotations

import time
from typing import Any

import casadi as ca
import numpy as np

from optikin.arms.cbha import CBHAArm
from optikin.curves import ShapeData, ShapeEnergyModel
from optikin.curves.tubes import CBHA_TUBE_ANGLES, FRAMES, TubeLayout, tube_lengths
from optikin.errors import InputDataError
from optikin.fastcall import BufferedFunction
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.problems import ph_figures as figures
from optikin.problems.ph_common import (
    COMMON_DEFAULTS,
    MM,
    MethodRun,
    backbone_lengths,
    check_options,
    end_data,
    load_recording,
    method_rows,
    ph_settings,
    solve_methods,
    summary_of,
)
from optikin.baselines.ph_comparators import COMPARATORS, HYBRID, NEWTON_RAPHSON, run_comparator
from optikin.results import MethodRow, Result

DEFAULTS: dict[str, Any] = {**COMMON_DEFAULTS, "frame": "rmf", "tube_radius": None}

SEED_TABLE_II_MM = {"PH": {"L1": (0.0112, 4.4020, 2.8239), "L2": (0.0032, 5.2327, 2.2020), "L3": (0.0012, 3.5959, 0.9768)},
                    "Newton-Raphson": {"L1": (1.9555, 13.2310, 6.3947), "L2": (0.1101, 7.5254, 3.9361),
                                       "L3": (0.0054, 9.9292, 6.2398)}}
"""Seed 002 Table II: (min, max, mean) absolute tube-length error over the trajectory, mm."""
SEED_TABLE_III_S = {"PH": 0.00027, NEWTON_RAPHSON: 0.23351, HYBRID: 0.01208}
"""Seed 002 Table III: time cost for one sample, seconds."""


def tube_length_function(model: ShapeEnergyModel, layout: TubeLayout) -> ca.Function:
    """``(x, P, n0) -> (L_1, ..., L_M)``: the tubes of the model's curve at its free parameters ``x``.

    The curve is the model's own (:meth:`ShapeEnergyModel.symbols`), of the same
    ``x`` and parameter vector ``P`` as its energy; ``n0`` is the reference normal.
    """
    x, P, curve = model.symbols()
    n0 = ca.SX.sym("n0", 3)
    return ca.Function("ph_tube_lengths", [x, P, n0], [tube_lengths(curve, n0, layout)], ["x", "P", "n0"], ["L"])


def timed_tube_lengths(function: ca.Function, run: MethodRun, samples: list[ShapeData], normals: np.ndarray,
                       compiled: bool) -> tuple[np.ndarray, np.ndarray]:
    """Tube lengths ``(N, M)`` of a method's solutions, one buffered call per sample, and each call's time."""
    f = BufferedFunction(function, compiled=compiled)
    x_in, p_in, n_in = f.inputs
    out = f.outputs[0]
    lengths, seconds = np.full((len(samples), out.size), np.nan), np.zeros(len(samples))
    for i, (sol, data) in enumerate(zip(run.solutions, samples)):
        if sol.status != "ok":
            continue
        tic = time.perf_counter()
        x_in[:] = sol.x
        p_in[:] = data.parameters()
        n_in[:] = normals[i]
        f()
        lengths[i] = out
        seconds[i] = time.perf_counter() - tic
    return lengths, seconds


def layout_of(ctx: ProblemContext, options: dict[str, Any]) -> TubeLayout:
    frame = options["frame"]
    if frame not in FRAMES:
        raise ctx.error("options.frame", f"must be one of {', '.join(FRAMES)}, got {frame!r}")
    radius = options["tube_radius"]
    if radius is None:
        if not isinstance(ctx.arm, CBHAArm):
            raise ctx.error("options.tube_radius", "required for an arm that is not a CBHA: [base, tip] in metres")
        return TubeLayout.cbha(ctx.arm.geometry, frame)
    try:
        r0, r1 = (float(r) for r in radius)
        return TubeLayout(r0, r1, CBHA_TUBE_ANGLES, frame)
    except (TypeError, ValueError) as exc:
        raise ctx.error("options.tube_radius", f"expected [base, tip] radii in metres: {exc}") from None


def error_metrics(errors_mm: np.ndarray) -> dict[str, float]:
    """``L<m> error min / avg / max [mm]`` per tube (Table II)."""
    out = {}
    for m in range(errors_mm.shape[1]):
        s = summary_of(errors_mm[:, m])
        out[f"L{m + 1} error min / avg / max [mm]"] = [s["min"], s["avg"], s["max"]]
    return out


def run(ctx: ProblemContext) -> Result:
    spec = ctx.spec
    options = check_options(ctx, DEFAULTS)
    settings = ph_settings(ctx, options)
    layout = layout_of(ctx, options)
    recording = load_recording(ctx)
    source = f"{ctx.path.name}: data"
    if recording.tube_lengths is None:
        raise InputDataError("no reference tube lengths: the recording needs columns L1, L2, L3", source=source,
                             field="L1")
    reference = recording.tube_lengths
    if settings.fixed_base:
        recording = recording.with_fixed_base()
    lengths = backbone_lengths(recording, settings.length, source)
    samples = end_data(recording, lengths, source)
    runs = solve_methods(ctx, settings, samples, others=COMPARATORS)
    normals = recording.base_normal

    tubes, extra, ik_seconds = {}, {}, {}
    for name, method in runs.items():
        tubes[name], tube_seconds = timed_tube_lengths(tube_length_function(method.model, layout), method, samples,
                                                       normals, method.compiled)
        ik_seconds[name] = method.seconds + tube_seconds
        err = np.abs(tubes[name] - reference) * MM
        extra[name] = {"mean |L error| [mm]": float(np.nanmean(err)), "max |L error| [mm]": float(np.nanmax(err)),
                       "median IK time per sample [us]": float(np.median(ik_seconds[name]) * 1e6)}
    main = runs[ctx.solver.name]
    errors = np.abs(tubes[ctx.solver.name] - reference) * MM
    comparison = method_rows(runs, extra)

    other = "euler_rodrigues" if layout.frame == "rmf" else "rmf"
    curves = main.curves
    other_tubes = tube_lengths(curves, normals, layout.with_frame(other))
    other_errors = np.abs(other_tubes - reference) * MM
    comparison.append(MethodRow(f"{ctx.solver.name}, {other} frame", "baseline",
                                {**error_metrics(other_errors), "mean |L error| [mm]": float(np.nanmean(other_errors))}))
    notes = [f"{len(recording)} postures from {recording.source or spec.data.source}; tubes carried by the "
             f"{layout.frame} frame at {layout.radius_start * MM:.1f} mm (base) to {layout.radius_end * MM:.1f} mm "
             f"(tip); backbone length: {settings.length}; end speeds "
             f"{'free, length held' if settings.free_speeds else 'set to the length'}"]
    comparator_arrays: dict[str, np.ndarray] = {}
    for name in (n for n in COMPARATORS if n in spec.baselines):
        found = run_comparator(ctx, name, recording)
        comparator_errors = np.abs(found.lengths - reference) * MM
        status = np.array(found.status)
        failed = np.flatnonzero(status != "ok")
        seed_time = SEED_TABLE_III_S.get(name)
        comparison.append(MethodRow(name, "baseline", {
            "ok": f"{len(status) - failed.size}/{len(status)}", "failures": int(failed.size),
            **error_metrics(comparator_errors), "mean |L error| [mm]": summary_of(comparator_errors.ravel())["avg"],
            "median IK time per sample [us]": float(np.median(found.seconds) * 1e6),
            **({f"seed 002 Table III, {name}: time per sample [us]": seed_time * 1e6} if seed_time else {})}))
        ik_seconds[name] = found.seconds
        key = name.replace("-", "_")
        comparator_arrays |= {f"tube_lengths_{key}": found.lengths, f"status_{key}": status,
                              f"ik_seconds_{name}": found.seconds}
        if failed.size:
            notes.append(f"{name}: {failed.size} of {len(status)} postures not ok (no tube lengths), "
                         f"e.g. sample {failed[0]}: {found.status[failed[0]]}, {found.messages[failed[0]]}")

    metrics: dict[str, Any] = {
        **error_metrics(errors),
        "median IK time per sample [us]": float(np.median(ik_seconds[ctx.solver.name]) * 1e6),
        "seed 002 Table II, PH: L1 / L2 / L3 mean error [mm]": [v[2] for v in SEED_TABLE_II_MM["PH"].values()],
        "seed 002 Table III, PH: time per sample [us]": SEED_TABLE_III_S["PH"] * 1e6,
        f"max |L({other}) - L({layout.frame})| [mm]": float(np.nanmax(np.abs(other_tubes - tubes[ctx.solver.name])) * MM),
    }
    if recording.truth is not None:
        metrics["backbone length estimate error mean / max [mm]"] = [
            float(np.mean(np.abs(lengths - recording.truth.backbone_length)) * MM),
            float(np.max(np.abs(lengths - recording.truth.backbone_length)) * MM)]
    arrays = {"t": recording.t, "reference_tube_lengths": reference, "tube_lengths": tubes[ctx.solver.name],
              f"tube_lengths_{other}": other_tubes, "backbone_length": lengths,
              "ph_points": curves.point(np.linspace(0, 1, 101))}
    for name in runs:
        arrays[f"ik_seconds_{name}"] = ik_seconds[name]
        arrays[f"energy_{name}"] = runs[name].energies
    arrays |= comparator_arrays

    def draw_errors(path):
        figures.per_sample(path, {"|L - L_ref|": errors, "L_ref": reference * MM}, "[mm]",
                           f"{spec.name}: tube-length errors ({ctx.solver.name}, {layout.frame} frame)",
                           {"|L - L_ref|": ["L1", "L2", "L3"], "L_ref": ["L1", "L2", "L3"]})

    def draw_times(path):
        figures.times_per_sample(path, ik_seconds, f"{spec.name}: IK time per sample (shape + tubes)")

    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=ctx.arm.describe(),
        status=main.status, iterations=main.iterations, residuals=np.nanmax(errors, axis=1) / MM,
        timings={"median IK per sample [us]": float(np.median(ik_seconds[ctx.solver.name]) * 1e6),
                 "build [s]": main.build_seconds},
        metrics=metrics, comparison=comparison, arrays=arrays,
        figures={"errors": draw_errors, "times": draw_times}, notes=notes,
    )


register_kind(ProblemKind(
    options=None,
    data_family="markers",
    name="ph_ik",
    summary="CBHA tube lengths from the PH backbone of the end poses, against the reference (seed 002 V.B)",
    run=run,
    backend_families=("ph",),
    default_solver="ph-newton",
    baselines=COMPARATORS,
))
