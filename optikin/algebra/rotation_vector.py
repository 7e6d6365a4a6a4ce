"""Rotation vectors (axis times angle) and their rotation matrices, for numpy arrays and CasADi symbols."""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array


def _skew(w: Array) -> Array:
    """The cross-product matrix ``[w]x`` of a CasADi 3-vector."""
    return ca.vertcat(
        ca.horzcat(0, -w[2], w[1]),
        ca.horzcat(w[2], 0, -w[0]),
        ca.horzcat(-w[1], w[0], 0),
    )


def matrix_from_rotation_vector(w: Array) -> Array:
    """Rodrigues' ``exp([w]x)`` of rotation vectors [rad], exact and smooth at ``w = 0``.

    Parameters
    ----------
    w : Array
        Rotation vectors (axis times angle): numpy ``(..., 3)``, or one CasADi ``3 x 1``.

    Returns
    -------
    Array
        numpy ``(..., 3, 3)`` or CasADi ``3 x 3`` rotation matrices: ``I + sin(a)/a K + (1 - cos a)/a^2 K^2``
        with ``K = [w]x`` and ``a = |w|`` (CasADi: as :func:`~optikin.algebra.backend.sinc_of_square` of
        ``a^2`` and ``a^2 / 4``, so that it differentiates at ``w = 0``; numpy: the series' limits below
        ``a = 1e-8``).
    """
    if B.is_casadi(w):
        a2 = ca.sumsqr(w)
        K = _skew(w)
        half = B.sinc_of_square(a2 / 4.0)
        return ca.SX.eye(3) + B.sinc_of_square(a2) * K + 0.5 * half * half * (K @ K)
    w = np.asarray(w, dtype=float)
    a = np.linalg.norm(w, axis=-1)[..., None, None]
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(a > 1e-8, np.sin(a) / np.where(a > 0, a, 1.0), 1.0)
        c = np.where(a > 1e-8, (1.0 - np.cos(a)) / np.where(a > 0, a * a, 1.0), 0.5)
    return np.eye(3) + s * K + c * (K @ K)


def rotation_vector_from_matrix(R: np.ndarray) -> np.ndarray:
    """The rotation vector ``(3,)`` [rad] of a rotation matrix ``(3, 3)`` (angle below pi), inverse of
    :func:`matrix_from_rotation_vector`."""
    R = np.asarray(R, dtype=float)
    angle = np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if angle < 1e-8:
        return 0.5 * axis
    return angle / (2.0 * np.sin(angle)) * axis
