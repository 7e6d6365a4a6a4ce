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
from optikin.dmp.model import DMP
from optikin.dmp.spaces import Euclidean, Product, UnitDualQuaternion, UnitQuaternion

PoseVariant = Literal["seed", "dual-quaternion", "cartesian"]
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
        ``seed``, ``dual-quaternion`` or ``cartesian`` (:data:`POSE_VARIANTS`).
    **options:
        ``n_basis`` and the keyword arguments of :class:`~optikin.dmp.DMP`.

    Raises
    ------
    ValueError
        An unknown label.
    """
    makers = {"seed": seed_dual_quaternion_dmp, "dual-quaternion": dual_quaternion_dmp, "cartesian": cartesian_dmp}
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
