"""Motion-capture measurements of a CBHA backbone: a synthetic recorder and a CSV reader.

Seed 002 (section IV) tracks the CBHA with an OptiTrack system (four Prime13
cameras, 240 frames per second): markers at the start and end of the arm and at
three intermediate points, the end poses giving the PH curve's data and the
intermediate markers the check of its shape (section V.A); wire potentiometers
give the tube lengths (section V.B, Table II).

:func:`synthetic_recording` plays the same experiment on the CBHA vertebra model
(:class:`optikin.arms.cbha.CBHAArm`, seed 004):

* **motion**: the arm is driven as the real one is, by its tubes. Each section ``s``
  and tube ``m`` has an elongation fraction ``f_sm(t)`` in ``[0, 1]``, a sinusoid of
  random frequency and phase (seeded); every leg ``(m, k)`` of the section's
  platforms then has length ``q_min,k + f_sm (q_max,k - q_min,k)``, within Table I
  by construction, and each platform's pose ``(Z_k, theta_k, psi_k)`` is solved from
  its three legs (Newton on seed 004 eqs. 3-6). So every posture is admissible
  (checked again with :meth:`CBHAArm.validate`) and the motion is smooth;
* **frames**: 240 Hz; one posture is kept every ``stride`` frames (default 24, so
  100 postures span about 10 s) and time-stamped ``frame / 240``;
* **markers**: the end poses are rigid bodies of three markers each, on the tubes'
  attachment points of the base and tip vertebrae (``r_n u_m``, eq. 3), fitted by
  the least-squares rotation (Kabsch / Horn) as motion-capture software does: the
  position is the vertebra centre (the three ``u_m`` add to zero), the rotation the
  vertebra frame (z along the backbone). Intermediate markers sit on the backbone
  at vertebrae 5, 9 and 13 (about a quarter, half and three quarters of the way).
  Every marker gets isotropic Gaussian noise, ``0.3 mm`` standard deviation per
  coordinate (seeded);
* **reference tube lengths**: the model's ``tube_lengths`` (section 1 and the whole
  tube, as the seed's six potentiometers), noise-free;
* **truth**: configurations, vertebra centres and backbone length, for honest
  comparisons of the PH backbone with the model's.

:func:`synthetic_rope_chain` records the closed chain of section IV.B: two such arms
and the rope they hold, hanging as an exact catenary.

Problem files name a source of family ``markers`` in ``data.source`` (registered with
:func:`optikin.data.sources.register_source`, params models :class:`SyntheticMarkerParams`,
:class:`CsvMarkerParams` and :class:`DiskParams`): ``synthetic``, ``csv`` or ``disks``. Source
``disks`` reads positions-only disk centres (columns ``<disk>_x, <disk>_y, <disk>_z``, e.g. the
``points_file`` of kind ``calibrate``) with a base pose given or read from the calibrated arm file,
and estimates the tip pose from the disks alone (:func:`disk_recording`, :func:`estimated_tip`: the
tangent at the last disk of the circle through the last three points). The rope chain has family
``rope_chains``, source ``synthetic`` (:class:`RopeChainParams`).

CSV files (:func:`read_marker_csv`, :func:`write_marker_csv`) have a header row and
one row per posture, all lengths in metres, quaternions ``(w, x, y, z)``:

=====================================  =========================================================
``t``                                  time, seconds
``base_x, base_y, base_z``             base rigid body: position (the backbone's start point)
``base_qw, base_qx, base_qy, base_qz`` base rigid body: orientation; its z axis is the backbone's
                                       start direction, its x axis the reference of the tube angles
``tip_x ... tip_qz``                   tip rigid body, the same eight columns
``m1_x, m1_y, m1_z``, ``m2_...``       intermediate markers from base to tip (at least one)
``L1, L2, L3``                         optional: whole tube lengths (potentiometers)
``S1_L1, S1_L2, S1_L3``                optional: tube lengths of section 1
=====================================  =========================================================

Other columns are ignored. Every cell read must be a finite number; ``t`` must increase
strictly; quaternions within 1e-3 of unit length are normalised. Anything else (missing
column, empty, non-numeric, NaN or infinite cell, non-unit quaternion, times that do not
increase; a file refused by :mod:`optikin.data.csvread`: not a regular file, over
200 MiB, binary, not UTF-8) raises :class:`InputDataError` naming the file, the row
(``sample`` counts data rows from 0; the message gives the line) and the column. The
``csv`` source reads every row, or the first ``data.samples`` when the problem file
gives it (the rows left out counted in :attr:`MarkerRecording.skipped_rows`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import casadi as ca
import numpy as np
import yaml
from pydantic import Field, field_validator

from optikin.algebra import quat_from_axis_angle, quat_from_matrix, quat_multiply, quat_normalize, quat_rotate
from optikin.arms.base import ArmModel
from optikin.arms.cbha import LEG_DIRECTIONS, PLATFORM_LEG_LENGTHS, CBHAArm
from optikin.curves.catenary import Catenary, catenary
from optikin.data.configurations import first_rows
from optikin.data.csvread import UNIT_METRES, columns_of, missing_columns, read_table
from optikin.data.files import data_file
from optikin.data.recording import FrameOptions, convert_body_orientations, convert_vectors, frame_matrix
from optikin.data.sources import register_source
from optikin.data.targets import BasePose
from optikin.errors import SpecError
from optikin.options import Options
from optikin.spec import DataSpec

FRAME_RATE = 240.0
"""Frames per second of the seed's OptiTrack Prime13 cameras (seed 002 section IV)."""
MARKER_NOISE = 0.3e-3
"""Standard deviation of each marker coordinate, metres."""
INTERMEDIATE_VERTEBRAE = (5, 9, 13)
"""1-based vertebrae carrying the three intermediate markers (base: 1, tip: 17)."""
QUATERNION_TOLERANCE = 1e-3
"""| |q| - 1 | accepted in a CSV file before normalising."""
COINCIDENT = 1e-6
"""Largest distance [m] between a posture's base and tip positions that counts as the same point (refused: an arm
has a length, so a tip at the base is a marker labelled twice)."""

POSE_COLUMNS = ("x", "y", "z", "qw", "qx", "qy", "qz")


@dataclass
class CBHATruth:
    """What the synthetic recorder knows and a real recording does not."""

    configurations: np.ndarray  # (N, 48)
    vertebrae: np.ndarray  # (N, 17, 3) vertebra centres
    backbone_length: np.ndarray  # (N,) sum of Z_k: the polyline through the vertebra centres
    marker_truth: np.ndarray  # (N, K, 3) intermediate markers without noise


@dataclass
class MarkerRecording:
    """End poses, intermediate markers and (optionally) reference tube lengths of ``N`` postures.

    Positions in metres, quaternions ``(w, x, y, z)`` (rigid-body orientation: z along
    the backbone). ``tube_lengths`` are whole tubes ``(N, 3)``, ``section_tube_lengths``
    section 1 ``(N, 3)``. ``marker_vertebrae``: the 1-based vertebra of each intermediate
    marker, when known (empty otherwise). ``skipped_rows``: rows of a file source left out
    because ``data.samples`` asked for fewer. A tip pose estimated from the markers (source ``disks``):
    ``tip_estimate`` says how, ``tip_markers`` are the intermediate markers it used (indices from 0), and
    ``held_out_tip_directions`` ``(N, K, 3)`` the unit tip tangent estimated without marker ``k``, for
    scoring each marker on a curve that did not use it (None: the tip pose is recorded).
    """

    t: np.ndarray
    base_position: np.ndarray
    base_orientation: np.ndarray
    tip_position: np.ndarray
    tip_orientation: np.ndarray
    markers: np.ndarray
    tube_lengths: np.ndarray | None = None
    section_tube_lengths: np.ndarray | None = None
    source: str = ""
    truth: CBHATruth | None = field(default=None, repr=False)
    marker_vertebrae: tuple[int, ...] = ()
    skipped_rows: int = 0
    held_out_tip_directions: np.ndarray | None = None
    tip_estimate: str = ""
    tip_markers: tuple[int, ...] = ()

    def __post_init__(self):
        if self.marker_vertebrae and len(self.marker_vertebrae) != self.markers.shape[1]:
            raise ValueError(f"{len(self.marker_vertebrae)} marker vertebrae for {self.markers.shape[1]} markers")

    def __len__(self) -> int:
        return len(self.t)

    @property
    def base_direction(self) -> np.ndarray:
        """Unit start tangents ``(N, 3)``: the base z axes."""
        return quat_rotate(self.base_orientation, np.array([0.0, 0.0, 1.0]), check=False)

    @property
    def tip_direction(self) -> np.ndarray:
        """Unit end tangents ``(N, 3)``: the tip z axes."""
        return quat_rotate(self.tip_orientation, np.array([0.0, 0.0, 1.0]), check=False)

    @property
    def base_normal(self) -> np.ndarray:
        """Reference normals of the tube angles ``(N, 3)``: the base x axes."""
        return quat_rotate(self.base_orientation, np.array([1.0, 0.0, 0.0]), check=False)

    def with_fixed_base(self) -> "MarkerRecording":
        """The base pose averaged over the recording (seed 002: the base is fixed), noise reduced by sqrt(N)."""
        q = self.base_orientation * np.where(self.base_orientation @ self.base_orientation[0] < 0, -1.0, 1.0)[:, None]
        mean_q = quat_normalize(q.mean(axis=0), check=False)
        n = len(self)
        return replace(
            self,
            base_position=np.tile(self.base_position.mean(axis=0), (n, 1)),
            base_orientation=np.tile(mean_q, (n, 1)),
        )

    def take(self, index) -> "MarkerRecording":
        """The postures ``index`` (a slice or an index array)."""
        pick = lambda a: None if a is None else a[index]  # noqa: E731
        truth = None
        if self.truth is not None:
            tr = self.truth
            truth = CBHATruth(
                tr.configurations[index], tr.vertebrae[index], tr.backbone_length[index], tr.marker_truth[index]
            )
        return replace(
            self,
            t=self.t[index],
            base_position=self.base_position[index],
            base_orientation=self.base_orientation[index],
            tip_position=self.tip_position[index],
            tip_orientation=self.tip_orientation[index],
            markers=self.markers[index],
            tube_lengths=pick(self.tube_lengths),
            section_tube_lengths=pick(self.section_tube_lengths),
            truth=truth,
            held_out_tip_directions=pick(self.held_out_tip_directions),
        )


# ------------------------------------------------------------------------------ the CBHA driven by its tubes
@lru_cache(maxsize=None)
def _platform_newton_step() -> ca.Function:
    """``(x = (Z, theta, psi), q_target, r_k, r_k1) -> (x - J^-1 (q(x) - q_target), max |q(x) - q_target|)``."""
    x, target = ca.SX.sym("x", 3), ca.SX.sym("q", 3)
    r_k, r_k1 = ca.SX.sym("r_k"), ca.SX.sym("r_k1")
    q = PLATFORM_LEG_LENGTHS(x[0], x[1], x[2], r_k, r_k1)
    residual = q - target
    step = ca.solve(ca.jacobian(q, x), residual)
    return ca.Function("cbha_platform_newton", [x, target, r_k, r_k1], [x - step, ca.mmax(ca.fabs(residual))])


def platform_poses_from_legs(
    legs: np.ndarray, r_lower: np.ndarray, r_upper: np.ndarray, iterations: int = 30, tolerance: float = 1e-13
) -> np.ndarray:
    """``(Z, theta, psi)`` of platforms from their three leg lengths (seed 004 eqs. 3-6), by Newton.

    ``legs`` ``(M, 3)``, radii ``(M,)``; starts from the straight pose at the mean leg
    length. Raises ``ValueError`` if a platform does not converge (legs no platform can have).
    A plain Newton loop of its own rather than the IK solver presets
    (:mod:`optikin.ik.platform`): the recording is the ground truth those are scored on.
    """
    legs = np.asarray(legs, dtype=float)
    M = legs.shape[0]
    mean = legs.mean(axis=1)
    x = np.column_stack([np.sqrt(np.maximum(mean**2 - (r_lower - r_upper) ** 2, 1e-12)), np.zeros(M), np.zeros(M)])
    step = _platform_newton_step().map(M)
    for _ in range(iterations):
        x_new, residual = step(x.T, legs.T, r_lower[None, :], r_upper[None, :])
        x = np.asarray(x_new).T
        if float(np.max(np.asarray(residual))) < tolerance:
            break
    final = np.asarray(step(x.T, legs.T, r_lower[None, :], r_upper[None, :])[1]).ravel()
    if not np.all(final < 1e-10):
        raise ValueError(f"platform legs not reachable: residual {final.max():.3g} m")
    return x


def tube_fractions(
    n_sections: int, t: np.ndarray, rng: np.random.Generator, frequency: tuple[float, float], amplitude: float
) -> np.ndarray:
    """Elongation fractions ``(N, sections, 3)`` in ``[0, 1]``: ``1/2 + amplitude/2 sin(2 pi nu t + phase)``."""
    nu = rng.uniform(frequency[0], frequency[1], (n_sections, 3))
    phase = rng.uniform(-np.pi, np.pi, (n_sections, 3))
    return 0.5 + 0.5 * amplitude * np.sin(2 * np.pi * nu * t[:, None, None] + phase)


def configurations_from_fractions(arm: CBHAArm, fractions: np.ndarray) -> np.ndarray:
    """Configurations ``(N, 48)`` of tube elongation fractions ``(N, sections, 3)`` (module docstring)."""
    g = arm.geometry
    N = fractions.shape[0]
    section_of = np.repeat(np.arange(arm.n_sections), g.platforms_per_section)
    lo, hi = np.asarray(g.leg_min), np.asarray(g.leg_max)
    legs = lo[None, :, None] + fractions[:, section_of, :] * (hi - lo)[None, :, None]  # (N, platform, tube)
    r = g.radii
    r_lower = np.tile(r[:-1], N)
    r_upper = np.tile(r[1:], N)
    poses = platform_poses_from_legs(legs.reshape(-1, 3), r_lower, r_upper)
    return poses.reshape(N, -1)


# ------------------------------------------------------------------------------ the recorder
def kabsch_rotation(local: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rigid fit ``measured ~ R local + p`` (Kabsch 1976), batched.

    ``local`` ``(K, 3)`` points in the body frame, centred; ``measured`` ``(N, K, 3)``.
    Returns ``(R (N, 3, 3), p (N, 3))``.
    """
    p = measured.mean(axis=1)
    H = np.einsum("ki,nkj->nij", local, measured - p[:, None, :])
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("nij,njk->nik", Vt.transpose(0, 2, 1), U.transpose(0, 2, 1))))
    D = np.zeros((len(d), 3, 3))
    D[:, 0, 0] = D[:, 1, 1] = 1.0
    D[:, 2, 2] = d
    R = np.einsum("nij,njk,nkl->nil", Vt.transpose(0, 2, 1), D, U.transpose(0, 2, 1))
    return R, p


def synthetic_recording(
    arm: CBHAArm,
    samples: int = 100,
    rng: np.random.Generator | None = None,
    *,
    noise: float = MARKER_NOISE,
    rate: float = FRAME_RATE,
    stride: int = 24,
    frequency: tuple[float, float] = (0.05, 0.2),
    amplitude: float = 0.9,
    intermediate: tuple[int, ...] = INTERMEDIATE_VERTEBRAE,
    source: str = "synthetic CBHA recording",
) -> MarkerRecording:
    """Record ``samples`` postures of the CBHA moved by its tubes (module docstring)."""
    rng = rng if rng is not None else np.random.default_rng(0)
    n_vertebrae = arm.geometry.n_vertebrae
    bad = [v for v in intermediate if not (isinstance(v, (int, np.integer)) and 1 < v < n_vertebrae)]
    if bad or not intermediate:
        raise ValueError(
            f"intermediate markers need vertebrae strictly between 1 and {n_vertebrae}, got {intermediate}"
        )
    if not (noise >= 0 and rate > 0 and stride >= 1 and 0 <= amplitude <= 1):
        raise ValueError("need noise >= 0, rate > 0, stride >= 1 and amplitude in [0, 1]")
    t = np.arange(samples) * stride / rate
    Q = configurations_from_fractions(arm, tube_fractions(arm.n_sections, t, rng, frequency, amplitude))
    Q = arm.validate(Q, source=source)
    vertebrae = arm.evaluate("vertebra_positions", Q).transpose(0, 2, 1)  # (N, 17, 3)
    tube_pts = arm.evaluate("tube_points", Q).reshape(samples, 3, 3, n_vertebrae)  # (N, xyz, tube, vertebra)
    lengths = arm.evaluate("tube_lengths", Q)  # (N, section, tube)

    def rigid_body(n: int):
        local = arm.geometry.vertebra_radius(n + 1) * LEG_DIRECTIONS  # (3 markers, xyz), centred
        measured = tube_pts[:, :, :, n].transpose(0, 2, 1) + noise * rng.standard_normal((samples, 3, 3))
        R, p = kabsch_rotation(local, measured)
        return p, quat_from_matrix(R)

    base_p, base_q = rigid_body(0)
    tip_p, tip_q = rigid_body(n_vertebrae - 1)
    index = np.asarray(intermediate) - 1
    marker_truth = vertebrae[:, index, :]
    markers = marker_truth + noise * rng.standard_normal(marker_truth.shape)
    truth = CBHATruth(Q, vertebrae, Q.reshape(samples, -1, 3)[:, :, 0].sum(axis=1), marker_truth)
    return MarkerRecording(
        t,
        base_p,
        base_q,
        tip_p,
        tip_q,
        markers,
        lengths.sum(axis=1),
        lengths[:, 0, :],
        source,
        truth,
        tuple(int(v) for v in intermediate),
    )


# ------------------------------------------------------------------------------ CSV files
def _header(n_markers: int, lengths: bool, section: bool) -> list[str]:
    cols = ["t"] + [f"{body}_{c}" for body in ("base", "tip") for c in POSE_COLUMNS]
    cols += [f"m{k}_{c}" for k in range(1, n_markers + 1) for c in "xyz"]
    if lengths:
        cols += ["L1", "L2", "L3"]
    if section:
        cols += ["S1_L1", "S1_L2", "S1_L3"]
    return cols


def write_marker_csv(recording: MarkerRecording, path: Path) -> Path:
    """Write ``recording`` in the documented columns (module docstring), full precision."""
    n, K = len(recording), recording.markers.shape[1]
    columns = [
        recording.t[:, None],
        recording.base_position,
        recording.base_orientation,
        recording.tip_position,
        recording.tip_orientation,
        recording.markers.reshape(n, 3 * K),
    ]
    if recording.tube_lengths is not None:
        columns.append(recording.tube_lengths)
    if recording.section_tube_lengths is not None:
        columns.append(recording.section_tube_lengths)
    table = np.hstack(columns)
    path = Path(path)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(_header(K, recording.tube_lengths is not None, recording.section_tube_lengths is not None))
        writer.writerows([[repr(float(v)) for v in row] for row in table])
    return path


def read_marker_csv(
    path: Path, units: Literal["m", "cm", "mm"] = "m", frame: FrameOptions | None = None
) -> MarkerRecording:
    """Read a recording from a CSV file in the documented columns (module docstring).

    Columns ``t`` [s]; ``base_x ... base_qz`` and ``tip_x ... tip_qz`` (positions [``units``],
    unit quaternions ``(w, x, y, z)``); ``m1_x, m1_y, m1_z, ...`` [``units``], at least one marker;
    optionally ``L1, L2, L3`` and ``S1_L1, S1_L2, S1_L3`` [``units``]. Other columns are ignored.

    Parameters
    ----------
    path:
        The file (:mod:`optikin.data.csvread`: UTF-8 text with a header row).
    units:
        The length unit of the file's positions and lengths; they are returned in metres.
    frame:
        The axes of the file's frame (default z-up): positions and orientations are returned in optikin's
        z-up axes, converted as a recording's (:func:`optikin.data.recording.frame_matrix`).

    Returns
    -------
    MarkerRecording
        Every row; quaternions normalised; ``source`` the file.

    Raises
    ------
    InputDataError
        The file cannot be read or is refused, lacks a column, has no data rows or a cell
        that is not a finite number; a quaternion's norm is more than
        :data:`QUATERNION_TOLERANCE` from 1; ``t`` does not increase strictly; a position is beyond
        :data:`~optikin.data.csvread.MAX_COORDINATE` (with a unit hint); the tip's position is the base's
        (within :data:`COINCIDENT`).
    """
    path = Path(path)
    source = str(path)
    scale = UNIT_METRES[units]

    def select(header: tuple[str, ...]) -> tuple[list[str], list[str]]:
        n_markers = 0
        while all(f"m{n_markers + 1}_{c}" in header for c in "xyz"):
            n_markers += 1
        hint = " (intermediate markers m1_x, m1_y, m1_z, ... are numbered from 1)"
        error = missing_columns(source, header, _header(max(n_markers, 1), False, False), hint)
        if error is not None:
            raise error
        has_lengths = all(c in header for c in ("L1", "L2", "L3"))
        has_section = all(c in header for c in ("S1_L1", "S1_L2", "S1_L3"))
        wanted = _header(n_markers, has_lengths, has_section)
        return wanted, wanted

    table = read_table(path, select)
    base_q, tip_q = (
        quat_normalize(
            table.check_unit_quaternions([f"{body}_{c}" for c in ("qw", "qx", "qy", "qz")], QUATERNION_TOLERANCE),
            check=False,
        )
        for body in ("base", "tip")
    )
    table.check_increasing("t")
    n_markers = sum(1 for c in table.columns if c.startswith("m") and c.endswith("_x"))
    n = len(table)
    has = set(table.columns)
    marker_columns = [f"m{k}_{c}" for k in range(1, n_markers + 1) for c in "xyz"]
    table.check_coordinates(
        [f"{body}_{c}" for body in ("base", "tip") for c in "xyz"] + marker_columns, scale, units, "data.params.units"
    )
    base, tip = (table.stacked([f"{body}_{c}" for c in "xyz"]) * scale for body in ("base", "tip"))
    distance = np.linalg.norm(tip - base, axis=1)
    close = np.flatnonzero(distance <= COINCIDENT)
    if close.size:
        i = int(close[0])
        raise table.error(
            f"the tip's position is the base's ({distance[i]:.3g} m apart): a marker labelled twice?", i, "tip_x"
        )
    matrix = frame_matrix(frame or FrameOptions())
    return MarkerRecording(
        t=table.column("t"),
        base_position=convert_vectors(base, matrix),
        base_orientation=convert_body_orientations(base_q, matrix),
        tip_position=convert_vectors(tip, matrix),
        tip_orientation=convert_body_orientations(tip_q, matrix),
        markers=convert_vectors(table.stacked(marker_columns).reshape(n, n_markers, 3) * scale, matrix),
        tube_lengths=table.stacked(["L1", "L2", "L3"]) * scale if "L1" in has else None,
        section_tube_lengths=table.stacked(["S1_L1", "S1_L2", "S1_L3"]) * scale if "S1_L1" in has else None,
        source=source,
    )


# ------------------------------------------------------------------------------ sources of problem files
class SyntheticMarkerParams(Options):
    """``data.params`` of source ``synthetic`` (family ``markers``): :func:`synthetic_recording`'s settings."""

    noise: float = Field(MARKER_NOISE, ge=0, description="standard deviation of each marker coordinate [m]")
    rate: float = Field(FRAME_RATE, gt=0, description="camera frame rate [Hz]")
    stride: int = Field(24, ge=1, description="frames between kept postures")
    frequency: tuple[float, float] = Field((0.05, 0.2), description="[low, high] tube frequencies [Hz]")
    amplitude: float = Field(0.9, ge=0, le=1, description="elongation amplitude, fraction of the Table I range")
    intermediate: tuple[int, ...] = Field(
        INTERMEDIATE_VERTEBRAE, min_length=1, description="1-based vertebrae carrying the intermediate markers"
    )

    @field_validator("frequency")
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not 0 <= value[0] <= value[1]:
            raise ValueError("frequency must be [low, high] with 0 <= low <= high")
        return value

    def motion(self) -> dict[str, Any]:
        """The keyword arguments of :func:`synthetic_recording` these params give."""
        return dict(
            noise=self.noise,
            rate=self.rate,
            stride=self.stride,
            frequency=self.frequency,
            amplitude=self.amplitude,
            intermediate=self.intermediate,
        )


class CsvMarkerParams(Options):
    """``data.params`` of source ``csv`` (family ``markers``)."""

    file: str = Field(description="the recording (columns in the module docstring), relative to the problem file")
    units: Literal["m", "cm", "mm"] = Field("m", description="length unit of the file's positions and lengths")
    frame: FrameOptions = Field(
        default_factory=FrameOptions,
        description="axes of the file's frame (frame: {up: y} for a y-up recording), converted to optikin's z-up "
        "frame as a recording's (optikin.data.recording)",
    )
    intermediate: tuple[int, ...] | None = Field(
        None,
        description="1-based vertebra of each intermediate marker, in column order (comparators that use "
        "a particular marker need it)",
    )


def _cbha(arm: ArmModel | None, path: Path, source: str) -> CBHAArm:
    if arm is None:
        raise SpecError(path, "arm", f"source {source!r} records a CBHA: give arm: {{type: cbha}}")
    if not isinstance(arm, CBHAArm):
        raise SpecError(path, "arm.type", f"source {source!r} records a CBHA; got arm {arm.name!r}")
    return arm


@register_source(
    "markers",
    "synthetic",
    "the CBHA vertebra model driven by its tubes, recorded by motion capture (the vertebra model's own assumptions)",
    params=SyntheticMarkerParams,
)
def synthetic_source(arm: ArmModel, data: DataSpec, params: SyntheticMarkerParams, path: Path) -> MarkerRecording:
    """:func:`synthetic_recording` of ``data.samples`` postures seeded by ``data.seed``."""
    cbha = _cbha(arm, path, "synthetic")
    try:
        return synthetic_recording(
            cbha,
            data.samples,
            np.random.default_rng([data.seed, 0]),
            **params.motion(),
            source=f"{Path(path).name}: synthetic",
        )
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None


@register_source(
    "markers", "csv", "a recorded marker CSV file (columns in optikin.data.markers)", params=CsvMarkerParams
)
def csv_source(arm: ArmModel | None, data: DataSpec, params: CsvMarkerParams, path: Path) -> MarkerRecording:
    """:func:`read_marker_csv` of ``params.file`` (relative to the problem file): every row, or the first
    ``data.samples`` when the problem file gives it."""
    try:
        recording = read_marker_csv(data_file(path, params.file), params.units, params.frame)
    except ValueError as exc:
        raise SpecError(path, "data.params.frame", str(exc)) from None
    if params.intermediate is not None:
        try:
            recording = replace(recording, marker_vertebrae=params.intermediate)
        except ValueError as exc:
            raise SpecError(
                path, "data.params.intermediate", f"{exc} (the file has {recording.markers.shape[1]} marker columns)"
            ) from None
    keep, skipped = first_rows(data, len(recording))
    return replace(recording.take(slice(0, keep)), skipped_rows=skipped)


# ------------------------------------------------------------------------------ positions-only disks
def circle_tangent(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Unit tangent at ``c`` of the circle through ``a``, ``b``, ``c``, travelled from ``a`` through ``b`` to ``c``.

    The inversion about ``c`` maps that circle to the straight line through ``(a - c) / |a - c|^2`` and
    ``(b - c) / |b - c|^2``, parallel to the circle's tangent at ``c``; so the tangent is the unit vector of
    their difference, in closed form, and three collinear points give their line's direction.

    Parameters
    ----------
    a, b, c:
        Three distinct points on the curve, in order, ``(N, 3)`` [m].

    Returns
    -------
    np.ndarray
        ``(N, 3)`` unit vectors, pointing onwards from ``c`` (NaN where two points coincide).
    """
    u, v = b - c, a - c
    with np.errstate(divide="ignore", invalid="ignore"):
        w = v / np.sum(v * v, axis=-1, keepdims=True) - u / np.sum(u * u, axis=-1, keepdims=True)
        return w / np.linalg.norm(w, axis=-1, keepdims=True)


def rotation_onto(q: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The orientations ``(N, 4)`` whose z axis is ``direction`` ``(N, 3)`` (unit), each the smallest rotation of
    orientation ``q`` ``(N, 4)`` that turns its z axis onto it (about the base x axis for a half turn)."""
    z = quat_rotate(q, np.array([0.0, 0.0, 1.0]), check=False)
    x = quat_rotate(q, np.array([1.0, 0.0, 0.0]), check=False)
    half = np.concatenate([1.0 + np.sum(z * direction, axis=1, keepdims=True), np.cross(z, direction)], axis=1)
    flip = half[:, 0] <= 1e-12
    half[flip] = np.concatenate([np.zeros((int(flip.sum()), 1)), x[flip]], axis=1)
    return quat_normalize(quat_multiply(quat_normalize(half, check=False), q), check=False)


def tip_tangents(chain: np.ndarray) -> np.ndarray:
    """The tip tangent of every posture from its last three points: ``chain`` ``(N, P, 3)`` (base point first,
    tip last, ``P >= 3``) -> ``(N, 3)`` (:func:`circle_tangent`)."""
    return circle_tangent(chain[:, -3], chain[:, -2], chain[:, -1])


def estimated_tip(recording: MarkerRecording) -> MarkerRecording:
    """``recording`` with its tip orientation estimated from its points alone (the tip position kept).

    The chain of each posture is the base point, the intermediate markers and the tip point, in order; the
    tip tangent is that of the circle through its last three points (:func:`tip_tangents`), the orientation
    the smallest rotation of the base orientation onto it (the tip's twist is not measured). Intermediate
    marker ``k`` is also given the tip tangent of the chain without it (``held_out_tip_directions``), so that
    every marker can be scored on a backbone that did not use it.

    Raises
    ------
    ValueError
        Fewer than two intermediate markers (three points after the base, the tip included), or two
        consecutive points of a chain that coincide (naming the posture).
    """
    K = recording.markers.shape[1]
    if K < 2:
        raise ValueError(
            f"a tip tangent from the circle through the last three disks, without each scored one, needs three "
            f"disks (two intermediate markers and the tip), got {K + 1}"
        )
    chain = np.concatenate(
        [recording.base_position[:, None], recording.markers, recording.tip_position[:, None]], axis=1
    )  # (N, K + 2, 3)
    for k in range(-1, K):  # the whole chain, then the chain without each marker
        points = chain if k < 0 else np.delete(chain, k + 1, axis=1)
        gaps = np.linalg.norm(np.diff(points, axis=1), axis=2)
        close = np.argwhere(gaps <= COINCIDENT)
        if close.size:
            i, j = (int(v) for v in close[0])
            labels = ["the base point"] + [f"disk {m + 1}" for m in range(K + 1) if m != k]
            raise ValueError(f"posture {i}: {labels[j]} and {labels[j + 1]} coincide ({gaps[i, j]:.3g} m apart)")
    held = np.stack([tip_tangents(np.delete(chain, k + 1, axis=1)) for k in range(K)], axis=1)
    return replace(
        recording,
        tip_orientation=rotation_onto(recording.base_orientation, tip_tangents(chain)),
        held_out_tip_directions=held,
        tip_estimate="tangent of the circle through the last three points of (base, disks)",
        tip_markers=tuple(k for k in range(K) if k >= K - 2),  # the markers among the last three points
    )


def disk_recording(
    disks: np.ndarray,
    base_position: np.ndarray,
    base_orientation: np.ndarray,
    t: np.ndarray | None = None,
    source: str = "",
) -> MarkerRecording:
    """End poses and intermediate markers of positions-only disks, the tip pose estimated from them alone.

    The tip position is the last disk, its orientation that of :func:`estimated_tip`; the other disks are
    the intermediate markers.

    Parameters
    ----------
    disks:
        ``(N, D, 3)`` disk centres from base to tip [m], ``D >= 3``.
    base_position, base_orientation:
        The base pose, ``(3,)`` [m] and a unit quaternion ``(4,)`` ``(w, x, y, z)`` (z along the backbone).
    t:
        Time or posture index of each row ``(N,)`` (default ``0, 1, ...``).
    source:
        Names the data.

    Raises
    ------
    ValueError
        As :func:`estimated_tip`.
    """
    N = disks.shape[0]
    p0 = np.tile(np.asarray(base_position, dtype=float), (N, 1))
    q0 = np.tile(quat_normalize(np.asarray(base_orientation, dtype=float), check=False), (N, 1))
    recording = MarkerRecording(
        t=np.arange(N, dtype=float) if t is None else np.asarray(t, dtype=float),
        base_position=p0,
        base_orientation=q0,
        tip_position=disks[:, -1].copy(),
        tip_orientation=q0.copy(),
        markers=disks[:, :-1].copy(),
        source=source,
    )
    return estimated_tip(recording)


class DiskParams(Options):
    """``data.params`` of source ``disks`` (family ``markers``): positions-only disks and the base pose."""

    file: str = Field(
        description="CSV file of disk centres, columns <disk>_x, <disk>_y, <disk>_z (e.g. the points_file of kind "
        "calibrate), relative to the problem file"
    )
    disks: tuple[str, ...] = Field(
        min_length=3, description="the disks' column prefixes from base to tip; the last is the tip"
    )
    units: Literal["m", "cm", "mm"] = Field("m", description="length unit of the file's positions")
    frame: FrameOptions = Field(
        default_factory=FrameOptions,
        description="axes of the file's frame, converted to optikin's z-up frame as a recording's",
    )
    base: BasePose | Literal["arm"] = Field(
        "arm",
        description="the base pose after the frame conversion: arm (calibration.base_position and base_quaternion "
        "of the calibrated arm file the problem's arm: includes) or {position, quaternion}",
    )


def calibrated_base(path: Path, field: str) -> tuple[np.ndarray, np.ndarray]:
    """``calibration.base_position`` [m] and ``base_quaternion`` of the arm file that problem file ``path`` includes
    (``arm: <file>``, written by kind ``calibrate``); a :class:`SpecError` on ``field`` otherwise."""
    try:
        arm = yaml.safe_load(Path(path).read_text()).get("arm")
    except (OSError, yaml.YAMLError, AttributeError) as exc:
        raise SpecError(path, field, f"cannot read the problem file again: {exc}") from None
    if not isinstance(arm, str):
        raise SpecError(path, field, "base: arm needs arm: <file> naming a calibrated arm file (kind calibrate)")
    included = (Path(path).parent / arm).resolve()
    try:
        facts = yaml.safe_load(included.read_text()).get("calibration") or {}
    except (OSError, yaml.YAMLError, AttributeError) as exc:
        raise SpecError(path, field, f"cannot read {included}: {exc}") from None
    try:
        position = np.asarray(facts["base_position"], dtype=float)
        quaternion = np.asarray(facts["base_quaternion"], dtype=float)
    except (KeyError, TypeError, ValueError):
        position = quaternion = np.zeros(0)
    if position.shape != (3,) or quaternion.shape != (4,) or not np.all(np.isfinite(np.r_[position, quaternion])):
        raise SpecError(
            path, field, f"{included} has no calibration.base_position (3 numbers) and base_quaternion (4 numbers)"
        )
    if abs(float(np.linalg.norm(quaternion)) - 1.0) > QUATERNION_TOLERANCE:
        raise SpecError(path, field, f"{included}: calibration.base_quaternion is not a unit quaternion")
    return position, quaternion


@register_source(
    "markers",
    "disks",
    "positions-only disk centres (a CSV file) with a given or calibrated base pose; the tip pose from the disks",
    params=DiskParams,
)
def disks_source(arm: ArmModel | None, data: DataSpec, params: DiskParams, path: Path) -> MarkerRecording:
    """:func:`disk_recording` of the disks of ``params.file``: every row, or the first ``data.samples``."""
    file = data_file(path, params.file)
    names = [f"{d}_{c}" for d in params.disks for c in "xyz"]
    table = read_table(file, columns_of(str(file), names, finite=names))
    scale = UNIT_METRES[params.units]
    table.check_coordinates(names, scale, params.units, "data.params.units")
    try:
        matrix = frame_matrix(params.frame)
    except ValueError as exc:
        raise SpecError(path, "data.params.frame", str(exc)) from None
    n = len(table)
    disks = convert_vectors(table.stacked(names).reshape(n * len(params.disks), 3) * scale, matrix)
    if params.base == "arm":
        position, quaternion = calibrated_base(path, "data.params.base")
    else:
        position, quaternion = np.asarray(params.base.position), np.asarray(params.base.quaternion)
    try:
        recording = disk_recording(disks.reshape(n, len(params.disks), 3), position, quaternion, source=str(file))
    except ValueError as exc:
        raise SpecError(path, "data.params.disks", f"{file}: {exc}") from None
    keep, skipped = first_rows(data, len(recording))
    return replace(recording.take(slice(0, keep)), skipped_rows=skipped)


# ------------------------------------------------------------------------------ two arms holding a rope
@dataclass
class RopeChainRecording:
    """Seed 002 section IV.B: CBHA 1 (A -> B), a rope (B -> C), CBHA 2 (C -> D), in one world frame.

    ``arm1``, ``arm2`` are the arms' recordings (arm 2 already placed at its base);
    the rope hangs between the true tips. ``rope_markers`` ``(N, K, 3)`` are its
    intermediate markers, ``rope_directions`` ``(N, 2, 3)`` its unit end directions
    from B towards C, estimated from a marker ``end_offset`` along the rope from each
    end; ``rope_truth`` ``(N, M, 3)`` dense points of the exact catenary.
    """

    arm1: MarkerRecording
    arm2: MarkerRecording
    rope_length: float
    rope_markers: np.ndarray
    rope_directions: np.ndarray
    rope_truth: np.ndarray
    rope_marker_truth: np.ndarray

    def __len__(self) -> int:
        return len(self.arm1)


def placed(recording: MarkerRecording, rotation: np.ndarray, translation: np.ndarray) -> MarkerRecording:
    """``recording`` seen from a world frame in which its base frame is rotated by ``rotation`` and moved by
    ``translation``."""
    move = lambda p: quat_rotate(rotation, p, check=False) + translation  # noqa: E731
    truth = recording.truth
    if truth is not None:
        truth = CBHATruth(truth.configurations, move(truth.vertebrae), truth.backbone_length, move(truth.marker_truth))
    return replace(
        recording,
        base_position=move(recording.base_position),
        base_orientation=quat_multiply(rotation, recording.base_orientation),
        tip_position=move(recording.tip_position),
        tip_orientation=quat_multiply(rotation, recording.tip_orientation),
        markers=move(recording.markers),
        truth=truth,
    )


def synthetic_rope_chain(
    arm: CBHAArm,
    samples: int,
    rng: np.random.Generator,
    *,
    base_distance: float = 0.25,
    rope_length: float = 0.65,
    rope_marker_fractions: tuple[float, ...] = (0.25, 0.5, 0.75),
    end_offset: float = 0.02,
    noise: float = MARKER_NOISE,
    truth_points: int = 200,
    source: str = "synthetic rope chain",
    **arm_options,
) -> RopeChainRecording:
    """Two CBHAs on one horizontal line, ``base_distance`` apart, upright, facing each other, holding a rope.

    Each arm moves as in :func:`synthetic_recording` (independent seeds); the rope is
    the inextensible catenary of ``rope_length`` between the true tips
    (:func:`optikin.curves.catenary.catenary`). Raises :class:`InputDataError` naming
    the posture where the tips are farther apart than the rope is long.
    """
    if not 0 < end_offset < rope_length / 2 or not all(0 < f < 1 for f in rope_marker_fractions):
        raise ValueError("need 0 < end_offset < rope_length / 2 and rope marker fractions within (0, 1)")
    arm1 = synthetic_recording(arm, samples, rng, noise=noise, source=f"{source}: CBHA 1", **arm_options)
    arm2 = placed(
        synthetic_recording(arm, samples, rng, noise=noise, source=f"{source}: CBHA 2", **arm_options),
        quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi),
        np.array([base_distance, 0.0, 0.0]),
    )
    assert arm1.truth is not None and arm2.truth is not None  # synthetic recordings
    B, C = arm1.truth.vertebrae[:, -1], arm2.truth.vertebrae[:, -1]
    ropes = [catenary(B[i], C[i], rope_length, source=source) for i in range(samples)]
    return recorded_rope(arm1, arm2, ropes, rope_marker_fractions, end_offset, noise, rng, truth_points)


def recorded_rope(
    arm1: MarkerRecording,
    arm2: MarkerRecording,
    ropes: list[Catenary],
    fractions: tuple[float, ...],
    end_offset: float,
    noise: float,
    rng: np.random.Generator,
    truth_points: int = 200,
) -> RopeChainRecording:
    """The chain of two arm recordings and the rope of each posture as motion capture sees it.

    Parameters
    ----------
    arm1, arm2:
        The arms' recordings in the world frame (``N`` postures).
    ropes:
        The rope of each posture, from arm 1's true tip to arm 2's.
    fractions:
        Intermediate rope markers, fractions of the rope length from arm 1's tip.
    end_offset:
        Arc length [m] from each end of the markers that give the rope's end directions
        (each the unit chord from the arm's measured tip position to that marker).
    noise:
        Standard deviation of each marker coordinate [m].
    rng:
        Draws the noise: the end markers first, then the intermediate ones.
    truth_points:
        Dense points of each rope kept as its truth.
    """
    length = ropes[0].length
    s_markers = length * np.asarray(fractions)
    s_truth = np.linspace(0.0, length, truth_points)
    truth = np.array([rope.points(s_truth) for rope in ropes])
    marker_truth = np.array([rope.points(s_markers) for rope in ropes])
    near = np.array([rope.points(np.array([end_offset, length - end_offset])) for rope in ropes])
    near = near + noise * rng.standard_normal(near.shape)
    start = near[:, 0] - arm1.tip_position
    end = arm2.tip_position - near[:, 1]
    directions = np.stack(
        [start / np.linalg.norm(start, axis=1, keepdims=True), end / np.linalg.norm(end, axis=1, keepdims=True)], axis=1
    )
    markers = marker_truth + noise * rng.standard_normal(marker_truth.shape)
    return RopeChainRecording(arm1, arm2, float(length), markers, directions, truth, marker_truth)


class RopeChainParams(SyntheticMarkerParams):
    """``data.params`` of source ``synthetic`` (family ``rope_chains``): the arms' motion and the rope."""

    rope_length: float = Field(0.65, gt=0, description="rope length [m]")
    base_distance: float = Field(0.25, gt=0, description="distance between the two arm bases [m]")
    end_offset: float = Field(0.02, gt=0, description="rope marker distance from each end, along the rope [m]")
    rope_markers: tuple[float, ...] = Field(
        (0.25, 0.5, 0.75), min_length=1, description="rope markers, as fractions of its length"
    )


@register_source(
    "rope_chains", "synthetic", "two synthetic CBHAs holding a hanging rope (exact catenary)", params=RopeChainParams
)
def synthetic_rope_chain_source(
    arm: ArmModel, data: DataSpec, params: RopeChainParams, path: Path
) -> RopeChainRecording:
    """:func:`synthetic_rope_chain` of ``data.samples`` postures seeded by ``data.seed``."""
    cbha = _cbha(arm, path, "synthetic")
    try:
        return synthetic_rope_chain(
            cbha,
            data.samples,
            np.random.default_rng([data.seed, 0]),
            base_distance=params.base_distance,
            rope_length=params.rope_length,
            rope_marker_fractions=params.rope_markers,
            end_offset=params.end_offset,
            **params.motion(),
            source=f"{Path(path).name}: synthetic",
        )
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
