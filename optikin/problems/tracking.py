"""Problem kind ``tracking``: a continuum arm follows a tip reference in closed loop (issue 6; seed 000 V-VI).

The solver under study is the constrained QP per control step
(:mod:`optikin.control.qp`, any ``qp`` backend preset); the baselines, run on the
same reference, plant and noise draws, are the seed's MRAC (``mrac``,
:mod:`optikin.baselines.mrac`), the plain pseudo-inverse (``pseudo_inverse``)
and damped least squares (``damped_least_squares``).

The reference (``data``) is either the forward kinematics of a minimum-jerk
configuration path (source ``waypoints``, :mod:`optikin.control.reference`) or
the roll-out of a pose DMP learned from the flexible-interface IMU demonstration
of seed 000 (source ``dmp``: params ``task``, ``rate``, ``variant``
(dual-quaternion | cartesian | seed), ``basis``, ``demonstration_samples``,
``hold``, ``smoothing`` (cut-off in Hz of the demonstration smoother, null for
none); the run starts from the interface's first configuration)::

    data:
      source: waypoints
      seed: 1                       # sensor-noise draws
      params:
        task: pose                  # pose (dual quaternion, 8 rows) | position (3 rows)
        rate: 500                   # control rate [Hz], 100 .. 1000
        waypoints: [[S1, theta1, phi1, S2, theta2, phi2], ...]   # SI units
        segment_time: 1.5           # seconds per segment (one value or one per segment)
        hold: 1.0                   # seconds at the last waypoint

Options (all optional)::

    start: [..]                  # initial configuration (default: first waypoint)
    start_offset: [..]           # added to the start
    gain: 10.0                   # K of the QP, pseudo-inverse and DLS (scalar or one per task row) [1/s]
    damping: 1.0e-4              # lambda of the QP and DLS
    rate_limits: {S: 0.1, theta: 3.14159, phi: 6.28319}   # by name or prefix [m/s, rad/s]
    limit_margin: 1.0e-9         # kept from the configuration limits by the QP (scalar or per variable)
    limit_gain: 1.0              # fraction of the distance to a limit one step may cover (pink: 0.5)
    fallback: hold               # hold | damped_least_squares, when the QP solver fails
    compiled: false              # compile the per-step CasADi Function with gcc
    plant: {length_scale: 1.05, disturbance: [..], disturbance_window: [t_on, t_off],
            configuration_noise: [..], tip_position_noise: 0.0005, tip_angle_noise: 0.005, feedback: tip}
    mrac: {gain: [..], adaptation: [..], gain_limit: 100, natural_frequency: 10, damping_ratio: 1}
    tolerance: {position_mm: 0.05, orientation_deg: 0.05}   # convergence check on the last 10 % of the run

Per-step status: ``ok``, or ``failed`` where the QP solver failed and the
fallback was applied (the reason is in the notes).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from optikin.baselines.mrac import MRACController
from optikin.baselines.pseudo_inverse import DampedLeastSquaresController, PseudoInverseController
from optikin.control import figures
from optikin.control.qp import FALLBACKS, QPController
from optikin.algebra import dq_from_rotation_translation, quat_hemisphere_continuous
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.reference import Reference, minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import Plant, TrackingRun, simulate
from optikin.control.task import TASK_FUNCTIONS, task_dimension
from optikin.data.demonstrations import imu_interface_recording
from optikin.dmp.pose import POSE_VARIANTS, from_variant, pose_dmp, to_variant
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.results import MethodRow, Result

DATA_DEFAULTS = {"task": "pose", "rate": 500.0, "waypoints": None, "segment_time": 1.5, "hold": 1.0}
DMP_DATA_DEFAULTS = {"task": "pose", "rate": 500.0, "variant": "dual-quaternion", "basis": 50,
                     "demonstration_samples": 1000, "hold": 1.0, "smoothing": 2.5}
OPTION_DEFAULTS: dict[str, Any] = {
    "start": None, "start_offset": None, "gain": 10.0, "damping": 1e-4, "rate_limits": None,
    "limit_margin": 1e-9, "limit_gain": 1.0,
    "fallback": "hold", "compiled": False, "plant": {}, "mrac": {},
    "tolerance": {"position_mm": 0.05, "orientation_deg": 0.05},
}
COMPARED = {
    "rms [mm]": "position error rms [mm]", "final [mm]": "position error final [mm]",
    "final [deg]": "orientation error final [deg]", "outside limits": "samples outside limits",
    "excess S [mm]": "max limit excess S [mm]", "excess theta [deg]": "max limit excess theta [deg]",
    "step [us]": "step time median [us]",
}
"""Columns of the comparison table: short name -> metric of :meth:`TrackingRun.metrics`."""
MRAC_KEYS = ("gain", "adaptation", "gain_limit", "natural_frequency", "damping_ratio")
BASELINES = ("mrac", "pseudo_inverse", "damped_least_squares")


def _settings(ctx: ProblemContext, given: dict, defaults: dict, where: str) -> dict:
    for key in given:
        if key not in defaults:
            raise ctx.error(f"{where}.{key}", f"unknown setting; known: {', '.join(defaults)}")
    return {**defaults, **given}


def _vector(ctx: ProblemContext, value, n: int, field: str, allow_scalar: bool = False) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ctx.error(field, f"expected numbers, got {value!r}") from None
    if allow_scalar and v.ndim == 0:
        v = np.full(n, float(v))
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise ctx.error(field, f"expected {n} finite numbers{' or one' if allow_scalar else ''}, got {value!r}")
    return v


def _reference(ctx: ProblemContext):
    """The reference and the configuration the run starts from (before ``options.start*``)."""
    spec = ctx.spec
    sources = {"waypoints": (_waypoint_reference, DATA_DEFAULTS), "dmp": (_dmp_reference, DMP_DATA_DEFAULTS)}
    if spec.data.source not in sources:
        raise ctx.error("data.source", f"unknown reference source {spec.data.source!r}; known: {', '.join(sources)}")
    if "samples" in spec.data.model_fields_set:
        raise ctx.error("data.samples", "not used by tracking: the run length follows from the path and rate")
    build, defaults = sources[spec.data.source]
    p = _settings(ctx, spec.data.params, defaults, "data.params")
    if p["task"] not in TASK_FUNCTIONS:
        raise ctx.error("data.params.task", f"unknown task {p['task']!r}; known: {', '.join(TASK_FUNCTIONS)}")
    rate = float(p["rate"])
    if not 100.0 <= rate <= 1000.0:
        raise ctx.error("data.params.rate", f"control rate {rate} Hz outside 100 .. 1000 Hz")
    return build(ctx, p, rate)


def _dmp_reference(ctx: ProblemContext, p: dict, rate: float):
    """A pose DMP learned from the flexible-interface demonstration (seed 000 sec. III), rolled out at ``rate``.

    The demonstration is the IMU recording of :func:`optikin.data.demonstrations.imu_interface_recording`
    (seeded by ``data.seed``); the DMP's roll-out is the tip reference, its derivative taken by
    central differences; the run starts from the interface's true first configuration.
    """
    arm = ctx.arm
    if not isinstance(arm, ConstantCurvatureArm) or arm.n_sections != 2:
        raise ctx.error("arm", "the dmp reference source learns from the two-section interface: "
                               "use a two-section constant_curvature arm")
    if p["variant"] not in POSE_VARIANTS:
        raise ctx.error("data.params.variant", f"unknown pose DMP variant {p['variant']!r}; known: "
                                               f"{', '.join(POSE_VARIANTS)}")
    recording = imu_interface_recording(samples=int(p["demonstration_samples"]), seed=ctx.spec.data.seed,
                                        section_lengths=tuple(arm.section_lengths))
    dmp = pose_dmp(p["variant"], n_basis=int(p["basis"]),
                   smoothing=None if p["smoothing"] is None else float(p["smoothing"]))
    dmp.imitate(recording.t, to_variant(p["variant"], recording.demonstration.dual_quaternion),
                source="IMU demonstration")
    rollout = dmp.rollout(dmp.tau + float(p["hold"]), dt=1.0 / rate)
    position, quaternion = from_variant(p["variant"], rollout.y)
    value = (dq_from_rotation_translation(quat_hemisphere_continuous(quaternion), position)
             if p["task"] == "pose" else position)
    reference = Reference(rollout.t, value, np.gradient(value, rollout.t, axis=0), p["task"])
    return reference, recording.configuration[0]


def _waypoint_reference(ctx: ProblemContext, p: dict, rate: float):
    arm = ctx.arm
    if p["waypoints"] is None:
        raise ctx.error("data.params.waypoints", "required: at least two configurations")
    try:
        W = np.asarray(p["waypoints"], dtype=float)
    except (TypeError, ValueError):
        raise ctx.error("data.params.waypoints", "expected a list of configurations (lists of numbers)") from None
    if W.ndim != 2 or W.shape[0] < 2 or W.shape[1] != arm.n_config or not np.all(np.isfinite(W)):
        raise ctx.error("data.params.waypoints",
                        f"expected at least two rows of {arm.n_config} numbers ({', '.join(arm.config_names)})")
    try:
        t, Q, Qdot = minimum_jerk_path(W, p["segment_time"], rate, float(p["hold"]))
    except ValueError as exc:
        raise ctx.error("data.params", str(exc)) from None
    return reference_from_configurations(arm, t, Q, Qdot, p["task"]), W[0]


def _plant(ctx: ProblemContext, given: dict, n: int) -> Plant:
    fields = Plant.__dataclass_fields__
    for key in given:
        if key not in fields:
            raise ctx.error(f"options.plant.{key}", f"unknown setting; known: {', '.join(fields)}")
    values = dict(given)
    if "disturbance" in values:
        values["disturbance"] = tuple(_vector(ctx, values["disturbance"], n, "options.plant.disturbance"))
    if "configuration_noise" in values:
        values["configuration_noise"] = tuple(_vector(ctx, values["configuration_noise"], n,
                                                      "options.plant.configuration_noise", allow_scalar=True))
    for key in ("length_scale", "disturbance_window"):
        if isinstance(values.get(key), list):
            values[key] = tuple(values[key])
    if values.get("feedback", "tip") not in ("tip", "model"):
        raise ctx.error("options.plant.feedback", "expected tip or model")
    plant = Plant(**values)
    try:
        plant.length_factors(ctx.arm)
    except ValueError as exc:
        raise ctx.error("options.plant.length_scale", str(exc)) from None
    return plant


def _controllers(ctx: ProblemContext, o: dict, dt: float, task: str) -> dict[str, Any]:
    arm, spec = ctx.arm, ctx.spec
    if o["fallback"] not in FALLBACKS:
        raise ctx.error("options.fallback", f"unknown fallback {o['fallback']!r}; known: {', '.join(FALLBACKS)}")
    common = {"compiled": bool(o["compiled"])}
    m = task_dimension(task)
    mrac = _settings(ctx, o["mrac"], dict.fromkeys(MRAC_KEYS), "options.mrac")
    try:
        qp = QPController(arm, dt, task, o["gain"], o["damping"], solver=ctx.adapter.create(arm.n_config, m),
                          rate_limits=o["rate_limits"], margin=o["limit_margin"], limit_gain=o["limit_gain"],
                          fallback=o["fallback"], **common)
        controllers: dict[str, Any] = {"qp": qp}
        for name in spec.baselines:
            if name == "mrac":
                kwargs = {k: v for k, v in mrac.items() if v is not None}
                controllers[name] = MRACController(arm, dt, task, **kwargs, **common)
            elif name == "damped_least_squares":
                controllers[name] = DampedLeastSquaresController(arm, dt, task, o["gain"], o["damping"], **common)
            else:
                controllers[name] = PseudoInverseController(arm, dt, task, o["gain"], **common)
    except ValueError as exc:
        raise ctx.error("options", str(exc)) from None
    return controllers


def run(ctx: ProblemContext) -> Result:
    spec, arm = ctx.spec, ctx.arm
    reference, path_start = _reference(ctx)
    o = _settings(ctx, spec.options, OPTION_DEFAULTS, "options")
    n = arm.n_config
    q0 = path_start if o["start"] is None else _vector(ctx, o["start"], n, "options.start")
    if o["start_offset"] is not None:
        q0 = q0 + _vector(ctx, o["start_offset"], n, "options.start_offset")
    plant = _plant(ctx, o["plant"], n)
    tolerance = _settings(ctx, o["tolerance"], OPTION_DEFAULTS["tolerance"], "options.tolerance")
    controllers = _controllers(ctx, o, reference.dt, reference.task)

    runs: dict[str, TrackingRun] = {}
    wall: dict[str, float] = {}
    with ctx.progress.task(f"tracking: {len(controllers)} controllers x {len(reference.t)} steps",
                           total=len(controllers)) as advance:
        for name, controller in controllers.items():
            start = time.perf_counter()
            runs[name] = simulate(controller, reference, q0, plant, seed=spec.data.seed)
            wall[name] = time.perf_counter() - start
            advance()

    qp_run = runs["qp"]
    summaries = {name: tracking.metrics() for name, tracking in runs.items()}
    comparison = []
    for name, tracking in runs.items():
        full = summaries[name]
        row = {short: full[key] for short, key in COMPARED.items() if key in full}
        row["converged"] = _converged(full, tolerance)
        comparison.append(MethodRow(tracking.controller, "solver" if name == "qp" else "baseline", row))
    metrics = summaries["qp"] | {"converged": comparison[0].metrics["converged"]}
    for name, tracking in runs.items():
        if summaries[name].get("gain saturation steps") is not None:
            metrics[f"{tracking.controller}: gain saturation steps"] = summaries[name]["gain saturation steps"]
    status = ["ok" if s == "ok" else "failed" for s in qp_run.status]
    notes = _notes(qp_run, runs, summaries)
    arrays: dict[str, np.ndarray] = {"t": reference.t, "reference": reference.value,
                                     "reference_position": reference.position}
    for name, tracking in runs.items():
        arrays |= {f"q_{name}": tracking.q, f"qdot_{name}": tracking.qdot, f"x_{name}": tracking.x,
                   f"V_{name}": tracking.lyapunov, f"step_time_{name}": tracking.step_time}
        if tracking.gains is not None:
            arrays[f"gains_{name}"] = tracking.gains
    shown = {tracking.controller: tracking for tracking in runs.values()}
    title = spec.name

    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=arm.describe(),
        status=status, residuals=qp_run.position_error,
        timings={f"{name} run [s]": value for name, value in wall.items()} | {
            "qp step median [us]": metrics["step time median [us]"], "qp step p95 [us]": metrics["step time p95 [us]"]},
        metrics=metrics, comparison=comparison, arrays=arrays, notes=notes,
        figures={
            "tracking": lambda path: figures.reference_vs_actual(path, shown, f"{title}: tip position"),
            "errors": lambda path: figures.errors(path, shown, f"{title}: tracking errors"),
            "limits": lambda path: figures.limits(path, shown, f"{title}: configuration and limits"),
            "lyapunov": lambda path: figures.lyapunov(path, shown, f"{title}: V(e) = e'e/2"),
            "step_times": lambda path: figures.step_times(path, shown, f"{title}: time per control step"),
        },
    )


def _converged(row: dict, tolerance: dict) -> bool:
    ok = row["position error final [mm]"] < tolerance["position_mm"]
    if "orientation error final [deg]" in row:
        ok = ok and row["orientation error final [deg]"] < tolerance["orientation_deg"]
    return bool(ok)


def _notes(qp_run: TrackingRun, runs: dict[str, TrackingRun], summaries: dict[str, dict]) -> list[str]:
    notes = []
    failed = [(t, s) for t, s in zip(qp_run.t, qp_run.status) if s != "ok"]
    if failed:
        notes.append(f"QP solver failed on {len(failed)} steps; first at t = {failed[0][0]:.4g} s: {failed[0][1]}")
    for name, tracking in runs.items():
        m = summaries[name]
        if m["samples outside limits"]:
            worst = ", ".join(f"{variable} {m[f'max limit excess {variable} [{unit}]']:.3g} {unit}"
                              for variable, unit in (("S", "mm"), ("theta", "deg"))
                              if m.get(f"max limit excess {variable} [{unit}]", 0) > 0)
            notes.append(f"{tracking.controller}: outside the configuration limits on {m['samples outside limits']} "
                         f"steps ({m['steps the controller kept or took outside']} by its own command); "
                         f"farthest: {worst}")
        if m.get("gain saturation steps"):
            notes.append(f"{tracking.controller}: adaptive gain saturated on {m['gain saturation steps']} steps, "
                         f"first at t = {m['first gain saturation [s]']:.4g} s")
    return notes


register_kind(ProblemKind(
    options=None,
    name="tracking",
    summary="closed-loop tip tracking: a bounded QP per control step vs MRAC, pseudo-inverse, DLS",
    run=run,
    backend_families=("qp",),
    default_solver="qp-osqp",
    baselines=BASELINES,
))
