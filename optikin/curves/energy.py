"""Bending and twist energies of PH quintics by Gauss-Legendre quadrature (numpy and CasADi).

Seed 002 (section II.A, after Singh et al., Soft Robotics 2018) selects, among
the PH quintic Hermite interpolants, the one of least "potential energy (combination of
bending and twisting energy)". With unit stiffnesses this is

    E = int kappa^2 ds + w_tau int tau^2 ds = int_0^1 (kappa^2 + w_tau tau^2) sigma dt,

and for a PH curve ``kappa^2 sigma = |r' x r''|^2 / sigma^5 = 4 (g_j^2 + g_k^2) / sigma^3``
with ``sigma = |A|^2`` and ``g_j, g_k`` the ``j, k`` components of ``G = A* A'``
(derived here: ``A' = A M`` with ``M = G/sigma`` gives ``r'' = 2 A vec(M i) A*``, and
rotating by ``A`` turns ``|r' x r''|`` into ``sigma^2 |i x 2 vec(M i)| = 2 sigma |(g_j, g_k)|``).
A rational integrand, so no closed form in general; an
``n``-point Gauss-Legendre rule converges geometrically (tests/test_ph_energy.py
shows :data:`DEFAULT_NODES` is converged to 1e-9 relative on the shapes of interest).

The torsion ``tau = (r' x r'').r''' / |r' x r''|^2`` is 0/0 where the curvature
vanishes (straight pieces, inflections). The twist term therefore uses
``tau kappa^2 / (kappa^2 + kappa_floor^2)``, equal to ``tau`` wherever
``kappa >> kappa_floor`` and 0 on straight pieces.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra import quat_conjugate, quat_multiply
from optikin.algebra.backend import Array
from optikin.curves.bernstein import bernstein_basis, gauss_legendre_unit
from optikin.curves.ph_quintic import PHQuintic
from optikin.curves.vectors import cross, dot

DEFAULT_NODES = 16
"""Gauss-Legendre nodes used unless told otherwise (see tests/test_ph_energy.py for convergence)."""

DEFAULT_CURVATURE_FLOOR = 1e-3
"""``kappa_floor`` of the regularised torsion, in 1/m."""


def bending_energy_density(curve: PHQuintic, t: Array) -> Array:
    """``kappa^2 sigma = 4 (g_j^2 + g_k^2) / sigma^3``, ``G = A* A'`` (module docstring)."""
    A, dA = curve.preimage(t), curve.preimage_derivative(t)
    G = quat_multiply(quat_conjugate(A), dA)
    _, _, gj, gk = B.components(G, 4)
    sigma = B.sum_squares(B.components(A, 4))
    return 4.0 * (gj * gj + gk * gk) / (sigma * sigma * sigma)


def twist_energy_density(curve: PHQuintic, t: Array, curvature_floor: float = DEFAULT_CURVATURE_FLOOR) -> Array:
    """Regularised ``tau^2 sigma`` at ``t`` (module docstring)."""
    d1, d2, d3 = curve.derivatives(t)
    c = cross(d1, d2)
    sigma2 = dot(d1, d1)
    sigma6 = sigma2 * sigma2 * sigma2
    tau = dot(c, d3) / (dot(c, c) + sigma6 * curvature_floor**2)
    return tau * tau * B.sqrt(sigma2)


def _integrate(values: Array, weights: np.ndarray) -> Array:
    if B.is_casadi(values):
        return ca.mtimes(values, ca.DM(weights))
    return values @ weights


def rotation_rate_coefficients(curve: PHQuintic) -> tuple[list[Array], list[Array], list[Array]]:
    """Cubic Bernstein coefficients of ``g_i(t), g_j(t), g_k(t)``, the vector part of ``G = A* A'``.

    ``2 (g_i, g_j, g_k) / sigma`` is the angular velocity of the Euler-Rodrigues frame
    ``A/|A|`` in its own axes: ``g_i`` its twist about the tangent, ``g_j, g_k`` the bending.

    ``A = sum A_i b_i^2``, ``A' = E_0 b_0^1 + E_1 b_1^1`` (``E_0 = 2(A1 - A0)``,
    ``E_1 = 2(A2 - A1)``) and ``b_i^2 b_l^1 = C(2,i) C(1,l) / C(3,i+l) b_{i+l}^3``.
    """
    A = [quat_conjugate(curve.A0), quat_conjugate(curve.A1), quat_conjugate(curve.A2)]
    E = [2.0 * (curve.A1 - curve.A0), 2.0 * (curve.A2 - curve.A1)]

    def ijk(P, C):
        _, i, j, k = B.components(quat_multiply(P, C), 4)
        return i, j, k

    terms = [
        [(1.0, ijk(A[0], E[0]))],
        [(1.0 / 3.0, ijk(A[0], E[1])), (2.0 / 3.0, ijk(A[1], E[0]))],
        [(2.0 / 3.0, ijk(A[1], E[1])), (1.0 / 3.0, ijk(A[2], E[0]))],
        [(1.0, ijk(A[2], E[1]))],
    ]
    x, y, z = ([sum(c * v[axis] for c, v in m) for m in terms] for axis in range(3))
    return x, y, z


@lru_cache(maxsize=None)
def _basis_at_nodes(degree: int, nodes: int) -> np.ndarray:
    t, _ = gauss_legendre_unit(nodes)
    return np.stack(bernstein_basis(degree, t), axis=-1)


def _at_nodes(coefficients: list[Array], degree: int, nodes: int) -> Array:
    """Values of a scalar Bernstein polynomial at the Gauss-Legendre nodes (numpy ``(..., n)``, CasADi ``n x 1``)."""
    basis = _basis_at_nodes(degree, nodes)
    if B.any_casadi(*coefficients):
        return ca.mtimes(ca.DM(basis), ca.vertcat(*coefficients))
    return np.stack(np.broadcast_arrays(*coefficients), axis=-1) @ basis.T


def bending_energy(curve: PHQuintic, nodes: int = DEFAULT_NODES) -> Array:
    """``int kappa^2 ds = int 4 (g_j^2 + g_k^2) / sigma^3 dt`` by an ``nodes``-point Gauss-Legendre rule.

    ``g_j, g_k`` (cubic) and ``sigma`` (quartic) are formed once in Bernstein form
    and evaluated at the nodes by constant matrices.
    """
    _, w = gauss_legendre_unit(nodes)
    _, gj, gk = rotation_rate_coefficients(curve)
    gj, gk = _at_nodes(gj, 3, nodes), _at_nodes(gk, 3, nodes)
    sigma = _at_nodes(curve.speed_coefficients(), 4, nodes)
    density = 4.0 * (gj * gj + gk * gk) / (sigma * sigma * sigma)
    if B.is_casadi(density):
        return ca.dot(density, ca.DM(w))
    return density @ w


def twist_energy(
    curve: PHQuintic, nodes: int = DEFAULT_NODES, curvature_floor: float = DEFAULT_CURVATURE_FLOOR
) -> Array:
    """Regularised ``int tau^2 ds`` by an ``nodes``-point Gauss-Legendre rule."""
    t, w = gauss_legendre_unit(nodes)
    return _integrate(twist_energy_density(curve, t, curvature_floor), w)


def shape_energy(
    curve: PHQuintic,
    twist_weight: float = 0.0,
    nodes: int = DEFAULT_NODES,
    curvature_floor: float = DEFAULT_CURVATURE_FLOOR,
) -> Array:
    """``int kappa^2 ds + twist_weight * int tau^2 ds``, both by the same Gauss-Legendre rule."""
    energy = bending_energy(curve, nodes)
    if twist_weight:
        energy = energy + twist_weight * twist_energy(curve, nodes, curvature_floor)
    return energy
