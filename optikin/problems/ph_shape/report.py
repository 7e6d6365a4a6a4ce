"""A ``ph_shape`` outcome as a Result: marker distances, the model-backbone check, the methods' table."""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.arms.cbha import CBHAArm
from optikin.data.configurations import skipped_rows_notes
from optikin.data.cosserat_markers import CosseratMarkerParams, CosseratRecording, CosseratTruth
from optikin.problems import ProblemContext
from optikin.problems.ph_shape import cc
from optikin.problems.fairness import ArmSize, Given, Manifest, recorded_arm
from optikin.problems.ph_shape.c1 import SECTIONS
from optikin.problems.ph_shape.options import PHShapeOptions
from optikin.problems.ph_shape.run import ShapeOutcome
from optikin.problems.ph_shape.wrench import NAME, distances_to_polylines
from optikin.problems.ph_shared import MM, distances_to_curves, method_rows, tube_marker_distances
from optikin.results import MethodRow, Result

SEED_MEAN_DISTANCES_MM = (1.2, 3.7, 3.1)
"""Singh et al. 2018, section V.A: mean distance of the three intermediate markers over its 100 postures."""

CURVE_POINTS = 101


def cosserat_metrics(outcome: ShapeOutcome) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Metrics and arrays of a Cosserat recording's truth and tube markers (like with like).

    The backbone markers (centroids of the three tubes' markers) are compared with the PH
    backbone by :func:`report`; here the truth backbone (every solver node) is compared with
    it, and each tube marker with the PH tube curve at its offset (not with the backbone,
    from which it is 29-40 mm away).
    """
    recording, curves, lengths = outcome.recording, outcome.main.curves, outcome.lengths
    truth = recording.truth
    assert isinstance(truth, CosseratTruth) and isinstance(recording, CosseratRecording)
    backbone = distances_to_curves(curves, truth.vertebrae) * MM  # (N, K)
    clean = distances_to_curves(curves, truth.marker_truth) * MM
    tubes = tube_marker_distances(curves, recording, recording.tube_markers)
    tubes_clean = tube_marker_distances(curves, recording, truth.tube_markers)
    assert tubes is not None and tubes_clean is not None
    metrics: dict[str, Any] = {
        "noise-free backbone markers: mean distance per marker [mm]": np.nanmean(clean, axis=0),
        "truth backbone: mean of the largest node distance [mm]": float(np.nanmean(backbone.max(1))),
        "truth backbone: largest node distance [mm]": float(np.nanmax(backbone)),
        "tube markers: mean distance to the PH tube curves per station [mm]": np.nanmean(tubes * MM, axis=(0, 1)),
        "tube markers: max distance to the PH tube curves per station [mm]": np.nanmax(tubes * MM, axis=(0, 1)),
        "noise-free tube markers: mean distance to the PH tube curves per station [mm]": np.nanmean(
            tubes_clean * MM, axis=(0, 1)
        ),
        "backbone length estimate error mean / max [mm]": [
            float(np.mean(np.abs(lengths - truth.backbone_length)) * MM),
            float(np.max(np.abs(lengths - truth.backbone_length)) * MM),
        ],
    }
    arrays = {
        "truth_backbone": truth.vertebrae,
        "truth_backbone_distance": backbone / MM,
        "tube_markers": recording.tube_markers,
        "tube_marker_distance": tubes,
    }
    return metrics, arrays


def truth_metrics(outcome: ShapeOutcome) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Metrics and arrays of the synthetic recording's ground truth (empty for a recorded file)."""
    truth, lengths = outcome.recording.truth, outcome.lengths
    if truth is None:
        return {}, {}
    if isinstance(truth, CosseratTruth):
        return cosserat_metrics(outcome)
    curves = outcome.main.curves
    vertebra_distance = distances_to_curves(curves, truth.vertebrae) * MM  # (N, 17)
    clean = distances_to_curves(curves, truth.marker_truth) * MM
    metrics = {
        "noise-free markers: mean distance per marker [mm]": np.nanmean(clean, axis=0),
        "model backbone: mean of the largest vertebra distance [mm]": float(np.nanmean(vertebra_distance.max(1))),
        "model backbone: largest vertebra distance [mm]": float(np.nanmax(vertebra_distance)),
        "backbone length estimate error mean / max [mm]": [
            float(np.mean(np.abs(lengths - truth.backbone_length)) * MM),
            float(np.max(np.abs(lengths - truth.backbone_length)) * MM),
        ],
    }
    return metrics, {"vertebrae": truth.vertebrae, "vertebra_distance": vertebra_distance / MM}


def wrench_row(outcome: ShapeOutcome) -> tuple[MethodRow, dict[str, np.ndarray]]:
    """The comparison row and arrays of baseline ``cosserat-wrench`` (:mod:`optikin.problems.ph_shape.wrench`).

    Marker distances like the PH rows' (NaN, so left out, where the fit did not converge),
    the truth backbone's distance where the recording has a truth, time per sample, statuses.
    """
    wrench = outcome.wrench
    assert wrench is not None
    status = np.array(wrench.status)
    distance = outcome.distances[NAME] * MM  # (N, K)
    converged = status == "ok"
    metrics: dict[str, Any] = {
        "ok": f"{int(converged.sum())}/{len(status)}",
        "failed fits": int((~converged).sum()),
        "mean marker distance [mm]": float(np.nanmean(distance)) if converged.any() else float("nan"),
        "mean distance per marker [mm]": np.nanmean(distance, axis=0) if converged.any() else float("nan"),
        "max distance per marker [mm]": np.nanmax(distance, axis=0) if converged.any() else float("nan"),
        "ambiguous fits": int(np.sum(wrench.ambiguous & converged)),
        "fitted tip force median / max [N]": [float(np.median(wrench.tip_forces)), float(np.max(wrench.tip_forces))],
        "elastic energy median / max [J]": [float(np.median(wrench.energies)), float(np.max(wrench.energies))],
        "median iterations": float(np.median(wrench.iterations)),
        "median time per sample [us]": float(np.median(wrench.seconds) * 1e6),
        "mean time per sample [us]": float(np.mean(wrench.seconds) * 1e6),
        "build [s]": wrench.build_seconds,
    }
    arrays = {
        f"seconds_{NAME}": wrench.seconds,
        f"marker_distance_{NAME}": distance / MM,
        f"tip_wrench_{NAME}": np.stack([f.wrench for f in wrench.fits]),
        f"elastic_energy_{NAME}": wrench.energies,
        f"ambiguous_{NAME}": wrench.ambiguous,
    }
    truth = outcome.recording.truth
    if truth is not None:
        backbone = distances_to_polylines(wrench.backbones, truth.vertebrae) * MM  # (N, nodes)
        if converged.any():
            metrics.update(backbone_metrics(backbone))
        arrays[f"truth_backbone_distance_{NAME}"] = backbone / MM
    return MethodRow(NAME, "baseline", metrics), arrays


def backbone_metrics(distance_mm: np.ndarray) -> dict[str, float]:
    """The truth-backbone metrics of a row from each node's distance to the method's curve ``(N, nodes)`` [mm]."""
    return {
        "truth backbone: mean of the largest node distance [mm]": float(np.nanmean(distance_mm.max(1))),
        "truth backbone: largest node distance [mm]": float(np.nanmax(distance_mm)),
    }


def cc_row(outcome: ShapeOutcome) -> tuple[MethodRow, dict[str, np.ndarray]]:
    """The comparison row and arrays of baseline ``cc-arc`` (:mod:`optikin.problems.ph_shape.cc`).

    Marker distances like the PH rows', the truth backbone's distance where the recording
    has a truth, time per sample; the angle between the arc's tip tangent and the measured
    one, and the arc length against the PH methods' backbone length.
    """
    arcs = outcome.arcs
    assert arcs is not None
    distance = outcome.distances[cc.NAME] * MM  # (N, K)
    measured = outcome.recording.tip_direction
    cosine = np.clip(np.sum(arcs.tip_tangent * measured, axis=1), -1.0, 1.0)
    used = np.array([s.length for s in outcome.samples], dtype=float)
    metrics: dict[str, Any] = {
        "ok": f"{len(distance)}/{len(distance)}",
        "mean marker distance [mm]": float(np.mean(distance)),
        "mean distance per marker [mm]": np.mean(distance, axis=0),
        "max distance per marker [mm]": np.max(distance, axis=0),
        "median time per sample [us]": float(np.median(arcs.seconds) * 1e6),
        "mean time per sample [us]": float(np.mean(arcs.seconds) * 1e6),
        "mean tip tangent error [deg]": float(np.degrees(np.mean(np.arccos(cosine)))),
        "mean |arc length - PH length| [mm]": float(np.mean(np.abs(arcs.arc_length - used)) * MM),
    }
    return _arc_row(cc.NAME, metrics, arcs, distance, outcome)


def two_arcs_row(outcome: ShapeOutcome) -> tuple[MethodRow, dict[str, np.ndarray]]:
    """The comparison row and arrays of baseline ``cc-two-arcs`` (:mod:`optikin.problems.ph_shape.cc`).

    The marker distances leave out the joint marker (the arcs pass through it), the truth
    backbone's distance where the recording has a truth, time per sample, the angle
    between section 2's tip tangent and the measured one.
    """
    two = outcome.two_arcs
    assert two is not None
    distance = outcome.distances[cc.TWO_ARCS] * MM  # (N, K)
    others = [k for k in range(distance.shape[1]) if k != two.joint_marker]
    cosine = np.clip(np.sum(two.sections[1].tip_tangent * outcome.recording.tip_direction, axis=1), -1.0, 1.0)
    metrics: dict[str, Any] = {
        "ok": f"{len(distance)}/{len(distance)}",
        "mean marker distance off the joint [mm]": float(np.mean(distance[:, others])),
        "mean distance per marker [mm]": np.mean(distance, axis=0),
        "max distance per marker [mm]": np.max(distance, axis=0),
        "median time per sample [us]": float(np.median(two.seconds) * 1e6),
        "mean time per sample [us]": float(np.mean(two.seconds) * 1e6),
        "mean tip tangent error [deg]": float(np.degrees(np.mean(np.arccos(cosine)))),
    }
    return _arc_row(cc.TWO_ARCS, metrics, two, distance, outcome)


def _arc_row(
    name: str, metrics: dict[str, Any], arcs: cc.CCRun | cc.TwoArcs, distance_mm: np.ndarray, outcome: ShapeOutcome
) -> tuple[MethodRow, dict[str, np.ndarray]]:
    """A constant-curvature baseline's row and arrays: its times, marker distances ``(N, K)`` [mm] and
    sampled arcs, and its truth-backbone distance (into ``metrics`` too) where the recording has a truth."""
    arrays = {
        f"seconds_{name}": arcs.seconds,
        f"marker_distance_{name}": distance_mm / MM,
        f"points_{name}": arcs.points,
    }
    truth = outcome.recording.truth
    if truth is not None:
        backbone = arcs.distances(truth.vertebrae) * MM  # (N, nodes)
        metrics.update(backbone_metrics(backbone))
        arrays[f"truth_backbone_distance_{name}"] = backbone / MM
    return MethodRow(name, "baseline", metrics), arrays


def c1_report(outcome: ShapeOutcome) -> tuple[dict[str, Any], list[MethodRow], dict[str, np.ndarray]]:
    """Metrics, comparison rows (one per method and section) and arrays of the C1 chain
    (:mod:`optikin.problems.ph_shape.c1`), side by side with the single curve's."""
    chain, recording, solver = outcome.chain, outcome.recording, outcome.solver
    assert chain is not None
    distance = chain.distances(solver, recording.markers) * MM  # (N, K)
    metrics: dict[str, Any] = {
        "C1 chain: mean distance per marker [mm]": np.nanmean(distance, axis=0),
        "C1 chain: max distance per marker [mm]": np.nanmax(distance, axis=0),
        "C1 chain: joint marker (the joint's own centroid)": chain.joint_marker + 1,
    }
    arrays: dict[str, np.ndarray] = {
        "c1_points": chain.points(solver, np.linspace(0, 1, CURVE_POINTS)),
        "c1_marker_distance": distance / MM,
        "c1_joint_position": chain.joint_position,
        "c1_joint_orientation": chain.joint_orientation,
    }
    truth = recording.truth
    if truth is not None:
        backbone = chain.distances(solver, truth.vertebrae) * MM
        name = "truth backbone" if isinstance(truth, CosseratTruth) else "model backbone"
        metrics[f"C1 chain: {name}: mean of the largest node distance [mm]"] = float(np.nanmean(backbone.max(1)))
        metrics[f"C1 chain: {name}: largest node distance [mm]"] = float(np.nanmax(backbone))
        arrays["c1_truth_backbone_distance"] = backbone / MM
    others = [k for k in range(recording.markers.shape[1]) if k != chain.joint_marker]  # the joint's is its own
    rows = []
    for section in SECTIONS:
        runs = chain.runs[section]
        extra = {
            method: {
                "mean marker distance off the joint [mm]": float(
                    np.nanmean(chain.distances(method, recording.markers)[:, others]) * MM
                )
            }
            for method in runs
        }
        for row in method_rows(runs, extra):
            row.method = f"{row.method} (C1 {section})"
            rows.append(row)
    return metrics, rows, arrays


def shape_arrays(outcome: ShapeOutcome) -> dict[str, np.ndarray]:
    """The arrays of the result (the figures draw from these)."""
    recording, curves = outcome.recording, outcome.main.curves
    arrays: dict[str, np.ndarray] = {
        "t": recording.t,
        "markers": recording.markers,
        "marker_distance": outcome.distances[outcome.solver],
        "backbone_length": outcome.lengths,
        "ph_points": curves.point(np.linspace(0, 1, CURVE_POINTS)),
        "ph_p0": curves.p0,
        "ph_coefficients": np.stack([curves.A0, curves.A1, curves.A2], axis=1),
        "base_position": recording.base_position,
        "tip_position": recording.tip_position,
    }
    for name, method in outcome.runs.items():
        arrays[f"energy_{name}"] = method.energies
        arrays[f"seconds_{name}"] = method.seconds
    return arrays


WRENCH_STIFFNESS = {
    "EA": "axial_stiffness",
    "EI": "bending_stiffness",
    "GA": "shear_stiffness",
    "GJ": "torsion_stiffness",
    "mass_per_length": "mass_per_length",
    "gravity": "gravity",
}
"""The ``cosserat-wrench`` rod's fields and the ``cosserat`` source's parameters they default to."""


def wrench_given(ctx: ProblemContext, options: PHShapeOptions) -> Given:
    """What ``cosserat-wrench`` is given: the truth's own rod when its options are the recording's parameters."""
    rod, params = options.cosserat_wrench, ctx.data_params
    budget = "Levenberg-Marquardt on the 6 clamp-wrench unknowns, from the arc's clamp couple, then the previous fit"
    information = "the base and tip rigid bodies, the PH methods' backbone length"
    if isinstance(params, CosseratMarkerParams):
        same = all(
            np.allclose(getattr(rod, mine), getattr(params, theirs)) for mine, theirs in WRENCH_STIFFNESS.items()
        )
        if same:
            return Given(
                NAME,
                "generator's own",
                budget=budget,
                information=information + "; the truth's stiffness, mass per length and gravity",
                label="the rod is the Cosserat truth's own (the defaults of options.cosserat_wrench): an upper "
                "bound for a rod a lab would calibrate",
            )
        return Given(NAME, "measured", budget=budget, information=information + "; options.cosserat_wrench's rod")
    return Given(
        NAME,
        "another arm",
        budget=budget,
        information=information + "; options.cosserat_wrench's rod",
        label="a uniform Cosserat rod of assumed stiffness on a recording of another model: a guessed rod",
    )


def manifest(ctx: ProblemContext) -> Manifest:
    """What every row of a ``ph_shape`` comparison is given (:mod:`optikin.problems.fairness`).

    The PH and constant-curvature rows get the end poses and no model of the arm (the tube
    offsets enter only the tube-marker distances); ``cc-two-arcs`` and the C1 rows also the
    marker at the end of section 1; ``cosserat-wrench`` a rod (:func:`wrench_given`).
    """
    options: PHShapeOptions = ctx.options
    if ctx.spec.data.source == "disks":  # a recorded file, whatever arm the problem names
        truth, shared = ArmSize("the recorded arm (disks)"), False
    else:
        truth, shared = recorded_arm(ctx.spec.data.source, ctx.data_params, ctx.arm_model)
    solver = ctx.solver.name if ctx.solver is not None else ""
    ends = "the base and tip rigid bodies"
    if ctx.spec.data.source == "disks" or options.tip == "circle":
        ends = "the base pose, the tip point and the tangent of the circle through the last three points"
    joint = "; the marker at the end of section 1 (an extra joint pose)"
    entries = []
    for name in [solver] + [b for b in ctx.spec.baselines if b != solver]:
        if name == NAME:
            entries.append(wrench_given(ctx, options))
        elif name == cc.TWO_ARCS:
            entries.append(Given(name, "none", information=ends + joint))
        else:
            entries.append(Given(name, "none", budget=f"preset {name}" if name != cc.NAME else "", information=ends))
            if options.c1_joint and name != cc.NAME:
                entries.append(Given(f"{name} (C1", "none", budget=f"preset {name}", information=ends + joint))
    return Manifest(truth, shared, tuple(entries))


def held_out_metrics(outcome: ShapeOutcome) -> tuple[dict[str, Any], dict[str, float]]:
    """Metrics and the solver's per-disk table entries of the held-out check (:func:`~optikin.problems.ph_shape.run.
    held_out_distances`); empty for a recording whose tip pose is recorded.

    Each intermediate marker is scored on the backbone whose tip tangent did not use it: median, 95th
    percentile and largest distance per marker and over all of them [mm]; the markers the main backbone's tip
    estimate used are named (its own marker distances are not a held-out check of those).
    """
    held, recording = outcome.held_out, outcome.recording
    if held is None:
        return {}, {}
    mm = held * MM  # (N, K)
    metrics: dict[str, Any] = {
        "tip pose": f"estimated from the markers: {recording.tip_estimate}",
        "markers the tip estimate used": [k + 1 for k in recording.tip_markers],
        "held-out marker distance median / p95 / max [mm]": [
            float(np.nanmedian(mm)),
            float(np.nanpercentile(mm, 95)),
            float(np.nanmax(mm)),
        ],
        "held-out distance per marker, median [mm]": np.nanmedian(mm, axis=0),
        "held-out distance per marker, p95 [mm]": np.nanpercentile(mm, 95, axis=0),
        "held-out distance per marker, max [mm]": np.nanmax(mm, axis=0),
    }
    row = {"held-out marker distance median [mm]": float(np.nanmedian(mm))}
    row.update({f"held-out m{k + 1} median [mm]": float(np.nanmedian(mm[:, k])) for k in range(mm.shape[1])})
    return metrics, row


def report(ctx: ProblemContext, outcome: ShapeOutcome) -> Result:
    """The Result of a ``ph_shape`` run."""
    spec, main, options = ctx.spec, outcome.main, outcome.options
    distance = outcome.distances[outcome.solver] * MM  # (N, K)
    metrics: dict[str, Any] = {
        "mean distance per marker [mm]": np.nanmean(distance, axis=0),
        "max distance per marker [mm]": np.nanmax(distance, axis=0),
    }
    if isinstance(ctx.arm_model, CBHAArm):  # the seed's figures are those of its CBHA
        metrics["seed 002 V.A mean distance per marker [mm]"] = list(SEED_MEAN_DISTANCES_MM)
    metrics["median time per sample [us]"] = float(np.median(main.seconds) * 1e6)
    held_metrics, held_row = held_out_metrics(outcome)
    metrics.update(held_metrics)
    truth, truth_arrays = truth_metrics(outcome)
    metrics.update(truth)
    extra = {name: {"mean marker distance [mm]": float(np.nanmean(d) * MM)} for name, d in outcome.distances.items()}
    extra[outcome.solver].update(held_row)
    if outcome.recording.truth is not None:
        for name, method in outcome.runs.items():
            extra[name].update(
                backbone_metrics(distances_to_curves(method.curves, outcome.recording.truth.vertebrae) * MM)
            )
    comparison = method_rows(outcome.runs, extra)
    wrench_arrays: dict[str, np.ndarray] = {}
    if outcome.wrench is not None:
        row, wrench_arrays = wrench_row(outcome)
        comparison.append(row)
    cc_arrays: dict[str, np.ndarray] = {}
    if outcome.arcs is not None:
        row, cc_arrays = cc_row(outcome)
        comparison.append(row)
    if outcome.two_arcs is not None:
        row, two_arrays = two_arcs_row(outcome)
        comparison.append(row)
        cc_arrays.update(two_arrays)
    chain_arrays: dict[str, np.ndarray] = {}
    if outcome.chain is not None:
        chain_metrics, chain_rows, chain_arrays = c1_report(outcome)
        metrics.update(chain_metrics)
        comparison.extend(chain_rows)
    given = manifest(ctx)
    metrics |= given.metrics()
    return ctx.result(
        solver=outcome.solver,
        status=main.status,
        iterations=main.iterations,
        residuals=np.nanmax(distance, axis=1) / MM,
        timings={
            "median per sample [us]": float(np.median(main.seconds) * 1e6),
            "mean per sample [us]": float(np.mean(main.seconds) * 1e6),
            "build [s]": main.build_seconds,
        },
        metrics=metrics,
        comparison=given.annotate(comparison),
        arrays={
            **shape_arrays(outcome),
            **truth_arrays,
            **wrench_arrays,
            **cc_arrays,
            **chain_arrays,
            **({} if outcome.held_out is None else {"held_out_marker_distance": outcome.held_out}),
        },
        notes=skipped_rows_notes(outcome.recording.skipped_rows, ctx.data_params)
        + [
            f"{len(outcome.recording)} postures from {outcome.recording.source or spec.data.source}; residual = "
            f"largest marker distance of the sample [m]; backbone length: {options.length}; end speeds "
            f"{options.speeds_note()}"
        ]
        + given.notes(),
    )
