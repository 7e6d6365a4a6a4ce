"""Synthetic recordings of a constant-curvature arm with known geometry: source ``synthetic`` of family ``recordings``.

:func:`synthetic_recording` plays a motion-capture session of a hanging
multi-section CC arm (:class:`optikin.arms.constant_curvature.ConstantCurvatureArm`,
its own forward kinematics, not the calibration's model) whose geometry is known:

* **postures**: ``N`` steady states, each section bent by ``theta`` uniform in
  ``[0, theta_max]`` in a plane ``phi`` uniform in ``[-pi, pi)``, at the true section
  lengths (seeded);
* **base pose**: position ``base_position`` [m] and orientation
  ``Rz(yaw) Ry(pitch) Rx(roll)`` from ``base_rpy_deg`` in the recording's z-up frame
  (default: roll 180 degrees, the arm hanging down, tilted by a few degrees);
* **markers**: one per section end disk, ``disk1`` ... , at ``marker_offsets`` [m] in
  the disk's frame, with isotropic Gaussian noise of ``noise`` [m] per coordinate;
* **tendons**: three per section, at ``tendon_radius`` from the backbone and angles
  ``2 pi k / 3``, run from the base to the section's end disk; channel ``tendon_<i><k>``
  reads the length ``sum_j<=i (S_j - r theta_j cos(phi_j - alpha_k))`` [m] (Webster &
  Jones 2010 eq. 20), with Gaussian noise of ``actuator_noise`` [m];
* **glitches**: a fraction ``corrupted_fraction`` of the postures has the labels of two
  of its markers exchanged (a motion-capture label swap), a fraction
  ``missing_fraction`` of the marker samples is NaN (occlusions).

The recording (:class:`SyntheticRecording`) carries the truth for honest checks.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, StrictFloat

from optikin.algebra import matrix_from_quat
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.data.recording import Recording
from optikin.data.sources import register_source
from optikin.errors import SpecError
from optikin.options import Options
from optikin.spec import DataSpec

FAMILY = "recordings"


@dataclass(frozen=True)
class CalibrationTruth:
    """The geometry and postures a synthetic recording was made with.

    Attributes
    ----------
    section_lengths : numpy.ndarray
        ``(m,)`` [m].
    base_position : numpy.ndarray
        ``(3,)`` [m].
    base_rotation : numpy.ndarray
        ``(3, 3)``.
    marker_offsets : numpy.ndarray
        ``(M, 3)`` [m] in each disk's frame.
    configurations : numpy.ndarray
        ``(N, 3 m)`` ``(S, theta, phi)`` per section.
    clean_markers : numpy.ndarray
        ``(N, M, 3)`` marker positions without noise or glitches [m].
    corrupted : numpy.ndarray
        ``(N,)`` bool: postures with two labels exchanged.
    """

    section_lengths: np.ndarray
    base_position: np.ndarray
    base_rotation: np.ndarray
    marker_offsets: np.ndarray
    configurations: np.ndarray
    clean_markers: np.ndarray
    corrupted: np.ndarray


@dataclass(frozen=True)
class SyntheticRecording(Recording):
    """A :class:`~optikin.data.recording.Recording` with the :class:`CalibrationTruth` it was made with."""

    truth: CalibrationTruth | None = field(default=None)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` [rad]."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def synthetic_recording(
    arm: ConstantCurvatureArm,
    samples: int,
    rng: np.random.Generator,
    section_lengths: np.ndarray | None = None,
    base_position: np.ndarray = np.array([0.0, 0.0, 0.6]),
    base_rotation: np.ndarray | None = None,
    marker_offsets: np.ndarray | None = None,
    theta_max: float = 1.2,
    noise: float = 0.3e-3,
    corrupted_fraction: float = 0.0,
    missing_fraction: float = 0.0,
    frame_rate: float = 10.0,
    tendon_radius: float = 0.01,
    actuator_noise: float = 0.0,
) -> SyntheticRecording:
    """A recording of ``samples`` postures of ``arm`` (module docstring).

    Parameters
    ----------
    arm : ConstantCurvatureArm
        Its forward kinematics make the markers.
    samples : int
        Postures ``N``.
    rng : numpy.random.Generator
        Source of every draw.
    section_lengths : numpy.ndarray, optional
        True lengths [m] (default the arm's nominal ones).
    base_position : numpy.ndarray
        ``(3,)`` [m].
    base_rotation : numpy.ndarray, optional
        ``(3, 3)`` (default: hanging down, roll 180 degrees).
    marker_offsets : numpy.ndarray, optional
        ``(m, 3)`` [m] (default zero: markers on the backbone).
    theta_max : float
        Largest bend per section [rad].
    noise : float
        Standard deviation per coordinate [m].
    corrupted_fraction, missing_fraction : float
        Share of postures with two labels exchanged, of marker samples missing.
    frame_rate : float
        Postures per second of the time stamps [Hz].
    tendon_radius, actuator_noise : float
        Distance of the tendons from the backbone, noise of their length readings [m].

    Returns
    -------
    SyntheticRecording
        Markers ``disk1 ... diskm`` [m] in the recording frame, with the truth.
    """
    m = arm.n_sections
    lengths = arm.section_lengths if section_lengths is None else np.asarray(section_lengths, dtype=float)
    R0 = rpy_matrix(np.pi, 0.0, 0.0) if base_rotation is None else np.asarray(base_rotation, dtype=float)
    p0 = np.asarray(base_position, dtype=float)
    offsets = np.zeros((m, 3)) if marker_offsets is None else np.asarray(marker_offsets, dtype=float)
    theta = rng.uniform(0.0, theta_max, size=(samples, m))
    phi = rng.uniform(-np.pi, np.pi, size=(samples, m))
    Q = np.stack([np.broadcast_to(lengths, (samples, m)), theta, phi], axis=-1).reshape(samples, 3 * m)
    frames = arm.section_frames(Q)
    clean = np.empty((samples, m, 3))
    for s, (quat, position) in enumerate(frames):
        local = position + np.einsum("nij,j->ni", matrix_from_quat(quat, check=False), offsets[s])
        clean[:, s] = p0 + local @ R0.T
    measured = clean + rng.normal(0.0, noise, size=clean.shape)
    corrupted = np.zeros(samples, dtype=bool)
    n_bad = int(round(corrupted_fraction * samples))
    if n_bad and m >= 2:
        bad = rng.choice(samples, size=n_bad, replace=False)
        corrupted[bad] = True
        for k in bad:
            a, b = rng.choice(m, size=2, replace=False)
            measured[k, [a, b]] = measured[k, [b, a]]
    if missing_fraction > 0:
        gone = rng.random((samples, m)) < missing_fraction
        measured[gone] = np.nan
    tendons = {}
    for i in range(m):
        for k in range(3):
            alpha = 2.0 * np.pi * k / 3.0
            length = np.sum(
                lengths[: i + 1] - tendon_radius * theta[:, : i + 1] * np.cos(phi[:, : i + 1] - alpha), axis=1
            )
            tendons[f"tendon_{i + 1}{k + 1}"] = length + rng.normal(0.0, actuator_noise, size=samples)
    truth = CalibrationTruth(lengths.copy(), p0.copy(), R0.copy(), offsets.copy(), Q, clean, corrupted)
    return SyntheticRecording(
        time=np.arange(samples) / frame_rate,
        markers={f"disk{s + 1}": measured[:, s].copy() for s in range(m)},
        actuators=tendons,
        source="synthetic",
        truth=truth,
    )


class SyntheticRecordingParams(Options):
    """``data.params`` of source ``synthetic`` (family ``recordings``)."""

    section_lengths: list[StrictFloat] | None = Field(
        None, description="true section lengths [m] (default: the arm's section_lengths)"
    )
    base_position: list[StrictFloat] = Field([0.0, 0.0, 0.6], min_length=3, max_length=3, description="[m]")
    base_rpy_deg: list[StrictFloat] = Field(
        [180.0, 0.0, 0.0],
        min_length=3,
        max_length=3,
        description="base orientation Rz(yaw) Ry(pitch) Rx(roll) [deg]; roll 180: hanging down",
    )
    marker_offsets: list[list[StrictFloat]] | None = Field(
        None, description="one offset [m] per section end disk, in the disk's frame (default: zero)"
    )
    theta_max: StrictFloat = Field(1.2, gt=0, le=np.pi, description="largest bend per section [rad]")
    noise: StrictFloat = Field(0.3e-3, ge=0, description="marker noise per coordinate [m]")
    corrupted_fraction: StrictFloat = Field(0.0, ge=0, le=1, description="share of postures with two labels swapped")
    missing_fraction: StrictFloat = Field(0.0, ge=0, lt=1, description="share of marker samples missing (NaN)")
    tendon_radius: StrictFloat = Field(0.01, gt=0, description="distance of the tendons from the backbone [m]")
    actuator_noise: StrictFloat = Field(0.0, ge=0, description="noise of the tendon length readings [m]")


@register_source(
    FAMILY, "synthetic", "a CC arm of known geometry recorded with noise and label swaps", SyntheticRecordingParams
)
def load_synthetic(
    arm: ArmModel, data: DataSpec, params: SyntheticRecordingParams, path: Path, **_: Any
) -> SyntheticRecording:
    """:func:`synthetic_recording` of ``data.samples`` postures, seeded by ``data.seed``."""
    if not isinstance(arm, ConstantCurvatureArm):
        raise SpecError(path, "arm.type", "the synthetic recording needs a constant_curvature arm")
    m = arm.n_sections
    lengths = None
    if params.section_lengths is not None:
        if len(params.section_lengths) != m or min(params.section_lengths) <= 0:
            raise SpecError(path, "data.params.section_lengths", f"expected {m} positive lengths")
        lengths = np.array(params.section_lengths)
    offsets = None
    if params.marker_offsets is not None:
        offsets = np.array(params.marker_offsets, dtype=float)
        if offsets.shape != (m, 3):
            raise SpecError(path, "data.params.marker_offsets", f"expected {m} offsets of 3 numbers")
    roll, pitch, yaw = np.radians(params.base_rpy_deg)
    return synthetic_recording(
        arm,
        data.samples,
        np.random.default_rng([data.seed, 0]),
        section_lengths=lengths,
        base_position=np.array(params.base_position),
        base_rotation=rpy_matrix(roll, pitch, yaw),
        marker_offsets=offsets,
        theta_max=params.theta_max,
        noise=params.noise,
        corrupted_fraction=params.corrupted_fraction,
        missing_fraction=params.missing_fraction,
        tendon_radius=params.tendon_radius,
        actuator_noise=params.actuator_noise,
    )
