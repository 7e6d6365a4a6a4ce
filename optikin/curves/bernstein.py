"""Bernstein polynomials and Gauss-Legendre rules on [0, 1], for numpy arrays and CasADi symbols.

Layout follows :mod:`optikin.algebra.backend`: a numpy coefficient carries its
components on the last axis ``(..., m)``; a CasADi coefficient is a column
``(m, 1)``. A numpy parameter array ``t`` of shape ``T`` gives values of shape
``(..., *T, m)``; a CasADi parameter (scalar or ``1 x M`` row) gives ``m x M``.
"""

from __future__ import annotations

from functools import lru_cache
from math import comb
from typing import Sequence

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array


def bernstein_basis(degree: int, t: Array) -> list[Array]:
    """``[b_0(t), ..., b_n(t)]`` with ``b_k(t) = C(n, k) (1 - t)^(n - k) t^k``."""
    s = 1.0 - t
    return [comb(degree, k) * s ** (degree - k) * t**k for k in range(degree + 1)]


def bernstein_combine(coefficients: Sequence[Array], t: Array) -> Array:
    """``sum_k c_k b_k(t)`` for vector coefficients ``c_k`` (see the module docstring for shapes)."""
    degree = len(coefficients) - 1
    if B.any_casadi(*coefficients) or B.is_casadi(t):
        t_row = t if B.is_casadi(t) else ca.DM(np.atleast_1d(np.asarray(t, dtype=float))).T
        basis = bernstein_basis(degree, t_row)
        symbolic = ca.mtimes(coefficients[0], basis[0])
        for c, b in zip(coefficients[1:], basis[1:]):
            symbolic = symbolic + ca.mtimes(c, b)
        return symbolic
    t = np.asarray(t, dtype=float)
    basis = bernstein_basis(degree, t)
    arrays = [np.asarray(c, dtype=float) for c in coefficients]
    batch = np.broadcast_shapes(*(c.shape[:-1] for c in arrays))
    m = arrays[0].shape[-1]
    shape_c = batch + (1,) * t.ndim + (m,)
    total = np.zeros(batch + t.shape + (m,))
    for c, b in zip(arrays, basis):
        total = total + np.broadcast_to(c, batch + (m,)).reshape(shape_c) * b[..., None]
    return total


@lru_cache(maxsize=None)
def gauss_legendre_unit(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of the ``n``-point Gauss-Legendre rule on [0, 1] (exact to degree 2n - 1)."""
    if n < 1:
        raise ValueError(f"a Gauss-Legendre rule needs at least one node, got {n}")
    x, w = np.polynomial.legendre.leggauss(n)
    nodes, weights = 0.5 * (x + 1.0), 0.5 * w
    nodes.setflags(write=False)
    weights.setflags(write=False)
    return nodes, weights
