"""Inverse-kinematics targets: tip positions, tip poses or CBHA leg lengths, with the configurations that made them.

The sources of data family ``targets`` (:mod:`optikin.data.sources`), each with its
params model, are called ``load(arm, data, params, path, kind)`` with ``kind`` the
target kind of :data:`TARGET_KINDS` and return :class:`Targets`:

``random``      forward kinematics of configurations drawn uniformly inside the
                bounds (reachable by construction); ``params.unreachable`` adds
                that many targets placed outside the workspace (:class:`RandomParams`).
``trajectory``  forward kinematics of a smooth configuration motion, every variable a
                sinusoid about its mid-range (:class:`TrajectoryParams`), to be solved
                in order, warm-started.
``csv``         targets read from a file (``params.file``, relative to the problem
                file) with columns ``x, y, z`` in metres, plus ``qw, qx, qy, qz`` for
                poses and optionally ``t`` (:class:`CsvParams`, :func:`read_target_csv`):
                every row, or the first ``data.samples`` when the problem file gives it
                (the rows left out counted in :attr:`Targets.skipped_rows`).

Unreachable targets lie beyond the arm's reach bound (:func:`reach_bound`) by a
factor drawn from ``params.margin`` (default ``[1.1, 1.5]``), in a uniformly random
direction (and, for poses, with a uniformly random orientation).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

import numpy as np
from pydantic import Field, StrictBool, StrictFloat, StrictInt, field_validator

from optikin.algebra import (
    dq_from_rotation_translation,
    dq_rotation,
    dq_translation,
    quat_conjugate,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.checks import UNIT_TOLERANCE, check_quaternion
from optikin.data.configurations import TrajectoryParams, first_rows, smooth_motion
from optikin.data.csvread import UNIT_METRES, columns_of, read_table
from optikin.data.files import data_file
from optikin.data.recording import FrameOptions, convert_body_orientations, convert_vectors, frame_matrix
from optikin.data.sources import register_source
from optikin.errors import SpecError
from optikin.ik.points import PointSet
from optikin.options import Options
from optikin.spec import DataSpec

TargetKind = Literal["position", "pose", "points", "legs"]
TARGET_KINDS: tuple[str, ...] = get_args(TargetKind)
"""Tip position (3), tip pose as a unit dual quaternion (8), measured points (:mod:`optikin.ik.points`),
or the leg lengths of a CBHA (48)."""
FAMILY = "targets"
"""The data family of the ``ik`` kind."""


@dataclass
class Targets:
    """``values`` are ``(N, 3)`` positions, ``(N, 8)`` unit dual quaternions or ``(N, 48)`` CBHA leg lengths.

    For ``points`` targets, ``values`` are ``(N, D)`` stacked point measurements laid out by
    ``points`` (:class:`~optikin.ik.points.PointSet`). ``configurations`` holds the configuration
    each target was made from (NaN rows when unknown), ``reachable`` whether the target is known to
    be reachable (True), known to be outside the workspace (False); ``t`` the sample times of a
    trajectory (else None); ``skipped_rows`` the rows of a file source left out because
    ``data.samples`` asked for fewer.
    """

    kind: str
    values: np.ndarray
    configurations: np.ndarray
    reachable: np.ndarray
    t: np.ndarray | None = None
    trajectory: bool = False
    skipped_rows: int = 0
    points: PointSet | None = None

    def __len__(self) -> int:
        return len(self.values)

    def subset(self, rows: np.ndarray) -> Targets:
        """The targets of ``rows`` only (as independent targets)."""
        return Targets(
            self.kind, self.values[rows], self.configurations[rows], self.reachable[rows], points=self.points
        )

    @property
    def positions(self) -> np.ndarray:
        """Tip positions ``(N, 3)`` [m]; for ``points``, the position of the last point that has one."""
        if self.kind == "points" and self.points is not None:
            where = [w["position"] for w in self.points.slices() if "position" in w]
            return self.values[:, where[-1]] if where else np.full((len(self), 3), np.nan)
        return self.values if self.kind == "position" else dq_translation(self.values)


def reach_bound(arm: ArmModel) -> float:
    """An upper bound of the distance base-tip.

    Constant-curvature arm: a section's chord is at most its arc length, so the tip lies
    within ``sum S_max``. Other arms: twice the largest distance over 20,000 random
    configurations (an estimate, not a proof).
    """
    if isinstance(arm, ConstantCurvatureArm):
        return float(arm.section_lengths.sum() * arm.length_range[1])
    Q = arm.sample_configurations(20_000, np.random.default_rng(0))
    return 2.0 * float(np.linalg.norm(arm.evaluate("fk_position", Q), axis=1).max())


def forward_targets(arm: ArmModel, Q: np.ndarray, kind: str, points: PointSet | None = None) -> np.ndarray:
    """Tip positions ``(N, 3)``, tip dual quaternions ``(N, 8)``, measured points ``(N, D)`` or leg lengths
    of configurations ``Q``."""
    if kind == "points":
        if points is None:
            raise ValueError("points targets need their PointSet")
        return points.forward(arm, Q)
    if kind == "legs":
        return arm.evaluate("leg_lengths", Q).reshape(len(Q), -1)
    return arm.evaluate("fk_position" if kind == "position" else "fk_dq", Q)


def with_position_noise(
    values: np.ndarray, kind: str, points: PointSet | None, sigma: float, rng: np.random.Generator
) -> np.ndarray:
    """``values`` with Gaussian noise of standard deviation ``sigma`` [m] on every position coordinate
    (the tip position, a pose's translation, or each point's position); orientations untouched."""
    if kind == "position":
        return values + rng.normal(0.0, sigma, values.shape)
    if kind == "pose":
        position = dq_translation(values) + rng.normal(0.0, sigma, (len(values), 3))
        return dq_from_rotation_translation(dq_rotation(values), position, check=False)
    assert points is not None
    out = values.copy()
    for where in points.slices():
        if "position" in where:
            s = where["position"]
            out[:, s] += rng.normal(0.0, sigma, out[:, s].shape)
    return out


def unreachable_targets(
    arm: ArmModel, count: int, kind: str, rng: np.random.Generator, margin: tuple[float, float]
) -> np.ndarray:
    """``count`` targets farther from the base than :func:`reach_bound` times a factor in ``margin``."""
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    position = direction * reach_bound(arm) * rng.uniform(*margin, size=(count, 1))
    if kind == "position":
        return position
    orientation = quat_normalize(rng.normal(size=(count, 4)), check=False)
    orientation *= np.where(orientation[:, :1] < 0, -1.0, 1.0)
    return dq_from_rotation_translation(orientation, position, check=False)


class RandomParams(Options):
    """``data.params`` of source ``random``."""

    unreachable: StrictInt = Field(0, ge=0, description="targets added outside the workspace (count)")
    noise: StrictFloat = Field(
        0.0,
        ge=0.0,
        description="standard deviation of Gaussian noise added to every measured position coordinate [m] "
        "(position, pose and points targets; seeded by data.seed)",
    )
    margin: tuple[StrictFloat, StrictFloat] = Field(
        (1.1, 1.5),
        description="[low, high]: an unreachable target's distance from the base, as a factor of the "
        "reach bound (1 < low <= high)",
    )

    @field_validator("margin")
    @classmethod
    def _beyond_reach(cls, margin: tuple[float, float]) -> tuple[float, float]:
        if not 1.0 < margin[0] <= margin[1]:
            raise ValueError(f"expected [low, high] with 1 < low <= high, got {list(margin)}")
        return margin


class BasePose(Options):
    """Where the arm's base frame lies in the file's frame (after the unit conversion)."""

    position: tuple[StrictFloat, StrictFloat, StrictFloat] = Field(
        (0.0, 0.0, 0.0), description="origin of the base frame in the file's frame [m]"
    )
    quaternion: tuple[StrictFloat, StrictFloat, StrictFloat, StrictFloat] = Field(
        (1.0, 0.0, 0.0, 0.0), description="orientation of the base frame in the file's frame, unit (w, x, y, z)"
    )

    @field_validator("quaternion")
    @classmethod
    def _unit(cls, q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        check_quaternion(q, name="quaternion")
        return q


UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
"""Length units a target file may be written in, as metres."""


class CsvParams(Options):
    """``data.params`` of source ``csv``."""

    file: str = Field(min_length=1, description="CSV file with a header row, relative to the problem file")
    trajectory: StrictBool = Field(
        False, description="solve the rows in order, each warm-started from the previous solution"
    )
    units: Literal["m", "cm", "mm"] = Field("m", description="length unit of the file's positions")
    frame: FrameOptions = Field(
        default_factory=FrameOptions,
        description="axes of the file's frame (frame: {up: y} for a y-up recording), converted to optikin's z-up "
        "frame as a recording's (optikin.data.recording)",
    )
    base: BasePose | None = Field(
        None,
        description="the arm's base pose in the file's frame after the frame conversion (e.g. from a calibration "
        "of the same recording); null: the file is in the base frame",
    )


@register_source(
    FAMILY,
    "random",
    "forward kinematics of uniform random configurations, optionally with targets outside the workspace",
    params=RandomParams,
)
def random_targets(
    arm: ArmModel,
    data: DataSpec,
    params: RandomParams,
    path: Path,
    kind: str = "position",
    points: PointSet | None = None,
) -> Targets:
    """Forward kinematics of ``data.samples`` uniform random configurations, plus ``params.unreachable``
    targets outside the workspace (module docstring); every draw from ``data.seed``."""
    extra = params.unreachable
    rng = np.random.default_rng(data.seed)
    Q = arm.sample_configurations(data.samples, rng)
    values = forward_targets(arm, Q, kind, points)
    reachable = np.ones(len(Q), dtype=bool)
    if extra and kind in ("legs", "points"):
        raise SpecError(str(path), "data.params.unreachable", f"{kind} targets have no unreachable variant")
    if params.noise and kind == "legs":
        raise SpecError(str(path), "data.params.noise", "leg-length targets take no position noise")
    if params.noise:
        values = with_position_noise(values, kind, points, params.noise, np.random.default_rng([data.seed, 1]))
    if extra:
        values = np.concatenate([values, unreachable_targets(arm, extra, kind, rng, params.margin)])
        Q = np.concatenate([Q, np.full((extra, arm.n_config), np.nan)])
        reachable = np.concatenate([reachable, np.zeros(extra, dtype=bool)])
    return Targets(kind, values, Q, reachable, points=points)


@register_source(
    FAMILY,
    "trajectory",
    "forward kinematics of a smooth configuration motion, solved in order",
    params=TrajectoryParams,
)
def trajectory_targets(
    arm: ArmModel,
    data: DataSpec,
    params: TrajectoryParams,
    path: Path,
    kind: str = "position",
    points: PointSet | None = None,
) -> Targets:
    """Forward kinematics of :func:`smooth_motion`, flagged as a trajectory (warm-started solves)."""
    Q, t = smooth_motion(arm, data.samples, data.seed, params)
    values = forward_targets(arm, Q, kind, points)
    return Targets(kind, values, Q, np.ones(len(Q), dtype=bool), t=t, trajectory=True, points=points)


@register_source(FAMILY, "csv", "targets read from a CSV file (x, y, z [, qw, qx, qy, qz] [, t])", params=CsvParams)
def csv_targets(
    arm: ArmModel, data: DataSpec, params: CsvParams, path: Path, kind: str = "position", points: PointSet | None = None
) -> Targets:
    """Targets from a CSV file with a header row (module docstring): every row, or the first ``data.samples``
    when the problem file gives it, converted to metres and to the base frame (``params.units``,
    ``params.base``); reachability unknown (treated as reachable)."""
    if kind == "legs":
        raise SpecError(str(path), "data.source", "leg-length targets cannot be read from a CSV file")
    values, t = read_target_csv(data_file(path, params.file), kind, points, UNITS[params.units])
    try:
        values = from_file_frame(values, kind, points, params.frame)
    except ValueError as exc:
        raise SpecError(str(path), "data.params.frame", str(exc)) from None
    if params.base is not None:
        values = to_base_frame(values, kind, points, params.base)
    keep, skipped = first_rows(data, len(values))
    values, t = values[:keep], (None if t is None else t[:keep])
    configurations = np.full((len(values), arm.n_config), np.nan)
    return Targets(
        kind,
        values,
        configurations,
        np.ones(len(values), dtype=bool),
        t=t,
        trajectory=params.trajectory,
        skipped_rows=skipped,
        points=points,
    )


def from_file_frame(values: np.ndarray, kind: str, points: PointSet | None, frame: FrameOptions) -> np.ndarray:
    """Targets in a file's axes (``frame``) expressed in optikin's z-up axes, as a recording is
    (:func:`optikin.data.recording.frame_matrix`): positions and directions ``A v``, orientations ``A R A^T``."""
    matrix = frame_matrix(frame)
    if np.array_equal(matrix, np.eye(3)):
        return values
    if kind == "position":
        return convert_vectors(values, matrix)
    if kind == "pose":
        rotation = convert_body_orientations(dq_rotation(values), matrix)
        return dq_from_rotation_translation(rotation, convert_vectors(dq_translation(values), matrix), check=False)
    assert points is not None
    out = values.copy()
    for where in points.slices():
        for component, s in where.items():
            convert = convert_body_orientations if component == "orientation" else convert_vectors
            out[:, s] = convert(values[:, s], matrix)
    return out


def to_base_frame(values: np.ndarray, kind: str, points: PointSet | None, base: BasePose) -> np.ndarray:
    """Targets given in a file's frame, expressed in the arm's base frame.

    With the base at position ``t`` and orientation ``q_b`` in the file's frame, a position
    ``p`` becomes ``q_b^-1 (p - t)``, a direction ``d`` becomes ``q_b^-1 d`` and an orientation
    ``q`` becomes ``q_b^-1 q``.
    """
    qb = np.asarray(base.quaternion, dtype=float) / np.linalg.norm(base.quaternion)
    inverse = quat_conjugate(qb)
    t = np.asarray(base.position, dtype=float)
    out = values.copy()
    if kind == "position":
        return quat_rotate(inverse, values - t, check=False)
    if kind == "pose":
        rotation = quat_multiply(inverse, dq_rotation(values))
        translation = quat_rotate(inverse, dq_translation(values) - t, check=False)
        return dq_from_rotation_translation(rotation, translation, check=False)
    assert points is not None
    for where in points.slices():
        for component, s in where.items():
            if component == "position":
                out[:, s] = quat_rotate(inverse, values[:, s] - t, check=False)
            elif component == "direction":
                out[:, s] = quat_rotate(inverse, values[:, s], check=False)
            else:
                out[:, s] = quat_multiply(inverse, values[:, s])
    return out


QUATERNION_TOLERANCE = UNIT_TOLERANCE
"""| |q| - 1 | accepted for a pose target read from a file (:data:`optikin.checks.UNIT_TOLERANCE`)."""


def read_target_csv(
    csv_path: Path, kind: str, points: PointSet | None = None, scale: float = 1.0
) -> tuple[np.ndarray, np.ndarray | None]:
    """Position, pose or measured-point targets from a CSV file with a header row.

    The format (:mod:`optikin.data.csvread` for what every reader refuses); every cell
    read must be a finite number:

    ======================  ================================================================
    ``x, y, z``             tip position in the arm's base frame, metres
    ``qw, qx, qy, qz``      poses only: tip orientation, a unit quaternion ``(w, x, y, z)``
                            (norm within :data:`QUATERNION_TOLERANCE` of 1)
    ``t``                   optional: time in seconds, strictly increasing
    ``<point>_x, ...``      ``points`` only: the columns of :meth:`~optikin.ik.points.PointSet.columns`
                            (positions, unit directions ``_dx, _dy, _dz``, unit quaternions
                            ``_qw, _qx, _qy, _qz``)
    other columns           ignored
    ======================  ================================================================

    Parameters
    ----------
    csv_path:
        The file.
    kind:
        ``position``, ``pose`` or ``points``.
    points:
        The measured points (``points`` targets only).
    scale:
        Metres per unit of the file's positions.

    Returns
    -------
    values, t:
        Positions ``(rows, 3)`` [m] or unit dual quaternions ``(rows, 8)``, and the ``t``
        column ``(rows,)`` [s] or None without one.

    Raises
    ------
    InputDataError
        Naming the file, the row (``sample`` from 0, and its line) and the column: the file
        cannot be read or is refused (not a regular file, over 200 MiB, binary, not UTF-8),
        is empty, lacks a column, has no data rows, a short row or a cell that is not a
        finite number (``nan``, ``inf``); ``t`` does not increase strictly; a quaternion's
        norm is not 1 to within :data:`QUATERNION_TOLERANCE`; a position is beyond
        :data:`~optikin.data.csvread.MAX_COORDINATE` (with a unit hint).
    """
    if kind == "points":
        if points is None:
            raise ValueError("points targets need their PointSet")
        names = points.columns()
    else:
        names = ("x", "y", "z") if kind == "position" else ("x", "y", "z", "qw", "qx", "qy", "qz")
    table = read_table(csv_path, columns_of(str(csv_path), names, optional=("t",), finite=(*names, "t")))
    t = None
    if "t" in table.columns:
        table.check_increasing("t")
        t = table.column("t")
    unit = next((u for u, f in UNIT_METRES.items() if f == scale), "m")
    if kind == "points":
        assert points is not None
        values = table.stacked(names)
        for where in points.slices():
            for component, s in where.items():
                if component == "position":
                    table.check_coordinates(names[s], scale, unit, "data.params.units")
                    values[:, s] *= scale
                else:  # unit directions and quaternions: the norm check
                    values[:, s] = table.check_unit_quaternions(names[s], QUATERNION_TOLERANCE)
        return values, t
    table.check_coordinates(("x", "y", "z"), scale, unit, "data.params.units")
    position = table.stacked(("x", "y", "z")) * scale
    if kind == "position":
        return position, t
    quaternion = table.check_unit_quaternions(("qw", "qx", "qy", "qz"), QUATERNION_TOLERANCE)
    return dq_from_rotation_translation(quaternion, position, check=False), t
