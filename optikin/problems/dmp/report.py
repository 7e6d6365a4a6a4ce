"""The ``dmp`` kind's outcome as a :class:`~optikin.results.Result`: metrics, comparison rows, arrays, notes.

Arrays: ``t``, ``demo_position``, ``demo_quaternion`` (the demonstration
learned, positions from ``options.origin_shift``), one ``<variant>__<scenario>`` per roll-out (``reproduction``,
``goal_switch``, ``perturbation_<label>``; states in the variant's layout), and
the recording's own signals (``imu``, ``relative``, ``section_angles`` of the
IMU interface; ``kinect_position``, ``kinect_rpy``, ``kinect_filtered_rpy``).
"""

from __future__ import annotations

import numpy as np

from optikin.data import demonstrations as sources
from optikin.dmp.tuning import TuningResult
from optikin.problems.dmp.run import DmpOutcome, PerturbationRun, Reproduction, TuningOutcome
from optikin.problems.dmp.variants import MM, rollout_status, unit_of
from optikin.results import MethodRow, Result
from optikin.spec import ProblemSpec


def rollout_key(variant: str, scenario: str) -> str:
    """The array name of a roll-out: ``<variant>__<scenario with spaces as underscores>``."""
    return f"{variant}__{scenario.replace(' ', '_')}"


def result(spec: ProblemSpec, outcome: DmpOutcome) -> Result:
    """The result of a run of the ``dmp`` kind."""
    demo = outcome.demo
    tau = float(demo.t[-1] - demo.t[0])
    metrics: dict[str, float | int] = {"demonstration samples": int(demo.t.size), "demonstration duration [s]": tau}
    labels = [f"{r.variant}: reproduction" for r in outcome.reproductions if r.role == "solver"]
    status = [rollout_status(r.rollout.y, r.unit_error or 0.0) for r in outcome.reproductions if r.role == "solver"]
    for run in outcome.goal_switches:
        for k, v in run.final.items():
            unit, scale = unit_of(k)
            metrics[f"{run.variant}: goal switch final {k} [{unit}]"] = v * scale
        labels.append(f"{run.variant}: goal switch")
        status.append(run.status)
    for push in outcome.perturbations:
        metrics |= _perturbation_metrics(push)
        labels.append(f"{push.variant}: perturbation {push.label}")
        status.append(push.status)
    comparison = [_reproduction_row(r, outcome.method) for r in outcome.reproductions]
    for tuning in outcome.tuning:
        comparison += _tuning_rows(tuning)
    first = outcome.reproductions[0]
    return Result(
        problem=spec.name,
        kind=spec.kind,
        solver=f"{outcome.method} regression",
        title=spec.title,
        arm={"demonstration": spec.data.source},
        status=status,
        timings={"fit [ms]": first.fit.seconds * 1e3},
        metrics=metrics,
        comparison=comparison,
        arrays=arrays(outcome),
        notes=notes(outcome, labels),
    )


def error_summary(errors: dict[str, np.ndarray], prefix: str) -> dict[str, float]:
    """``<prefix> position max [mm]`` and ``<prefix> orientation max [mrad]`` of per-sample errors [m | rad]."""
    out = {}
    for k in ("position", "orientation"):
        if k in errors:
            unit, scale = unit_of(k)
            out[f"{prefix} {k} max [{unit}]"] = float(errors[k].max() * scale)
    return out


def _reproduction_row(r: Reproduction, method: str) -> MethodRow:
    row: dict[str, float | int | str] = {
        "fit residual": r.fit.residual,
        "fit time [ms]": r.fit.seconds * 1e3,
        "roll-out time [ms]": r.rollout.seconds * 1e3,
        **error_summary(r.errors, "reproduction"),
    }
    if "position" in r.errors:
        row["reproduction position rms [mm]"] = _rms(r.errors["position"]) * MM
    if r.truth_errors is not None:  # the recording's noise-free motion
        row |= error_summary(r.truth_errors, "vs true motion")
    if r.unit_error is not None:
        row["unit-norm error"] = r.unit_error
    if r.bound is not None:
        row |= _bound_metrics(r, *r.bound)
    return MethodRow(f"dmp {r.variant} ({r.method})", r.role, row)


LIMITATION = "structural: |Q_d| is fixed, so |p| cannot change (a limitation of the variant, not of the truth)"
"""The label of a ``seed`` variant's row."""


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _bound_metrics(r: Reproduction, radius: float, bound: np.ndarray) -> dict[str, float | str]:
    """A ``seed`` variant's structural bound (max and RMS [mm]), the radius it keeps and its position error at 0."""
    return {
        "structural bound position max [mm]": float(bound.max() * MM),
        "structural bound position rms [mm]": _rms(bound) * MM,
        "distance kept from the origin [mm]": radius * MM,
        "reproduction position at t = 0 [mm]": float(r.errors["position"][0] * MM),
        "limitation": LIMITATION,
    }


def _perturbation_metrics(push: PerturbationRun) -> dict[str, float]:
    name = f"{push.variant}: perturbation {push.label}"
    out = {}
    for k, v in push.deviation.items():
        unit, scale = unit_of(k)
        out[f"{name} peak {k} deviation [{unit}]"] = float(v.max() * scale)
        out[f"{name} final {k} deviation [{unit}]"] = float(v[-1] * scale)
    out[f"{name} phase at the end"] = push.phase_end
    out[f"{name} undisturbed phase at the end"] = push.calm_phase_end
    return out


def _tuning_rows(tuning: TuningOutcome) -> list[MethodRow]:
    """One row per tuner and seed (the first seed unlabelled), and one for the reference gains if given."""
    rows, seen = [], set()
    by_method: dict[str, int] = {}
    for found in tuning.results:
        k = by_method[found.method] = by_method.get(found.method, -1) + 1
        label = found.method if found.method not in seen else f"{found.method}, seed {tuning.seeds[k]}"
        seen.add(found.method)
        rows.append(_tuning_row(tuning, found, label))
    if tuning.reference_error is not None:
        metrics: dict[str, float | int | str] = {"eq. 29 error": tuning.reference_error, **tuning.reference}
        rows.append(MethodRow(f"tuning {tuning.variant} (reference gains)", "baseline", metrics))
    return rows


def _gain(found: TuningResult, name: str) -> float:
    """A tuned gain, ``beta_g0[i]`` the ``i``-th rate of a diagonal ``beta_g0``."""
    if name.startswith("beta_g0["):
        return float(np.atleast_1d(found.gains.beta_g0)[int(name[len("beta_g0[") : -1])])
    return float(getattr(found.gains, name))


def _tuning_row(tuning: TuningOutcome, found: TuningResult, label: str) -> MethodRow:
    metrics: dict[str, float | int | str] = {
        "eq. 29 error": found.error,
        "eq. 29 error at start": found.initial_error,
        "time [s]": found.seconds,
        "objective evaluations": found.evaluations,
        "status": found.status,
        **{n: _gain(found, n) for n in tuning.names},
    }
    return MethodRow(f"tuning {tuning.variant} ({label})", "solver" if found.method == "ipopt" else "baseline", metrics)


def arrays(outcome: DmpOutcome) -> dict[str, np.ndarray]:
    """The demonstration, every roll-out and the recording's signals (the module docstring)."""
    demo = outcome.demo
    out: dict[str, np.ndarray] = {"t": demo.t, "demo_position": demo.position, "demo_quaternion": demo.quaternion}
    for r in outcome.reproductions:
        if r.role == "solver":
            out[rollout_key(r.variant, "reproduction")] = r.rollout.y
    for run in outcome.goal_switches:
        out[rollout_key(run.variant, "goal switch")] = run.y
    for push in outcome.perturbations:
        out[rollout_key(push.variant, f"perturbation {push.label}")] = push.y
    recording = outcome.recording
    if isinstance(recording, sources.InterfaceRecording):
        out |= {"imu": recording.imu, "relative": recording.relative, "section_angles": recording.angles}
    if isinstance(recording, sources.KinectRecording):
        out |= {
            "kinect_position": recording.position,
            "kinect_rpy": recording.rpy,
            "kinect_filtered_rpy": recording.filtered_rpy,
        }
    return out


def notes(outcome: DmpOutcome, labels: list[str]) -> list[str]:
    """The structural limitation of each ``seed`` variant (its fixed ``|Q_d|``), and the labels of the per-roll-out
    status."""
    out = []
    radius = np.linalg.norm(outcome.demo.position, axis=1) * MM
    for r in outcome.reproductions:
        if r.bound is None or r.role != "solver":
            continue
        kept, bound = r.bound
        error = r.errors["position"] * MM
        out.append(
            f"{r.variant} variant, a structural limitation of the variant, not of the truth: the roll-out keeps "
            f"|Q_d| = {kept / 2:.4f} m, so the tip stays {kept * MM:.1f} mm from the world origin, while the "
            f"demonstration goes from {radius[0]:.1f} to {radius[-1]:.1f} mm (range {radius.min():.1f} .. "
            f"{radius.max():.1f}); no roll-out of it is closer than | |p(t)| - {kept * MM:.1f} mm | = "
            f"{bound.max() * MM:.2f} mm (max), {_rms(bound) * MM:.2f} mm (RMS); its error {error.max():.2f} mm "
            f"(max), {_rms(error):.2f} mm (RMS), {error[0]:.2f} mm at t = 0; the bound moves with the "
            "world origin (options.origin_shift; optikin.dmp.pose)"
        )
    out.append(f"labels of the per-roll-out status: {labels}")
    return out
