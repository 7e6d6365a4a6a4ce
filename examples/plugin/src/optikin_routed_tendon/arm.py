"""A multi-section tendon arm whose configuration is the length change of three tendons per section.

Each section ``i`` of nominal length ``L_i`` holds three tendons at radius ``r_i`` from the backbone,
at angles ``alpha_ij = offset_i + 2 pi j / 3`` around it. A constant-curvature section of arc
length ``S`` bent by ``theta`` towards ``phi`` changes tendon ``j``'s length by
``d_j = (S - L) - r theta cos(alpha_j - phi)``, so the tendons' length changes ``d`` give

* the extension ``S - L = mean(d)``,
* the bending vector ``u = theta (cos phi, sin phi) = -(2 / (3 r)) sum_j d_j (cos alpha_j, sin alpha_j)``,

(Webster and Jones, "Design and kinematic modeling of constant curvature continuum robots: a review",
IJRR 29(13) 2010, section 3.2, for three tendons at equal spacing). The section's end pose is written
in ``u`` itself, not in ``(theta, phi)``, so that it is smooth through the straight section:
rotation vector ``(-u_y, u_x, 0)``, position ``S ((1 - cos t) / t^2 u_x, (1 - cos t) / t^2 u_y, sin t / t)``
with ``t = |u|``, the ratios by their Taylor series near ``t = 0``.
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

from optikin.arms.base import ArmModel

__all__ = ["RoutedTendonArm"]

SERIES_BELOW = 1e-4
"""``theta^2`` below which the ratios are taken from their Taylor series (error below 1e-14)."""


def _ratios(t2: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """``cos(t/2)``, ``sin(t/2)/t``, ``(1 - cos t)/t^2`` and ``sin t / t`` of ``t = sqrt(t2)``."""
    t = ca.sqrt(t2)
    exact = (ca.cos(t / 2), ca.sin(t / 2) / t, (1 - ca.cos(t)) / t2, ca.sin(t) / t)
    series = (
        1 - t2 / 8 + t2**2 / 384,
        0.5 - t2 / 48 + t2**2 / 3840,
        0.5 - t2 / 24 + t2**2 / 720,
        1 - t2 / 6 + t2**2 / 120,
    )
    near = t2 < SERIES_BELOW
    return tuple(ca.if_else(near, s, e) for s, e in zip(series, exact))  # type: ignore[return-value]


def _quat_multiply(p: ca.SX, q: ca.SX) -> ca.SX:
    pw, pv, qw, qv = p[0], p[1:4], q[0], q[1:4]
    return ca.vertcat(pw * qw - ca.dot(pv, qv), pw * qv + qw * pv + ca.cross(pv, qv))


def _rotate(q: ca.SX, v: ca.SX) -> ca.SX:
    w, u = q[0], q[1:4]
    return v + 2 * ca.cross(u, ca.cross(u, v) + w * v)


class RoutedTendonArm(ArmModel):
    """Sections bent by three tendons each, ``q = (d_11, d_12, d_13, ..., d_m3)`` tendon length changes [m].

    Parameters
    ----------
    section_lengths : sequence of float
        Nominal length ``L_i`` of each section [m].
    routing_radius : sequence of float
        Distance ``r_i`` of the tendons from the backbone in each section [m].
    routing_offset : sequence of float
        Angle ``offset_i`` of the first tendon of each section around the backbone [rad].
    max_change : float
        Bound on every tendon's length change ``|d_ij|`` [m].
    name : str
        Identifier in Function names and reports.
    """

    def __init__(
        self,
        section_lengths: Sequence[float] = (0.15, 0.15),
        routing_radius: Sequence[float] = (0.01, 0.008),
        routing_offset: Sequence[float] = (0.0, np.pi / 3),
        max_change: float = 0.01,
        name: str = "routed_tendon",
    ) -> None:
        self.section_lengths = np.asarray(section_lengths, dtype=float)
        self.routing_radius = np.asarray(routing_radius, dtype=float)
        self.routing_offset = np.asarray(routing_offset, dtype=float)
        m = len(self.section_lengths)
        if self.routing_radius.shape != (m,) or self.routing_offset.shape != (m,):
            raise ValueError(f"routing_radius and routing_offset need one value per section ({m})")
        if not (np.all(self.section_lengths > 0) and np.all(self.routing_radius > 0) and max_change > 0):
            raise ValueError("section_lengths, routing_radius and max_change must be positive")
        names = tuple(f"d{i + 1}{j + 1}" for i in range(m) for j in range(3))
        bound = np.full(3 * m, float(max_change))
        super().__init__(name, names, -bound, bound)
        self.max_change = float(max_change)

    @property
    def n_sections(self) -> int:
        """Number of sections ``m``."""
        return len(self.section_lengths)

    def section_state(self, q: ca.SX, section: int) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Arc length ``S`` [m] and bending vector ``(u_x, u_y)`` [rad] of ``section`` (module docstring)."""
        d = [q[3 * section + j] for j in range(3)]
        angles = self.routing_offset[section] + 2 * np.pi * np.arange(3) / 3
        scale = -2.0 / (3.0 * self.routing_radius[section])
        ux = scale * sum(dj * np.cos(a) for dj, a in zip(d, angles))
        uy = scale * sum(dj * np.sin(a) for dj, a in zip(d, angles))
        return self.section_lengths[section] + sum(d) / 3, ux, uy

    def _local(self, S: ca.SX, ux: ca.SX, uy: ca.SX, f: float) -> tuple[ca.SX, ca.SX]:
        """Pose ``(quaternion, position)`` at fraction ``f`` of a section's arc, in the section's base frame."""
        half_cos, half_sin, bend, straight = _ratios((f * ux) ** 2 + (f * uy) ** 2)
        quat = ca.vertcat(half_cos, -half_sin * f * uy, half_sin * f * ux, 0)
        return quat, f * S * ca.vertcat(bend * f * ux, bend * f * uy, straight)

    def _chain(self, q: ca.SX, fractions: Sequence[float]) -> tuple[list[tuple[ca.SX, ca.SX]], list[ca.SX]]:
        """Section end frames, and the points at ``fractions`` of every section."""
        quat, pos = ca.SX([1, 0, 0, 0]), ca.SX.zeros(3)
        frames, points = [], []
        for i in range(self.n_sections):
            S, ux, uy = self.section_state(q, i)
            points += [pos + _rotate(quat, self._local(S, ux, uy, f)[1]) for f in fractions]
            relative, end = self._local(S, ux, uy, 1.0)
            pos = pos + _rotate(quat, end)
            quat = _quat_multiply(quat, relative)
            frames.append((quat, pos))
        return frames, points

    def section_frames(self, q: Any) -> list[tuple[Any, Any]]:
        """End pose ``(quaternion (w, x, y, z), position [m])`` of every section in the base frame.

        Parameters
        ----------
        q : casadi.SX
            Tendon length changes ``3m x 1`` [m].
        """
        return self._chain(q, ())[0]

    def backbone_points(self, q: ca.SX, points_per_section: int) -> ca.SX:
        """``3 x (1 + m points_per_section)`` points [m] at equal arc-length fractions, base point first."""
        fractions = list(np.linspace(0.0, 1.0, points_per_section + 1)[1:])
        points = self._chain(q, fractions)[1]
        return ca.horzcat(ca.DM.zeros(3), *points)

    def straight_configuration(self) -> np.ndarray:
        """Every tendon at its nominal length: the sections straight, the tip at ``(0, 0, sum L_i)``."""
        return np.zeros(self.n_config)

    def describe(self) -> dict[str, Any]:
        """:meth:`ArmModel.describe` plus the geometry."""
        return {
            **super().describe(),
            "kind": "routed_tendon",
            "section_lengths": self.section_lengths.tolist(),
            "routing_radius": self.routing_radius.tolist(),
            "routing_offset": self.routing_offset.tolist(),
            "max_change": self.max_change,
        }
