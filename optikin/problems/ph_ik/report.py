"""A ``ph_ik`` outcome as a Result: the Table II analogue per tube, Table III times, every method's row."""

from __future__ import annotations

from typing import Any, cast

import numpy as np

from optikin.data.configurations import skipped_rows_notes
from optikin.data.cosserat_markers import CosseratTruth
from optikin.arms.cbha import CBHAArm
from optikin.baselines.ph_comparators import (
    COMPARATORS,
    HYBRID,
    HYBRID_STORES,
    NEWTON_RAPHSON,
    NR_TARGETS,
    hybrid_inputs,
    networks_arm,
    training_tips,
)
from optikin.problems import ProblemContext
from optikin.problems.fairness import ArmSize, Given, Manifest, cbha_name, cbha_size, coverage, recorded_arm
from optikin.problems.ph_ik.options import PHIkOptions
from optikin.problems.ph_ik.run import IkOutcome
from optikin.problems.ph_shared import MM, method_rows, summary_of
from optikin.results import MethodRow, Result
from optikin.status import Status

SEED_TABLE_II_MM = {
    "PH": {"L1": (0.0112, 4.4020, 2.8239), "L2": (0.0032, 5.2327, 2.2020), "L3": (0.0012, 3.5959, 0.9768)},
    "Newton-Raphson": {"L1": (1.9555, 13.2310, 6.3947), "L2": (0.1101, 7.5254, 3.9361), "L3": (0.0054, 9.9292, 6.2398)},
}
"""Singh et al. 2018, Table II: (min, max, mean) absolute tube-length error over the trajectory, mm."""
SEED_TABLE_III_S = {"PH": 0.00027, NEWTON_RAPHSON: 0.23351, HYBRID: 0.01208}
"""Singh et al. 2018, Table III: time cost for one sample, seconds."""


def error_metrics(errors_mm: np.ndarray) -> dict[str, list[float]]:
    """``L<m> error min / avg / max [mm]`` per tube (Table II)."""
    out = {}
    for m in range(errors_mm.shape[1]):
        s = summary_of(errors_mm[:, m])
        out[f"L{m + 1} error min / avg / max [mm]"] = [s["min"], s["avg"], s["max"]]
    return out


def ph_rows(outcome: IkOutcome) -> list[MethodRow]:
    """The ``ph`` methods' rows, then the solver's curves carried by the other frame."""
    extra = {}
    for name in outcome.runs:
        err = np.abs(outcome.tubes[name] - outcome.reference) * MM
        extra[name] = {
            "mean |L error| [mm]": float(np.nanmean(err)),
            "max |L error| [mm]": float(np.nanmax(err)),
            "median IK time per sample [us]": float(np.median(outcome.ik_seconds[name]) * 1e6),
        }
    rows = method_rows(outcome.runs, extra)
    other_errors = np.abs(outcome.other_tubes - outcome.reference) * MM
    other: dict[str, Any] = {**error_metrics(other_errors), "mean |L error| [mm]": float(np.nanmean(other_errors))}
    rows.append(MethodRow(f"{outcome.solver}, {outcome.other_frame} frame", "baseline", other))
    return rows


def comparator_rows(outcome: IkOutcome) -> tuple[list[MethodRow], dict[str, np.ndarray], list[str]]:
    """The comparators' rows, arrays and notes (postures not ``ok`` are counted)."""
    rows: list[MethodRow] = []
    arrays: dict[str, np.ndarray] = {}
    notes: list[str] = []
    for name, found in outcome.comparators.items():
        errors = np.abs(found.lengths - outcome.reference) * MM
        status = np.array(found.status)
        failed = np.flatnonzero(status != Status.OK)
        seed_time = SEED_TABLE_III_S.get(name)
        metrics: dict[str, Any] = {
            "ok": f"{len(status) - failed.size}/{len(status)}",
            "failures": int(failed.size),
            **error_metrics(errors),
            "mean |L error| [mm]": summary_of(errors.ravel())["avg"],
            "median IK time per sample [us]": float(np.median(found.seconds) * 1e6),
            **({f"seed 002 Table III, {name}: time per sample [us]": seed_time * 1e6} if seed_time else {}),
        }
        rows.append(MethodRow(name, "baseline", metrics))
        key = name.replace("-", "_")
        arrays |= {f"tube_lengths_{key}": found.lengths, f"status_{key}": status, f"ik_seconds_{name}": found.seconds}
        if failed.size:
            notes.append(
                f"{name}: {failed.size} of {len(status)} postures not ok (no tube lengths), "
                f"e.g. sample {failed[0]}: {found.status[failed[0]]}, {found.messages[failed[0]]}"
            )
    return rows, arrays, notes


def ik_metrics(outcome: IkOutcome) -> dict[str, Any]:
    """The solver's Table II analogue, its time per sample and the seed's numbers."""
    tubes = outcome.tubes[outcome.solver]
    metrics: dict[str, Any] = {
        **error_metrics(np.abs(tubes - outcome.reference) * MM),
        "median IK time per sample [us]": float(np.median(outcome.ik_seconds[outcome.solver]) * 1e6),
        "seed 002 Table II, PH: L1 / L2 / L3 mean error [mm]": [v[2] for v in SEED_TABLE_II_MM["PH"].values()],
        "seed 002 Table III, PH: time per sample [us]": SEED_TABLE_III_S["PH"] * 1e6,
        f"max |L({outcome.other_frame}) - L({outcome.layout.frame})| [mm]": float(
            np.nanmax(np.abs(outcome.other_tubes - tubes)) * MM
        ),
    }
    truth = outcome.recording.truth
    if isinstance(truth, CosseratTruth):
        clean = np.abs(tubes - truth.tube_lengths) * MM
        metrics["L1 / L2 / L3 mean error against the noise-free tube lengths [mm]"] = list(np.nanmean(clean, axis=0))
    if truth is not None:
        metrics["backbone length estimate error mean / max [mm]"] = [
            float(np.mean(np.abs(outcome.lengths - truth.backbone_length)) * MM),
            float(np.max(np.abs(outcome.lengths - truth.backbone_length)) * MM),
        ]
    return metrics


def ik_arrays(outcome: IkOutcome) -> dict[str, np.ndarray]:
    """The arrays of the ``ph`` methods (the figures draw from these and the comparators')."""
    arrays = {
        "t": outcome.recording.t,
        "reference_tube_lengths": outcome.reference,
        "tube_lengths": outcome.tubes[outcome.solver],
        f"tube_lengths_{outcome.other_frame}": outcome.other_tubes,
        "backbone_length": outcome.lengths,
        "ph_points": outcome.main.curves.point(np.linspace(0, 1, 101)),
    }
    for name, method in outcome.runs.items():
        arrays[f"ik_seconds_{name}"] = outcome.ik_seconds[name]
        arrays[f"energy_{name}"] = method.energies
    return arrays


NR_INFORMATION = {
    "sections": "the tip rigid body and the marker at the end of section 1 (one measurement more than the PH rows)",
    "pose": "the tip pose relative to the base (the PH rows' data)",
}


def manifest(ctx: ProblemContext, tube_lengths: np.ndarray | None = None) -> Manifest:
    """What every row of a ``ph_ik`` comparison is given (:mod:`optikin.problems.fairness`).

    The PH rows get the tube offsets (a lab measures them); the Newton-Raphson rows the
    problem's CBHA vertebra model; the hybrid rows their networks' own arm, labelled when it
    is not the problem's. ``tube_lengths`` [m], the recorded ones, are checked against each
    model's range.
    """
    options: PHIkOptions = ctx.options
    arm = ctx.arm
    truth, shared = recorded_arm(ctx.spec.data.source, ctx.data_params, arm)
    own = "generator's own" if shared else "measured"
    if options.tube_radius is not None:
        radii = (float(options.tube_radius[0]), float(options.tube_radius[1]))
        offsets = ArmSize("tube offsets of options.tube_radius", radii)
    else:
        geometry = cast(CBHAArm, arm).geometry
        offsets = ArmSize("tube offsets of the arm's r_max, r_min", (float(geometry.r_max), float(geometry.r_min)))
    solver = ctx.solver.name if ctx.solver is not None else ""
    ph = [solver] + [b for b in ctx.spec.baselines if b not in COMPARATORS and b != solver]
    entries = [
        Given(
            name,
            own,
            offsets,
            budget=f"preset {name}, one solve per posture",
            information="the base and tip rigid bodies",
        )
        for name in ph
    ]
    for name in (n for n in COMPARATORS if n in ctx.spec.baselines):
        geometry = cast(CBHAArm, arm).geometry
        if name in NR_TARGETS:
            entries.append(
                Given(
                    name,
                    own,
                    cbha_size(geometry, cbha_name(geometry)),
                    budget="Newton (CasADi rootfinder) to |r| <= 1e-9 m per posture, warm-started along the recording",
                    limits="Table I (the affine elongation distribution keeps every leg inside)",
                    information=NR_INFORMATION[NR_TARGETS[name]],
                )
            )
            continue
        store = HYBRID_STORES[name]
        theirs = networks_arm(store).geometry
        another = cbha_size(theirs, "") != cbha_size(geometry, "")
        entries.append(
            Given(
                name,
                "another arm" if another else own,
                cbha_size(theirs, f"the shipped networks' arm, {cbha_name(theirs)}"),
                training=f"the shipped networks NN1-NN4 of {store.parent.name} (setting adam)",
                budget="one forward pass per posture",
                information="the tip position relative to the base",
                label=(
                    f"trained on {cbha_name(theirs)}, not this problem's {cbha_name(geometry)}: what reusing "
                    "them on this arm costs, not the hybrid approach's accuracy"
                    if another
                    else ""
                ),
            )
        )
    return Manifest(truth, shared, tuple(entries), tube_lengths)


def report(ctx: ProblemContext, outcome: IkOutcome) -> Result:
    """The Result of a ``ph_ik`` run."""
    spec, main, layout, options = ctx.spec, outcome.main, outcome.layout, outcome.options
    errors = np.abs(outcome.tubes[outcome.solver] - outcome.reference) * MM
    rows, comparator_arrays, comparator_notes = comparator_rows(outcome)
    given = manifest(ctx, outcome.reference)
    if options.coverage:
        tips = hybrid_inputs(outcome.recording)
        for name in (n for n in outcome.comparators if n in HYBRID_STORES):
            label = "tested outside its training range: the recording's tips lie beyond its database's"
            given = given.with_coverage(name, coverage(training_tips(HYBRID_STORES[name]), tips), label)
    metrics = ik_metrics(outcome) | given.metrics()
    notes = [
        f"{len(outcome.recording)} postures from {outcome.recording.source or spec.data.source}; tubes carried "
        f"by the {layout.frame} frame at {layout.radius_start * MM:.1f} mm (base) to "
        f"{layout.radius_end * MM:.1f} mm (tip); backbone length: {options.length}; end speeds "
        f"{options.speeds_note()}"
    ]
    return ctx.result(
        solver=outcome.solver,
        status=main.status,
        iterations=main.iterations,
        residuals=np.nanmax(errors, axis=1) / MM,
        timings={
            "median IK per sample [us]": float(np.median(outcome.ik_seconds[outcome.solver]) * 1e6),
            "build [s]": main.build_seconds,
        },
        metrics=metrics,
        comparison=given.annotate(ph_rows(outcome) + rows),
        arrays={**ik_arrays(outcome), **comparator_arrays},
        notes=skipped_rows_notes(outcome.recording.skipped_rows, ctx.data_params)
        + notes
        + comparator_notes
        + given.notes(),
    )
