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
``stack(parts, like)`` rebuilds one in the layout of ``like``. Every other
helper dispatches on the type of its argument.
"""

from __future__ import annotations

from typing import Any, Sequence

import casadi as ca
import numpy as np

Array = Any
"""A numpy array or a CasADi ``SX``/``MX``/``DM`` matrix."""

_CASADI_TYPES = (ca.SX, ca.MX, ca.DM)

# Below this magnitude a sinc-type ratio switches to its Taylor series.  The
# series used below are accurate to double precision well past this band.
SERIES_BAND = 1e-3


def is_casadi(x: Array) -> bool:
    """True when ``x`` is a CasADi matrix (symbolic or numeric)."""
    return isinstance(x, _CASADI_TYPES)


def any_casadi(*xs: Array) -> bool:
    return any(is_casadi(x) for x in xs)


def components(x: Array, n: int) -> list[Array]:
    """Split ``x`` into its ``n`` components (see the module docstring)."""
    if is_casadi(x):
        if x.shape[0] != n:
            raise ValueError(f"expected {n} rows, got a CasADi matrix of shape {x.shape}")
        return [x[i, :] for i in range(n)]
    x = np.asarray(x, dtype=float)
    if x.shape[-1:] != (n,):
        raise ValueError(f"expected a last axis of length {n}, got shape {x.shape}")
    return [x[..., i] for i in range(n)]


def stack(parts: Sequence[Array]) -> Array:
    """Inverse of :func:`components`: CasADi parts are stacked as rows."""
    if any_casadi(*parts):
        return ca.vertcat(*parts)
    return np.stack(np.broadcast_arrays(*parts), axis=-1)


def concat(a: Array, b: Array) -> Array:
    """Join two elements along the component axis (e.g. Q_r and Q_d into a dual quaternion)."""
    if any_casadi(a, b):
        return ca.vertcat(a, b)
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    batch = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    return np.concatenate(
        [np.broadcast_to(a, batch + a.shape[-1:]), np.broadcast_to(b, batch + b.shape[-1:])], axis=-1
    )


def split(x: Array, n_first: int, n_total: int) -> tuple[Array, Array]:
    """Split an element into its first ``n_first`` and its remaining components."""
    if is_casadi(x):
        if x.shape[0] != n_total:
            raise ValueError(f"expected {n_total} rows, got a CasADi matrix of shape {x.shape}")
        return x[:n_first, :], x[n_first:, :]
    x = np.asarray(x, dtype=float)
    if x.shape[-1:] != (n_total,):
        raise ValueError(f"expected a last axis of length {n_total}, got shape {x.shape}")
    return x[..., :n_first], x[..., n_first:]


def _pick(name: str, *xs: Array):
    return getattr(ca, name) if any_casadi(*xs) else getattr(np, name)


def sin(x: Array) -> Array:
    return _pick("sin", x)(x)


def cos(x: Array) -> Array:
    return _pick("cos", x)(x)


def sqrt(x: Array) -> Array:
    return _pick("sqrt", x)(x)


def atan2(y: Array, x: Array) -> Array:
    return ca.atan2(y, x) if any_casadi(y, x) else np.arctan2(y, x)


def fabs(x: Array) -> Array:
    return ca.fabs(x) if is_casadi(x) else np.abs(x)


def fmax(a: Array, b: Array) -> Array:
    return ca.fmax(a, b) if any_casadi(a, b) else np.maximum(a, b)


def fmin(a: Array, b: Array) -> Array:
    return ca.fmin(a, b) if any_casadi(a, b) else np.minimum(a, b)


def where(cond: Array, a: Array, b: Array) -> Array:
    """Element-wise ``a if cond else b`` (both branches are evaluated)."""
    if any_casadi(cond, a, b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def clip(x: Array, lo: float, hi: float) -> Array:
    return fmin(fmax(x, lo), hi)


def _sqrt_safe(x2: Array, small: Array) -> Array:
    """sqrt(x2) outside the series band, 1 inside (keeps the unused branch finite and differentiable)."""
    return sqrt(where(small, 1.0, x2))


def sinc_of_square(x2: Array) -> Array:
    """sin(x)/x as a function of x^2: exact and smooth at x = 0, values and derivatives."""
    small = x2 < SERIES_BAND**2
    x = _sqrt_safe(x2, small)
    return where(small, 1.0 - x2 / 6.0 + x2 * x2 / 120.0, sin(x) / x)


def cos_of_square(x2: Array) -> Array:
    """cos(x) as a function of x^2 (differentiable through x = 0)."""
    small = x2 < SERIES_BAND**2
    x = _sqrt_safe(x2, small)
    return where(small, 1.0 - x2 / 2.0 + x2 * x2 / 24.0, cos(x))


def inv_sinc_of_square(x2: Array) -> Array:
    """x/sin(x) as a function of x^2, for |x| < pi."""
    small = x2 < SERIES_BAND**2
    x = _sqrt_safe(x2, small)
    return where(small, 1.0 + x2 / 6.0 + 7.0 * x2 * x2 / 360.0, x / sin(x))


def sinc(x: Array) -> Array:
    """sin(x)/x, exact and smooth at x = 0."""
    return sinc_of_square(x * x)


def one_minus_cos_over_square(x: Array) -> Array:
    """(1 - cos x)/x^2 = sinc(x/2)^2 / 2, exact and smooth at x = 0."""
    half = sinc(0.5 * x)
    return 0.5 * half * half


def scale(t: Array, x: Array, n: int) -> Array:
    """Every component of ``x`` times ``t``, where ``t`` has the batch shape (numpy) or is a row (CasADi)."""
    return stack([t * c for c in components(x, n)])


def sum_squares(parts: Sequence[Array]) -> Array:
    total = parts[0] * parts[0]
    for p in parts[1:]:
        total = total + p * p
    return total
