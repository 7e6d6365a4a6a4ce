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

from optikin.algebra import dq_from_rotation_translation, quat_hemisphere_continuous
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.reference import Reference, minimum_jerk_path, reference_from_configurations
from optikin.data.demonstrations import imu_interface_recording
from optikin.data.sources import register_source
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
