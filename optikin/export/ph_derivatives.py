"""The PH shape export's Newton derivatives: the model cut after its data-only part, and the bending
energy's gradient and Hessian through its Bernstein coefficients.

:func:`split_model` cuts a given-speeds :class:`~optikin.curves.min_energy.ShapeEnergyModel` after
the Hermite family (one sample's constants, computed once per sample); :func:`bending_derivatives`
gives ``E = int kappa^2 ds`` with its gradient and Hessian in the two free angles through the 13
coefficients of the rotation-rate and speed polynomials of the PH quintic (the energy of
:func:`optikin.curves.energy.bending_energy`), at about half the operations of reverse mode
through the whole graph.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

if TYPE_CHECKING:
    from optikin.curves.min_energy import ShapeEnergyModel
    from optikin.curves.ph_quintic import PHQuintic

FAMILY_FIELDS = ("A0_bar", "A2_bar", "center", "pole", "pole_root")
"""The fields of :class:`optikin.curves.ph_quintic.HermiteFamily` a member needs besides the angles."""


@dataclass(frozen=True)
class SplitModel:
    """A given-speeds model cut into its data-only part and the rest.

    ``family`` (an SX of the parameter vector ``P``) holds the :data:`FAMILY_FIELDS` of the
    Hermite family, one sample's constants; ``curve`` is the family member at the angles ``x``
    built on the symbols ``F`` that stand for them. The cut changes no operation: the energy of
    ``curve`` at ``(x, family(P))`` is the model's, rounding included.
    """

    x: ca.SX
    P: ca.SX
    F: ca.SX
    family: ca.SX
    curve: PHQuintic


def split_model(model: ShapeEnergyModel) -> SplitModel:
    """The model's curve ``hermite_family(p0, s0 t0, p1, s1 t1).member(phi0, phi2)`` cut after the family."""
    from optikin.curves.min_energy import ShapeParameters
    from optikin.curves.ph_quintic import hermite_family

    x, P, _ = model.symbols()
    p = ShapeParameters.of(P)
    family = hermite_family(p.p0, p.s0 * p.t0, p.p1, p.s1 * p.t1)
    values = [getattr(family, name) for name in FAMILY_FIELDS]
    offsets = np.cumsum([0] + [v.numel() for v in values]).tolist()
    F = ca.SX.sym("F", offsets[-1])
    fields = dict(zip(FAMILY_FIELDS, ca.vertsplit(F, offsets)))
    curve = replace(family, **fields).member(x[0], x[1], 0.0)
    return SplitModel(x, P, F, ca.vertcat(*values), curve)


def _mirrored(coefficients: list, degree: int) -> tuple[list, list]:
    """``(c_i + c_{d-i}, c_i - c_{d-i})`` for ``i < d/2`` (and the middle ``c_{d/2}`` among the sums)."""
    half = (degree + 1) // 2
    sums = [coefficients[i] + coefficients[degree - i] for i in range(half)]
    if degree % 2 == 0:
        sums.append(coefficients[degree // 2])
    return sums, [coefficients[i] - coefficients[degree - i] for i in range(half)]


def _pair_basis(degree: int, t: float) -> tuple[list[float], list[float]]:
    """Weights of the sums and differences of :func:`_mirrored` giving a polynomial at ``t`` and ``1 - t``."""
    from optikin.curves.bernstein import bernstein_basis

    b = [float(v) for v in bernstein_basis(degree, np.array(t))]
    half = (degree + 1) // 2
    even = [0.5 * (b[i] + b[degree - i]) for i in range(half)] + ([b[degree // 2]] if degree % 2 == 0 else [])
    return even, [0.5 * (b[i] - b[degree - i]) for i in range(half)]


def bending_derivatives(curve: PHQuintic, x: ca.SX, nodes: int) -> tuple[ca.SX, ...]:
    """``(E, S, g, h00, h01, h11)``: ``E = int kappa^2 ds``, the arc length, gradient (2) and Hessian.

    ``E = sum_n w_n f(u_n, v_n, s_n)`` with ``f = 4 (u^2 + v^2) / s^3`` at the Gauss-Legendre
    nodes, where ``u, v`` (cubic) and ``s = sigma`` (quartic) are Bernstein polynomials of the
    13 coefficients ``c(x)`` (:func:`optikin.curves.energy.bending_energy`). The derivatives go
    through ``c``: with ``J = dc/dx`` (forward mode twice, also for the second derivatives
    ``c_ab``) and the node values' derivatives ``D_n = B_n J`` (rows ``a, b, d`` for ``u, v, s``),

        g = J' G,   G = sum_n w_n B_n' grad f_n,
        H = sum_n 8 w_n r^3 (a~ a~' + b~ b~' - 3 q r^2 d d') + sum_i G_i c_i,xx,

    ``r = 1/s``, ``q = u^2 + v^2``, ``a~ = a - 3 r u d``, ``b~ = b - 3 r v d`` (the Hessian of
    ``f`` as a sum of squares). The nodes come in pairs ``t, 1 - t`` (equal weights), where the
    Bernstein basis is mirrored: each value at a pair is a sum and a difference of two half-length
    dot products (:func:`_mirrored`), and so is each entry of ``G``. Reverse mode through the whole
    graph costs about twice as much.
    """
    from optikin.curves.bernstein import gauss_legendre_unit
    from optikin.curves.energy import rotation_rate_coefficients

    t, w = gauss_legendre_unit(nodes)
    _, gj, gk = rotation_rate_coefficients(curve)
    sigma = curve.speed_coefficients()
    length = (sigma[0] + sigma[1] + sigma[2] + sigma[3] + sigma[4]) / 5.0
    c = ca.vertcat(*gj, *gk, *sigma)
    e = [ca.DM([1.0, 0.0]), ca.DM([0.0, 1.0])]
    dc = [ca.jtimes(c, x, e[0]), ca.jtimes(c, x, e[1])]
    ddc = {(a, b): ca.jtimes(dc[a], x, e[b]) for a, b in ((0, 0), (0, 1), (1, 1))}
    degrees, offsets = (3, 3, 4), (0, 4, 8, 13)

    def split(vector: Any) -> list[tuple[list, list]]:
        """The mirrored sums and differences of the three polynomials whose coefficients are ``vector``."""
        parts = ca.vertsplit(vector, list(offsets))
        return [_mirrored(ca.vertsplit(part, 1), d) for part, d in zip(parts, degrees)]

    values, slopes = split(c), [split(d) for d in dc]
    pairs = [(k, nodes - 1 - k, w[k]) for k in range(nodes // 2)]
    if nodes % 2:
        pairs.append((nodes // 2, nodes // 2, 0.5 * w[nodes // 2]))  # the middle node, half its weight twice
    energy: Any = 0.0
    H: dict[tuple[int, int], Any] = {ab: 0.0 for ab in ddc}
    G_sums: list[list] = [[0.0] * len(values[j][0]) for j in range(3)]
    G_differences: list[list] = [[0.0] * len(values[j][1]) for j in range(3)]
    for k, _, weight in pairs:
        bases = [_pair_basis(d, float(t[k])) for d in degrees]

        def at_pair(split_vector: list[tuple[list, list]], j: int) -> tuple[Any, Any]:
            (even, odd), (sums, differences) = bases[j], split_vector[j]
            ev = sum(ei * si for ei, si in zip(even, sums))
            od = sum(oi * di for oi, di in zip(odd, differences))
            return ev + od, ev - od

        node_values = [at_pair(values, j) for j in range(3)]  # (at t, at 1 - t) of u, v, s
        node_slopes = [[at_pair(slopes[a], j) for j in range(3)] for a in (0, 1)]
        weighted = [[0.0, 0.0] for _ in range(3)]  # w grad f at t, 1 - t
        for side in (0, 1):
            u, v, sv = (node_values[j][side] for j in range(3))
            r = 1.0 / sv
            q = u * u + v * v
            k1 = (8.0 * weight) * (r * r * r)
            energy = energy + 0.5 * k1 * q
            weighted[0][side], weighted[1][side], weighted[2][side] = k1 * u, k1 * v, -1.5 * k1 * q * r
            du, dv, ds = ([node_slopes[a][j][side] for a in (0, 1)] for j in range(3))
            a_t = [du[a] - 3.0 * r * u * ds[a] for a in (0, 1)]
            b_t = [dv[a] - 3.0 * r * v * ds[a] for a in (0, 1)]
            curvature = -3.0 * q * r * r
            for a, b in H:
                H[a, b] = H[a, b] + k1 * (a_t[a] * a_t[b] + b_t[a] * b_t[b] + curvature * ds[a] * ds[b])
        for j in range(3):
            (even, odd), total, difference = bases[j], weighted[j][0] + weighted[j][1], weighted[j][0] - weighted[j][1]
            G_sums[j] = [g + ei * total for g, ei in zip(G_sums[j], even)]
            G_differences[j] = [g + oi * difference for g, oi in zip(G_differences[j], odd)]
    G = []
    for j, d in enumerate(degrees):
        half = (d + 1) // 2
        low = [G_sums[j][i] + G_differences[j][i] for i in range(half)]
        high = [G_sums[j][i] - G_differences[j][i] for i in range(half)]
        G += low + ([G_sums[j][half]] if d % 2 == 0 else []) + high[::-1]
    Gv = ca.vertcat(*G)
    g = ca.vertcat(ca.dot(Gv, dc[0]), ca.dot(Gv, dc[1]))
    h = {ab: H[ab] + ca.dot(Gv, ddc[ab]) for ab in ddc}
    return energy, length, g, h[0, 0], h[0, 1], h[1, 1]
