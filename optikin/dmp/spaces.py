"""The spaces a DMP moves in: vectors, unit quaternions, unit dual quaternions, and products of them.

Every DMP of Seleem et al. (2020) (eqs. 11-12 per angle, eqs. 17-23 on a unit quaternion)
has the same structure once two operations of its space are named:

``gap(target, y)``
    the error that drives the spring, in *gap units*: ``target - y`` for
    vectors; ``2 log(target * conj(y))`` for quaternions (the rotation vector,
    Seleem et al.'s eq. 19, Ude et al. 2014); ``2 log(target * conj(y))`` in the dual
    algebra for unit dual quaternions (rotation vector and screw translation).
``advance(y, v)``
    move ``y`` by a gap-unit step ``v``: ``y + v`` for vectors,
    ``exp(v / 2) * y`` for quaternions (Seleem et al.'s eq. 23) and dual quaternions.

``lift(e, previous)``
    the gap ``e`` on the branch nearest ``previous``: a rotation vector
    ``theta n`` stands for the same rotation as ``(theta + 2 pi k) n`` for every
    integer ``k`` (and a screw likewise, its moment scaled with the angle), and
    :func:`optikin.algebra.quat_log` returns one branch only (angle in
    ``[0, 2 pi]``), which jumps where the rotation to the goal passes a full
    turn (or, for the other sign of the goal, half a turn). The imitation
    lifts the goal gaps along the demonstration from the goal backwards
    (:func:`lifted_gaps`) and the roll-out lifts each gap against the one
    before, so both see the same continuous gap, whatever the sign of the goal
    and however far the motion turns (a heading that winds past a full turn
    included). Vectors have a single branch.

``gap(advance(y, v), y) = v`` (up to the branch), so the DMP of
one space is written once (:mod:`optikin.dmp.rollout`) for all of them. Each
operation accepts numpy batches (components on the last axis) and CasADi
column vectors, like :mod:`optikin.algebra`.

Quaternion parts of a state are unit on the demonstrations Seleem et al. use; the
paper also runs the quaternion DMP on ``Q_d`` (not unit): the same operations
apply (``quat_log`` of a product is scale invariant and ``exp(v/2) * y`` keeps
``|y|``), which is exactly why that variant cannot change ``|Q_d|``
(:mod:`optikin.dmp.pose`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from optikin.algebra import (
    dq_conjugate,
    dq_exp,
    dq_log,
    dq_multiply,
    quat_conjugate,
    quat_exp,
    quat_log,
    quat_multiply,
)
from optikin.algebra import backend as B
from optikin.algebra.backend import Array


def _slice(x: Array, start: int, stop: int) -> Array:
    return x[start:stop, :] if B.is_casadi(x) else np.asarray(x, dtype=float)[..., start:stop]


def _join(parts: list[Array]) -> Array:
    if B.any_casadi(*parts):
        return ca.vertcat(*parts)
    parts = [np.asarray(p, dtype=float) for p in parts]
    batch = np.broadcast_shapes(*[np.shape(p)[:-1] for p in parts])
    return np.concatenate([np.broadcast_to(p, batch + np.shape(p)[-1:]) for p in parts], axis=-1)


class Space:
    """A state space of a DMP: ``size`` stored components, ``dim`` gap (tangent) components."""

    name: str
    size: int
    dim: int
    quaternion_blocks: tuple[tuple[int, int], ...] = ()
    """``(start, 4)`` of every 4-component block whose sign is free (q and -q are one rotation)."""

    def gap(self, target: Array, y: Array) -> Array:
        """The error that drives the spring (eq. 19 on a quaternion), in gap units.

        Parameters
        ----------
        target, y:
            ``(..., size)`` elements (numpy, broadcast) or ``size x 1`` CasADi columns.

        Returns
        -------
        Array
            ``(..., dim)`` (or ``dim x 1``): ``target - y`` for vectors, the
            rotation vector / screw ``2 log(target conj(y))`` [rad | m] otherwise.
        """
        raise NotImplementedError

    def advance(self, y: Array, v: Array) -> Array:
        """``y`` moved by a gap-unit step ``v`` (eq. 23 on a quaternion).

        Parameters
        ----------
        y:
            ``(..., size)`` elements (or a CasADi column).
        v:
            ``(..., dim)`` steps in gap units.

        Returns
        -------
        Array
            ``(..., size)``: ``y + v`` for vectors, ``exp(v/2) y`` otherwise (unit stays unit).
        """
        raise NotImplementedError

    def toward(self, y: Array, v: Array, goal: Array, e: Array) -> Array:
        """One roll-out step of the pose: ``advance(y, v)`` (Seleem et al.'s eq. 23, Ude et al. 2014).

        Parameters
        ----------
        y, goal:
            The pose and the (filtered) goal, ``size`` components each.
        v:
            The step ``dt/tau (eta + coupling)`` in gap units.
        e:
            The goal gap ``lift(gap(goal, y))`` the step was computed from.

        Returns
        -------
        Array
            The next pose. :class:`GoalLogQuaternion` steps in the logarithm of the
            rotation to the goal instead.
        """
        return self.advance(y, v)

    def step_gap(self, y_next: Array, y: Array, e_next: Array, e: Array) -> Array:
        """One step of a demonstration in the units :meth:`toward` takes: ``gap(y_next, y)``.

        Parameters
        ----------
        y_next, y:
            ``(..., size)`` consecutive samples (numpy, broadcast) or ``size x 1`` CasADi columns.
        e_next, e:
            ``(..., dim)`` their lifted goal gaps (:func:`lifted_gaps`).

        Returns
        -------
        Array
            ``(..., dim)`` (or ``dim x 1``). :class:`GoalLogQuaternion` returns ``e - e_next``.
        """
        return self.gap(y_next, y)

    def step_gaps(self, Y: np.ndarray, goal_gaps: np.ndarray) -> np.ndarray:
        """The steps ``(N - 1, dim)`` of a demonstration ``Y (N, size)`` (:meth:`step_gap` along it);
        ``goal_gaps (N, dim)`` are its lifted goal gaps (:func:`lifted_gaps`)."""
        return np.asarray(self.step_gap(Y[1:], Y[:-1], goal_gaps[1:], goal_gaps[:-1]), dtype=float)

    def lift(self, e: Array, previous: Array) -> Array:
        """The gap ``e`` on the branch nearest ``previous`` (the module docstring).

        Parameters
        ----------
        e:
            ``(..., dim)`` gaps from :meth:`gap` (or a ``dim x 1`` CasADi column).
        previous:
            ``(..., dim)`` gaps the branch is chosen against.

        Returns
        -------
        Array
            ``(..., dim)``: ``e`` itself for vectors, ``(theta + 2 pi k) n`` for a
            rotation vector ``theta n`` with ``k`` the integer nearest
            ``(previous . n - theta) / (2 pi)``.
        """
        return e

    def align(self, x: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """``x`` with the sign of each quaternion block chosen to have a non-negative dot with ``reference``."""
        x = np.array(x, dtype=float)
        for start, length in self.quaternion_blocks:
            block = slice(start, start + length)
            dot = np.sum(x[..., block] * np.asarray(reference, dtype=float)[..., block], axis=-1)
            x[..., block] *= np.where(dot < 0, -1.0, 1.0)[..., None]
        return x

    def continuous(self, Y: np.ndarray) -> np.ndarray:
        """A sequence ``(T, size)`` with every quaternion block made sign-continuous along it."""
        Y = np.array(Y, dtype=float)
        for start, length in self.quaternion_blocks:
            block = Y[:, start : start + length]
            dots = np.einsum("ij,ij->i", block[1:], block[:-1])
            flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
            Y[:, start : start + length] = block * flips[:, None]
        return Y

    def __repr__(self) -> str:
        return self.name


@dataclass(frozen=True, repr=False)
class Euclidean(Space):
    """``R^n`` (one DMP per degree of freedom, Seleem et al.'s eqs. 11-12): ``gap = target - y``."""

    n: int

    @property
    def name(self) -> str:  # type: ignore[override]
        return f"R{self.n}"

    @property
    def size(self) -> int:  # type: ignore[override]
        return self.n

    @property
    def dim(self) -> int:  # type: ignore[override]
        return self.n

    def gap(self, target: Array, y: Array) -> Array:
        return target - y

    def advance(self, y: Array, v: Array) -> Array:
        return y + v


@dataclass(frozen=True, repr=False)
class UnitQuaternion(Space):
    """``S^3`` (Seleem et al.'s eqs. 17-23, Ude et al. 2014).

    ``gap = 2 log(target conj(y))``, ``advance = exp(v/2) y``.
    """

    name = "S3"
    size = 4
    dim = 3
    quaternion_blocks = ((0, 4),)

    def gap(self, target: Array, y: Array) -> Array:
        return 2.0 * quat_log(quat_multiply(target, quat_conjugate(y)), check=False)

    def advance(self, y: Array, v: Array) -> Array:
        return quat_multiply(quat_exp(0.5 * v), y)

    def lift(self, e: Array, previous: Array) -> Array:
        turns, axis, _ = _turns(e, previous)
        return e + (2.0 * np.pi) * turns * axis


@dataclass(frozen=True, repr=False)
class GoalLogQuaternion(UnitQuaternion):
    """``S^3`` with the DMP in the logarithm of the rotation to the goal (Koutras & Doulgeri 2020).

    L. Koutras, Z. Doulgeri, "A correct formulation for the orientation dynamic
    movement primitives for robot control in the Cartesian space", CoRL 2020,
    PMLR 100:293-302. Their DMP is the linear one of eq. (11) on
    ``y_e = log(q * conj(q_g))``, driven to 0, with the orientation recovered
    as ``q = exp(y_e) q_g``. In the gap units here ``e = 2 log(q_g conj(q)) =
    -2 y_e``, so the state is the same quaternion, the gap the same as
    :class:`UnitQuaternion`'s, and only the step differs: the roll-out moves
    ``e`` itself, ``q <- exp(-(e - v)/2) q_g`` (:meth:`toward`), and the
    imitation's velocities are differences of ``e`` (:meth:`step_gaps`), where
    Ude et al.'s DMP turns ``q`` by the angular velocity, ``q <- exp(v/2) q``.
    Each gap component is then exactly a linear critically damped spring plus
    the forcing term, whatever the size of the gap; in Ude et al.'s form the
    map from angular velocity to the gap's rate is the inverse Jacobian of
    ``log``, whose eigenvalues across the gap, ``(theta/2) cot(theta/2)``, fall
    to 0 at half a turn and turn negative past it, so a stiff spring there
    pushes the motion away sideways.
    """

    name = "S3-log"

    def toward(self, y: Array, v: Array, goal: Array, e: Array) -> Array:
        return quat_multiply(quat_exp(-0.5 * (e - v)), goal)

    def step_gap(self, y_next: Array, y: Array, e_next: Array, e: Array) -> Array:
        return e - e_next


@dataclass(frozen=True, repr=False)
class UnitDualQuaternion(Space):
    """Unit dual quaternions (rigid poses): ``gap = 2 log(target y*)`` and ``advance = exp(v/2) y`` in the dual algebra.

    The gap is the spatial screw from ``y`` to ``target``: the rotation vector
    and, for a pure translation ``p``, the vector ``p`` itself. Because the
    exponential of a pure dual vector is a unit dual quaternion and the product
    of unit dual quaternions is unit, a roll-out stays a rigid pose
    (``|Q_r| = 1``, ``Q_r . Q_d = 0``) to rounding, unlike two quaternion DMPs
    on ``Q_r`` and ``Q_d``. The screw is taken about the world origin, so (as
    for every spatial-frame dual-quaternion error) the translational gap of a
    rotation grows with the distance of the motion from the origin.
    """

    name = "DQ"
    size = 8
    dim = 6
    quaternion_blocks = ((0, 8),)

    def gap(self, target: Array, y: Array) -> Array:
        return 2.0 * dq_log(dq_multiply(target, dq_conjugate(y)))

    def advance(self, y: Array, v: Array) -> Array:
        return dq_multiply(dq_exp(0.5 * v), y)

    def lift(self, e: Array, previous: Array) -> Array:
        """The screw ``(theta n, d n + theta m)`` on the branch nearest ``previous``: ``theta + 2 pi k`` about the
        same line (axis ``n``, moment ``m``) with the same translation ``d`` along it (parameters as
        :meth:`Space.lift`).

        Where the rotation to the goal passes a whole turn with a translation left, the screw's axis goes to
        infinity (``(I - R) c = p`` with ``R`` near the identity) and so does the lifted moment: a motion that
        turns past a full turn from its goal while translating is not carried by this gap (the position x
        orientation DMP of :func:`optikin.dmp.pose.cartesian_dmp` is).
        """
        u, v = _slice(e, 0, 3), _slice(e, 3, 6)
        turns, axis, angle = _turns(u, _slice(previous, 0, 3))
        along = _dot(v, axis)
        moment = (v - along * axis) / angle
        return _join([u + (2.0 * np.pi) * turns * axis, v + (2.0 * np.pi) * turns * moment])

    def align(self, x: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Flip the whole dual quaternion (``Q`` and ``-Q`` are one pose) by the sign of its real parts' dot."""
        x = np.array(x, dtype=float)
        dot = np.sum(x[..., :4] * np.asarray(reference, dtype=float)[..., :4], axis=-1)
        return x * np.where(dot < 0, -1.0, 1.0)[..., None]

    def continuous(self, Y: np.ndarray) -> np.ndarray:
        Y = np.array(Y, dtype=float)
        dots = np.einsum("ij,ij->i", Y[1:, :4], Y[:-1, :4])
        flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
        return Y * flips[:, None]


class Product(Space):
    """The product of spaces, stored and stepped part by part (e.g. position x orientation)."""

    def __init__(self, *parts: Space):
        if not parts:
            raise ValueError("a product space needs at least one part")
        self.parts = tuple(parts)
        self.name = " x ".join(p.name for p in parts)
        self.size = sum(p.size for p in parts)
        self.dim = sum(p.dim for p in parts)
        blocks, offset = [], 0
        for p in parts:
            blocks += [(offset + start, length) for start, length in p.quaternion_blocks]
            offset += p.size
        self.quaternion_blocks = tuple(blocks)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Product) and self.parts == other.parts

    def __hash__(self) -> int:
        return hash(self.parts)

    def _split(self, x: Array, sizes: list[int]) -> list[Array]:
        out, offset = [], 0
        for n in sizes:
            out.append(_slice(x, offset, offset + n))
            offset += n
        return out

    def gap(self, target: Array, y: Array) -> Array:
        sizes = [p.size for p in self.parts]
        return _join([p.gap(t, v) for p, t, v in zip(self.parts, self._split(target, sizes), self._split(y, sizes))])

    def advance(self, y: Array, v: Array) -> Array:
        ys = self._split(y, [p.size for p in self.parts])
        vs = self._split(v, [p.dim for p in self.parts])
        return _join([p.advance(a, b) for p, a, b in zip(self.parts, ys, vs)])

    def toward(self, y: Array, v: Array, goal: Array, e: Array) -> Array:
        sizes, dims = [p.size for p in self.parts], [p.dim for p in self.parts]
        ys, vs, gs, es = self._split(y, sizes), self._split(v, dims), self._split(goal, sizes), self._split(e, dims)
        return _join([p.toward(*parts) for p, *parts in zip(self.parts, ys, vs, gs, es)])

    def step_gap(self, y_next: Array, y: Array, e_next: Array, e: Array) -> Array:
        sizes, dims = [p.size for p in self.parts], [p.dim for p in self.parts]
        split = (self._split(y_next, sizes), self._split(y, sizes), self._split(e_next, dims), self._split(e, dims))
        return _join([p.step_gap(*parts) for p, *parts in zip(self.parts, *split)])

    def lift(self, e: Array, previous: Array) -> Array:
        dims = [p.dim for p in self.parts]
        return _join([p.lift(a, b) for p, a, b in zip(self.parts, self._split(e, dims), self._split(previous, dims))])

    def align(self, x: np.ndarray, reference: np.ndarray) -> np.ndarray:
        sizes = [p.size for p in self.parts]
        xs, rs = self._split(x, sizes), self._split(reference, sizes)
        return _join([p.align(a, r) for p, a, r in zip(self.parts, xs, rs)])

    def continuous(self, Y: np.ndarray) -> np.ndarray:
        return _join([p.continuous(part) for p, part in zip(self.parts, self._split(Y, [p.size for p in self.parts]))])


def _dot(a: Array, b: Array) -> Array:
    """Dot product of 3-vectors: a ``1 x 1`` CasADi value or numpy ``(..., 1)``."""
    if B.any_casadi(a, b):
        return ca.dot(a, b)
    return np.sum(np.asarray(a) * np.asarray(b), axis=-1, keepdims=True)


def _turns(u: Array, previous: Array) -> tuple[Array, Array, Array]:
    """``(k, n, theta)`` of a rotation vector ``u = theta n``: the whole turns ``k`` that bring it nearest
    ``previous``, its unit axis and its angle (1 at ``u = 0``, a safe divisor). At ``u = 0`` (whole turns
    from the goal) the axis is ``previous``'s, or 0 when that is 0 too."""
    norm2, before2 = _dot(u, u), _dot(previous, previous)
    zero, still = norm2 < 1e-24, before2 < 1e-24
    angle = B.sqrt(B.where(zero, 1.0, norm2))
    axis = B.where(zero, previous / B.sqrt(B.where(still, 1.0, before2)), u / angle)
    shift = (_dot(previous, axis) - B.where(zero, 0.0, angle)) / (2.0 * np.pi)
    turns = ca.floor(shift + 0.5) if B.any_casadi(shift) else np.floor(shift + 0.5)
    return turns, axis, angle


def lifted_gaps(space: Space, goal: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``gap(goal, y_k)`` ``(N, dim)`` along a sequence ``Y (N, size)``, continuous from the last sample back.

    The last gap is taken on the branch nearest zero (the shortest rotation to
    the goal), each earlier one on the branch nearest the gap after it
    (:meth:`Space.lift`): the gaps the roll-out will meet when it follows ``Y``.
    """
    raw = np.asarray(space.gap(goal, Y), dtype=float)
    if np.all(np.linalg.norm(np.diff(raw, axis=0), axis=-1) < np.pi) and np.all(
        np.asarray(space.lift(raw[-1], np.zeros(raw.shape[-1])), dtype=float).reshape(-1) == raw[-1]
    ):
        return raw  # continuous and ending on the branch nearest zero: every lift keeps its branch (k = 0)
    out = np.empty_like(raw)
    previous = np.zeros(raw.shape[-1])
    for k in range(raw.shape[0] - 1, -1, -1):
        previous = out[k] = np.asarray(space.lift(raw[k], previous), dtype=float).reshape(-1)
    return out


def smooth_norm(e: Array, eps: float = 1e-12) -> Array:
    """``sqrt(|e|^2 + eps^2) - eps``: the norm of a gap column (CasADi) or of each row (numpy), differentiable at 0."""
    if B.is_casadi(e):
        return ca.sqrt(ca.sumsqr(e) + eps * eps) - eps
    return np.sqrt(np.sum(np.square(e), axis=-1) + eps * eps) - eps
