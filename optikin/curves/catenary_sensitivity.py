"""The hanging rope's shape and lowest point as functions of its two grips, with derivatives by the implicit function.

A rope of length ``L`` held at grips ``A`` and ``B`` hangs as the catenary of
:mod:`optikin.curves.catenary`: with ``up = -g/|g|``, the rise ``v = (B - A)' up``, the
horizontal chord ``f = B - A - v up``, the span ``h = |f|`` and its direction ``e = f / h``,
the catenary parameter ``a`` solves

    r(a; h, v) = 2 a sinh(h / (2a)) - sqrt(L^2 - v^2) = 0,

the vertex lies at the abscissa ``x0 = h/2 - a artanh(v / L)`` from ``A``, and the vertex is

    P = A + x0 e + a (1 - cosh(x0 / a)) up.

The rope's lowest point is the vertex when ``0 <= x0 <= h`` (it hangs below both grips) and the
lower grip otherwise. The mass per length ``mu`` does not change the shape; it sets the
horizontal tension ``H = mu |g| a``, constant along the rope.

Sensitivities. ``a`` is defined implicitly by ``r = 0``: by the implicit-function theorem
``da/dG = -(dr/da)^-1 dr/dG`` for the grips ``G = (A, B)`` (``dr/da = 2 sinh(xi) - 2 xi cosh(xi) < 0``
with ``xi = h/(2a) > 0``, so ``r = 0`` has one root and it is regular wherever the rope is longer
than the chord), and every other quantity is explicit in ``(G, a)``:
``dP/dG = dP/dG|_a + dP/da da/dG``. The partial derivatives are CasADi's, of the expressions
above, in one Function ``(A, B, a) -> (P, dP/dG, a, da/dG, x0, H, dH/dG)``; ``a`` itself comes from the
safeguarded Newton solve of :func:`optikin.curves.catenary.solve_sinhc` (exact to rounding), so
the Function evaluates no solver and its derivative is exact for the root it is given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from optikin.curves.catenary import GRAVITY_DIRECTION, solve_sinhc
from optikin.errors import InputDataError
from optikin.fastcall import BufferedFunction

G_ACCELERATION = 9.81
"""Magnitude of gravity [m/s^2] used for the rope's weight ``mu |g|``."""


@dataclass(frozen=True)
class LowestPoint:
    """The rope's lowest point and its derivatives with respect to the grips ``G = (A, B)``.

    Attributes
    ----------
    point:
        The lowest point of the rope ``(3,)`` [m]: the catenary's vertex, or the lower grip.
    jacobian:
        ``dP/dG`` ``(3, 6)``: columns 0-2 with respect to ``A``, 3-5 to ``B``.
    vertex_on_rope:
        Whether the vertex lies between the grips (``0 <= x0 <= span``); otherwise ``point`` is the lower grip.
    a, a_gradient:
        The catenary parameter [m] and ``da/dG`` ``(6,)``.
    x0, span, rise:
        The vertex's abscissa from ``A``, the horizontal and the vertical distance from ``A`` to ``B`` [m].
    tension, tension_gradient:
        The horizontal tension ``H = mu |g| a`` [N] and ``dH/dG`` ``(6,)`` [N/m].
    """

    point: np.ndarray
    jacobian: np.ndarray
    vertex_on_rope: bool
    a: float
    a_gradient: np.ndarray
    x0: float
    span: float
    rise: float
    tension: float
    tension_gradient: np.ndarray


class CatenarySensitivity:
    """The lowest point of a rope of ``length`` hung between two grips, and its derivatives (module docstring).

    Parameters
    ----------
    length:
        Rope length ``L`` [m], positive.
    mass_per_length:
        ``mu`` [kg/m], non-negative (sets the tension only).
    gravity:
        Direction of gravity (any length), ``(3,)``; the default points along ``-z``.
    compiled:
        Compile the Function with a C compiler.
    source:
        Named in the errors (e.g. the problem file).

    Raises
    ------
    InputDataError
        A length that is not positive, a negative mass per length, a zero gravity direction (``field`` names it).
    """

    def __init__(
        self,
        length: float,
        mass_per_length: float = 0.0,
        gravity=GRAVITY_DIRECTION,
        compiled: bool = False,
        source: str = "",
    ):
        if not (math.isfinite(length) and length > 0):
            raise InputDataError(f"rope length must be positive, got {length}", source=source, field="length")
        if not (math.isfinite(mass_per_length) and mass_per_length >= 0):
            raise InputDataError(
                f"mass per length must be non-negative, got {mass_per_length}", source=source, field="mass_per_length"
            )
        g = np.asarray(gravity, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)) or not np.linalg.norm(g) > 0:
            raise InputDataError(
                f"gravity must be a non-zero 3-vector, got {gravity!r}", source=source, field="gravity"
            )
        self.length, self.mass_per_length, self.source = float(length), float(mass_per_length), source
        self.up = -g / np.linalg.norm(g)
        self.function = self._function()
        self._f = BufferedFunction(self.function, compiled=compiled)
        self._A, self._B, self._a = self._f.inputs
        out = self._f.outputs
        self._P, self._dP, self._da, self._x0, self._H, self._dH = out

    def _function(self) -> ca.Function:
        A, B, a = ca.SX.sym("A", 3), ca.SX.sym("B", 3), ca.SX.sym("a")
        G, e, x0, da = self.plane(A, B, a)
        up = ca.DM(self.up)
        P = A + x0 * e + a * (1.0 - ca.cosh(x0 / a)) * up
        dP = ca.jacobian(P, G) + ca.jacobian(P, a) @ da
        H = self.mass_per_length * G_ACCELERATION * a
        return ca.Function(
            "catenary_lowest_point",
            [A, B, a],
            [P, dP, da.T, x0, H, self.mass_per_length * G_ACCELERATION * da.T],
            ["A", "B", "a"],
            ["P", "dP_dG", "da_dG", "x0", "H", "dH_dG"],
            {"cse": True},
        )

    def plane(self, A: ca.SX, B: ca.SX, a: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """``G = (A, B)``, the horizontal direction ``e``, the vertex abscissa ``x0`` and ``da/dG`` ``(1, 6)``
        (implicit-function theorem) as CasADi expressions of the grips and ``a`` (module docstring)."""
        L, up = self.length, ca.DM(self.up)
        G = ca.vertcat(A, B)
        chord = B - A
        v = ca.dot(chord, up)
        flat = chord - v * up
        h = ca.sqrt(ca.sumsqr(flat))
        residual = 2.0 * a * ca.sinh(h / (2.0 * a)) - ca.sqrt(L * L - v * v)
        da = -ca.jacobian(residual, G) / ca.jacobian(residual, a)
        return G, flat / h, h / 2.0 - a * ca.atanh(v / L), da

    def shape(self, A: np.ndarray, B: np.ndarray) -> tuple[float, float, float]:
        """``(a, span, rise)`` [m] of the rope between ``A`` and ``B``.

        Raises
        ------
        InputDataError
            The rope is shorter than the distance between the grips (``field="length"``), or the grips lie on one
            vertical (``field="grips"``: no span, the rope hangs folded and its lowest point is not smooth in them).
        """
        chord = np.subtract(B, A, dtype=float)
        rise = float(chord @ self.up)
        span = float(np.linalg.norm(chord - rise * self.up))
        distance = math.hypot(span, rise)
        if not self.length > distance * (1.0 + 1e-12):
            raise InputDataError(
                f"rope of length {self.length:.6g} m is not longer than the distance between its grips, "
                f"{distance:.6g} m: it cannot hang (straight or torn)",
                source=self.source,
                field="length",
            )
        if span <= 1e-9 * self.length:
            raise InputDataError(
                f"grips {np.asarray(A).tolist()} and {np.asarray(B).tolist()} lie on one vertical: the rope hangs "
                "folded and its lowest point is not differentiable in them",
                source=self.source,
                field="grips",
            )
        rho = math.sqrt(self.length * self.length - rise * rise) / span
        return span / (2.0 * solve_sinhc(rho)), span, rise

    def lowest_point(self, A: np.ndarray, B: np.ndarray) -> LowestPoint:
        """The lowest point of the rope held at ``A`` and ``B`` ``(3,)`` [m] and its derivatives.

        Raises
        ------
        InputDataError
            See :meth:`shape`.
        """
        a, span, rise = self.shape(A, B)
        self._A[:], self._B[:], self._a[0] = A, B, a
        self._f()
        x0 = float(self._x0[0])
        on_rope = 0.0 <= x0 <= span
        if on_rope:
            point, jacobian = self._P.copy(), self._dP.reshape(6, 3).T.copy()
        else:  # the lower grip is the lowest point: dP/dG selects it
            lower = 0 if rise > 0 else 3
            point = np.array(A if lower == 0 else B, dtype=float)
            jacobian = np.zeros((3, 6))
            jacobian[:, lower : lower + 3] = np.eye(3)
        return LowestPoint(
            point,
            jacobian,
            on_rope,
            a,
            self._da.copy(),
            x0,
            span,
            rise,
            float(self._H[0]),
            self._dH.copy(),
        )


class RopeSamples:
    """Points of the hanging rope at fixed arc lengths from ``A`` and their derivatives with respect to the grips.

    With ``u = s/a - sinh(x0/a)`` the point at arc length ``s`` is
    ``A + (x0 + a asinh(u)) e + a (sqrt(1 + u^2) - cosh(x0/a)) up`` (:mod:`optikin.curves.catenary`);
    its derivative with respect to ``G`` goes through ``a`` by the implicit-function theorem, as the
    lowest point's (:class:`CatenarySensitivity`).

    Parameters
    ----------
    rope:
        The rope (length, gravity).
    arc_lengths:
        ``M`` arc lengths from ``A`` [m], in ``[0, L]``.
    compiled:
        Compile the Function with a C compiler.

    Attributes
    ----------
    P, J, squared:
        After :meth:`evaluate`: the points ``(M, 3)``, ``dP/dG`` ``(M, 3, 6)`` and ``|p_i|^2`` ``(M,)`` (views,
        valid until the next call).
    """

    def __init__(self, rope: CatenarySensitivity, arc_lengths, compiled: bool = False):
        s = np.asarray(arc_lengths, dtype=float)
        if s.ndim != 1 or len(s) == 0 or np.any(s < 0) or np.any(s > rope.length):
            raise ValueError(f"arc lengths must lie in [0, {rope.length}], got {arc_lengths!r}")
        self.rope, self.arc_lengths = rope, s
        A, B, a = ca.SX.sym("A", 3), ca.SX.sym("B", 3), ca.SX.sym("a")
        G, e, x0, da = rope.plane(A, B, a)
        up = ca.DM(rope.up)
        columns = []
        for arc in s:
            u = arc / a - ca.sinh(x0 / a)
            columns.append(A + (x0 + a * ca.asinh(u)) * e + a * (ca.sqrt(1.0 + u * u) - ca.cosh(x0 / a)) * up)
        P = ca.horzcat(*columns)
        flat = ca.vec(P)
        dP = ca.jacobian(flat, G) + ca.jacobian(flat, a) @ da
        self.function = ca.Function(
            "rope_samples",
            [A, B, a],
            [P, dP.T, ca.sum1(P * P)],
            ["A", "B", "a"],
            ["P", "dP_dG", "squared"],
            {"cse": True},
        )
        self._f = BufferedFunction(self.function, compiled=compiled)
        self._A, self._B, self._a = self._f.inputs
        M = len(s)
        self.P = self._f.outputs[0].reshape(M, 3)
        self.J = self._f.outputs[1].reshape(M, 3, 6)
        self.squared = self._f.outputs[2]

    def evaluate(self, A: np.ndarray, B: np.ndarray, a: float | None = None) -> None:
        """Refresh :attr:`P`, :attr:`J` for grips ``A``, ``B`` (``a``: the catenary parameter if known).

        Raises
        ------
        InputDataError
            See :meth:`CatenarySensitivity.shape`.
        """
        self._A[:], self._B[:] = A, B
        self._a[0] = self.rope.shape(A, B)[0] if a is None else a
        self._f()
