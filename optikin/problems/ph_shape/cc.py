"""Baseline ``cc-arc`` of ``ph_shape``: every backbone as one constant-curvature arc.

The constant-curvature arm's inverse kinematics of the tip position (Webster & Jones,
Int. J. Robot. Res. 29(13), pp. 1661-1683, 2010): the circular arc that leaves the
measured base point ``p0`` along the measured base tangent ``t0`` and passes through the
measured tip point ``p1`` (:func:`optikin.physics.comparison.cc_arc_points`). With the
chord ``c = p1 - p0``, ``alpha`` the angle between ``t0`` and ``c`` and ``n`` the unit part of
``c`` normal to ``t0``, the arc has curvature ``kappa = 2 sin(alpha) / |c|``, turns by
``theta = 2 alpha`` and is ``S = alpha |c| / sin(alpha)`` long; its point at arc length
``sigma`` is::

    r(sigma) = p0 + sin(kappa sigma) / kappa t0 + (1 - cos(kappa sigma)) / kappa n.

It gets the same end poses as the PH methods (base averaged with ``fixed_base``), and
uses of them only ``p0``, ``t0`` and ``p1``: a single-section arc is fixed by these three, so
neither the tip tangent nor the backbone length ``L`` of the PH methods enters it. Both
show how far the recording is from constant curvature, and are reported: the angle
between the arc's tip tangent ``cos(theta) t0 + sin(theta) n`` and the measured one, and
``|S - L|``. One arc per posture, whatever the arm's number of sections.

Baseline ``cc-two-arcs``: the piecewise constant-curvature backbone of the CBHA's two
sections (Webster & Jones section 3), for a recording with a marker at the end of
section 1 (vertebra 9 of the vertebra model, :data:`~optikin.problems.ph_shape.c1.JOINT_VERTEBRA`):
section 1 is the arc of ``(p0, t0)`` through that marker ``pm``, and section 2 the arc of
``(pm, t_m)`` through ``p1``, with ``t_m = cos(theta_1) t0 + sin(theta_1) n_1`` the first arc's end
tangent (the two are joined with C1 continuity). It uses one marker more than the PH methods,
so that marker is its own and left out of its marker distance (``mean marker distance off the
joint``); its truth-backbone distance compares like with like.

Its distances are those of the PH rows: the distance of each point to the whole curve,
here in closed form (:meth:`CCRun.distances`), not to a sampled polyline. The time per
sample is that of :func:`~optikin.physics.comparison.cc_arc_points` for the sampled backbone
(``CURVE_POINTS`` points per arc, both arcs for ``cc-two-arcs``), the reconstruction itself.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from optikin.data.markers import MarkerRecording
from optikin.errors import InputDataError
from optikin.physics.comparison import cc_arc_points
from optikin.problems.ph_shape.c1 import JOINT_VERTEBRA

NAME = "cc-arc"
"""The single-arc baseline's name in ``baselines``."""
TWO_ARCS = "cc-two-arcs"
"""The two-section baseline's name in ``baselines``."""
CURVE_POINTS = 101
"""Points of each sampled arc, at equal fractions of its arc length."""
STRAIGHT = 1e-15
"""The arc is the straight segment when the chord's part normal to ``t0`` is below this fraction of the chord
(the test of :func:`~optikin.physics.comparison.cc_arc_points`)."""


@dataclass
class CCRun:
    """The constant-curvature arcs of every posture.

    Attributes
    ----------
    base, tangent, normal, tip:
        ``p0``, ``t0``, ``n`` and ``p1`` of each arc ``(N, 3)`` (``n`` zero on a straight arc).
    curvature:
        ``kappa`` ``(N,)`` [1/m] (zero on a straight arc).
    angle:
        Turning angle ``theta = 2 alpha`` ``(N,)`` [rad].
    arc_length:
        ``S`` ``(N,)`` [m].
    points:
        Each arc at ``CURVE_POINTS`` equal fractions of its arc length ``(N, CURVE_POINTS, 3)`` [m].
    seconds:
        Time to sample each arc ``(N,)`` [s].
    """

    base: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    tip: np.ndarray
    curvature: np.ndarray
    angle: np.ndarray
    arc_length: np.ndarray
    points: np.ndarray
    seconds: np.ndarray

    @property
    def tip_tangent(self) -> np.ndarray:
        """Unit tangent at each arc's end, ``cos(theta) t0 + sin(theta) n`` ``(N, 3)``."""
        return np.cos(self.angle)[:, None] * self.tangent + np.sin(self.angle)[:, None] * self.normal

    def distances(self, points: np.ndarray) -> np.ndarray:
        """Distance of each point ``(N, K, 3)`` to arc ``n``: ``(N, K)`` [m], in closed form.

        A point ``q = p0 + a t0 + b n + z (t0 x n)`` is at squared distance
        ``z^2 + rho^2 + R^2 - 2 rho R cos(phi - phi_q)`` from the arc's point at turning angle ``phi``
        (``R = 1 / kappa``, the centre ``p0 + R n``, ``rho`` and ``phi_q`` the polar coordinates of ``q``
        about it in the arc's plane, ``phi_q = atan2(kappa a, 1 - kappa b)`` in ``[0, 2 pi)``). The least,
        over ``phi`` in ``[0, theta]``, is ``sqrt(z^2 + (rho - R)^2)`` when ``phi_q <= theta``, else at the
        nearer end. ``rho - R = (kappa (a^2 + b^2) - 2 b) / (kappa rho + 1)`` keeps its precision on an
        arc of large radius. A straight arc is the
        segment from ``p0`` to ``p0 + S t0``; the ends are ``p0`` and ``p1``.
        """
        p0, t0, n = self.base[:, None], self.tangent[:, None], self.normal[:, None]  # (N, 1, 3)
        kappa = self.curvature[:, None]  # (N, 1)
        d = points - p0
        a, b, z = (np.sum(d * e, axis=-1) for e in (t0, n, np.cross(t0, n)))
        u, v = kappa * a, 1.0 - kappa * b
        phi = np.mod(np.arctan2(u, v), 2.0 * np.pi)
        radial = (kappa * (a * a + b * b) - 2.0 * b) / (np.hypot(u, v) + 1.0)  # rho - R, times 1
        ends = np.minimum(np.linalg.norm(d, axis=-1), np.linalg.norm(points - self.tip[:, None], axis=-1))
        on_arc = np.where(phi <= self.angle[:, None], np.hypot(z, radial), ends)
        along = np.clip(a, 0.0, self.arc_length[:, None])
        segment = np.linalg.norm(d - along[..., None] * t0, axis=-1)
        return np.where((self.curvature <= 0.0)[:, None], segment, on_arc)


def cc_arcs(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray) -> CCRun:
    """The arc from ``p0`` tangent to ``t0`` through ``p1`` of each posture (module docstring).

    Parameters
    ----------
    p0, t0, p1:
        Start points [m], unit start tangents and end points [m], each ``(N, 3)``.
    """
    chord = p1 - p0
    c = np.linalg.norm(chord, axis=1)
    along = np.sum(chord * t0, axis=1)
    normal = chord - along[:, None] * t0
    h = np.linalg.norm(normal, axis=1)
    alpha = np.arctan2(h, along)
    straight = h <= STRAIGHT * c
    normal -= np.sum(normal * t0, axis=1)[:, None] * t0  # again: |t0| = 1 to rounding leaves along (1 - |t0|^2) t0
    n = np.where(straight[:, None], 0.0, normal / np.where(straight, 1.0, np.linalg.norm(normal, axis=1))[:, None])
    curvature = np.where(straight, 0.0, 2.0 * np.sin(alpha) / c)
    fractions = np.linspace(0.0, 1.0, CURVE_POINTS)
    points, lengths, seconds = [], [], []
    for i in range(len(p0)):
        tic = time.perf_counter()
        arc, S = cc_arc_points(p0[i], t0[i], p1[i], fractions)
        seconds.append(time.perf_counter() - tic)
        points.append(arc)
        lengths.append(S)
    angle = np.where(straight, 0.0, 2.0 * alpha)
    return CCRun(p0, t0, n, p1, curvature, angle, np.array(lengths), np.stack(points), np.array(seconds))


def run_cc(recording: MarkerRecording) -> CCRun:
    """Baseline ``cc-arc``: the arc of the base pose through the tip point of each posture of ``recording``.

    Parameters
    ----------
    recording:
        End poses (base already averaged when the kind's ``fixed_base`` is set).
    """
    return cc_arcs(recording.base_position, recording.base_direction, recording.tip_position)


@dataclass
class TwoArcs:
    """The two-section arcs of every posture (baseline ``cc-two-arcs``, module docstring).

    Attributes
    ----------
    sections:
        Section 1's arcs, then section 2's.
    joint_marker:
        Index of the intermediate marker at the end of section 1 (the joint).
    """

    sections: tuple[CCRun, CCRun]
    joint_marker: int

    @property
    def seconds(self) -> np.ndarray:
        """Time to sample both arcs of each posture ``(N,)`` [s]."""
        return self.sections[0].seconds + self.sections[1].seconds

    @property
    def points(self) -> np.ndarray:
        """Both arcs, the joint once: ``(N, 2 CURVE_POINTS - 1, 3)`` [m]."""
        return np.concatenate([self.sections[0].points, self.sections[1].points[:, 1:]], axis=1)

    def distances(self, points: np.ndarray) -> np.ndarray:
        """Distance of each point ``(N, K, 3)`` to the nearer arc of its posture: ``(N, K)`` [m]."""
        return np.minimum(self.sections[0].distances(points), self.sections[1].distances(points))


def run_two_arcs(recording: MarkerRecording, source: str) -> TwoArcs:
    """Baseline ``cc-two-arcs`` on every posture of ``recording`` (module docstring).

    Parameters
    ----------
    recording:
        End poses and intermediate markers whose ``marker_vertebrae`` hold the end of section 1.
    source:
        Names the data in errors.

    Raises
    ------
    InputDataError
        No marker is known to sit at the end of section 1.
    """
    if JOINT_VERTEBRA not in recording.marker_vertebrae:
        raise InputDataError(
            f"baseline {TWO_ARCS} needs a marker at the end of section 1 (vertebra {JOINT_VERTEBRA}); the "
            f"markers' vertebrae: {recording.marker_vertebrae or 'unknown (data.params.intermediate)'}",
            source=source,
            field="baselines",
        )
    k = recording.marker_vertebrae.index(JOINT_VERTEBRA)
    joint = recording.markers[:, k]
    first = cc_arcs(recording.base_position, recording.base_direction, joint)
    second = cc_arcs(joint, first.tip_tangent, recording.tip_position)
    return TwoArcs((first, second), k)
