"""The DMP variants of the ``dmp`` kind: their models, state layouts, and errors against poses.

A variant (:data:`~optikin.problems.dmp.options.Variant`) is a DMP on one
representation of the tip pose: ``seed``, ``seed-qd-start``, ``dual-quaternion``
and ``cartesian`` are the pose DMPs of :mod:`optikin.dmp.pose`; ``quaternion`` a
unit-quaternion DMP on the orientation (Seleem et al. 2020, eqs. 17-23, the form of
Ude et al. 2014); ``koutras-doulgeri`` the orientation DMP of Koutras & Doulgeri
(CoRL 2020) in the logarithm of the rotation to the goal; ``rpy`` three
per-angle DMPs on roll-pitch-yaw (eqs. 11-16, angles by eq. 30); ``position``
a translation DMP.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.algebra import (
    dq_from_rotation_translation,
    dq_norm_residual,
    dq_rotation,
    dq_translation,
    quat_angle,
    quat_conjugate,
    quat_from_rpy,
    quat_multiply,
    rpy_from_quat,
)
from optikin.dmp import DMP, Euclidean, Gains, GoalLogQuaternion, Space, UnitQuaternion
from optikin.dmp.pose import POSE_VARIANTS, pose_dmp, radial_bound

MM, MRAD = 1e3, 1e3
"""Metres and radians to the millimetres and milliradians of the reported metrics."""

ORIENTATION = ("quaternion", "koutras-doulgeri")
"""The variants whose state is the tip's unit quaternion alone."""

SEED = ("seed", "seed-qd-start")
"""Seleem et al.'s quaternion DMPs on ``Q_r`` and ``Q_d``: states ``(Q_r, Q_d)``, ``|Q_d|`` fixed by the roll-out."""

DUAL = (*SEED, "dual-quaternion")
"""The variants whose state is a dual quaternion ``(Q_r, Q_d)``."""

UNIT_TOLERANCE = 1e-9
"""Largest departure from unit norm of a roll-out's unit quaternions (or dual quaternion) counted ``ok``."""


def make_dmp(variant: str, n_basis: int, gains: Gains, **options: Any) -> DMP:
    """The DMP of a variant label; ``options``: the other keyword arguments of :class:`DMP` (smoothing, ...)."""
    if variant in POSE_VARIANTS:
        return pose_dmp(variant, n_basis=n_basis, gains=gains, **options)
    spaces: dict[str, Space] = {"quaternion": UnitQuaternion(), "koutras-doulgeri": GoalLogQuaternion()}
    return DMP(spaces.get(variant, Euclidean(3)), n_basis=n_basis, gains=gains, **options)


def variant_data(
    variant: str, position: np.ndarray, quaternion: np.ndarray, rpy_reference: np.ndarray | None = None
) -> np.ndarray:
    """Poses ``(..., size)`` in the state layout of a variant from positions ``(..., 3)`` [m] and unit
    quaternions ``(..., 4)``; ``rpy`` angles [rad] are unwrapped along a sequence, or taken nearest to
    ``rpy_reference`` for a single pose."""
    if variant in DUAL:
        return dq_from_rotation_translation(quaternion, position, check=False)
    if variant == "cartesian":
        return np.concatenate([position, quaternion], axis=-1)
    if variant in ORIENTATION:
        return quaternion
    if variant == "position":
        return position
    rpy = rpy_from_quat(quaternion, check=False)
    if rpy.ndim == 2:
        return np.unwrap(rpy, axis=0)
    assert rpy_reference is not None, "a single rpy pose needs the angles it should be nearest to"
    return rpy + 2 * np.pi * np.round((rpy_reference - rpy) / (2 * np.pi))


def variant_pose(variant: str, y: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(positions (..., 3), quaternions (..., 4))`` of states of a variant (``None`` where it has none)."""
    if variant in DUAL:
        return dq_translation(y), dq_rotation(y)
    if variant == "cartesian":
        return y[..., :3], y[..., 3:]
    if variant in ORIENTATION:
        return None, y
    if variant == "position":
        return y, None
    return None, quat_from_rpy(y[..., 0], y[..., 1], y[..., 2])


def pose_errors(
    variant: str, y: np.ndarray, position: np.ndarray | None, quaternion: np.ndarray | None
) -> dict[str, np.ndarray]:
    """Per-sample ``position`` error [m] and ``orientation`` error [rad] of roll-out states against poses."""
    p, q = variant_pose(variant, y)
    errors = {}
    if p is not None and position is not None:
        errors["position"] = np.linalg.norm(p - position, axis=-1)
    if q is not None and quaternion is not None:
        errors["orientation"] = quat_angle(quat_multiply(q, quat_conjugate(quaternion)))
    return errors


def structural_bound(variant: str, y: np.ndarray, position: np.ndarray) -> tuple[float, np.ndarray] | None:
    """The radius a ``seed`` variant's roll-out keeps and the least position error it implies per sample.

    Parameters
    ----------
    variant:
        A variant label; only those of :data:`SEED` have the bound.
    y:
        ``(K, 8)`` roll-out states ``(Q_r, Q_d)``.
    position:
        ``(K, 3)`` positions [m] the roll-out is compared with.

    Returns
    -------
    tuple or None
        ``(2 |Q_d(0)| [m], | |p| - 2 |Q_d(0)| | (K,) [m])`` (:func:`optikin.dmp.pose.radial_bound`); ``None``
        for the other variants, whose ``|p|`` is free.
    """
    if variant not in SEED:
        return None
    radius = 2.0 * float(np.linalg.norm(y[0, 4:]))
    return radius, radial_bound(position, radius)


def unit_error(variant: str, y: np.ndarray) -> float:
    """Largest departure from unit norm of the quaternion parts the variant should keep unit."""
    if variant == "dual-quaternion":
        n, d = dq_norm_residual(y)
        return float(max(np.abs(n).max(), np.abs(d).max()))
    if variant in SEED or variant in ORIENTATION:
        return float(np.abs(np.linalg.norm(y[..., :4], axis=-1) - 1).max())
    if variant == "cartesian":
        return float(np.abs(np.linalg.norm(y[..., 3:], axis=-1) - 1).max())
    return 0.0


def rollout_status(y: np.ndarray, unit: float) -> str:
    """``ok`` for a finite roll-out whose unit parts stay unit, else ``failed``."""
    return "ok" if np.isfinite(y).all() and unit < UNIT_TOLERANCE else "failed"


def unit_of(error: str) -> tuple[str, float]:
    """The reported unit of an error kind and the factor to it: ``("mm", 1e3)`` or ``("mrad", 1e3)``."""
    return ("mm", MM) if error == "position" else ("mrad", MRAD)
