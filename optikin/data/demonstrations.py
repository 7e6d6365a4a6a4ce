"""Demonstrations to learn motions from (Seleem et al. 2020, secs. III-A and IV): synthetic sources and a CSV reader.

Every source takes a seed and returns its recording with a
:class:`PoseDemonstration` (times, tip positions, unit quaternions,
hemisphere-continuous) to learn from.

* :func:`smooth_pose_demonstration` -- a clean rest-to-rest pose motion
  (minimum-jerk profile plus a smooth detour).
* :func:`gimbal_demonstration` -- a motion through pitch +-90 degrees, where
  the roll-pitch-yaw angles of eq. (30) jump (Seleem et al.'s Figs. 13-14).
* :func:`imu_interface_recording` -- the flexible teleoperation interface of
  Seleem et al. (2020) sec. III-A: two 18 cm sections bent along a smooth human-like
  motion, an MPU-6050-like IMU at each section tip sampled at 100 Hz (noise and
  yaw drift), the relative quaternion of eq. (7), the section angles
  (eq. 8, derived again in :mod:`optikin.arms.constant_curvature`) and the tip
  pose from those angles as a dual quaternion (eqs. 9-10).
* :func:`kinect_recording` -- the Kinect v2 capture of sec. IV: right-wrist
  positions and left-wrist orientations at 30 frames per second with skeleton
  jitter, calibrated into the 36 cm cube workspace, roll-pitch-yaw by eq. (30)
  and smoothed by the moving-average filter of eq. (31).
* :func:`read_demonstration` -- a recorded demonstration file of tip poses
  (``t,x,y,z,qw,qx,qy,qz``), tip positions (``t,x,y,z``) or configurations (``t``
  and the arm's variables), in seconds, metres (or the declared unit), unit
  quaternions ``(w, x, y, z)``, radians; :func:`read_csv` / :func:`write_csv` the
  pose files; :func:`resample_uniform` puts a recording with jittery time stamps
  on the fixed step a DMP integrates with.

The noise figures are assumptions stated where they are used; Seleem et al. give
none (its data came from hardware).

Each is also a data source of the family ``demonstrations`` (``data.source``
of the ``dmp`` kind): ``imu``, ``kinect``, ``smooth``, ``gimbal`` and ``csv``,
``data.params`` the keyword arguments of the function (validated by
:class:`ImuParams`, :class:`KinectParams`, :class:`SmoothParams`,
:class:`GimbalParams`, :class:`CsvParams`: ``file``, ``content``, ``units``,
``samples``), ``data.samples`` and ``data.seed`` its sample count and seed. A loader returns the recording (an
:class:`InterfaceRecording`, a :class:`KinectRecording` or a
:class:`PoseDemonstration`); :func:`pose_demonstration` is the demonstration
in it.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Literal, Sequence, get_args

import numpy as np
from numpy.typing import ArrayLike
from pydantic import Field
from scipy.interpolate import CubicSpline

from optikin.algebra import (
    dq_from_rotation_translation,
    dq_rotation,
    dq_translation,
    quat_exp,
    quat_from_rpy,
    quat_hemisphere_continuous,
    quat_multiply,
    quat_normalize,
    quat_slerp,
    rpy_from_quat,
)
from optikin.arms.constant_curvature import (
    ConstantCurvatureArm,
    relative_section_quaternions,
    section_angles_from_quaternion,
)
from optikin.arms.base import ArmModel
from optikin.data.csvread import missing_columns, read_table
from optikin.data.files import FileParams
from optikin.data.recording import FrameOptions, convert_body_orientations, convert_vectors, frame_matrix
from optikin.data.sources import register_source
from optikin.errors import InputDataError, SpecError
from optikin.options import Options
from optikin.spec import DataSpec

CSV_COLUMNS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz")


@dataclass(frozen=True)
class PoseDemonstration:
    """Times ``(N,)``, positions ``(N, 3)`` [m] and unit quaternions ``(N, 4)`` ``(w, x, y, z)`` of a tip."""

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray

    @property
    def dual_quaternion(self) -> np.ndarray:
        """``(N, 8)``: ``Q_r + eps 0.5 (0, p) Q_r`` (Seleem et al.'s eqs. 9-10)."""
        return dq_from_rotation_translation(self.quaternion, self.position, check=False)

    @property
    def pose(self) -> np.ndarray:
        """``(N, 7)``: ``(x, y, z, qw, qx, qy, qz)``."""
        return np.concatenate([self.position, self.quaternion], axis=1)


def minimum_jerk(u: np.ndarray) -> np.ndarray:
    """``10 u^3 - 15 u^4 + 6 u^5``: rises from 0 to 1 with zero velocity and acceleration at both ends."""
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _times(samples: int, rate: float) -> np.ndarray:
    if samples < 3 or rate <= 0:
        raise ValueError(f"need at least 3 samples at a positive rate, got {samples} at {rate} Hz")
    return np.arange(samples) / rate


def smooth_path(
    t: np.ndarray, low: ArrayLike, high: ArrayLike, via_points: int, rng: np.random.Generator
) -> np.ndarray:
    """A human-like smooth path: a cubic spline through ``via_points + 2`` random points at equal times,
    at rest at both ends (clamped), each coordinate drawn in ``[low, high]``. Returns ``(N, d)``."""
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    knots = np.linspace(t[0], t[-1], via_points + 2)
    points = rng.uniform(low, high, (knots.size, low.size))
    return CubicSpline(knots, points, bc_type="clamped")(t)


def smooth_pose_demonstration(
    samples: int = 1000,
    duration: float = 10.0,
    seed: int = 0,
    reach: float = 0.12,
    turn: float = 1.2,
    centre: tuple[float, float, float] = (0.0, 0.0, 0.30),
) -> PoseDemonstration:
    """A smooth rest-to-rest pose motion: minimum-jerk from start to goal plus a detour ``sin^2(pi u)``.

    Start and goal positions are drawn in a cube of half-width ``reach``
    about ``centre``; start and goal rotation vectors with norm up to ``turn``
    rad; the detours are of the same size. Velocities vanish at both ends.
    """
    if samples < 3 or duration <= 0:
        raise ValueError(f"need at least 3 samples over a positive duration, got {samples} over {duration}")
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, duration, samples)
    u = t / duration
    rise = minimum_jerk(u)[:, None]
    detour = (np.sin(np.pi * u) ** 2)[:, None]
    wiggle = (np.sin(np.pi * u) ** 2 * np.sin(2 * np.pi * u))[:, None]

    p0, p1 = rng.uniform(-reach, reach, (2, 3)) + np.asarray(centre)
    bend, twist = rng.uniform(-0.5 * reach, 0.5 * reach, (2, 3))
    position = p0 + (p1 - p0) * rise + bend * detour + twist * wiggle

    def rotation_vector() -> np.ndarray:
        axis = rng.normal(size=3)
        return axis / np.linalg.norm(axis) * rng.uniform(0.3, 1.0) * turn

    r0, r1 = rotation_vector(), rotation_vector()
    r_bend, r_twist = rng.uniform(-0.4 * turn, 0.4 * turn, (2, 3))
    rotation = r0 + (r1 - r0) * rise + r_bend * detour + r_twist * wiggle
    quaternion = quat_hemisphere_continuous(quat_exp(0.5 * rotation))
    return PoseDemonstration(t=t, position=position, quaternion=quaternion)


def gimbal_demonstration(
    samples: int = 1000, duration: float = 10.0, seed: int = 0, peak_pitch_deg: float = 120.0, reach: float = 0.1
) -> PoseDemonstration:
    """A rest-to-rest motion whose pitch (eq. 30) rises from -20 degrees through +90 (gimbal lock) to the peak.

    Roll and yaw change smoothly too (random, up to 40 degrees); the position
    is a smooth detour of size ``reach``. Past 90 degrees of pitch, eq. (30)
    reports the same orientation with pitch folded back below 90 and roll and
    yaw jumped by 180 degrees: the per-angle representation of Seleem et al.'s Fig. 13.
    """
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, duration, samples)
    u = t / duration
    rise = minimum_jerk(u)
    detour = np.sin(np.pi * u) ** 2
    roll = np.deg2rad(rng.uniform(-40, 40) * rise + rng.uniform(-15, 15) * detour)
    yaw = np.deg2rad(rng.uniform(-40, 40) + rng.uniform(-40, 40) * rise)
    pitch = np.deg2rad(-20.0 + (peak_pitch_deg + 20.0) * rise)
    quaternion = quat_hemisphere_continuous(quat_from_rpy(roll, pitch, yaw))
    p0, p1 = rng.uniform(-reach, reach, (2, 3)) + np.array([0.0, 0.0, 0.30])
    position = p0 + (p1 - p0) * rise[:, None] + rng.uniform(-reach, reach, 3) * detour[:, None]
    return PoseDemonstration(t=t, position=position, quaternion=quaternion)


# ----------------------------------------------------------------------------- the IMU teleoperation interface


@dataclass(frozen=True)
class InterfaceRecording:
    """The flexible interface of Seleem et al. (2020) sec. III-A, recorded by two IMUs.

    ``configuration (N, 6)`` true ``(S, theta, phi)`` per section; ``imu (N, 2, 4)``
    the IMU quaternions in the base frame; ``relative (N, 2, 4)`` each section
    relative to its base (eq. 7); ``angles (N, 2, 2)`` the measured
    ``(theta, phi)`` per section; ``demonstration`` the tip pose from the
    measured angles at the nominal section lengths.
    """

    t: np.ndarray
    configuration: np.ndarray
    imu: np.ndarray
    relative: np.ndarray
    angles: np.ndarray
    demonstration: PoseDemonstration


def imu_interface_recording(
    samples: int = 1000,
    rate: float = 100.0,
    seed: int = 0,
    via_points: int = 2,
    theta_range: tuple[float, float] = (0.15, 1.2),
    noise_deg: float = 0.1,
    drift_deg_per_s: float = 0.02,
    section_lengths: tuple[float, float] = (0.18, 0.18),
) -> InterfaceRecording:
    """Two IMUs on the flexible interface, moved along a smooth human-like path, at ``rate`` Hz.

    The section angles follow :func:`smooth_path` (``theta`` kept inside
    ``theta_range`` so the bending plane stays defined). Each IMU reports its
    section tip's orientation in the base frame as the MPU-6050's on-chip
    fusion does, modelled as ``exp(n/2) exp(d(t)/2 z) q_true``: white noise
    ``n`` of ``noise_deg`` per axis and a yaw drift ``d`` growing at
    ``drift_deg_per_s`` (its accelerometer corrects roll and pitch, nothing
    corrects yaw without a magnetometer; a random rate per IMU up to the given
    value). Both figures are assumptions of typical fused-output behaviour
    (the datasheet specifies the raw gyroscope, not the fused orientation).
    """
    rng = np.random.default_rng(seed)
    t = _times(samples, rate)
    arm = ConstantCurvatureArm(section_lengths=section_lengths)
    lo, hi = theta_range
    angles = smooth_path(t, [lo, -np.pi, lo, -np.pi], [hi, np.pi, hi, np.pi], via_points, rng)
    angles[:, [0, 2]] = np.clip(angles[:, [0, 2]], lo, hi)
    lengths = np.asarray(section_lengths, dtype=float)
    configuration = np.column_stack(
        [
            np.full(samples, lengths[0]),
            angles[:, 0],
            angles[:, 1],
            np.full(samples, lengths[1]),
            angles[:, 2],
            angles[:, 3],
        ]
    )
    frames = arm.section_frames(configuration)
    true = np.stack([frames[0][0], frames[1][0]], axis=1)  # (N, 2, 4)

    noise = np.deg2rad(noise_deg) * rng.normal(size=(samples, 2, 3))
    rates = np.deg2rad(drift_deg_per_s) * rng.uniform(-1.0, 1.0, 2)
    drift = np.zeros((samples, 2, 3))
    drift[..., 2] = t[:, None] * rates[None, :]
    imu = quat_multiply(quat_exp(0.5 * noise), quat_multiply(quat_exp(0.5 * drift), true))
    imu = np.stack([quat_hemisphere_continuous(imu[:, i]) for i in range(2)], axis=1)

    relative = relative_section_quaternions(imu, source="IMU quaternions")
    theta, phi = section_angles_from_quaternion(relative)
    measured = np.stack([theta, phi], axis=-1)  # (N, 2, 2)
    phi_unwrapped = np.unwrap(phi, axis=0)
    q_measured = np.column_stack(
        [
            np.full(samples, lengths[0]),
            theta[:, 0],
            phi_unwrapped[:, 0],
            np.full(samples, lengths[1]),
            theta[:, 1],
            phi_unwrapped[:, 1],
        ]
    )
    tip_quaternion, tip_position = arm.section_frames(q_measured)[-1]
    tip = PoseDemonstration(t=t, position=tip_position, quaternion=quat_hemisphere_continuous(tip_quaternion))
    return InterfaceRecording(
        t=t, configuration=configuration, imu=imu, relative=relative, angles=measured, demonstration=tip
    )


# ----------------------------------------------------------------------------- the Kinect v2 capture


@dataclass(frozen=True)
class KinectRecording:
    """Kinect v2 wrist capture (Seleem et al. 2020, sec. IV).

    ``wrist (N, 3)`` right-wrist positions in the camera frame [m],
    ``orientation (N, 4)`` left-wrist quaternions in the camera frame,
    ``position (N, 3)`` the wrist calibrated into the robot workspace,
    ``rpy (N, 3)`` roll, pitch, yaw of the left wrist by eq. (30) (unwrapped),
    ``filtered_position``/``filtered_rpy`` after the moving average of eq. (31),
    ``demonstration`` the filtered pose.
    """

    t: np.ndarray
    wrist: np.ndarray
    orientation: np.ndarray
    position: np.ndarray
    rpy: np.ndarray
    filtered_position: np.ndarray
    filtered_rpy: np.ndarray
    demonstration: PoseDemonstration


def moving_average(x: np.ndarray, window: int) -> np.ndarray:
    """Seleem et al. (2020) eq. (31): ``o(i) = 1/M sum_{m=1..M} l(i - m)``, the mean of the ``M`` previous samples.

    Causal, so it delays the signal by ``(M + 1)/2`` samples. The first
    samples average the previous samples there are (``o(0) = l(0)``).
    Works along the first axis of ``x``.
    """
    if window < 1:
        raise ValueError(f"the moving-average window must be at least 1 sample, got {window}")
    x = np.asarray(x, dtype=float)
    sums = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    i = np.arange(x.shape[0])
    first = np.maximum(i - window, 0)
    count = np.maximum(i - first, 1).reshape((-1,) + (1,) * (x.ndim - 1))
    out = (sums[np.maximum(i, 1)] - sums[first]) / count
    out[0] = x[0]
    return out


def calibrate_to_cube(points: np.ndarray, edge: float, centre: np.ndarray) -> np.ndarray:
    """Scale and shift points uniformly so their bounding box fits a cube of ``edge`` about ``centre``."""
    low, high = points.min(axis=0), points.max(axis=0)
    span = float(np.max(high - low))
    scale = edge / span if span > 0 else 1.0
    return np.asarray(centre) + (points - 0.5 * (low + high)) * scale


CAMERA_TO_ROBOT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""Kinect camera axes (x right, y up, z away from the camera) to robot base axes (z up): a proper rotation."""


def kinect_recording(
    samples: int = 300,
    rate: float = 30.0,
    seed: int = 0,
    via_points: int = 3,
    position_noise: float = 0.008,
    orientation_noise_deg: float = 3.0,
    window: int = 5,
    cube_edge: float = 0.36,
    workspace_centre: tuple[float, float, float] = (0.0, 0.0, 0.27),
    spine_shoulder: tuple[float, float, float] = (0.0, 0.35, 2.2),
) -> KinectRecording:
    """A Kinect v2 recording of the wrists moving along smooth human-like paths at ``rate`` frames per second.

    Skeleton jitter is modelled as white noise of ``position_noise`` m per axis
    on the right wrist and ``orientation_noise_deg`` per axis on the left
    wrist's orientation (Kinect v2 joint jitter is of the order of a
    centimetre and its wrist orientations are noisier still: assumptions).
    The wrist is expressed relative to the spine-shoulder joint, turned into
    robot axes (:data:`CAMERA_TO_ROBOT`) and scaled into the ``cube_edge``
    cube (36 cm in Seleem et al.) about ``workspace_centre``. Orientations become
    roll-pitch-yaw by eq. (30), are unwrapped and filtered by eq. (31) with
    ``window`` samples, as are the positions.
    """
    rng = np.random.default_rng(seed)
    t = _times(samples, rate)
    shoulder = np.asarray(spine_shoulder, dtype=float)
    reach = np.array([0.35, 0.30, 0.25])
    wrist_true = shoulder + np.array([0.25, -0.1, -0.3]) + smooth_path(t, -reach, reach, via_points, rng)
    turn = np.array([0.8, 0.6, 1.0])
    rotation = smooth_path(t, -turn, turn, via_points, rng)
    orientation_true = quat_exp(0.5 * rotation)

    wrist = wrist_true + position_noise * rng.normal(size=wrist_true.shape)
    jitter = np.deg2rad(orientation_noise_deg) * rng.normal(size=(samples, 3))
    orientation = quat_hemisphere_continuous(quat_multiply(quat_exp(0.5 * jitter), orientation_true))

    relative = (wrist - shoulder) @ CAMERA_TO_ROBOT.T
    position = calibrate_to_cube(relative, cube_edge, np.asarray(workspace_centre, dtype=float))
    rpy = np.unwrap(rpy_from_quat(orientation, check=False), axis=0)
    filtered_position = moving_average(position, window)
    filtered_rpy = moving_average(rpy, window)
    quaternion = quat_hemisphere_continuous(quat_from_rpy(filtered_rpy[:, 0], filtered_rpy[:, 1], filtered_rpy[:, 2]))
    return KinectRecording(
        t=t,
        wrist=wrist,
        orientation=orientation,
        position=position,
        rpy=rpy,
        filtered_position=filtered_position,
        filtered_rpy=filtered_rpy,
        demonstration=PoseDemonstration(t=t, position=filtered_position, quaternion=quaternion),
    )


# ----------------------------------------------------------------------------- recorded files


Content = Literal["pose", "position", "configuration"]
"""What a demonstration file records: tip poses, tip positions or the arm's configurations."""
CONTENTS: tuple[str, ...] = get_args(Content)
POSITION_COLUMNS = CSV_COLUMNS[:4]
"""``t, x, y, z``: the columns of a file of tip positions."""
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
"""Metres per length unit a demonstration file may be written in."""
MIN_ROWS = 3
"""Rows a demonstration needs at least."""


@dataclass(frozen=True)
class RecordedDemonstration:
    """A demonstration file as read: times and what the file records (SI units, the arm's base frame).

    Attributes
    ----------
    source:
        The file, as errors name it.
    content:
        ``pose``, ``position`` or ``configuration``.
    t:
        ``(N,)`` times [s], strictly increasing.
    position:
        ``(N, 3)`` tip positions [m] (pose and position files), else None.
    quaternion:
        ``(N, 4)`` unit tip quaternions ``(w, x, y, z)``, hemisphere-continuous (pose files), else None.
    configuration:
        ``(N, n)`` configurations in the arm's variables' order and units (configuration files), else None.
    lines:
        ``(N,)`` the 1-based line of the file each row is on.
    """

    source: str
    content: Content
    t: np.ndarray
    position: np.ndarray | None = None
    quaternion: np.ndarray | None = None
    configuration: np.ndarray | None = None
    lines: np.ndarray | None = None

    def error(self, message: str, row: int, column: str) -> InputDataError:
        """An error on data row ``row`` (from 0) and ``column`` of the file; the message gets the line."""
        line = "" if self.lines is None else f" (line {int(self.lines[row])})"
        return InputDataError(f"{message}{line}", source=self.source, sample=int(row), field=column)

    def pose(self, arm: ArmModel | None = None) -> PoseDemonstration:
        """The tip poses: the file's, or the forward kinematics of its configurations on ``arm``.

        Raises
        ------
        ValueError
            A position file (it has no orientations), or a configuration file without ``arm``.
        """
        if self.position is not None and self.quaternion is not None:
            return PoseDemonstration(self.t, self.position, self.quaternion)
        if self.configuration is None:
            raise ValueError(f"{self.source}: a file of tip positions (t, x, y, z) holds no orientations")
        if arm is None:
            raise ValueError(f"{self.source}: the tip poses of configurations need the arm")
        dq = arm.evaluate("fk_dq", self.configuration)
        return PoseDemonstration(self.t, dq_translation(dq), quat_hemisphere_continuous(dq_rotation(dq)))


def content_columns(content: str, names: Sequence[str]) -> tuple[str, ...]:
    """The columns a file of ``content`` must have: ``t`` then ``x, y, z [, qw, qx, qy, qz]`` or ``names``."""
    if content == "pose":
        return CSV_COLUMNS
    if content == "position":
        return POSITION_COLUMNS
    return ("t", *names)


def detect_content(header: Sequence[str], names: Sequence[str]) -> Content:
    """What a file records, from its header: poses if it has a column of ``qw, qx, qy, qz``, else
    configurations if it names a variable of ``names`` and not ``x``, else positions."""
    if any(c in header for c in CSV_COLUMNS[4:]):
        return "pose"
    if "x" not in header and any(n in header for n in names):
        return "configuration"
    return "position"


def read_demonstration(
    path: str | Path,
    content: Content | None = None,
    names: Sequence[str] = (),
    units: str = "m",
    unit_tolerance: float = 1e-3,
) -> RecordedDemonstration:
    """A demonstration from a CSV file with a header row: tip poses, tip positions or configurations.

    The formats (:mod:`optikin.data.csvread` for what every reader refuses); every cell read
    must be a finite number, every row as wide as the header, and there must be at least
    :data:`MIN_ROWS` rows:

    ======================  ================================================================
    ``t``                   time in seconds, strictly increasing (every format)
    ``x, y, z``             tip position in the arm's base frame (pose and position files),
                            in ``units``
    ``qw, qx, qy, qz``      pose files: tip orientation ``(w, x, y, z)``, unit to within
                            ``unit_tolerance`` (then normalised)
    ``names``               configuration files: one column per variable of the arm
                            (``S1, theta1, phi1, ...``), metres and radians
    other columns           ignored
    ======================  ================================================================

    Parameters
    ----------
    path:
        The file.
    content:
        ``pose``, ``position`` or ``configuration``; None: :func:`detect_content` from the header.
    names:
        The arm's configuration variables (configuration files).
    units:
        The length unit of ``x, y, z``: ``m``, ``cm`` or ``mm`` (:data:`LENGTH_UNITS`).
    unit_tolerance:
        Largest ``| |q| - 1 |`` accepted.

    Returns
    -------
    RecordedDemonstration
        Every row, positions in metres, quaternions normalised and made hemisphere-continuous.

    Raises
    ------
    InputDataError
        Naming the file, the row (``sample`` from 0, and its line) and the column: the file
        cannot be read or is refused (not a regular file, over 200 MiB, binary, not UTF-8),
        is empty, lacks a column, has fewer than 3 rows, a row with fewer or more cells than
        the header, a cell that is not a finite number; times do not increase strictly; a
        quaternion is not unit.
    """
    path = Path(path)
    source = str(path)
    chosen: list[Content] = []

    def select(header: tuple[str, ...]) -> tuple[Sequence[str], Sequence[str]]:
        kind = content or detect_content(header, names)
        chosen.append(kind)
        wanted = content_columns(kind, names)
        how = "given as data.params.content" if content else "read from the header; data.params.content chooses"
        error = missing_columns(source, header, wanted, hint=f" (a {kind} file, {how})")
        if error is not None:
            raise error
        return wanted, ("t",)

    table = read_table(path, select, exact=True)
    kind = chosen[0]
    if len(table) < MIN_ROWS:
        raise InputDataError(f"a demonstration needs at least {MIN_ROWS} rows, got {len(table)}", source=source)
    columns = content_columns(kind, names)
    table.check_finite(columns[1:])
    table.check_increasing("t")
    t = table.column("t")
    if kind == "configuration":
        return RecordedDemonstration(source, kind, t, configuration=table.stacked(columns[1:]), lines=table.lines)
    table.check_coordinates(POSITION_COLUMNS[1:], LENGTH_UNITS[units], units, "data.params.units")
    position = table.stacked(POSITION_COLUMNS[1:]) * LENGTH_UNITS[units]
    quaternion = None
    if kind == "pose":
        q = table.check_unit_quaternions(CSV_COLUMNS[4:], unit_tolerance)
        quaternion = quat_hemisphere_continuous(quat_normalize(q, check=False))
    return RecordedDemonstration(source, kind, t, position, quaternion, lines=table.lines)


def read_csv(path: str | Path, unit_tolerance: float = 1e-3) -> PoseDemonstration:
    """A pose demonstration from a CSV file with a header naming (at least) ``t,x,y,z,qw,qx,qy,qz``.

    :func:`read_demonstration` of a pose file in metres (its format and refusals).

    Parameters
    ----------
    path:
        The file.
    unit_tolerance:
        Largest ``| |q| - 1 |`` accepted.

    Returns
    -------
    PoseDemonstration
        Every row; quaternions normalised and made hemisphere-continuous.

    Raises
    ------
    InputDataError
        As :func:`read_demonstration`.
    """
    return read_demonstration(path, "pose", unit_tolerance=unit_tolerance).pose()


def write_csv(path: str | Path, demo: PoseDemonstration) -> None:
    """Write a demonstration in the format :func:`read_csv` reads."""
    with Path(path).open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        for t, p, q in zip(demo.t, demo.position, demo.quaternion):
            writer.writerow([repr(float(v)) for v in (t, *p, *q)])


def resample_uniform(demo: PoseDemonstration, samples: int | None = None) -> PoseDemonstration:
    """The demonstration at ``samples`` equally spaced times over its span (default: as many as it has).

    Positions are interpolated linearly, orientations by slerp between the
    neighbouring samples.
    """
    n = demo.t.size if samples is None else int(samples)
    if n < 3:
        raise ValueError(f"need at least 3 samples, got {n}")
    t = np.linspace(demo.t[0], demo.t[-1], n)
    k = np.clip(np.searchsorted(demo.t, t, side="right") - 1, 0, demo.t.size - 2)
    u = (t - demo.t[k]) / (demo.t[k + 1] - demo.t[k])
    position = demo.position[k] + u[:, None] * (demo.position[k + 1] - demo.position[k])
    quaternion = quat_slerp(demo.quaternion[k], demo.quaternion[k + 1], u)
    return PoseDemonstration(t=t, position=position, quaternion=quat_hemisphere_continuous(quaternion))


# ----------------------------------------------------------------------------- data sources of the dmp kind

Recording = PoseDemonstration | InterfaceRecording | KinectRecording
"""What a source of the ``demonstrations`` family returns."""

Triple = tuple[float, float, float]


def pose_demonstration(recording: Recording) -> PoseDemonstration:
    """The demonstration to learn from in a recording (a :class:`PoseDemonstration` is its own)."""
    return recording if isinstance(recording, PoseDemonstration) else recording.demonstration


class ImuParams(Options):
    """``data.params`` of source ``imu`` (:func:`imu_interface_recording`)."""

    rate: float = Field(100.0, gt=0, description="IMU sample rate [Hz]")
    via_points: int = Field(2, ge=0, description="random via points of the smooth section-angle path")
    theta_range: tuple[float, float] = Field((0.15, 1.2), description="range of each section's bending angle [rad]")
    noise_deg: float = Field(0.1, ge=0, description="white orientation noise per axis of each IMU [deg]")
    drift_deg_per_s: float = Field(0.02, ge=0, description="largest yaw drift rate of an IMU [deg/s]")
    section_lengths: tuple[float, float] | None = Field(
        None, description="lengths of the interface's two sections [m]; null: the arm's"
    )


class KinectParams(Options):
    """``data.params`` of source ``kinect`` (:func:`kinect_recording`)."""

    rate: float = Field(30.0, gt=0, description="frame rate [frames/s]")
    via_points: int = Field(3, ge=0, description="random via points of the smooth wrist paths")
    position_noise: float = Field(0.008, ge=0, description="skeleton jitter of the right wrist per axis [m]")
    orientation_noise_deg: float = Field(3.0, ge=0, description="jitter of the left wrist's orientation per axis [deg]")
    window: int = Field(5, ge=1, description="samples M of the moving average of eq. (31)")
    cube_edge: float = Field(0.36, gt=0, description="edge of the workspace cube the wrist is scaled into [m]")
    workspace_centre: Triple = Field((0.0, 0.0, 0.27), description="centre of that cube in the robot base frame [m]")
    spine_shoulder: Triple = Field((0.0, 0.35, 2.2), description="spine-shoulder joint in the camera frame [m]")


class SmoothParams(Options):
    """``data.params`` of source ``smooth`` (:func:`smooth_pose_demonstration`)."""

    duration: float = Field(10.0, gt=0, description="length of the motion [s]")
    reach: float = Field(0.12, ge=0, description="half-width of the cube start and goal are drawn in [m]")
    turn: float = Field(1.2, ge=0, description="largest rotation-vector norm of start and goal [rad]")
    centre: Triple = Field((0.0, 0.0, 0.30), description="centre of that cube [m]")


class GimbalParams(Options):
    """``data.params`` of source ``gimbal`` (:func:`gimbal_demonstration`)."""

    duration: float = Field(10.0, gt=0, description="length of the motion [s]")
    peak_pitch_deg: float = Field(120.0, description="pitch at the end of the motion (eq. 30) [deg]")
    reach: float = Field(0.1, ge=0, description="size of the position detour [m]")


class DemonstrationFileParams(FileParams):
    """``data.params`` of a source reading a demonstration file (:func:`read_demonstration`)."""

    file: str = Field(
        min_length=1,
        description="the CSV file (t and x,y,z[,qw,qx,qy,qz], or t and the arm's variables), "
        "relative to the problem file's folder",
    )
    content: Content | None = Field(
        None, description="pose | position | configuration; null: from the header (qw..qz: pose, x: position)"
    )
    units: Literal["m", "cm", "mm"] = Field("m", description="length unit of the file's x, y, z")
    frame: FrameOptions = Field(
        default_factory=FrameOptions,
        description="axes of the file's frame (frame: {up: y} for a y-up recording), converted to optikin's z-up "
        "frame as a recording's (optikin.data.recording)",
    )


class CsvParams(DemonstrationFileParams):
    """``data.params`` of source ``csv`` (family ``demonstrations``): a file of tip poses or configurations."""

    samples: int | None = Field(
        None,
        ge=3,
        description="resample to this many equally spaced samples; null: as "
        "many as the file has (resampled only if its steps vary)",
    )


def read_params_file(arm: ArmModel | None, params: DemonstrationFileParams, path: Path) -> RecordedDemonstration:
    """:func:`read_demonstration` of ``params.file`` (relative to the problem file ``path``), for ``arm``."""
    names = () if arm is None else arm.config_names
    demonstration = read_demonstration(params.resolve(path), params.content, names, params.units)
    matrix = frame_matrix(params.frame)
    if demonstration.position is None or np.array_equal(matrix, np.eye(3)):
        return demonstration
    if demonstration.quaternion is not None and np.linalg.det(matrix) < 0:
        raise SpecError(path, "data.params.frame", "a left-handed frame cannot carry orientations of an arm's frames")
    quaternion = demonstration.quaternion
    return replace(
        demonstration,
        position=convert_vectors(demonstration.position, matrix),
        quaternion=None
        if quaternion is None
        else quat_hemisphere_continuous(convert_body_orientations(quaternion, matrix)),
    )


def _generated(maker: Callable[..., Any], data: DataSpec, path: Path, **params: Any) -> Any:
    """``maker(samples, seed, **params)``; a value it refuses is a :class:`SpecError` on ``data.params``."""
    try:
        return maker(samples=data.samples, seed=data.seed, **params)
    except ValueError as exc:
        raise SpecError(str(path), "data.params", str(exc)) from None


@register_source(
    "demonstrations", "imu", "IMU teleoperation interface (Seleem et al. 2020, sec. III-A)", params=ImuParams
)
def load_imu(arm: ArmModel, data: DataSpec, params: ImuParams, path: Path) -> InterfaceRecording:
    """The IMU recording; its sections default to the arm's (a two-section constant-curvature arm)."""
    values = params.model_dump()
    if values["section_lengths"] is None:
        lengths = getattr(arm, "section_lengths", None)
        values["section_lengths"] = (0.18, 0.18) if lengths is None else tuple(lengths)
    return _generated(imu_interface_recording, data, path, **values)


@register_source(
    "demonstrations", "kinect", "Kinect v2 wrist capture (Seleem et al. 2020, sec. IV)", params=KinectParams
)
def load_kinect(arm: ArmModel, data: DataSpec, params: KinectParams, path: Path) -> KinectRecording:
    """The Kinect recording."""
    return _generated(kinect_recording, data, path, **params.model_dump())


@register_source("demonstrations", "smooth", "a clean rest-to-rest pose motion", params=SmoothParams)
def load_smooth(arm: ArmModel, data: DataSpec, params: SmoothParams, path: Path) -> PoseDemonstration:
    """The smooth pose demonstration."""
    return _generated(smooth_pose_demonstration, data, path, **params.model_dump())


@register_source("demonstrations", "gimbal", "a motion through pitch 90 degrees (gimbal lock)", params=GimbalParams)
def load_gimbal(arm: ArmModel, data: DataSpec, params: GimbalParams, path: Path) -> PoseDemonstration:
    """The gimbal-lock demonstration."""
    return _generated(gimbal_demonstration, data, path, **params.model_dump())


@register_source(
    "demonstrations",
    "csv",
    "a recorded demonstration file: tip poses (t,x,y,z,qw,qx,qy,qz) or configurations (t and the arm's variables)",
    params=CsvParams,
)
def load_csv(arm: ArmModel, data: DataSpec, params: CsvParams, path: Path) -> PoseDemonstration:
    """The file's tip poses (of a configuration file: their forward kinematics on the arm), resampled to
    ``params.samples`` or onto a fixed step if its steps vary.

    Raises
    ------
    SpecError
        Naming ``data.params.content`` for a file of tip positions: every DMP variant of the kind
        learns the pose.
    """
    recorded = read_params_file(arm, params, path)
    if recorded.content == "position":
        raise SpecError(
            str(path),
            "data.params.content",
            f"{recorded.source} holds tip positions only (t, x, y, z); the dmp kind learns tip poses: add the "
            "columns qw, qx, qy, qz, or give the arm's configurations (a position demonstration can be tracked: "
            "source csv of the tracking kind)",
        )
    demo = recorded.pose(arm)
    steps = np.diff(demo.t)
    if params.samples is not None or not np.allclose(steps, steps.mean(), rtol=1e-6):
        demo = resample_uniform(demo, params.samples)
    return demo
