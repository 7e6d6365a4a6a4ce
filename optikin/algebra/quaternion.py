"""Unit-quaternion algebra, written once for batched numpy arrays and CasADi symbols.

Quaternions are Hamilton quaternions ``(w, x, y, z)``. numpy inputs carry the
components on the last axis ``(..., 4)``; CasADi inputs carry them on the rows
``(4, 1)`` or ``(4, N)`` (see :mod:`optikin.algebra.backend`). A rotation of
angle ``a`` about the unit axis ``n`` is ``(cos(a/2), sin(a/2) n)``.

The logarithm follows Ude, Nemec, Petric & Morimoto (ICRA 2014), the form the
quaternion DMPs of Seleem et al. 2020 (seed 000, eqs. 17-23) are built on: for
``q = (cos a, sin a n)``, ``log q = a n`` (half the rotation angle along the axis)
and ``exp`` is its inverse. Both are exact and smooth at the identity.

Checked inputs (``docs/conventions.md``): with ``check=True`` (the default) the functions
that read a quaternion as a rotation, divide by a norm or take angles refuse numpy inputs
that are not numbers, of the wrong shape, non-finite, zero, not of unit norm (within
:data:`optikin.checks.UNIT_TOLERANCE`) or beyond :data:`optikin.checks.MAX_MAGNITUDE`,
raising :class:`ValueError` / :class:`TypeError` that name the argument; the algebraic
operations (product, conjugate, norm, parts) check types and shapes only. CasADi
matrices are never checked (they build expression graphs); inner loops pass ``check=False``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array
from optikin.checks import (
    MAX_MAGNITUDE,
    UNIT_TOLERANCE,
    check_finite,
    check_magnitude,
    check_numbers,
    check_quaternion,
    check_rotation_matrix,
    check_vectors,
)
from optikin.errors import InputDataError

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
"""The identity rotation ``(1, 0, 0, 0)``."""


def refuse_degenerate(q: Array, name: str = "q", unit: bool = True) -> Array:
    """Check numpy quaternions (:func:`optikin.checks.check_quaternion`); CasADi matrices pass unchecked.

    Parameters
    ----------
    q : Array
        Quaternions ``(..., 4)``.
    name : str
        The argument's name, for the message.
    unit : bool
        Require ``| |q| - 1 | <=`` :data:`~optikin.checks.UNIT_TOLERANCE`; else only a finite nonzero ``q``.

    Returns
    -------
    Array
        ``q`` (as floats when numpy).

    Raises
    ------
    TypeError
        For numpy input that is not numbers.
    ValueError
        For a wrong shape, a non-finite component, a zero quaternion or (``unit``) a norm off 1,
        naming ``name`` and the batch index.
    """
    return q if B.is_casadi(q) else check_quaternion(q, unit=unit, name=name)


def _checked_scalars(value: Array, name: str, limit: float = MAX_MAGNITUDE, unit: str = "rad") -> Array:
    """``value`` checked as finite numbers within ``+-limit`` (numpy), or unchanged (CasADi)."""
    if B.is_casadi(value):
        return value
    return check_magnitude(check_finite(check_numbers(value, name), name), name, limit, unit)


def quat_multiply(p: Array, q: Array) -> Array:
    """Hamilton product ``p q``.

    Parameters
    ----------
    p, q : Array
        Quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` (batch shapes broadcast) or CasADi ``4 x N``.

    Returns
    -------
    Array
        ``p q`` in the same layout; for rotations, ``q`` applied first, then ``p`` (``R(p q) = R(p) R(q)``).
    """
    pw, px, py, pz = B.components(p, 4, "p")
    qw, qx, qy, qz = B.components(q, 4, "q")
    return B.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def quat_conjugate(q: Array) -> Array:
    """Conjugate ``q* = (w, -x, -y, -z)``; the inverse of a unit quaternion.

    Parameters
    ----------
    q : Array
        Quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    Returns
    -------
    Array
        ``q*``, same layout.
    """
    w, x, y, z = B.components(q, 4, "q")
    return B.stack([w, -x, -y, -z])


def quat_norm(q: Array) -> Array:
    """Euclidean norm ``|q|``.

    Parameters
    ----------
    q : Array
        Quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    Returns
    -------
    Array
        numpy ``(...)`` or CasADi ``1 x N``.
    """
    return B.sqrt(B.sum_squares(B.components(q, 4, "q")))


def quat_normalize(q: Array, check: bool = True) -> Array:
    """``q / |q|``.

    Parameters
    ----------
    q : Array
        Nonzero quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    check : bool
        Refuse a numpy ``q`` that is not finite or is zero (:func:`refuse_degenerate`); False in inner loops.

    Returns
    -------
    Array
        Unit quaternions, same layout.

    Raises
    ------
    ValueError
        With ``check``, for a non-finite or zero quaternion, naming ``q``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=False)
    w, x, y, z = B.components(q, 4)
    n = quat_norm(q)
    return B.stack([w / n, x / n, y / n, z / n])


def quat_inverse(q: Array, check: bool = True) -> Array:
    """Inverse ``q^-1 = q* / |q|^2`` (the conjugate for a unit quaternion).

    Parameters
    ----------
    q : Array
        Nonzero quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    check : bool
        Refuse a numpy ``q`` that is not finite or is zero (:func:`refuse_degenerate`); False in inner loops.

    Returns
    -------
    Array
        ``q^-1``, same layout.

    Raises
    ------
    ValueError
        With ``check``, for a non-finite or zero quaternion, naming ``q``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=False)
    w, x, y, z = B.components(q, 4)
    n2 = B.sum_squares([w, x, y, z])
    return B.stack([w / n2, -x / n2, -y / n2, -z / n2])


def quat_from_pure(v: Array) -> Array:
    """The pure quaternion ``(0, v)`` of a 3-vector.

    Parameters
    ----------
    v : Array
        Vectors: numpy ``(..., 3)`` or CasADi ``3 x N``.

    Returns
    -------
    Array
        numpy ``(..., 4)`` or CasADi ``4 x N``.
    """
    x, y, z = B.components(v, 3, "v")
    return B.stack([0.0 * x, x, y, z])


def quat_vector(q: Array) -> Array:
    """The vector part ``(x, y, z)`` of a quaternion.

    Parameters
    ----------
    q : Array
        Quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    Returns
    -------
    Array
        numpy ``(..., 3)`` or CasADi ``3 x N``.
    """
    return B.split(q, 1, 4, "q")[1]


def quat_exp(v: Array, check: bool = True) -> Array:
    """Exponential ``exp(v) = (cos|v|, sin|v| v/|v|)`` of a 3-vector, exact and smooth at ``v = 0``.

    Ude et al. 2014; the update ``exp(eta dt / 2 tau) Q`` of seed 000 eq. (23).
    ``exp(a/2 n)`` is the rotation by ``a`` about the unit axis ``n``.

    Parameters
    ----------
    v : Array
        Vectors (half rotation vectors, rad): numpy ``(..., 3)`` or CasADi ``3 x N``.
    check : bool
        Refuse a numpy ``v`` with a non-finite component or one beyond :data:`~optikin.checks.MAX_MAGNITUDE`
        rad; False in inner loops.

    Returns
    -------
    Array
        Unit quaternions, numpy ``(..., 4)`` or CasADi ``4 x N``.

    Raises
    ------
    ValueError
        With ``check``, for a wrong shape, a non-finite or implausibly large component, naming ``v``.
    """
    if check and not B.is_casadi(v):
        v = check_magnitude(check_vectors(v, "v"), "v", MAX_MAGNITUDE, "rad")
    x, y, z = B.components(v, 3, "v")
    a2 = B.sum_squares([x, y, z])
    s = B.sinc_of_square(a2)
    return B.stack([B.cos_of_square(a2), s * x, s * y, s * z])


def quat_log(q: Array, check: bool = True) -> Array:
    """Logarithm ``log q = a n`` of a unit ``q = (cos a, sin a n)``, with ``a`` in ``[0, pi]``.

    Ude et al. 2014; the gap ``2 log(Q_g conj(Q))`` of seed 000 eq. (19) is the rotation
    vector from ``Q`` to ``Q_g``. Exact and smooth at the identity. At ``q = -1`` (a full
    turn) the axis is undefined: the result is ``(pi, 0, 0)``. Keep sequences in one
    hemisphere (:func:`quat_hemisphere_continuous`) to stay away from it.

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion (:func:`refuse_degenerate`); False in inner loops.

    Returns
    -------
    Array
        Half rotation vectors [rad], numpy ``(..., 3)`` or CasADi ``3 x N``; inverse of :func:`quat_exp`.

    Raises
    ------
    ValueError
        With ``check``, for a non-finite, zero or non-unit quaternion, naming ``q``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=True)
    w, x, y, z = B.components(q, 4)
    s2 = B.sum_squares([x, y, z])
    # atan2(s, w) / s with s = |(x, y, z)|; near the identity, its series in s^2.
    small = (s2 < B.SERIES_BAND**2) * (w > 0)
    full_turn = (s2 == 0) * (w < 0)
    s = B.sqrt(B.where(small + full_turn, 1.0, s2))
    w_safe = B.where(small, w, 1.0)
    t2 = s2 / (w_safe * w_safe)
    series = (1.0 - t2 / 3.0 + t2 * t2 / 5.0) / w_safe
    ratio = B.where(small, series, B.atan2(s, w) / s)
    return B.stack([ratio * x + B.where(full_turn, np.pi, 0.0), ratio * y, ratio * z])


def quat_angle(q: Array, check: bool = True) -> Array:
    """Rotation angle of a unit quaternion, either sign (``q`` and ``-q`` give the same).

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion (:func:`refuse_degenerate`); False in inner loops.

    Returns
    -------
    Array
        Angles in ``[0, pi]`` [rad], numpy ``(...)`` or CasADi ``1 x N``.

    Raises
    ------
    ValueError
        With ``check``, for a non-finite, zero or non-unit quaternion, naming ``q``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=True)
    w, x, y, z = B.components(q, 4, "q")
    return 2.0 * B.atan2(B.sqrt(B.sum_squares([x, y, z])), B.fabs(w))


def quat_power(q: Array, t: Array, check: bool = True) -> Array:
    """Power ``q^t = exp(t log q)`` of a unit quaternion: the rotation scaled by ``t``.

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    t : Array
        A scalar, or one exponent per quaternion (numpy ``(...)``, CasADi ``1 x N``).
    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion and a ``t`` that is not a finite number
        within :data:`~optikin.checks.MAX_MAGNITUDE`; False in inner loops.

    Returns
    -------
    Array
        Unit quaternions, same layout as ``q``.

    Raises
    ------
    ValueError
        With ``check``, naming ``q`` or ``t``.
    """
    if check:
        q, t = refuse_degenerate(q, "q", unit=True), _checked_scalars(t, "t", unit="")
    return quat_exp(B.scale(t, quat_log(q, check=False), 3), check=False)


def quat_from_axis_angle(axis: Array, angle: Array, check: bool = True) -> Array:
    """Rotation by ``angle`` about the unit vector ``axis``: ``(cos(angle/2), sin(angle/2) axis)``.

    Parameters
    ----------
    axis : Array
        Unit vectors: numpy ``(..., 3)`` or CasADi ``3 x N``.
    angle : Array
        Angles [rad], broadcast against the batch shape of ``axis`` (CasADi: a scalar or ``1 x N``).
    check : bool
        Refuse a numpy ``axis`` that is not a finite unit vector (within :data:`~optikin.checks.UNIT_TOLERANCE`)
        and a numpy ``angle`` that is not finite or beyond :data:`~optikin.checks.MAX_MAGNITUDE`; False in
        inner loops.

    Returns
    -------
    Array
        Unit quaternions, numpy ``(..., 4)`` or CasADi ``4 x N``.

    Raises
    ------
    ValueError
        With ``check``, for a zero, non-unit or non-finite axis or a bad angle, naming ``axis`` or ``angle``.
    """
    if check:
        axis = axis if B.is_casadi(axis) else check_vectors(axis, "axis", unit=True)
        angle = _checked_scalars(angle, "angle")
    x, y, z = B.components(axis, 3, "axis")
    h = 0.5 * angle
    s = B.sin(h)
    return B.stack([B.cos(h), s * x, s * y, s * z])


def quat_rotate(q: Array, v: Array, check: bool = True) -> Array:
    """Rotate 3-vectors by unit quaternions: ``vec(q (0, v) q*) = R(q) v``.

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    v : Array
        Vectors: numpy ``(..., 3)`` or CasADi ``3 x N`` (batch shapes broadcast).

    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion (:func:`refuse_degenerate`) and a numpy ``v``
        that is not finite; False in inner loops.

    Returns
    -------
    Array
        The rotated vectors, numpy ``(..., 3)`` or CasADi ``3 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``q`` or ``v``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=True)
        v = v if B.is_casadi(v) else check_vectors(v, "v")
    return quat_vector(quat_multiply(quat_multiply(q, quat_from_pure(v)), quat_conjugate(q)))


def matrix_from_quat(q: Array, check: bool = True) -> Array:
    """Rotation matrix ``R(q)`` of a unit quaternion (seed 000 eq. 6, derived again: its diagonal is garbled).

    ``R(q) v = vec(q (0, v) q*)``: it maps vectors of the rotated frame to the reference frame.

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)``, or one CasADi ``4 x 1``.

    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion (:func:`refuse_degenerate`); False in inner loops.

    Returns
    -------
    Array
        numpy ``(..., 3, 3)`` or CasADi ``3 x 3``.

    Raises
    ------
    ValueError
        For a CasADi input with more than one column; with ``check``, for a numpy ``q`` that is not a
        finite unit quaternion.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=True)
    w, x, y, z = B.components(q, 4, "q")
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    if B.is_casadi(q):
        if q.shape[1] != 1:
            raise ValueError("matrix_from_quat takes one CasADi quaternion (4x1) at a time")
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def quat_from_matrix(R: Array, check: bool = True) -> Array:
    """Unit quaternion (``w >= 0``) of a rotation matrix, by Shepperd's method (Shepperd 1978).

    Of the four algebraically equal formulas, the one with the largest pivot is
    used, so the result is accurate for every rotation; inverse of :func:`matrix_from_quat`.

    Parameters
    ----------
    R : Array
        Rotation matrices: numpy ``(..., 3, 3)`` or one CasADi ``3 x 3``.
    check : bool
        Refuse a numpy ``R`` that is not finite, not orthonormal (within :data:`~optikin.checks.UNIT_TOLERANCE`)
        or a reflection (:func:`optikin.checks.check_rotation_matrix`); False in inner loops.

    Returns
    -------
    Array
        numpy ``(..., 4)`` or CasADi ``4 x 1``.

    Raises
    ------
    ValueError
        When the matrices are not 3 x 3; with ``check``, when a numpy matrix is not a rotation, naming ``R``.
    """
    if B.is_casadi(R):
        if R.shape != (3, 3):
            raise ValueError(f"quat_from_matrix takes a 3x3 CasADi matrix, got {R.shape}")
        m = [[R[i, j] for j in range(3)] for i in range(3)]
    else:
        R = check_rotation_matrix(R, "R") if check else np.asarray(R, dtype=float)
        if R.shape[-2:] != (3, 3):
            raise ValueError(f"R: expected rotation matrices of shape (..., 3, 3), got {R.shape}")
        m = [[R[..., i, j] for j in range(3)] for i in range(3)]
    trace = m[0][0] + m[1][1] + m[2][2]
    pivots = [
        1 + trace,
        1 + m[0][0] - m[1][1] - m[2][2],
        1 - m[0][0] + m[1][1] - m[2][2],
        1 - m[0][0] - m[1][1] + m[2][2],
    ]
    candidates = []
    for k, pivot in enumerate(pivots):
        r = B.sqrt(B.fmax(pivot, 1e-300))
        inv = 0.5 / r
        if k == 0:
            c = [0.5 * r, (m[2][1] - m[1][2]) * inv, (m[0][2] - m[2][0]) * inv, (m[1][0] - m[0][1]) * inv]
        elif k == 1:
            c = [(m[2][1] - m[1][2]) * inv, 0.5 * r, (m[0][1] + m[1][0]) * inv, (m[0][2] + m[2][0]) * inv]
        elif k == 2:
            c = [(m[0][2] - m[2][0]) * inv, (m[0][1] + m[1][0]) * inv, 0.5 * r, (m[1][2] + m[2][1]) * inv]
        else:
            c = [(m[1][0] - m[0][1]) * inv, (m[0][2] + m[2][0]) * inv, (m[1][2] + m[2][1]) * inv, 0.5 * r]
        candidates.append(c)
    # Select the candidate of the largest pivot, component by component.
    best, best_pivot = candidates[0], pivots[0]
    for c, pivot in zip(candidates[1:], pivots[1:]):
        take = pivot > best_pivot
        best = [B.where(take, ci, bi) for ci, bi in zip(c, best)]
        best_pivot = B.fmax(pivot, best_pivot)
    sign = B.where(best[0] < 0, -1.0, 1.0)
    return B.stack([sign * c for c in best])


def quat_from_rpy(roll: Array, pitch: Array, yaw: Array, check: bool = True) -> Array:
    """Quaternion of ``R = Rz(yaw) Ry(pitch) Rx(roll)``, the convention of seed 000 eq. (30).

    Parameters
    ----------
    roll, pitch, yaw : Array
        Angles [rad] about x, y and z: numpy arrays (broadcast together) or CasADi rows ``1 x N``.
    check : bool
        Refuse numpy angles that are not finite or beyond :data:`~optikin.checks.MAX_MAGNITUDE`; False in
        inner loops.

    Returns
    -------
    Array
        Unit quaternions, numpy ``(..., 4)`` or CasADi ``4 x N``; inverse of :func:`rpy_from_quat`.

    Raises
    ------
    ValueError
        With ``check``, naming ``roll``, ``pitch`` or ``yaw``.
    """
    if check:
        roll, pitch, yaw = (_checked_scalars(a, n) for a, n in ((roll, "roll"), (pitch, "pitch"), (yaw, "yaw")))
    cr, sr = B.cos(0.5 * roll), B.sin(0.5 * roll)
    cp, sp = B.cos(0.5 * pitch), B.sin(0.5 * pitch)
    cy, sy = B.cos(0.5 * yaw), B.sin(0.5 * yaw)
    return B.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


def rpy_from_quat(q: Array, check: bool = True) -> Array:
    """Roll, pitch, yaw of a unit quaternion, seed 000 eq. (30) (its printed denominators are garbled).

    ``roll = atan2(2(w x + y z), 1 - 2(x^2 + y^2))``,
    ``pitch = asin(2(w y - x z))`` (argument clipped to [-1, 1]),
    ``yaw = atan2(2(w z + x y), 1 - 2(y^2 + z^2))``, so that
    ``R = Rz(yaw) Ry(pitch) Rx(roll)``. At pitch = +-90 degrees (gimbal lock) roll
    and yaw are not unique.

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.

    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion (:func:`refuse_degenerate`); False in inner loops.

    Returns
    -------
    Array
        ``(roll, pitch, yaw)`` [rad], numpy ``(..., 3)`` or CasADi ``3 x N``.

    Raises
    ------
    ValueError
        With ``check``, naming ``q``.
    """
    if check:
        q = refuse_degenerate(q, "q", unit=True)
    w, x, y, z = B.components(q, 4, "q")
    roll = B.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    sin_pitch = B.clip(2 * (w * y - x * z), -1.0, 1.0)
    pitch = ca.asin(sin_pitch) if B.is_casadi(sin_pitch) else np.arcsin(sin_pitch)
    yaw = B.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return B.stack([roll, pitch, yaw])


def check_unit_quaternions(q: np.ndarray, source: str = "quaternions", tolerance: float = UNIT_TOLERANCE) -> np.ndarray:
    """Check that ``q`` holds unit quaternions; raise naming the first sample that is not one.

    Rejects a wrong shape, NaN or infinite components, and ``| |q| - 1 | > tolerance``
    (sensor quaternions are unit only to a few decimals; normalise them before use).

    Parameters
    ----------
    q : numpy.ndarray
        Quaternions ``(w, x, y, z)``, shape ``(..., 4)``; the first axis is the sample.
    source : str
        Where the data came from, for the error message.
    tolerance : float
        Largest accepted ``| |q| - 1 |``.

    Returns
    -------
    numpy.ndarray
        ``q`` as a float array ``(..., 4)``.

    Raises
    ------
    optikin.errors.InputDataError
        Naming ``source``, the sample and (for ``q.ndim > 2``) the quaternion's index.
    """
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != 4:
        raise InputDataError(f"expected quaternions of shape (..., 4) as (w, x, y, z), got {q.shape}", source=source)
    flat = q.reshape(-1, 4)
    bad = ~np.isfinite(flat).all(axis=1)
    norm_error = np.abs(np.linalg.norm(flat, axis=1) - 1.0)
    bad |= norm_error > tolerance
    if bad.any():
        i = int(np.argmax(bad))
        index = np.unravel_index(i, q.shape[:-1]) if q.ndim > 1 else (0,)
        rest = ", ".join(str(int(j)) for j in index[1:])
        raise InputDataError(
            f"{flat[i].tolist()} is not a unit quaternion (| |q| - 1 | = {norm_error[i]:.3g}, tolerance {tolerance:g})",
            source=source,
            sample=int(index[0]),
            field=f"quaternion [{rest}]" if rest else "",
        )
    return q


def quat_hemisphere_continuous(qs: np.ndarray, check: bool = True) -> np.ndarray:
    """Flip signs along a sequence so consecutive quaternions have a non-negative dot product.

    ``q`` and ``-q`` are the same rotation; a continuous sequence keeps logarithms and
    interpolation away from the full-turn branch of :func:`quat_log`.

    Parameters
    ----------
    qs : numpy.ndarray
        Quaternions ``(T, 4)`` ``(w, x, y, z)``, in time order.
    check : bool
        Refuse rows that are not finite unit quaternions (:func:`optikin.checks.check_quaternion`); False in
        inner loops.

    Returns
    -------
    numpy.ndarray
        A copy ``(T, 4)`` with the first quaternion unchanged.

    Raises
    ------
    ValueError
        When ``qs`` is not ``(T, 4)``; with ``check``, for a row that is not a finite unit quaternion, naming
        ``qs[i]``.
    """
    qs = np.array(check_numbers(qs, "qs"), dtype=float)
    if qs.ndim != 2 or qs.shape[1] != 4:
        raise ValueError(f"qs: expected a sequence of shape (T, 4), got {qs.shape}")
    if check:
        check_quaternion(qs, unit=True, name="qs")
    dots = np.einsum("ij,ij->i", qs[1:], qs[:-1])
    flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
    return qs * flips[:, None]


def quat_slerp(q0: Array, q1: Array, t: Array, check: bool = True) -> Array:
    """Spherical linear interpolation along the shorter arc: ``q0 (q0* q1)^t``.

    Parameters
    ----------
    q0, q1 : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    t : Array
        Interpolation parameter (``0 -> q0``, ``1 -> +-q1``): a scalar or one per element.
    check : bool
        Refuse numpy ``q0``, ``q1`` that are not finite unit quaternions and a ``t`` that is not a finite number
        within :data:`~optikin.checks.MAX_MAGNITUDE`; False in inner loops.

    Returns
    -------
    Array
        Unit quaternions, same layout.

    Raises
    ------
    ValueError
        With ``check``, naming ``q0``, ``q1`` or ``t``.
    """
    if check:
        q0, q1 = refuse_degenerate(q0, "q0", unit=True), refuse_degenerate(q1, "q1", unit=True)
        t = _checked_scalars(t, "t", unit="")
    rel = quat_multiply(quat_conjugate(q0), q1)
    sign = B.where(B.components(rel, 4)[0] < 0, -1.0, 1.0)
    return quat_multiply(q0, quat_power(B.scale(sign, rel, 4), t, check=False))
