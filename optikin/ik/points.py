"""Inverse-kinematics targets at measured points along an arm: section ends, markers, tip directions.

A :class:`MeasuredPoint` is a point rigidly attached to the backbone frame at a
fraction of one section's arc length (:meth:`~optikin.arms.base.ArmModel.frame_at`),
at an offset ``o`` in that frame (a marker on a disk, or on a tube at its distance
from the backbone). Its measured components, in the order of :data:`COMPONENTS`:

``position``     ``p(q) + R(q) o`` (3 values, metres): rows ``w (p(q) + R(q) o - p*)``;
``direction``    the frame's z axis (3 values, a unit vector): rows ``w L (R(q) e_z - d*)``,
                 the tip direction without its twist (2 independent rows);
``orientation``  the frame's orientation (a unit quaternion ``(w, x, y, z)``, 4 values):
                 rows ``w 2 L vec(q*^-1 q(q))``, as for a tip pose in :mod:`optikin.problems.ik`.

``w`` is the point's weight (a pure number) and ``L`` the orientation length [m], so
every row is in metres. A :class:`PointSet` stacks the points in order: the target of
one sample is the concatenation of every point's components, ``(D,)`` with
``D = sum_k (3 [position] + 3 [direction] + 4 [orientation])``, and a CSV file names
its columns ``<point>_x, <point>_y, <point>_z``, ``<point>_dx, ...`` and ``<point>_qw, ...``
(:meth:`PointSet.columns`).
"""

from __future__ import annotations

from dataclasses import dataclass
import casadi as ca
import numpy as np

from optikin.algebra import quat_conjugate, quat_multiply, quat_rotate
from optikin.arms.base import ArmModel

COMPONENTS = ("position", "direction", "orientation")
"""What a point may measure, in the order its values are stacked."""
SIZES = {"position": 3, "direction": 3, "orientation": 4}
"""Values per component in a target vector."""
SUFFIXES = {
    "position": ("x", "y", "z"),
    "direction": ("dx", "dy", "dz"),
    "orientation": ("qw", "qx", "qy", "qz"),
}
"""CSV column suffixes per component."""


@dataclass(frozen=True)
class MeasuredPoint:
    """One measured point on the arm (module docstring).

    Attributes
    ----------
    name:
        Its name (CSV column prefix, report labels).
    section:
        Section index from 0 (base section).
    fraction:
        Fraction of that section's arc length, ``(0, 1]`` (1: the section's end).
    offset:
        ``(3,)`` offset from the backbone in the frame there [m].
    components:
        Measured components, a subset of :data:`COMPONENTS` in that order.
    weight:
        Weight of its rows (a pure number, > 0).
    """

    name: str
    section: int
    fraction: float = 1.0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    components: tuple[str, ...] = ("position",)
    weight: float = 1.0

    @property
    def size(self) -> int:
        """Number of target values of this point."""
        return sum(SIZES[c] for c in self.components)

    @property
    def rows(self) -> int:
        """Number of residual rows of this point (3 per component)."""
        return 3 * len(self.components)


@dataclass(frozen=True)
class PointSet:
    """The measured points of one problem, in order (module docstring)."""

    points: tuple[MeasuredPoint, ...]

    def __len__(self) -> int:
        return len(self.points)

    @property
    def size(self) -> int:
        """``D``, the length of one sample's target vector."""
        return sum(p.size for p in self.points)

    @property
    def rows(self) -> int:
        """Number of residual rows."""
        return sum(p.rows for p in self.points)

    def columns(self) -> tuple[str, ...]:
        """The CSV columns of a target vector, in its order: ``<point>_<suffix>``."""
        return tuple(f"{p.name}_{s}" for p in self.points for c in p.components for s in SUFFIXES[c])

    def slices(self) -> list[dict[str, slice]]:
        """Per point, where each of its components lies in a target vector."""
        out, start = [], 0
        for p in self.points:
            where = {}
            for c in p.components:
                where[c] = slice(start, start + SIZES[c])
                start += SIZES[c]
            out.append(where)
        return out

    def check(self, arm: ArmModel) -> None:
        """Raise ValueError naming the point when ``arm`` does not offer its section or fraction."""
        q = ca.SX.sym("q", arm.n_config)
        for p in self.points:
            try:
                arm.frame_at(q, p.section, p.fraction)
            except ValueError as error:
                raise ValueError(f"point {p.name!r}: {error}") from None

    def values(self, arm: ArmModel, q: ca.SX) -> ca.SX:
        """The target vector ``D x 1`` the configuration ``q`` (CasADi ``n x 1``) produces."""
        parts = []
        for p in self.points:
            quat, position = arm.frame_at(q, p.section, p.fraction)
            for c in p.components:
                if c == "position":
                    parts.append(position + quat_rotate(quat, ca.DM(p.offset), check=False))
                elif c == "direction":
                    parts.append(quat_rotate(quat, ca.DM([0.0, 0.0, 1.0]), check=False))
                else:
                    parts.append(quat)
        return ca.vertcat(*parts)

    def forward(self, arm: ArmModel, X: np.ndarray) -> np.ndarray:
        """The target vectors ``(N, D)`` of configurations ``X (N, n)`` (rows that are not finite give NaN)."""
        q = ca.SX.sym("q", arm.n_config)
        function = ca.Function(f"{arm.name}_points", [q], [self.values(arm, q)])
        X = np.atleast_2d(np.asarray(X, dtype=float))
        finite = np.all(np.isfinite(X), axis=1)
        values = np.asarray(function.map(len(X))(np.where(finite[:, None], X, 0.0).T)).T.reshape(len(X), -1)
        values[~finite] = np.nan
        return values

    def residual(self, arm: ArmModel, orientation_length: float) -> ca.Function:
        """``(q, target) -> r`` of the module docstring (``rows`` values, metres)."""
        q, target = ca.SX.sym("q", arm.n_config), ca.SX.sym("points", self.size)
        rows = []
        for p, where in zip(self.points, self.slices()):
            quat, position = arm.frame_at(q, p.section, p.fraction)
            for c in p.components:
                measured = target[where[c]]
                if c == "position":
                    rows.append(p.weight * (position + quat_rotate(quat, ca.DM(p.offset), check=False) - measured))
                elif c == "direction":
                    axis = quat_rotate(quat, ca.DM([0.0, 0.0, 1.0]), check=False)
                    rows.append(p.weight * orientation_length * (axis - measured))
                else:
                    error = quat_multiply(quat_conjugate(measured), quat)
                    rows.append(p.weight * orientation_length * 2.0 * error[1:])
        return ca.Function(f"{arm.name}_ik_points", [q, target], [ca.vertcat(*rows)], ["q", "points"], ["r"])

    def errors(self, arm: ArmModel, X: np.ndarray, targets: np.ndarray) -> dict[str, np.ndarray]:
        """Per sample and point, the unweighted errors of solutions ``X (N, n)`` against ``targets (N, D)``.

        Returns
        -------
        dict
            ``position`` ``(N, k)`` distances [m] (NaN where the point has no position),
            ``angle`` ``(N, k)`` [rad]: the angle between measured and reached directions, or the
            rotation angle between measured and reached orientations (NaN where neither is measured).
        """
        finite = np.all(np.isfinite(X), axis=1)
        reached = self.forward(arm, X)
        position = np.full((len(X), len(self)), np.nan)
        angle = np.full((len(X), len(self)), np.nan)
        for k, where in enumerate(self.slices()):
            if "position" in where:
                s = where["position"]
                position[:, k] = np.linalg.norm(reached[:, s] - targets[:, s], axis=1)
            if "orientation" in where:
                s = where["orientation"]
                relative = quat_multiply(quat_conjugate(targets[:, s]), reached[:, s])
                angle[:, k] = 2.0 * np.arctan2(np.linalg.norm(relative[:, 1:], axis=1), np.abs(relative[:, 0]))
            elif "direction" in where:
                s = where["direction"]
                a, b = reached[:, s], targets[:, s]
                angle[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))
        position[~finite], angle[~finite] = np.nan, np.nan
        return {"position": position, "angle": angle}

    def rms_distance(self, arm: ArmModel, X: np.ndarray, targets: np.ndarray, orientation_length: float) -> np.ndarray:
        """``(N,)`` RMS over the measured components of the unweighted distances [m]: position errors in
        metres, direction and orientation errors as ``L`` times their angle. The quantity the ``noise``
        option of :mod:`optikin.problems.ik` is compared with."""
        e = self.errors(arm, X, targets)
        counts = np.array([[len(p.components) for p in self.points]])
        with_position = np.array([["position" in p.components for p in self.points]])
        squares = np.where(with_position, np.nan_to_num(e["position"]) ** 2, 0.0) + np.where(
            counts > with_position, (orientation_length * np.nan_to_num(e["angle"])) ** 2, 0.0
        )
        total = squares.sum(axis=1) / counts.sum()
        rms = np.sqrt(total)
        rms[~np.all(np.isfinite(X), axis=1)] = np.nan
        return rms
