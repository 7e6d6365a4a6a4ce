"""Tip references of the ``tracking`` kind (data family ``references``): where the tip should be, step by step.

``waypoints``
    The forward kinematics of a minimum-jerk configuration path through
    waypoints written in the problem file (:mod:`optikin.control.reference`):
    exactly reachable by the model wherever the path stays inside the limits.
``dmp``
    The roll-out of a pose DMP learned from the flexible-interface IMU
    demonstration of Seleem et al. 2020 (section VII): the two IMUs record the
    interface (:func:`optikin.data.demonstrations.imu_interface_recording`,
    seeded by ``data.seed``), a DMP of the chosen variant learns the tip pose
    (:mod:`optikin.dmp.pose`) and its roll-out, differentiated by central
    differences, is the reference; the run starts from the interface's first
    configuration.
``kinect-dmp``
    The chain of Seleem et al. 2020 section IV and Figs. 26-27: a Kinect v2
    right-wrist recording at 30 frames per second
    (:func:`optikin.data.demonstrations.kinect_recording`, seeded by
    ``data.seed``), calibrated into a workspace cube and smoothed by the
    moving-average filter of eq. (31) there, learned by a translation DMP
    (:class:`optikin.dmp.DMP` on :class:`optikin.dmp.Euclidean` ``(3)``) whose
    roll-out at the control rate, differentiated by central differences, is
    the tip-position reference. The seed's 36 cm cube does not fit in the
    reachable shell of two 18 cm CC sections, so the cube's edge and centre are
    parameters (default: 10 cm about (0.18, 0, 0.26) m, inside it). The run
    starts from a configuration whose tip is the reference's first point
    (bounded least squares from a fixed set of starts).

``csv``
    A user's recorded demonstration (:func:`optikin.data.demonstrations.read_demonstration`:
    the same files the ``dmp`` kind reads -- ``t`` and tip positions ``x, y, z``, tip poses
    ``x, y, z, qw, qx, qy, qz`` or the arm's configurations, ``data.params.file`` relative
    to the problem file), either tracked as recorded -- interpolated at the control rate
    (cubic splines through positions and configurations, slerp between orientations; no
    interpolation across a gap longer than ``max_step``), rates from the splines'
    derivatives -- or, with ``dmp: {...}``, learned by a DMP first (:mod:`optikin.dmp.pose`
    for poses, a translation DMP for positions) whose roll-out is the reference. A
    configuration file gives the exact reference ``fk(q(t))``, ``J(q(t)) qdot(t)`` and
    starts from its first row; a pose or position file starts from a configuration whose
    tip reaches the first sample (bounded least squares), which must be within
    ``start_tolerance`` of it.

Each loader returns a :class:`TrackingReference`: the reference at the control
rate and the configuration the run starts from (before ``options.start`` and
``options.start_offset``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, PositiveFloat
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares

from optikin.algebra import (
    dq_from_rotation_translation,
    dq_rotation,
    dq_translation,
    quat_hemisphere_continuous,
    quat_slerp,
)
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.limits import wrap_periodic
from optikin.control.reference import Reference, minimum_jerk_path, reference_from_configurations
from optikin.data.demonstrations import (
    DemonstrationFileParams,
    RecordedDemonstration,
    imu_interface_recording,
    kinect_recording,
    read_params_file,
)
from optikin.data.sources import register_source
from optikin.dmp import DMP, Euclidean
from optikin.dmp.pose import PoseVariant, from_variant, pose_dmp, to_variant
from optikin.errors import SpecError
from optikin.options import Options
from optikin.spec import DataSpec


@dataclass(frozen=True)
class TrackingReference:
    """A tip reference and the configuration ``(n,)`` the run starts from (SI units)."""

    reference: Reference
    start: np.ndarray


class ReferenceParams(Options):
    """What every reference source takes: the tracked task and the control rate."""

    task: Literal["pose", "position"] = Field(
        "pose", description="pose: tip dual quaternion (8 rows); position: tip position (3 rows)"
    )
    rate: float = Field(500.0, ge=100.0, le=1000.0, description="control rate [Hz]")


WAYPOINT_REACH = 0.5
"""How far a waypoint may lie outside the arm's limits of a (non-periodic) variable, as a fraction of the larger
magnitude of its two limits: a reference the arm cannot follow within its limits is a scenario (track-into-limits
takes theta_1 to 1.3 x its limit), a waypoint far beyond them (theta at 5 rad for a 2.09 rad limit) a typing
error."""


class WaypointParams(ReferenceParams):
    """A minimum-jerk configuration path through waypoints, held at the last one."""

    waypoints: list[list[float]] = Field(
        min_length=2, description="at least two configurations of the arm, in its variables' order [SI units]"
    )
    segment_time: PositiveFloat | list[PositiveFloat] = Field(
        1.5, description="seconds per segment: one value, or one per segment [s]"
    )
    hold: float = Field(1.0, ge=0.0, description="seconds held at the last waypoint [s]")


class DmpParams(ReferenceParams):
    """A pose DMP learned from the IMU demonstration of the flexible interface, rolled out at the control rate."""

    variant: PoseVariant = Field("dual-quaternion", description="pose DMP variant (optikin.dmp.pose)")
    basis: int = Field(50, ge=1, description="basis functions of the DMP")
    demonstration_samples: int = Field(1000, ge=2, description="samples of the recorded demonstration (100 Hz)")
    hold: float = Field(1.0, ge=0.0, description="seconds rolled out after the demonstration's duration [s]")
    smoothing: PositiveFloat | None = Field(
        2.5, description="cut-off of the demonstration smoother [Hz]; null for none"
    )


class KinectDmpParams(Options):
    """A translation DMP learned from the filtered Kinect wrist recording, rolled out at the control rate."""

    task: Literal["position"] = Field("position", description="the tip position (3 rows): the wrist gives no pose")
    rate: float = Field(100.0, ge=100.0, le=1000.0, description="control rate [Hz]")
    demonstration_samples: int = Field(300, ge=10, description="Kinect frames recorded")
    frame_rate: PositiveFloat = Field(30.0, description="Kinect frame rate [frames/s]")
    via_points: int = Field(3, ge=0, description="random via points of the wrist path")
    position_noise: float = Field(0.008, ge=0.0, description="skeleton jitter of the wrist per axis [m]")
    window: int = Field(5, ge=1, description="samples M of the moving average of eq. (31)")
    cube_edge: PositiveFloat = Field(0.10, description="edge of the cube the wrist is scaled into [m]")
    workspace_centre: tuple[float, float, float] = Field(
        (0.18, 0.0, 0.26), description="centre of that cube in the arm's base frame [m]"
    )
    basis: int = Field(30, ge=2, description="basis functions of the DMP")
    hold: float = Field(1.0, ge=0.0, description="seconds rolled out after the demonstration's duration [s]")
    smoothing: PositiveFloat | None = Field(
        None, description="cut-off of the DMP's own demonstration smoother [Hz]; null: the moving average only"
    )


class FileDmpParams(Options):
    """The DMP a recorded demonstration is learned by before it is tracked (source ``csv``)."""

    variant: PoseVariant | Literal["position"] = Field(
        "dual-quaternion",
        description="dual-quaternion | cartesian | seed (pose DMPs, optikin.dmp.pose) | position (a translation DMP)",
    )
    basis: int = Field(30, ge=2, description="basis functions of the DMP")
    smoothing: PositiveFloat | None = Field(
        None, description="cut-off of the DMP's demonstration smoother [Hz] (sensor data); null for none"
    )


class FileReferenceParams(ReferenceParams, DemonstrationFileParams):
    """A recorded demonstration file, tracked as recorded or through a DMP learned from it."""

    dmp: FileDmpParams | None = Field(None, description="learn the demonstration by this DMP first; null: track it")
    hold: float = Field(1.0, ge=0.0, description="seconds the last sample (or the DMP's goal) is held [s]")
    max_step: PositiveFloat = Field(
        0.1, description="largest time step between two rows the reference is interpolated across [s]"
    )
    max_duration: PositiveFloat = Field(
        600.0, description="longest demonstration accepted [s] (a longer one usually has times in ms)"
    )
    start_tolerance: PositiveFloat = Field(
        0.005, description="largest distance of the first tip sample from the closest reachable tip position [m]"
    )


@register_source(
    "references", "waypoints", "forward kinematics of a minimum-jerk path through configurations", params=WaypointParams
)
def waypoint_reference(arm: ArmModel, data: DataSpec, params: WaypointParams, path: Path) -> TrackingReference:
    """The reference ``fk(q(t))``, ``J(q(t)) qdot(t)`` of the path; the run starts at the first waypoint."""
    try:
        W = np.asarray(params.waypoints, dtype=float)
    except ValueError:  # rows of different lengths
        W = np.zeros((0, 0))
    if W.ndim != 2 or W.shape[1] != arm.n_config:
        raise SpecError(
            str(path),
            "data.params.waypoints",
            f"expected at least two rows of {arm.n_config} numbers ({', '.join(arm.config_names)})",
        )
    reach = WAYPOINT_REACH * np.maximum(np.abs(arm.lower), np.abs(arm.upper))
    for i, row in enumerate(W):
        for j, name in enumerate(arm.config_names):
            low, high = arm.lower[j] - reach[j], arm.upper[j] + reach[j]
            if not arm.periodic[j] and not low <= row[j] <= high:
                raise SpecError(
                    str(path),
                    f"data.params.waypoints.{i}.{j}",
                    f"{name} = {row[j]:g} is too far outside the arm's limits [{arm.lower[j]:g}, {arm.upper[j]:g}]: "
                    f"a waypoint may lie in [{low:g}, {high:g}]",
                )
    try:
        t, Q, Qdot = minimum_jerk_path(W, params.segment_time, params.rate, params.hold)
    except ValueError as exc:
        raise SpecError(str(path), "data.params", str(exc)) from None
    return TrackingReference(reference_from_configurations(arm, t, Q, Qdot, params.task), W[0])


@register_source(
    "references", "dmp", "roll-out of a pose DMP learned from the IMU interface demonstration", params=DmpParams
)
def dmp_reference(arm: ArmModel, data: DataSpec, params: DmpParams, path: Path) -> TrackingReference:
    """The DMP roll-out as the reference; the run starts from the interface's true first configuration.

    Needs a two-section constant-curvature arm (the interface's geometry is the arm's).
    """
    if not isinstance(arm, ConstantCurvatureArm) or arm.n_sections != 2:
        raise SpecError(
            str(path),
            "arm",
            "the dmp reference source learns from the two-section interface: use a two-section constant_curvature arm",
        )
    recording = imu_interface_recording(
        samples=params.demonstration_samples, seed=data.seed, section_lengths=tuple(arm.section_lengths)
    )
    dmp = pose_dmp(params.variant, n_basis=params.basis, smoothing=params.smoothing)
    dmp.imitate(
        recording.t, to_variant(params.variant, recording.demonstration.dual_quaternion), source="IMU demonstration"
    )
    rollout = dmp.rollout(dmp.tau + params.hold, dt=1.0 / params.rate)
    position, quaternion = from_variant(params.variant, rollout.y)
    value = (
        dq_from_rotation_translation(quat_hemisphere_continuous(quaternion), position, check=False)
        if params.task == "pose"
        else position
    )
    reference = Reference(rollout.t, value, np.gradient(value, rollout.t, axis=0), params.task)
    return TrackingReference(reference, recording.configuration[0])


@register_source(
    "references",
    "kinect-dmp",
    "roll-out of a translation DMP learned from the filtered Kinect wrist recording",
    params=KinectDmpParams,
)
def kinect_dmp_reference(arm: ArmModel, data: DataSpec, params: KinectDmpParams, path: Path) -> TrackingReference:
    """Kinect wrist -> moving average (eq. 31) -> DMP -> tip-position reference; the start reaches its first point.

    Raises
    ------
    SpecError
        Naming ``data.params.workspace_centre`` when no configuration within the limits reaches
        the reference's first point to 0.1 mm (the cube lies outside the arm's workspace there).
    """
    recording = kinect_recording(
        samples=params.demonstration_samples,
        rate=params.frame_rate,
        seed=data.seed,
        via_points=params.via_points,
        position_noise=params.position_noise,
        window=params.window,
        cube_edge=params.cube_edge,
        workspace_centre=params.workspace_centre,
    )
    dmp = DMP(Euclidean(3), params.basis, smoothing=params.smoothing)
    dmp.imitate(recording.t, recording.filtered_position, source="filtered Kinect wrist")
    rollout = dmp.rollout(dmp.tau + params.hold, dt=1.0 / params.rate)
    value = np.asarray(rollout.y, dtype=float)
    reference = Reference(rollout.t, value, np.gradient(value, rollout.t, axis=0), "position")
    start, miss = configuration_reaching(arm, value[0])
    if miss > 1e-4:
        raise SpecError(
            str(path),
            "data.params.workspace_centre",
            f"no configuration within the limits reaches the first reference point {np.round(value[0], 4).tolist()} m "
            f"(closest {miss * 1e3:.3g} mm off): move the cube into the arm's workspace or make it smaller",
        )
    return TrackingReference(reference, start)


def configuration_reaching(
    arm: ArmModel, position: np.ndarray, starts: int = 20, pose: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """A configuration within the limits whose tip is closest to ``position`` (bounded least squares).

    Parameters
    ----------
    arm:
        The arm (its ``fk_position`` and ``fk_dq`` Functions and bounds; periodic variables unbounded).
    position:
        ``(3,)`` target tip position [m].
    starts:
        Starting configurations, drawn once from a fixed seed (``arm.sample_configurations``).
    pose:
        ``(8,)`` a target tip pose (unit dual quaternion, its translation ``position``): then the
        residual is the difference of the tip's dual quaternion (of the sign nearer the target) from
        it, so the orientation is reached too.

    Returns
    -------
    tuple
        The configuration ``(n,)`` and its tip's distance from ``position`` [m].
    """
    lower, upper = arm.lower.copy(), arm.upper.copy()
    lower[arm.periodic], upper[arm.periodic] = -np.inf, np.inf

    def residual(q: np.ndarray) -> np.ndarray:
        if pose is None:
            return arm.evaluate("fk_position", q[None])[0] - position
        dq = arm.evaluate("fk_dq", q[None])[0]
        return (dq if dq[:4] @ pose[:4] >= 0 else -dq) - pose

    best: tuple[np.ndarray, float] | None = None
    for q0 in arm.sample_configurations(starts, np.random.default_rng(0)):
        fit = least_squares(residual, q0, bounds=(lower, upper))
        cost = float(np.linalg.norm(fit.fun))
        if best is None or cost < best[1]:
            best = (fit.x, cost)
        if cost < 1e-9:
            break
    assert best is not None
    miss = float(np.linalg.norm(arm.evaluate("fk_position", best[0][None])[0] - position))
    return wrap_periodic(best[0], arm.periodic), miss


def control_times(recorded: RecordedDemonstration, params: FileReferenceParams) -> np.ndarray:
    """The control instants ``(N,)`` [s from the first row] over the recording's span at ``params.rate``.

    Raises
    ------
    InputDataError
        Naming the file, the row and ``t``: a span longer than ``params.max_duration`` (times in
        milliseconds?), or a step longer than ``params.max_step`` (samples missing).
    """
    t = recorded.t
    span = float(t[-1] - t[0])
    if span > params.max_duration:
        raise recorded.error(
            f"the demonstration lasts {span:.6g} s, more than data.params.max_duration = {params.max_duration:g} s "
            "(are the times in ms? t is in seconds)",
            len(t) - 1,
            "t",
        )
    steps = np.diff(t)
    k = int(np.argmax(steps))
    if steps[k] > params.max_step:
        raise recorded.error(
            f"{steps[k]:.6g} s since the previous row, more than data.params.max_step = {params.max_step:g} s: "
            "samples are missing there (fill the gap, or raise max_step to interpolate across it)",
            k + 1,
            "t",
        )
    return np.arange(int(np.floor(span * params.rate + 1e-9)) + 1) / params.rate


def _held(
    t: np.ndarray, value: np.ndarray, rate: np.ndarray, hold: float, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``t, value, rate`` with ``hold`` seconds of the last value at zero rate appended."""
    extra = int(round(hold / dt))
    if extra == 0:
        return t, value, rate
    t = np.concatenate([t, t[-1] + dt * np.arange(1, extra + 1)])
    value = np.concatenate([value, np.repeat(value[-1:], extra, axis=0)])
    rate = np.concatenate([rate, np.zeros((extra, rate.shape[1]))])
    return t, value, rate


def _resampled_pose(
    recorded: RecordedDemonstration, arm: ArmModel, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Positions ``(N, 3)``, their rates and unit quaternions ``(N, 4)`` at the control instants ``t``."""
    s = recorded.t - recorded.t[0]
    if recorded.configuration is not None:
        dq = arm.evaluate("fk_dq", CubicSpline(s, recorded.configuration)(t))
        position = dq_translation(dq)
        return position, np.gradient(position, t, axis=0), quat_hemisphere_continuous(dq_rotation(dq))
    assert recorded.position is not None
    spline = CubicSpline(s, recorded.position)
    quaternion = None
    if recorded.quaternion is not None:
        k = np.clip(np.searchsorted(s, t, side="right") - 1, 0, s.size - 2)
        u = (t - s[k]) / (s[k + 1] - s[k])
        q = recorded.quaternion
        quaternion = quat_hemisphere_continuous(quat_slerp(q[k], q[k + 1], u))
    return spline(t), spline(t, 1), quaternion


@register_source(
    "references",
    "csv",
    "a recorded demonstration file (tip positions, tip poses or configurations), tracked as recorded or "
    "through a DMP learned from it",
    params=FileReferenceParams,
)
def file_reference(arm: ArmModel, data: DataSpec, params: FileReferenceParams, path: Path) -> TrackingReference:
    """The file's demonstration at the control rate (module docstring), or a DMP's roll-out of it.

    Raises
    ------
    InputDataError
        The file's own faults (:func:`~optikin.data.demonstrations.read_demonstration`, :func:`control_times`),
        or a first sample farther than ``params.start_tolerance`` from every reachable tip position.
    SpecError
        A pose task (or a pose DMP) on a file of tip positions, or a position DMP on a pose task.
    """
    recorded = read_params_file(arm, params, path)
    variant = None if params.dmp is None else params.dmp.variant
    if recorded.content == "position" and (params.task == "pose" or variant not in (None, "position")):
        field = "data.params.task" if params.task == "pose" else "data.params.dmp.variant"
        raise SpecError(
            str(path),
            field,
            f"{recorded.source} holds tip positions only (t, x, y, z): track it with task: position "
            "(and dmp variant position), or add the columns qw, qx, qy, qz",
        )
    if params.task == "pose" and variant == "position":
        raise SpecError(str(path), "data.params.dmp.variant", "a position DMP gives no orientations: task: position")
    t = control_times(recorded, params)
    dt = 1.0 / params.rate
    if recorded.configuration is not None and params.dmp is None:
        spline = CubicSpline(recorded.t - recorded.t[0], recorded.configuration)
        t, Q, Qdot = _held(t, spline(t), spline(t, 1), params.hold, dt)
        reference = reference_from_configurations(arm, t, Q, Qdot, params.task)
        return TrackingReference(reference, recorded.configuration[0])
    position, velocity, quaternion = _resampled_pose(recorded, arm, t)
    if params.dmp is not None:
        position, quaternion, t = _dmp_rollout(params.dmp, params.hold, dt, t, position, quaternion, recorded)
        value = position if params.task == "position" else _dq(position, quaternion)
        reference = Reference(t, value, np.gradient(value, t, axis=0), params.task)
    elif params.task == "position":
        reference = Reference(*_held(t, position, velocity, params.hold, dt), "position")
    else:
        value = _dq(position, quaternion)
        reference = Reference(*_held(t, value, np.gradient(value, t, axis=0), params.hold, dt), "pose")
    if recorded.configuration is not None:
        return TrackingReference(reference, recorded.configuration[0])
    pose = reference.value[0] if reference.task == "pose" else None
    start, miss = configuration_reaching(arm, reference.position[0], pose=pose)
    if miss > params.start_tolerance:
        raise recorded.error(
            f"the first tip position {np.round(reference.position[0], 4).tolist()} m is {miss * 1e3:.3g} mm from "
            f"every tip position within the arm's limits (more than data.params.start_tolerance = "
            f"{params.start_tolerance * 1e3:g} mm): is the file in the arm's base frame and in "
            f"data.params.units ({params.units})?",
            0,
            "x, y, z",
        )
    return TrackingReference(reference, start)


def _dq(position: np.ndarray, quaternion: np.ndarray | None) -> np.ndarray:
    assert quaternion is not None
    return dq_from_rotation_translation(quaternion, position, check=False)


def _dmp_rollout(
    options: FileDmpParams,
    hold: float,
    dt: float,
    t: np.ndarray,
    position: np.ndarray,
    quaternion: np.ndarray | None,
    recorded: RecordedDemonstration,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The positions, orientations (None for a position DMP) and times of a DMP learned from the resampled
    demonstration and rolled out for its duration plus ``hold`` at the control step ``dt``."""
    source = f"demonstration {recorded.source}"
    if options.variant == "position":
        dmp = DMP(Euclidean(3), options.basis, smoothing=options.smoothing)
        dmp.imitate(t, position, source=source)
        out = dmp.rollout(dmp.tau + hold, dt=dt)
        return np.asarray(out.y, dtype=float), None, out.t
    dmp = pose_dmp(options.variant, n_basis=options.basis, smoothing=options.smoothing)
    dmp.imitate(t, to_variant(options.variant, _dq(position, quaternion)), source=source)
    out = dmp.rollout(dmp.tau + hold, dt=dt)
    p, q = from_variant(options.variant, out.y)
    return p, quat_hemisphere_continuous(q), out.t
