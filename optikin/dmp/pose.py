"""Pose DMPs: the seed's dual-quaternion DMP, a sound one on the dual-quaternion logarithm, and position x orientation.

``seed_dual_quaternion_dmp`` (label ``seed``)
    Seed 000 (sec. III-C-2, Figs. 15-21) runs the unit-quaternion DMP of
    eqs. (17)-(23) on ``Q_r`` and, separately, on ``Q_d``. That is unsound:

    1. ``Q_d = 0.5 (0, p) Q_r`` has norm ``|p| / 2``, not 1. The update of
       eq. (23), ``Q <- exp(eta dt / 2 tau) Q``, preserves the norm, so the
       roll-out keeps ``|Q_d| = |Q_d(0)|``: the distance of the tip from the
       origin can never change and a goal at another distance is never
       reached. (The ``Q_d`` values printed with Fig. 16 have unit norm, which
       a true ``Q_d`` has only at ``|p| = 2`` m, far outside the 36 cm
       workspace: the seed must have normalised ``Q_d``, discarding ``|p|``.)
    2. ``Q_r`` and ``Q_d`` are integrated independently, so the unit
       dual-quaternion condition ``Q_r . Q_d = 0`` is lost and
       ``2 Q_d conj(Q_r)`` acquires a scalar part: the output is not a rigid
       pose.
    3. ``2 log(Q_dg conj(Q_d))`` is the angle between two directions in R^4,
       not a translation: the spring has no geometric meaning.

    It is provided so the seed's figures can be reproduced and compared.

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
    """Seed 000's variant: quaternion DMPs on ``Q_r`` and on ``Q_d`` of ``(Q_r, Q_d)`` (unsound, see module doc).

    ``options``: the keyword arguments of :class:`~optikin.dmp.DMP` (gains, overlap, smoothing, ...).
    """
    return DMP(Product(UnitQuaternion(), UnitQuaternion()), n_basis, **options)


def dual_quaternion_dmp(n_basis: int = 50, **options) -> DMP:
    """A DMP on unit dual quaternions through ``dq_log``/``dq_exp`` (sound); ``options`` as :class:`DMP`'s."""
    return DMP(UnitDualQuaternion(), n_basis, **options)


def cartesian_dmp(n_basis: int = 50, **options) -> DMP:
    """A translation DMP and a quaternion DMP on ``(x, y, z, qw, qx, qy, qz)`` (sound); ``options``: :class:`DMP`'s."""
    return DMP(Product(Euclidean(3), UnitQuaternion()), n_basis, **options)


def pose_dmp(variant: str, **options) -> DMP:
    """The pose DMP of a variant label (:data:`POSE_VARIANTS`)."""
    makers = {"seed": seed_dual_quaternion_dmp, "dual-quaternion": dual_quaternion_dmp, "cartesian": cartesian_dmp}
    if variant not in makers:
        raise ValueError(f"unknown pose DMP variant {variant!r}; choose from {POSE_VARIANTS}")
    return makers[variant](**options)


def to_variant(variant: str, dq: np.ndarray) -> np.ndarray:
    """Dual quaternions ``(..., 8)`` in the state layout of a variant (``(p, q)`` for ``cartesian``)."""
    dq = np.asarray(dq, dtype=float)
    if variant == "cartesian":
        return np.concatenate([dq_translation(dq), dq_rotation(dq)], axis=-1)
    return dq


def from_variant(variant: str, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(positions (..., 3), quaternions (..., 4))`` of states of a variant.

    For the seed's variant the translation is read as ``2 Q_d conj(Q_r)``
    (its scalar part, nonzero when ``Q_r . Q_d != 0``, is dropped).
    """
    y = np.asarray(y, dtype=float)
    if variant == "cartesian":
        return y[..., :3], y[..., 3:]
    return dq_translation(y), dq_rotation(y)
