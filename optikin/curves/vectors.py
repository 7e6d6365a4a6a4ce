"""3-vector operations for numpy arrays ``(..., 3)`` and CasADi columns ``(3, N)``."""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array


def dot(a: Array, b: Array) -> Array:
    ax, ay, az = B.components(a, 3)
    bx, by, bz = B.components(b, 3)
    return ax * bx + ay * by + az * bz


def cross(a: Array, b: Array) -> Array:
    ax, ay, az = B.components(a, 3)
    bx, by, bz = B.components(b, 3)
    return B.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])


def norm(a: Array) -> Array:
    return B.sqrt(B.sum_squares(B.components(a, 3)))


def scale(a: Array, s: Array) -> Array:
    """``s * a`` for a scalar field ``s`` (numpy: shape ``(...)``; CasADi: ``1 x N``)."""
    return B.stack([s * c for c in B.components(a, 3)])


def as_column(x: Array, n: int) -> Array:
    """A CasADi ``n x 1`` column from a CasADi matrix or a numpy vector of length ``n``."""
    if B.is_casadi(x):
        return x
    x = np.asarray(x, dtype=float)
    if x.shape != (n,):
        raise ValueError(f"expected a single {n}-vector to mix with CasADi symbols, got shape {x.shape}")
    return ca.DM(x)
