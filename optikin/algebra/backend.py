"""One set of elementary operations for numpy arrays and CasADi symbols.

The algebra in :mod:`optikin.algebra` is written once against this module, so
the same function evaluates a batch of numpy quaternions and builds a CasADi
expression graph for automatic differentiation.

Layout conventions
------------------
* numpy: the components run along the **last** axis, ``(..., n)``; any leading
  batch shape is allowed.
* CasADi (``SX``, ``MX``, ``DM``): the components run along the **rows**,
  ``(n, 1)`` for one element or ``(n, N)`` for ``N`` columns.

``components(x, n)`` splits an element into its ``n`` scalar components and
``stack(parts)`` rebuilds one. Every other helper dispatches on the type of its
arguments: CasADi if any argument is a CasADi matrix, numpy otherwise.
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

import casadi as ca
import numpy as np

from optikin.checks import check_numbers

Array = Any
"""A numpy array (or a float) or a CasADi ``SX``/``MX``/``DM`` matrix."""

_CASADI_TYPES = (ca.SX, ca.MX, ca.DM)

SERIES_BAND = 1e-3
"""Below this magnitude a sinc-type ratio switches to its Taylor series.

The series used here are accurate to double precision well past this band.
"""


def is_casadi(x: Array) -> bool:
    """Whether ``x`` is a CasADi matrix (symbolic or numeric).

    Parameters
    ----------
    x : Array
        Anything.

    Returns
    -------
    bool
        True for ``SX``, ``MX`` and ``DM``.
    """
    return isinstance(x, _CASADI_TYPES)


def any_casadi(*xs: Array) -> bool:
    """Whether any of ``xs`` is a CasADi matrix.

    Parameters
    ----------
    *xs : Array
        Anything.

    Returns
    -------
    bool
        True when the operation on ``xs`` must build a CasADi expression.
    """
    return any(is_casadi(x) for x in xs)


def components(x: Array, n: int, name: str = "x") -> list[Array]:
    """Split ``x`` into its ``n`` components.

    Parameters
    ----------
    x : Array
        numpy ``(..., n)`` (or anything :func:`optikin.checks.check_numbers` takes) or CasADi ``n x N``.
    n : int
        Number of components.
    name : str
        The argument's name, for the message.

    Returns
    -------
    list of Array
        ``n`` arrays of the batch shape ``(...)`` (numpy) or ``1 x N`` rows (CasADi).

    Raises
    ------
    TypeError
        When a numpy ``x`` is not real numbers (a string, ``None``, complex values), naming ``name``.
    ValueError
        When the last axis (numpy) or the number of rows (CasADi) is not ``n``, naming ``name``.
    """
    if is_casadi(x):
        if x.shape[0] != n:
            raise ValueError(f"{name}: expected {n} rows, got a CasADi matrix of shape {x.shape}")
        return [x[i, :] for i in range(n)]
    x = check_numbers(x, name)
    if x.shape[-1:] != (n,):
        raise ValueError(f"{name}: expected a last axis of length {n}, got shape {x.shape}")
    return [x[..., i] for i in range(n)]


def stack(parts: Sequence[Array]) -> Array:
    """Inverse of :func:`components`.

    Parameters
    ----------
    parts : sequence of Array
        Scalar components: numpy arrays or floats (broadcast together) or CasADi rows.

    Returns
    -------
    Array
        numpy ``(..., len(parts))`` or CasADi ``len(parts) x N`` (parts stacked as rows).
    """
    if any_casadi(*parts):
        return ca.vertcat(*parts)
    return np.stack(np.broadcast_arrays(*parts), axis=-1)


def concat(a: Array, b: Array) -> Array:
    """Join two elements along the component axis (e.g. ``Q_r`` and ``Q_d`` into a dual quaternion).

    Parameters
    ----------
    a, b : Array
        numpy ``(..., n_a)`` and ``(..., n_b)`` (batch shapes broadcast) or CasADi ``n_a x N``, ``n_b x N``.

    Returns
    -------
    Array
        numpy ``(..., n_a + n_b)`` or CasADi ``(n_a + n_b) x N``.

    Raises
    ------
    TypeError
        When a numpy part is not real numbers, naming ``a`` or ``b``.
    """
    if any_casadi(a, b):
        return ca.vertcat(a, b)
    a, b = check_numbers(a, "a"), check_numbers(b, "b")
    batch = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    return np.concatenate([np.broadcast_to(a, batch + a.shape[-1:]), np.broadcast_to(b, batch + b.shape[-1:])], axis=-1)


def split(x: Array, n_first: int, n_total: int, name: str = "x") -> tuple[Array, Array]:
    """Split an element into its first ``n_first`` and its remaining components.

    Parameters
    ----------
    x : Array
        numpy ``(..., n_total)`` or CasADi ``n_total x N``.
    n_first : int
        Number of components of the first part.
    n_total : int
        Number of components of ``x`` (checked).
    name : str
        The argument's name, for the message.

    Returns
    -------
    tuple of Array
        ``(x[..., :n_first], x[..., n_first:])``, or the same row blocks for CasADi.

    Raises
    ------
    TypeError
        When a numpy ``x`` is not real numbers, naming ``name``.
    ValueError
        When ``x`` does not have ``n_total`` components, naming ``name``.
    """
    if is_casadi(x):
        if x.shape[0] != n_total:
            raise ValueError(f"{name}: expected {n_total} rows, got a CasADi matrix of shape {x.shape}")
        return x[:n_first, :], x[n_first:, :]
    x = check_numbers(x, name)
    if x.shape[-1:] != (n_total,):
        raise ValueError(f"{name}: expected a last axis of length {n_total}, got shape {x.shape}")
    return x[..., :n_first], x[..., n_first:]


def _pick(name: str, *xs: Array) -> Callable[..., Array]:
    return getattr(ca, name) if any_casadi(*xs) else getattr(np, name)


def sin(x: Array) -> Array:
    """Element-wise sine.

    Parameters
    ----------
    x : Array
        numpy array (or float) or CasADi matrix, in radians.

    Returns
    -------
    Array
        ``sin(x)``, of the same shape and kind.
    """
    return _pick("sin", x)(x)


def cos(x: Array) -> Array:
    """Element-wise cosine.

    Parameters
    ----------
    x : Array
        numpy array (or float) or CasADi matrix, in radians.

    Returns
    -------
    Array
        ``cos(x)``, of the same shape and kind.
    """
    return _pick("cos", x)(x)


def sqrt(x: Array) -> Array:
    """Element-wise square root.

    Parameters
    ----------
    x : Array
        numpy array (or float) or CasADi matrix, non-negative.

    Returns
    -------
    Array
        ``sqrt(x)``, of the same shape and kind.
    """
    return _pick("sqrt", x)(x)


def atan2(y: Array, x: Array) -> Array:
    """Element-wise four-quadrant arctangent of ``y / x``.

    Parameters
    ----------
    y, x : Array
        numpy arrays (broadcast together) or CasADi matrices.

    Returns
    -------
    Array
        Angles in ``(-pi, pi]`` [rad].
    """
    return ca.atan2(y, x) if any_casadi(y, x) else np.arctan2(y, x)


def fabs(x: Array) -> Array:
    """Element-wise absolute value.

    Parameters
    ----------
    x : Array
        numpy array (or float) or CasADi matrix.

    Returns
    -------
    Array
        ``|x|``, of the same shape and kind.
    """
    return ca.fabs(x) if is_casadi(x) else np.abs(x)


def fmax(a: Array, b: Array) -> Array:
    """Element-wise maximum.

    Parameters
    ----------
    a, b : Array
        numpy arrays (broadcast together) or CasADi matrices.

    Returns
    -------
    Array
        ``max(a, b)``.
    """
    return ca.fmax(a, b) if any_casadi(a, b) else np.maximum(a, b)


def fmin(a: Array, b: Array) -> Array:
    """Element-wise minimum.

    Parameters
    ----------
    a, b : Array
        numpy arrays (broadcast together) or CasADi matrices.

    Returns
    -------
    Array
        ``min(a, b)``.
    """
    return ca.fmin(a, b) if any_casadi(a, b) else np.minimum(a, b)


def where(cond: Array, a: Array, b: Array) -> Array:
    """Element-wise ``a if cond else b``; both branches are evaluated.

    Parameters
    ----------
    cond : Array
        Boolean (numpy) or 0/1 (CasADi) condition.
    a, b : Array
        Values taken where ``cond`` is true and false.

    Returns
    -------
    Array
        ``numpy.where(cond, a, b)`` or ``casadi.if_else(cond, a, b)``.
    """
    if any_casadi(cond, a, b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def clip(x: Array, lo: float, hi: float) -> Array:
    """Element-wise ``min(max(x, lo), hi)``.

    Parameters
    ----------
    x : Array
        numpy array or CasADi matrix.
    lo, hi : float
        Bounds, ``lo <= hi``.

    Returns
    -------
    Array
        ``x`` clipped to ``[lo, hi]``.
    """
    return fmin(fmax(x, lo), hi)


def _sqrt_safe(x2: Array, small: Array) -> Array:
    """sqrt(x2) outside the series band, 1 inside (keeps the unused branch finite and differentiable)."""
    return sqrt(where(small, 1.0, x2))


def sinc_of_square(x2: Array) -> Array:
    """``sin(x)/x`` as a function of ``x^2``, exact and smooth at ``x = 0`` (values and derivatives).

    Parameters
    ----------
    x2 : Array
        ``x^2 >= 0``, any shape.

    Returns
    -------
    Array
        ``sin(x)/x``; the series ``1 - x^2/6 + x^4/120`` inside :data:`SERIES_BAND`.
    """
    small = x2 < SERIES_BAND**2
    x = _sqrt_safe(x2, small)
    return where(small, 1.0 - x2 / 6.0 + x2 * x2 / 120.0, sin(x) / x)


def cos_of_square(x2: Array) -> Array:
    """``cos(x)`` as a function of ``x^2``, differentiable through ``x = 0``.

    Parameters
    ----------
    x2 : Array
        ``x^2 >= 0``, any shape.

    Returns
    -------
    Array
        ``cos(x)``; the series ``1 - x^2/2 + x^4/24`` inside :data:`SERIES_BAND`.
    """
    small = x2 < SERIES_BAND**2
    x = _sqrt_safe(x2, small)
    return where(small, 1.0 - x2 / 2.0 + x2 * x2 / 24.0, cos(x))


def inv_sinc_of_square(x2: Array) -> Array:
    """``x/sin(x)`` as a function of ``x^2``, for ``|x| < pi``, smooth at ``x = 0``.

    Parameters
    ----------
    x2 : Array
        ``x^2`` in ``[0, pi^2)``, any shape.

    Returns
    -------
    Array
        ``x/sin(x)``; the series ``1 + x^2/6 + 7 x^4/360`` inside :data:`SERIES_BAND`.
    """
    small = x2 < SERIES_BAND**2
    x = _sqrt_safe(x2, small)
    return where(small, 1.0 + x2 / 6.0 + 7.0 * x2 * x2 / 360.0, x / sin(x))


def sinc(x: Array) -> Array:
    """``sin(x)/x``, exact and smooth at ``x = 0``.

    Written with the half angle, ``sin(x)/x = sin(x/2) cos(x/2) / (x/2)``, so that a symbolic
    expression shares ``sin(x/2)`` and ``cos(x/2)`` with the rotation quaternion of the same
    angle (``cos(x/2) + sin(x/2) n``) instead of evaluating ``sin(x)`` and a square root again;
    inside :data:`SERIES_BAND` the series of :func:`sinc_of_square`.

    Parameters
    ----------
    x : Array
        numpy array (or float) or CasADi matrix, in radians.

    Returns
    -------
    Array
        ``sin(x)/x``, 1 at ``x = 0``, of the same shape and kind.
    """
    x2 = x * x
    small = x2 < SERIES_BAND**2
    h = 0.5 * x
    return where(small, 1.0 - x2 / 6.0 + x2 * x2 / 120.0, sin(h) * cos(h) / where(small, 1.0, h))


def one_minus_cos_over_square(x: Array) -> Array:
    """``(1 - cos x)/x^2 = sinc(x/2)^2 / 2``, exact and smooth at ``x = 0``.

    The ratio of the constant-curvature tip position (seed 000 eq. 1, without the
    singularity that its eq. 2 works around).

    Parameters
    ----------
    x : Array
        Angle [rad], any shape.

    Returns
    -------
    Array
        ``(1 - cos x)/x^2``, ``1/2`` at ``x = 0``.
    """
    x2 = x * x
    small = x2 < SERIES_BAND**2
    h = 0.5 * x
    half = sin(h) / where(small, 1.0, h)  # sin(x/2)/(x/2), sharing sin(x/2) as sinc does
    return where(small, 0.5 - x2 / 24.0 + x2 * x2 / 720.0, 0.5 * half * half)


def scale(t: Array, x: Array, n: int) -> Array:
    """Every component of ``x`` times ``t``.

    Parameters
    ----------
    t : Array
        A scalar, or one factor per element: the batch shape ``(...)`` (numpy) or a ``1 x N`` row (CasADi).
    x : Array
        numpy ``(..., n)`` or CasADi ``n x N``.
    n : int
        Number of components of ``x``.

    Returns
    -------
    Array
        ``t x`` in the layout of ``x``.
    """
    return stack([t * c for c in components(x, n)])


def sum_squares(parts: Sequence[Array]) -> Array:
    """``sum_i parts[i]^2``, element-wise.

    Parameters
    ----------
    parts : sequence of Array
        Components (e.g. from :func:`components`), at least one.

    Returns
    -------
    Array
        The sum of their squares, of their common (broadcast) shape.
    """
    total = parts[0] * parts[0]
    for p in parts[1:]:
        total = total + p * p
    return total
