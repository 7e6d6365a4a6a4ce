"""Unit dual quaternions ``Q = Q_r + eps Q_d`` for rigid transforms (seed 000 eqs. 9-10).

A dual quaternion is stored as 8 components ``(Q_r, Q_d)``: on the last axis
``(..., 8)`` for numpy, on the rows ``(8, 1)``/``(8, N)`` for CasADi. A pose with
rotation ``Q_r`` and translation ``p`` has ``Q_d = 0.5 (0, p) Q_r`` (seed 000 eq. 10).

The logarithm and exponential are the true ones of the dual-number algebra
(so ``Q^t = exp(t log Q)`` is the screw motion used by ScLERP). For a pure dual
vector ``u + eps v``, ``exp(u + eps v) = exp(u) + eps Dexp(u)[v]``, the
directional derivative of the quaternion exponential; ``log`` inverts it. Both
are exact at the identity and for pure translations.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array
from optikin.algebra.quaternion import (
    matrix_from_quat,
    quat_conjugate,
    quat_exp,
    quat_from_matrix,
    quat_from_pure,
    quat_log,
    quat_multiply,
    quat_vector,
)

IDENTITY = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])


def dq_parts(dq: Array) -> tuple[Array, Array]:
    """``(Q_r, Q_d)`` of a dual quaternion."""
    return B.split(dq, 4, 8)


def dq_from_parts(real: Array, dual: Array) -> Array:
    return B.concat(real, dual)


def dq_from_rotation_translation(q: Array, p: Array) -> Array:
    """``Q_r + eps 0.5 (0, p) Q_r`` from a unit quaternion and a translation (seed 000 eqs. 9-10)."""
    return B.concat(q, 0.5 * quat_multiply(quat_from_pure(p), q))


def dq_rotation(dq: Array) -> Array:
    return dq_parts(dq)[0]


def dq_translation(dq: Array) -> Array:
    """``p = 2 Q_d Q_r*`` (inverse of seed 000 eq. 10)."""
    real, dual = dq_parts(dq)
    return quat_vector(2.0 * quat_multiply(dual, quat_conjugate(real)))


def dq_from_transform(T: Array) -> Array:
    """Dual quaternion of a 4x4 homogeneous transform (numpy ``(..., 4, 4)`` or CasADi ``4 x 4``)."""
    if B.is_casadi(T):
        return dq_from_rotation_translation(quat_from_matrix(T[:3, :3]), T[:3, 3])
    T = np.asarray(T, dtype=float)
    return dq_from_rotation_translation(quat_from_matrix(T[..., :3, :3]), T[..., :3, 3])


def transform_from_dq(dq: Array) -> Array:
    """4x4 homogeneous transform of a unit dual quaternion."""
    R = matrix_from_quat(dq_rotation(dq))
    p = dq_translation(dq)
    if B.is_casadi(dq):
        return ca.vertcat(ca.horzcat(R, p), ca.DM([[0, 0, 0, 1]]))
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def dq_multiply(a: Array, b: Array) -> Array:
    """``(a_r + eps a_d)(b_r + eps b_d) = a_r b_r + eps (a_r b_d + a_d b_r)``."""
    ar, ad = dq_parts(a)
    br, bd = dq_parts(b)
    return B.concat(quat_multiply(ar, br), quat_multiply(ar, bd) + quat_multiply(ad, br))


def dq_conjugate(dq: Array) -> Array:
    """Quaternion conjugate of both parts, ``Q_r* + eps Q_d*``: the inverse of a unit dual quaternion."""
    real, dual = dq_parts(dq)
    return B.concat(quat_conjugate(real), quat_conjugate(dual))


def dq_dual_number_conjugate(dq: Array) -> Array:
    """Dual-number conjugate ``Q_r - eps Q_d``."""
    real, dual = dq_parts(dq)
    return B.concat(real, -dual)


def dq_combined_conjugate(dq: Array) -> Array:
    """Both conjugates at once, ``Q_r* - eps Q_d*`` (used to transform points)."""
    real, dual = dq_parts(dq)
    return B.concat(quat_conjugate(real), -quat_conjugate(dual))


def dq_norm_residual(dq: Array) -> tuple[Array, Array]:
    """How far ``dq`` is from unit: ``(|Q_r| - 1, Q_r . Q_d)``."""
    real, dual = dq_parts(dq)
    r = B.components(real, 4)
    d = B.components(dual, 4)
    return B.sqrt(B.sum_squares(r)) - 1.0, sum(ri * di for ri, di in zip(r, d))


def dq_transform_point(dq: Array, point: Array) -> Array:
    """Apply the rigid transform ``dq`` to a 3-D point."""
    real = dq_rotation(dq)
    rotated = quat_vector(quat_multiply(quat_multiply(real, quat_from_pure(point)), quat_conjugate(real)))
    return rotated + dq_translation(dq)


def _dexp_coefficients(a2: Array) -> tuple[Array, Array, Array]:
    """sinc(a), cos(a), and (cos a - sinc a)/a^2, each as a smooth function of a^2."""
    s = B.sinc_of_square(a2)
    c = B.cos_of_square(a2)
    small = a2 < B.SERIES_BAND**2
    safe = B.where(small, 1.0, a2)
    h = B.where(small, -1.0 / 3.0 + a2 / 30.0, (c - s) / safe)
    return s, c, h


def dq_exp(xi: Array) -> Array:
    """Exponential of the pure dual vector ``u + eps v`` given as 6 components ``(u, v)``.

    ``exp(u) + eps (-(u.v) sinc|u|, sinc|u| v + (u.v) h(|u|) u)`` with
    ``h(a) = (cos a - sinc a)/a^2``. For a pose of rotation angle ``phi`` about
    axis ``n`` and translation ``p`` with no rotation, ``u = phi/2 n`` and ``v = p/2``.
    """
    u, v = B.split(xi, 3, 6)
    ux, uy, uz = B.components(u, 3)
    vx, vy, vz = B.components(v, 3)
    a2 = B.sum_squares([ux, uy, uz])
    s, _, h = _dexp_coefficients(a2)
    uv = ux * vx + uy * vy + uz * vz
    dual = B.stack([-uv * s, s * vx + uv * h * ux, s * vy + uv * h * uy, s * vz + uv * h * uz])
    return B.concat(quat_exp(u), dual)


def dq_log(dq: Array) -> Array:
    """Logarithm ``(u, v)`` of a unit dual quaternion; inverse of :func:`dq_exp`.

    ``u = log Q_r`` and ``v = x / sinc a + (x.u) g(a) u - w sinc(a) u`` with
    ``(w, x) = Q_d``, ``a = |u|`` and ``g(a) = (cos a - a/sin a)/a^2``.
    Requires ``Q_r`` in the hemisphere ``w >= 0`` for a shortest screw.
    """
    real, dual = dq_parts(dq)
    u = quat_log(real)
    ux, uy, uz = B.components(u, 3)
    w, x, y, z = B.components(dual, 4)
    a2 = B.sum_squares([ux, uy, uz])
    s = B.sinc_of_square(a2)
    inv_s = B.inv_sinc_of_square(a2)
    c = B.cos_of_square(a2)
    small = a2 < B.SERIES_BAND**2
    safe = B.where(small, 1.0, a2)
    g = B.where(small, -2.0 / 3.0 + a2 / 45.0, (c - inv_s) / safe)
    xu = x * ux + y * uy + z * uz
    v = B.stack([x * inv_s + (xu * g - w * s) * ux, y * inv_s + (xu * g - w * s) * uy,
                 z * inv_s + (xu * g - w * s) * uz])
    return B.concat(u, v)


def dq_power(dq: Array, t: Array) -> Array:
    """``Q^t = exp(t log Q)``: the screw motion scaled by ``t`` (a scalar or one exponent per element)."""
    return dq_exp(B.scale(t, dq_log(dq), 6))


def _relative_shortest(a: Array, b: Array) -> Array:
    """``a* b``, sign-flipped into the hemisphere ``w >= 0`` (``Q`` and ``-Q`` are the same pose)."""
    rel = dq_multiply(dq_conjugate(a), b)
    return B.scale(B.where(B.components(rel, 8)[0] < 0, -1.0, 1.0), rel, 8)


def dq_sclerp(a: Array, b: Array, t: Array) -> Array:
    """Screw linear interpolation ``a (a* b)^t`` along the shorter screw."""
    return dq_multiply(a, dq_power(_relative_shortest(a, b), t))


def dq_pose_error(actual: Array, desired: Array) -> Array:
    """Pose error as the 6-vector ``log(actual* desired)``, zero iff the poses agree (either sign)."""
    return dq_log(_relative_shortest(actual, desired))
