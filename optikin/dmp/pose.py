"""Pose DMPs: Seleem et al.'s dual-quaternion DMP, a sound one on the dual-quaternion log, and position x orientation.

``seed_dual_quaternion_dmp`` (label ``seed``)
    Seleem et al. (2020, sec. III-C-2, Figs. 15-21) run the unit-quaternion DMP of
    eqs. (17)-(23) on ``Q_r`` and, separately, on ``Q_d``. That is unsound:

    1. ``Q_d = 0.5 (0, p) Q_r`` has norm ``|p| / 2``, not 1. The update of
       eq. (23), ``Q <- exp(eta dt / 2 tau) Q``, preserves the norm, so the
       roll-out keeps ``|Q_d| = |Q_d(0)|``: the distance of the tip from the
       origin can never change and a goal at another distance is never
       reached. (The ``Q_d`` values printed with Fig. 16 have unit norm, which
       a true ``Q_d`` has only at ``|p| = 2`` m, far outside the 36 cm
       workspace: Seleem et al. must have normalised ``Q_d``, discarding ``|p|``.)
    2. ``Q_r`` and ``Q_d`` are integrated independently, so the unit
       dual-quaternion condition ``Q_r . Q_d = 0`` is lost and
       ``2 Q_d conj(Q_r)`` acquires a scalar part: the output is not a rigid
       pose.
    3. ``2 log(Q_dg conj(Q_d))`` is the angle between two directions in R^4,
       not a translation: the spring has no geometric meaning.

    It is provided so Seleem et al.'s figures can be reproduced and compared.
    Which ``|Q_d|`` it keeps is the learned start's: the demonstration's
    first sample, or, with ``smoothing`` (the low-pass maps every sample
    through ``advance`` from the last one, :mod:`optikin.dmp.smoothing`), the
    goal's, so the smoothed roll-out is off by ``| |p(0)| - |p_goal| |`` at
    ``t = 0`` already. Whatever the recording, its position error is bounded
    below by :func:`radial_bound` (a property of the variant, not of the data;
    where the tip is nearer the origin than the radius kept, up to the scalar
    part the lost rigidity adds), and the bound moves with the world origin,
    since ``|p|`` is a distance from it.

``seed_start_dual_quaternion_dmp`` (label ``seed-qd-start``)
    The same DMPs on ``Q_r`` and ``Q_d`` (still unsound), rolled out from
    the learned start with ``|Q_d|`` rescaled to the demonstration's first
    sample ``|Q_d(0)|``, unsmoothed: the roll-out starts at the demonstration's
    distance from the origin and keeps it. The gap ``2 log(Q_dg conj(Q_d))``
    does not see ``|Q_d|`` and ``exp(v/2) Q_d`` scales with it, so this is the
    ``seed`` roll-out with ``Q_d`` scaled by ``|Q_d(0)| / |Q_d(start)|``;
    without smoothing the two coincide.

``dual_quaternion_dmp`` (label ``dual-quaternion``, sound)
    One DMP on the group of unit dual quaternions: the gap is the screw
    ``2 log(G Q*)`` (:func:`optikin.algebra.dq_log`, a 6-vector) and the update
    ``Q <- exp(v / 2) Q`` (:func:`optikin.algebra.dq_exp`): every roll-out is
    a rigid pose to rounding, and the goal is a fixed point of the dynamics.

``cartesian_dmp`` (label ``cartesian``, sound)
    A translation DMP and a unit-quaternion DMP side by side on
    ``(p, q)``, the layout of movement_primitives' ``CartesianDMP``
    (``x, y, z, qw, qx, qy, qz``).
"""

from __future__ import annotations

from typing import Literal, get_args

import numpy as np

from optikin.algebra import dq_rotation, dq_translation
from optikin.dmp.model import DMP, RolloutPlan
from optikin.dmp.regression import Fit
from optikin.dmp.spaces import Euclidean, Product, UnitDualQuaternion, UnitQuaternion

PoseVariant = Literal["seed", "seed-qd-start", "dual-quaternion", "cartesian"]
"""The label of a pose DMP (the module docstring)."""
POSE_VARIANTS: tuple[PoseVariant, ...] = get_args(PoseVariant)


def seed_dual_quaternion_dmp(n_basis: int = 50, **options) -> DMP:
    """Seleem et al.'s variant: quaternion DMPs on ``Q_r`` and on ``Q_d`` of ``(Q_r, Q_d)`` (unsound, see module doc).

    Parameters
    ----------
    n_basis:
        Basis functions per gap component.
    **options:
        The other keyword arguments of :class:`~optikin.dmp.DMP` (gains, overlap, smoothing, ...).

    Returns
    -------
    DMP
        On ``S^3 x S^3``: states ``(8,)`` ``(Q_r, Q_d)``, gaps ``(6,)``.
    """
    return DMP(Product(UnitQuaternion(), UnitQuaternion()), n_basis, **options)


class SeedStartDMP(DMP):
    """Seleem et al.'s variant rolled out with ``|Q_d|`` at the demonstration's first sample (the module doc).

    Parameters as :class:`~optikin.dmp.DMP`; the space is ``S^3 x S^3`` on ``(Q_r, Q_d)``.

    Attributes
    ----------
    start_dual_norm:
        ``|Q_d(0)|`` of the demonstration as given to :meth:`imitate` (before any smoothing); ``None`` before.
    """

    def __init__(self, n_basis: int = 50, **options) -> None:
        super().__init__(Product(UnitQuaternion(), UnitQuaternion()), n_basis, **options)
        self.start_dual_norm: float | None = None

    def imitate(self, t: np.ndarray, Y: np.ndarray, *args, **kwargs) -> Fit:
        """:meth:`DMP.imitate`, keeping ``|Q_d|`` of the first sample ``Y[0, 4:]``."""
        fit = super().imitate(t, Y, *args, **kwargs)
        self.start_dual_norm = float(np.linalg.norm(np.asarray(Y, dtype=float)[0, 4:]))
        return fit

    def plan(self, duration: float | None = None, *, start: np.ndarray | None = None, **kwargs) -> RolloutPlan:
        """:meth:`DMP.plan`; the default start is the learned one with ``|Q_d|`` set to :attr:`start_dual_norm`."""
        if start is None:
            y0 = np.array(self._learned().start, dtype=float)
            assert self.start_dual_norm is not None  # set by imitate with the learned demonstration
            y0[4:] *= self.start_dual_norm / np.linalg.norm(y0[4:])
            start = y0
        return super().plan(duration, start=start, **kwargs)


def seed_start_dual_quaternion_dmp(n_basis: int = 50, **options) -> DMP:
    """Seleem et al.'s variant with ``|Q_d|`` taken from the demonstration's start (:class:`SeedStartDMP`).

    Parameters as :func:`seed_dual_quaternion_dmp`: states ``(8,)`` ``(Q_r, Q_d)``, gaps ``(6,)``.
    """
    return SeedStartDMP(n_basis, **options)


def radial_bound(position: np.ndarray, radius: float | np.ndarray) -> np.ndarray:
    """The least distance from ``position`` to a point at distance ``radius`` from the origin: ``| |p| - r |``.

    A roll-out of the ``seed`` variants keeps ``|Q_d| = r / 2``; its translation
    quaternion ``2 Q_d conj(Q_r)`` then has norm ``r``, so its distance to
    ``(0, p)`` is at least this bound, and so is its position error wherever
    ``|p| >= r`` (the vector part has norm at most ``r``). Where ``|p| < r``
    the vector part may fall short of ``r`` by the scalar part ``s`` the
    variant's lost rigidity gives it, and the error is at least
    ``sqrt(r^2 - s^2) - |p|``.

    Parameters
    ----------
    position:
        ``(..., 3)`` positions [m] in the world frame the variant is learned in.
    radius:
        The distance from the origin the roll-out keeps [m], ``2 |Q_d|`` (broadcast).

    Returns
    -------
    ndarray
        ``(...)`` bounds [m].
    """
    return np.abs(np.linalg.norm(np.asarray(position, dtype=float), axis=-1) - np.asarray(radius, dtype=float))


def dual_quaternion_dmp(n_basis: int = 50, **options) -> DMP:
    """A DMP on unit dual quaternions through ``dq_log``/``dq_exp`` (sound): states ``(8,)``, gaps ``(6,)``.

    Parameters as :func:`seed_dual_quaternion_dmp`.
    """
    return DMP(UnitDualQuaternion(), n_basis, **options)


def cartesian_dmp(n_basis: int = 50, **options) -> DMP:
    """A translation DMP and a quaternion DMP on ``(x, y, z, qw, qx, qy, qz)`` (sound): states ``(7,)`` [m | -],
    gaps ``(6,)``. Parameters as :func:`seed_dual_quaternion_dmp`."""
    return DMP(Product(Euclidean(3), UnitQuaternion()), n_basis, **options)


def pose_dmp(variant: str, **options) -> DMP:
    """The pose DMP of a variant label.

    Parameters
    ----------
    variant:
        ``seed``, ``seed-qd-start``, ``dual-quaternion`` or ``cartesian`` (:data:`POSE_VARIANTS`).
    **options:
        ``n_basis`` and the keyword arguments of :class:`~optikin.dmp.DMP`.

    Raises
    ------
    ValueError
        An unknown label.
    """
    makers = {
        "seed": seed_dual_quaternion_dmp,
        "seed-qd-start": seed_start_dual_quaternion_dmp,
        "dual-quaternion": dual_quaternion_dmp,
        "cartesian": cartesian_dmp,
    }
    if variant not in makers:
        raise ValueError(f"unknown pose DMP variant {variant!r}; choose from {POSE_VARIANTS}")
    return makers[variant](**options)


def to_variant(variant: str, dq: np.ndarray) -> np.ndarray:
    """Poses in the state layout of a variant.

    Parameters
    ----------
    variant:
        A label of :data:`POSE_VARIANTS`.
    dq:
        ``(..., 8)`` unit dual quaternions ``Q_r + eps Q_d`` (eqs. 9-10).

    Returns
    -------
    ndarray
        ``(..., 7)`` ``(x, y, z, qw, qx, qy, qz)`` [m | -] for ``cartesian``, else ``dq`` itself ``(..., 8)``.
    """
    dq = np.asarray(dq, dtype=float)
    if variant == "cartesian":
        return np.concatenate([dq_translation(dq), dq_rotation(dq)], axis=-1)
    return dq


def from_variant(variant: str, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions and orientations of states of a variant (the inverse of :func:`to_variant`).

    Parameters
    ----------
    variant:
        A label of :data:`POSE_VARIANTS`.
    y:
        ``(..., 7)`` or ``(..., 8)`` states in the variant's layout.

    Returns
    -------
    tuple
        Positions ``(..., 3)`` [m] and unit quaternions ``(..., 4)``. For
        Seleem et al.'s variant the translation is read as ``2 Q_d conj(Q_r)``
        (eq. 10; its scalar part, nonzero when ``Q_r . Q_d != 0``, is dropped).
    """
    y = np.asarray(y, dtype=float)
    if variant == "cartesian":
        return y[..., :3], y[..., 3:]
    return dq_translation(y), dq_rotation(y)
