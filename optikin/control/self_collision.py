"""Two arms in one frame: their backbone samples, the distances between the two tubes, and the barrier rows.

Placement. Arm ``k`` stands at base position ``b_k`` with rotation ``R_k`` (from a unit
quaternion) in the shared frame: a point ``p`` of its own base frame is ``b_k + R_k p`` there,
and its Jacobian ``R_k dp/dq_k``.

Tubes and their distance. Each arm is a tube of radius ``r_k`` around its backbone, sampled at
``points_per_section`` equal arc-length steps per section
(:meth:`optikin.arms.base.ArmModel.backbone_points`), spacing ``h_k <= S_max,k / points_per_section``.
For samples ``i`` of arm 1 and ``j`` of arm 2 the clearance is

    d_ij = |p_i(q_1) - p_j(q_2)| - r_1 - r_2,   d d_ij / d(q_1, q_2) = (n' R_1 J_i, -n' R_2 J_j),

``n = (p_i - p_j) / |p_i - p_j|``, with the sample Jacobians ``J_i = d p_i / d q`` from CasADi
(one Function per arm: the samples and the Jacobian of all of them). Between samples: every
backbone point lies within arc length, so within distance, ``h_k / 2`` of a sample of its arm,
and the Euclidean distance is 1-Lipschitz in both points, so the two tubes keep at least
``min d_ij - (h_1 + h_2)/2`` apart. With every sampled pair held at ``d_ij >= margin`` and
``h_k <= margin / 2`` (the default density ``ceil(2 S_max / margin)`` per section) the tubes
never come closer than ``margin / 2``: no penetration anywhere along the continuous arms.

Barrier rows. The discrete-time control barrier function condition (Agrawal & Sreenath 2017)
on ``h = d_ij - margin``, linearised over one step as in :mod:`optikin.control.obstacles`, is the row

    (d d_ij / d q) qdot >= -gamma (d_ij - margin).

Which pairs enter the QP: for every sample of arm 1 its nearest sample of arm 2, and of those
the ``pairs`` nearest (a fixed row count; the rows spread along arm 1 instead of piling up at
one contact). Every pair of samples is checked along the run (:meth:`TwoTubes.clearances`), so a
pair left out that came too close would show.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from optikin.algebra import matrix_from_quat
from optikin.arms.base import ArmModel
from optikin.control.obstacles import max_section_length
from optikin.fastcall import BufferedFunction


def rotation_from_quaternion(quaternion) -> np.ndarray:
    """The rotation matrix ``(3, 3)`` of a quaternion ``(w, x, y, z)``, normalised here
    (:func:`optikin.algebra.matrix_from_quat`)."""
    q = np.asarray(quaternion, dtype=float)
    return matrix_from_quat(q / np.linalg.norm(q), check=False)


def collision_density(arm: ArmModel, margin: float) -> int:
    """Points per section whose spacing is at most ``margin / 2``: ``ceil(2 S_max / margin)`` (module docstring)."""
    return max(1, int(np.ceil(2.0 * max_section_length(arm) / margin - 1e-9)))


@dataclass
class PlacedArm:
    """One arm in the shared frame, with its tube radius and backbone sampling.

    Parameters
    ----------
    arm:
        The arm model.
    base:
        Base position in the shared frame ``(3,)`` [m].
    rotation:
        Base rotation ``(3, 3)`` (the base frame's axes as columns).
    radius:
        Tube radius around the backbone [m].
    points_per_section:
        Backbone samples per section.
    compiled:
        Compile the Function with a C compiler.

    Attributes
    ----------
    samples:
        ``K = 1 + sections points_per_section``.
    spacing:
        Upper bound of the arc length between consecutive samples [m].
    P, J, tip, tip_jacobian, squared:
        After :meth:`evaluate`: samples ``(K, 3)``, their Jacobian ``(K, 3, n)``, the tip ``(3,)`` and its
        Jacobian ``(3, n)``, all in the shared frame, and ``|p_j|^2`` ``(K,)`` (views, valid until the next call).
    """

    arm: ArmModel
    base: np.ndarray
    rotation: np.ndarray
    radius: float
    points_per_section: int
    compiled: bool = False
    function: ca.Function = field(init=False)

    def __post_init__(self):
        n = self.arm.n_config
        self.base = np.asarray(self.base, dtype=float)
        self.rotation = np.asarray(self.rotation, dtype=float)
        q = ca.SX.sym("q", n)
        R, b = ca.DM(self.rotation), ca.DM(self.base)
        local = self.arm.backbone_points(q, self.points_per_section)
        points = R @ local + ca.repmat(b, 1, local.shape[1])
        tip = R @ self.arm.fk_position(q) + b
        self.samples = K = int(points.shape[1])
        self.spacing = max_section_length(self.arm) / self.points_per_section
        # Transposed Jacobians, so the column-major buffers read as row-major (K 3, n) and (3, n) without copies.
        self.function = ca.Function(
            "placed_arm",
            [q],
            [points, ca.jacobian(ca.vec(points), q).T, tip, ca.jacobian(tip, q).T, ca.sum1(points * points)],
            ["q"],
            ["P", "J", "tip", "tip_J", "squared"],
            {"cse": True},
        )
        self._f = BufferedFunction(self.function, compiled=self.compiled)
        self._q = self._f.inputs[0]
        out = self._f.outputs
        self.P = out[0].reshape(K, 3)
        self.J = out[1].reshape(K, 3, n)
        self.tip = out[2]
        self.tip_jacobian = out[3].reshape(3, n)
        self.squared = out[4]

    def evaluate(self, q: np.ndarray) -> None:
        """Refresh :attr:`P`, :attr:`J`, :attr:`tip`, :attr:`tip_jacobian` at configuration ``q``."""
        self._q[:] = q
        self._f()

    def points_at(self, q: np.ndarray) -> np.ndarray:
        """A copy of the samples ``(K, 3)`` [m] of configuration ``q``."""
        self.evaluate(q)
        return self.P.copy()


class TwoTubes:
    """Clearances between the tubes of two placed arms and the barrier rows of the nearest pairs (module docstring).

    Parameters
    ----------
    first, second:
        The two arms.
    margin:
        Clearance every sampled pair keeps [m].
    gamma:
        Barrier rate [1/s], ``0 < gamma dt <= 1``.
    dt:
        Control period [s].
    pairs:
        Rows in the QP (nearest pairs, at most one per sample of ``first``).

    Attributes
    ----------
    A, b:
        ``(pairs, n_1 + n_2)`` and ``(pairs,)``: ``A qdot >= b``, refreshed by :meth:`update`.
    chosen:
        ``(pairs, 2)`` sample indices ``(i, j)`` of the rows.
    """

    def __init__(self, first: PlacedArm, second: PlacedArm, margin: float, gamma: float, dt: float, pairs: int = 4):
        if not margin > 0:
            raise ValueError(f"margin must be positive, got {margin}")
        if not 0 < gamma * dt <= 1:
            raise ValueError(f"gamma dt must be in (0, 1], got gamma {gamma} 1/s at dt {dt} s")
        if not pairs >= 1:
            raise ValueError(f"pairs must be at least 1, got {pairs}")
        self.first, self.second = first, second
        self.margin, self.gamma, self.dt = float(margin), float(gamma), float(dt)
        self.pairs = min(int(pairs), first.samples)
        self.radii = first.radius + second.radius
        self.n1, self.n2 = first.arm.n_config, second.arm.n_config
        self.A = np.zeros((self.pairs, self.n1 + self.n2))
        self.b = np.zeros(self.pairs)
        self.chosen = np.zeros((self.pairs, 2), dtype=int)
        self._rows = np.arange(first.samples)

    @property
    def between_samples(self) -> float:
        """How much closer the tubes may come between samples than the sampled pairs: ``(h_1 + h_2) / 2`` [m]."""
        return 0.5 * (self.first.spacing + self.second.spacing)

    def clearance_matrix(self, P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
        """``d_ij`` ``(K_1, K_2)`` [m] of samples ``P1`` ``(K_1, 3)`` and ``P2`` ``(K_2, 3)``."""
        diff = P1[:, None, :] - P2[None, :, :]
        return np.sqrt(np.einsum("ijk,ijk->ij", diff, diff)) - self.radii

    def update(self) -> None:
        """The rows of the step from the arms' last :meth:`PlacedArm.evaluate` (both arms evaluated)."""
        P1, P2 = self.first.P, self.second.P
        # |p_i - p_j|^2 = |p_i|^2 + |p_j|^2 - 2 p_i'p_j: one matrix product instead of a (K_1, K_2, 3) difference.
        squared = P1 @ P2.T
        squared *= -2.0
        squared += self.first.squared[:, None]
        squared += self.second.squared
        nearest = np.argmin(squared, axis=1)
        best = squared[self._rows, nearest]
        k = self.pairs
        i = np.argpartition(best, k - 1)[:k] if k < len(best) else self._rows
        j = nearest[i]
        self.chosen[:, 0], self.chosen[:, 1] = i, j
        gap = P1[i] - P2[j]
        length = np.sqrt(np.einsum("rk,rk->r", gap, gap))
        normal = gap / length[:, None]
        self.A[:, : self.n1] = np.einsum("rk,rkn->rn", normal, self.first.J[i])
        self.A[:, self.n1 :] = -np.einsum("rk,rkn->rn", normal, self.second.J[j])
        self.b[:] = -self.gamma * (length - self.radii - self.margin)

    def clearances(self, Q1: np.ndarray, Q2: np.ndarray) -> np.ndarray:
        """The least sampled clearance ``min_ij d_ij`` at each of ``N`` configuration pairs, ``(N,)`` [m]."""
        out = np.empty(len(Q1))
        for k, (q1, q2) in enumerate(zip(Q1, Q2)):
            out[k] = self.clearance_matrix(self.first.points_at(q1), self.second.points_at(q2)).min()
        return out
