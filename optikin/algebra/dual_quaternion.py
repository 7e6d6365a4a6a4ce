"""Unit dual quaternions ``Q = Q_r + eps Q_d`` for rigid transforms (Seleem et al. 2020, seed 000 eqs. 9-10).

A dual quaternion is stored as 8 components ``(Q_r, Q_d)``: on the last axis
``(..., 8)`` for numpy, on the rows ``(8, 1)``/``(8, N)`` for CasADi. A pose with
rotation ``Q_r`` and translation ``p`` (metres) has ``Q_d = 0.5 (0, p) Q_r``
(seed 000 eq. 10): the point map ``x -> R(Q_r) x + p``.

The logarithm and exponential are the true ones of the dual-number algebra
(so ``Q^t = exp(t log Q)`` is the screw motion used by ScLERP). For a pure dual
vector ``u + eps v``, ``exp(u + eps v) = exp(u) + eps Dexp(u)[v]``, the
directional derivative of the quaternion exponential; ``log`` inverts it. Both
are exact at the identity and for pure translations.

Checked inputs (``docs/conventions.md``): with ``check=True`` (the default) the functions that
read a dual quaternion as a pose refuse numpy inputs that are not finite or whose real part
is not of unit norm (within :data:`optikin.checks.UNIT_TOLERANCE`); those that need a screw
(``dq_log``, ``dq_power``, ``dq_sclerp``, ``dq_pose_error``) also a dual part orthogonal to
it. The algebraic operations (product, conjugates, parts) check types and shapes only;
CasADi matrices are never checked; inner loops pass ``check=False``.
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
    refuse_degenerate,
)
from optikin.checks import (
    MAX_MAGNITUDE,
    UNIT_TOLERANCE,
    check_dual_quaternion,
    check_finite,
    check_magnitude,
    check_numbers,
    check_rotation_matrix,
    check_shape,
    check_vectors,
)

IDENTITY = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])
"""The identity pose ``(1, 0, 0, 0, 0, 0, 0, 0)``."""


def dq_parts(dq: Array) -> tuple[Array, Array]:
    """The real and dual parts ``(Q_r, Q_d)`` of a dual quaternion.

    Parameters
    ----------
    dq : Array
        Dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.

    Returns
    -------
    tuple of Array
        ``(Q_r, Q_d)``, each numpy ``(..., 4)`` or CasADi ``4 x N``.
    """
    return B.split(dq, 4, 8, "dq")


def dq_from_parts(real: Array, dual: Array) -> Array:
    """The dual quaternion ``real + eps dual``; inverse of :func:`dq_parts`.

    Parameters
    ----------
    real, dual : Array
        Quaternions ``Q_r``, ``Q_d``: numpy ``(..., 4)`` (batch shapes broadcast) or CasADi ``4 x N``.

    Returns
    -------
    Array
        numpy ``(..., 8)`` or CasADi ``8 x N``.
    """
    return B.concat(real, dual)


def dq_from_rotation_translation(q: Array, p: Array, check: bool = True) -> Array:
    """Pose ``Q_r + eps 0.5 (0, p) Q_r`` from a rotation and a translation (seed 000 eqs. 9-10).

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)`` of the rotation: numpy ``(..., 4)`` or CasADi ``4 x N``.
    p : Array
        Translations [m]: numpy ``(..., 3)`` or CasADi ``3 x N`` (batch shapes broadcast).
    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion
        (:func:`~optikin.algebra.quaternion.refuse_degenerate`) and a numpy ``p`` that is not finite or beyond
        :data:`~optikin.checks.MAX_MAGNITUDE` m; False in inner loops.

    Returns
    -------
    Array
        Unit dual quaternions ``(Q_r, Q_d)``, numpy ``(..., 8)`` or CasADi ``8 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``q`` or ``p``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=True)
        p = p if B.is_casadi(p) else check_magnitude(check_vectors(p, "p"), "p", MAX_MAGNITUDE, "m")
    return B.concat(q, 0.5 * quat_multiply(quat_from_pure(p), q))


def _pose(dq: Array, name: str = "dq", screw: bool = False) -> Array:
    """``dq`` checked as unit dual quaternions (numpy; a dual part orthogonal to the real part for a ``screw``),
    or unchanged (CasADi)."""
    return dq if B.is_casadi(dq) else check_dual_quaternion(dq, unit=True, name=name, orthogonal=screw)


def dq_rotation(dq: Array) -> Array:
    """The rotation ``Q_r`` of a unit dual quaternion.

    Parameters
    ----------
    dq : Array
        Dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.

    Returns
    -------
    Array
        Unit quaternions, numpy ``(..., 4)`` or CasADi ``4 x N``.
    """
    return dq_parts(dq)[0]


def dq_translation(dq: Array, check: bool = True) -> Array:
    """The translation ``p = 2 vec(Q_d Q_r*)`` of a unit dual quaternion (seed 000 eq. 10 inverted).

    Parameters
    ----------
    dq : Array
        Unit dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.
    check : bool
        Refuse a numpy ``dq`` that is not finite or whose real part is not of unit norm; False in inner loops.

    Returns
    -------
    Array
        Translations [m], numpy ``(..., 3)`` or CasADi ``3 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``dq`` and the batch index.
    """
    if check:
        dq = _pose(dq)
    real, dual = dq_parts(dq)
    return quat_vector(2.0 * quat_multiply(dual, quat_conjugate(real)))


def dq_from_transform(T: Array, check: bool = True) -> Array:
    """Unit dual quaternion of a homogeneous transform ``[R, p; 0, 1]``.

    Parameters
    ----------
    T : Array
        Transforms (translation in metres): numpy ``(..., 4, 4)`` or one CasADi ``4 x 4``.
    check : bool
        Refuse a numpy ``T`` that is not finite, whose ``R`` is not a rotation
        (:func:`optikin.checks.check_rotation_matrix`), whose last row is not ``(0, 0, 0, 1)`` or whose
        translation is beyond :data:`~optikin.checks.MAX_MAGNITUDE` m; False in inner loops.

    Returns
    -------
    Array
        numpy ``(..., 8)`` or CasADi ``8 x 1``, with ``w >= 0`` in ``Q_r``.

    Raises
    ------
    ValueError
        For a numpy ``T`` that is not ``(..., 4, 4)``; with ``check``, naming ``T``.
    """
    if B.is_casadi(T):
        return dq_from_rotation_translation(quat_from_matrix(T[:3, :3]), T[:3, 3])
    T = check_shape(check_numbers(T, "T"), "T", (4, 4), "homogeneous transforms")
    if check:
        check_rotation_matrix(check_finite(T, "T")[..., :3, :3], "T[..., :3, :3]")
        if np.abs(T[..., 3, :] - [0.0, 0.0, 0.0, 1.0]).max() > UNIT_TOLERANCE:
            raise ValueError("T: the last row of a homogeneous transform must be (0, 0, 0, 1)")
        check_magnitude(T[..., :3, 3], "T[..., :3, 3]", MAX_MAGNITUDE, "m")
    return dq_from_rotation_translation(quat_from_matrix(T[..., :3, :3], check=False), T[..., :3, 3], check=False)


def transform_from_dq(dq: Array, check: bool = True) -> Array:
    """Homogeneous transform ``[R(Q_r), p; 0, 1]`` of a unit dual quaternion; inverse of :func:`dq_from_transform`.

    Parameters
    ----------
    dq : Array
        Unit dual quaternions: numpy ``(..., 8)`` or one CasADi ``8 x 1``.
    check : bool
        Refuse a numpy ``dq`` that is not finite or whose real part is not of unit norm; False in inner loops.

    Returns
    -------
    Array
        numpy ``(..., 4, 4)`` or CasADi ``4 x 4`` (translation in metres).

    Raises
    ------
    ValueError
        With ``check``, naming ``dq``.
    """
    if check:
        dq = _pose(dq)
    R = matrix_from_quat(dq_rotation(dq), check=False)
    p = dq_translation(dq, check=False)
    if B.is_casadi(dq):
        return ca.vertcat(ca.horzcat(R, p), ca.DM([[0, 0, 0, 1]]))
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def dq_multiply(a: Array, b: Array) -> Array:
    """Product ``(a_r + eps a_d)(b_r + eps b_d) = a_r b_r + eps (a_r b_d + a_d b_r)``.

    For poses, the composition: ``b`` expressed in the frame ``a`` (``T(a b) = T(a) T(b)``).

    Parameters
    ----------
    a, b : Array
        Dual quaternions: numpy ``(..., 8)`` (batch shapes broadcast) or CasADi ``8 x N``.

    Returns
    -------
    Array
        ``a b`` in the same layout.
    """
    ar, ad = B.split(a, 4, 8, "a")
    br, bd = B.split(b, 4, 8, "b")
    return B.concat(quat_multiply(ar, br), quat_multiply(ar, bd) + quat_multiply(ad, br))


def dq_conjugate(dq: Array) -> Array:
    """Quaternion conjugate of both parts, ``Q_r* + eps Q_d*``: the inverse of a unit dual quaternion.

    Parameters
    ----------
    dq : Array
        Dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.

    Returns
    -------
    Array
        Same layout.
    """
    real, dual = dq_parts(dq)
    return B.concat(quat_conjugate(real), quat_conjugate(dual))


def dq_dual_number_conjugate(dq: Array) -> Array:
    """Dual-number conjugate ``Q_r - eps Q_d``.

    Parameters
    ----------
    dq : Array
        Dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.

    Returns
    -------
    Array
        Same layout.
    """
    real, dual = dq_parts(dq)
    return B.concat(real, -dual)


def dq_combined_conjugate(dq: Array) -> Array:
    """Both conjugates at once, ``Q_r* - eps Q_d*`` (the form that transforms points).

    Parameters
    ----------
    dq : Array
        Dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.

    Returns
    -------
    Array
        Same layout.
    """
    real, dual = dq_parts(dq)
    return B.concat(quat_conjugate(real), -quat_conjugate(dual))


def dq_norm_residual(dq: Array) -> tuple[Array, Array]:
    """How far ``dq`` is from a unit dual quaternion: ``(|Q_r| - 1, Q_r . Q_d)``, both zero when unit.

    Parameters
    ----------
    dq : Array
        Dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.

    Returns
    -------
    tuple of Array
        The two residuals, each numpy ``(...)`` or CasADi ``1 x N``.
    """
    real, dual = dq_parts(dq)
    r = B.components(real, 4)
    d = B.components(dual, 4)
    return B.sqrt(B.sum_squares(r)) - 1.0, sum(ri * di for ri, di in zip(r, d))


def dq_transform_point(dq: Array, point: Array, check: bool = True) -> Array:
    """Apply the rigid transform of ``dq`` to points: ``R(Q_r) x + p``.

    Parameters
    ----------
    dq : Array
        Unit dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.
    point : Array
        Points [m]: numpy ``(..., 3)`` or CasADi ``3 x N`` (batch shapes broadcast).
    check : bool
        Refuse a numpy ``dq`` that is not finite or whose real part is not of unit norm, and numpy points that
        are not finite; False in inner loops.

    Returns
    -------
    Array
        The transformed points [m], numpy ``(..., 3)`` or CasADi ``3 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``dq`` or ``point``.
    """
    if check:
        dq = _pose(dq)
        point = point if B.is_casadi(point) else check_vectors(point, "point")
    real = dq_rotation(dq)
    rotated = quat_vector(quat_multiply(quat_multiply(real, quat_from_pure(point)), quat_conjugate(real)))
    return rotated + dq_translation(dq, check=False)


def _dexp_coefficients(a2: Array) -> tuple[Array, Array, Array]:
    """sinc(a), cos(a), and (cos a - sinc a)/a^2, each as a smooth function of a^2."""
    s = B.sinc_of_square(a2)
    c = B.cos_of_square(a2)
    small = a2 < B.SERIES_BAND**2
    safe = B.where(small, 1.0, a2)
    h = B.where(small, -1.0 / 3.0 + a2 / 30.0, (c - s) / safe)
    return s, c, h


def dq_exp(xi: Array, check: bool = True) -> Array:
    """Exponential of the pure dual vector ``u + eps v``.

    ``exp(u + eps v) = exp(u) + eps (-(u.v) sinc|u|, sinc|u| v + (u.v) h(|u|) u)`` with
    ``h(a) = (cos a - sinc a)/a^2``: the dual part is the directional derivative of
    :func:`~optikin.algebra.quaternion.quat_exp` at ``u`` along ``v``. A rotation by
    ``phi`` about the axis ``n`` has ``u = phi/2 n``; a pure translation ``p`` has
    ``u = 0``, ``v = p/2``. Exact and smooth at ``u = 0``.

    Parameters
    ----------
    xi : Array
        ``(u, v)``: numpy ``(..., 6)`` or CasADi ``6 x N``.
    check : bool
        Refuse a numpy ``xi`` with a non-finite component or one beyond :data:`~optikin.checks.MAX_MAGNITUDE`;
        False in inner loops.

    Returns
    -------
    Array
        Unit dual quaternions, numpy ``(..., 8)`` or CasADi ``8 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``xi``.
    """
    if check and not B.is_casadi(xi):
        xi = check_magnitude(check_vectors(xi, "xi", width=6), "xi", MAX_MAGNITUDE)
    u, v = B.split(xi, 3, 6, "xi")
    ux, uy, uz = B.components(u, 3)
    vx, vy, vz = B.components(v, 3)
    a2 = B.sum_squares([ux, uy, uz])
    s, _, h = _dexp_coefficients(a2)
    uv = ux * vx + uy * vy + uz * vz
    dual = B.stack([-uv * s, s * vx + uv * h * ux, s * vy + uv * h * uy, s * vz + uv * h * uz])
    return B.concat(quat_exp(u, check=False), dual)


def dq_log(dq: Array, check: bool = True) -> Array:
    """Logarithm ``(u, v)`` of a unit dual quaternion; inverse of :func:`dq_exp`.

    ``u = log Q_r`` and ``v = x / sinc a + (x.u) g(a) u - w sinc(a) u`` with
    ``(w, x) = Q_d``, ``a = |u|`` and ``g(a) = (cos a - a/sin a)/a^2``.
    ``Q_r`` must be in the hemisphere ``w >= 0`` for the shortest screw.

    Parameters
    ----------
    dq : Array
        Unit dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.
    check : bool
        Refuse a numpy ``dq`` that is not a finite unit dual quaternion (unit real part, dual part orthogonal
        to it, :func:`optikin.checks.check_dual_quaternion`); False in inner loops.

    Returns
    -------
    Array
        ``(u, v)``: numpy ``(..., 6)`` or CasADi ``6 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``dq`` and the batch index.
    """
    if check:
        dq = _pose(dq, screw=True)
    real, dual = dq_parts(dq)
    u = quat_log(real, check=False)
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
    v = B.stack(
        [x * inv_s + (xu * g - w * s) * ux, y * inv_s + (xu * g - w * s) * uy, z * inv_s + (xu * g - w * s) * uz]
    )
    return B.concat(u, v)


def dq_power(dq: Array, t: Array, check: bool = True) -> Array:
    """Power ``Q^t = exp(t log Q)``: the screw motion of ``Q`` scaled by ``t``.

    Parameters
    ----------
    dq : Array
        Unit dual quaternions (``w >= 0`` in ``Q_r``): numpy ``(..., 8)`` or CasADi ``8 x N``.
    t : Array
        A scalar, or one exponent per element (numpy ``(...)``, CasADi ``1 x N``).
    check : bool
        Refuse a numpy ``dq`` that is not a finite unit dual quaternion and a ``t`` that is not a finite number
        within :data:`~optikin.checks.MAX_MAGNITUDE`; False in inner loops.

    Returns
    -------
    Array
        Unit dual quaternions, same layout.

    Raises
    ------
    ValueError
        With ``check``, naming ``dq`` or ``t``.
    """
    if check:
        dq, t = _pose(dq, screw=True), _exponent(t)
    return dq_exp(B.scale(t, dq_log(dq, check=False), 6), check=False)


def _relative_shortest(a: Array, b: Array) -> Array:
    """``a* b``, sign-flipped into the hemisphere ``w >= 0`` (``Q`` and ``-Q`` are the same pose)."""
    rel = dq_multiply(dq_conjugate(a), b)
    return B.scale(B.where(B.components(rel, 8)[0] < 0, -1.0, 1.0), rel, 8)


def _exponent(t: Array) -> Array:
    """``t`` checked as finite numbers within :data:`~optikin.checks.MAX_MAGNITUDE` (numpy), or unchanged."""
    if B.is_casadi(t):
        return t
    return check_magnitude(check_finite(check_numbers(t, "t"), "t"), "t")


def dq_sclerp(a: Array, b: Array, t: Array, check: bool = True) -> Array:
    """Screw linear interpolation (ScLERP) ``a (a* b)^t`` along the shorter screw.

    Parameters
    ----------
    a, b : Array
        Unit dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.
    t : Array
        Interpolation parameter (``0 -> a``, ``1 -> +-b``): a scalar or one per element.
    check : bool
        Refuse numpy ``a``, ``b`` that are not finite unit dual quaternions and a ``t`` that is not a finite
        number within :data:`~optikin.checks.MAX_MAGNITUDE`; False in inner loops.

    Returns
    -------
    Array
        Unit dual quaternions, same layout.

    Raises
    ------
    ValueError
        With ``check``, naming ``a``, ``b`` or ``t``.
    """
    if check:
        a, b, t = _pose(a, "a", screw=True), _pose(b, "b", screw=True), _exponent(t)
    return dq_multiply(a, dq_power(_relative_shortest(a, b), t, check=False))


def dq_pose_error(actual: Array, desired: Array, check: bool = True) -> Array:
    """Pose error as the 6-vector ``log(actual* desired)``, zero iff the poses agree (either sign).

    Parameters
    ----------
    actual, desired : Array
        Unit dual quaternions: numpy ``(..., 8)`` or CasADi ``8 x N``.
    check : bool
        Refuse numpy poses that are not finite unit dual quaternions; False in inner loops.

    Returns
    -------
    Array
        ``(u, v)`` of :func:`dq_log` (``u``: half rotation vector [rad]; ``v``: metres),
        numpy ``(..., 6)`` or CasADi ``6 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``actual`` or ``desired``.
    """
    if check:
        actual, desired = _pose(actual, "actual", screw=True), _pose(desired, "desired", screw=True)
    return dq_log(_relative_shortest(actual, desired), check=False)
