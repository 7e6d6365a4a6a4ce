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
from scipy.optimize import least_squares

from optikin.algebra import dq_from_rotation_translation, quat_hemisphere_continuous
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.limits import wrap_periodic
from optikin.control.reference import Reference, minimum_jerk_path, reference_from_configurations
from optikin.data.demonstrations import imu_interface_recording, kinect_recording
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


def configuration_reaching(arm: ArmModel, position: np.ndarray, starts: int = 20) -> tuple[np.ndarray, float]:
    """A configuration within the limits whose tip is closest to ``position`` (bounded least squares).

    Parameters
    ----------
    arm:
        The arm (its ``fk_position`` Function and bounds; periodic variables unbounded).
    position:
        ``(3,)`` target tip position [m].
    starts:
        Starting configurations, drawn once from a fixed seed (``arm.sample_configurations``).

    Returns
    -------
    tuple
        The configuration ``(n,)`` and its tip's distance from ``position`` [m].
    """
    lower, upper = arm.lower.copy(), arm.upper.copy()
    lower[arm.periodic], upper[arm.periodic] = -np.inf, np.inf

    def residual(q: np.ndarray) -> np.ndarray:
        return arm.evaluate("fk_position", q[None])[0] - position

    best: tuple[np.ndarray, float] | None = None
    for q0 in arm.sample_configurations(starts, np.random.default_rng(0)):
        fit = least_squares(residual, q0, bounds=(lower, upper))
        miss = float(np.linalg.norm(fit.fun))
        if best is None or miss < best[1]:
            best = (fit.x, miss)
        if miss < 1e-9:
            break
    assert best is not None
    return wrap_periodic(best[0], arm.periodic), best[1]
