"""The inextensible catenary of given length hanging between two points: ground truth for a rope link.

Seed 002 (section IV.B) closes a kinematic chain with a rope held by two arm tips
and reconstructs it by a PH quintic from its end poses. A perfectly flexible,
inextensible rope of length ``l`` hanging under gravity between ``A`` and ``B``
lies in the vertical plane through them; with ``h`` the horizontal and ``v`` the
(upward) vertical distance from ``A`` to ``B``, and ``x`` the horizontal
coordinate from ``A``,

    z(x) = a (cosh((x - x0)/a) - cosh(x0/a)),

where the catenary parameter ``a`` solves ``sqrt(l^2 - v^2) = 2 a sinh(h / (2a))``
and ``x0 = h/2 - a artanh(v / l)`` (derived from ``l = a (sinh u - sinh w)``,
``v = a (cosh u - cosh w)`` with ``u = (h - x0)/a``, ``w = -x0/a``).

With ``xi = h / (2a)`` the first equation is ``sinh(xi)/xi = rho``,
``rho = sqrt(l^2 - v^2)/h >= 1``: its left side increases monotonically, and
:func:`solve_sinhc` solves ``log(sinh(xi)/xi) = log(rho)`` by safeguarded Newton
from a start that is exact in both limits (``rho -> 1``: ``xi ~ sqrt(6 (rho - 1))``;
large ``rho``: ``xi ~ log(2 rho xi)``). The limits are handled explicitly:
a rope exactly as long as the chord is a straight segment; a rope between two
points on one vertical hangs folded (two vertical pieces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from optikin.errors import InputDataError

GRAVITY_DIRECTION = np.array([0.0, 0.0, -1.0])


def solve_sinhc(rho: float, tol: float = 1e-15) -> float:
    """The ``xi >= 0`` with ``sinh(xi)/xi = rho`` (``rho >= 1``)."""
    if rho < 1.0:
        raise ValueError(f"sinh(xi)/xi >= 1, got rho = {rho}")
    if rho - 1.0 < 1e-12:
        return math.sqrt(6.0 * (rho - 1.0))
    target = math.log(rho)
    # Start: the small-xi series inverted, or the large-xi fixed point of xi = log(2 rho xi).
    if rho < 3.0:
        xi = math.sqrt(6.0 * (rho - 1.0))
    else:
        xi = math.log(2.0 * rho)
        for _ in range(4):
            xi = math.log(2.0 * rho * xi)
    for _ in range(60):
        value = _log_sinhc(xi) - target
        slope = 1.0 / math.tanh(xi) - 1.0 / xi  # d/dxi log(sinh(xi)/xi) > 0
        new = xi - value / slope
        if new <= 0.0:
            new = 0.5 * xi
        if abs(new - xi) <= tol * max(xi, 1.0):
            return new
        xi = new
    return xi


def _log_sinhc(xi: float) -> float:
    """``log(sinh(xi)/xi)`` without overflow."""
    if xi < 1e-4:
        return xi * xi / 6.0
    if xi > 20.0:
        return xi - math.log(2.0 * xi) + math.log1p(-math.exp(-2.0 * xi))
    return math.log(math.sinh(xi) / xi)


@dataclass(frozen=True)
class Catenary:
    """A rope of length ``length`` from ``start`` to ``end`` (see the module docstring).

    ``horizontal``/``up`` span the rope's vertical plane (``up`` opposite to
    gravity); ``span``, ``rise`` are ``h``, ``v``; ``a`` is the catenary parameter
    (``inf`` for a straight rope, 0 for a folded one) and ``x0`` the abscissa of
    the lowest point.
    """

    start: np.ndarray
    end: np.ndarray
    length: float
    horizontal: np.ndarray
    up: np.ndarray
    span: float
    rise: float
    a: float
    x0: float

    @property
    def kind(self) -> str:
        if math.isinf(self.a):
            return "straight"
        return "folded" if self.a == 0.0 else "catenary"

    def _plane(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Plane coordinates ``(x, z)`` and unit tangent ``(dx/ds, dz/ds)`` at arc lengths ``s``."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        if self.kind == "straight":
            frac = s / self.length
            tx, tz = self.span / self.length, self.rise / self.length
            return frac * self.span, frac * self.rise, np.full_like(s, tx), np.full_like(s, tz)
        if self.kind == "folded":
            drop = 0.5 * (self.length - self.rise)  # from the start down to the fold
            down = s <= drop
            z = np.where(down, -s, -drop + (s - drop))
            return np.zeros_like(s), z, np.zeros_like(s), np.where(down, -1.0, 1.0)
        a, x0 = self.a, self.x0
        u = s / a - math.sinh(x0 / a)  # sinh((x - x0)/a)
        x = x0 + a * np.arcsinh(u)
        cosh = np.sqrt(1.0 + u * u)
        z = a * (cosh - math.cosh(x0 / a))
        return x, z, 1.0 / cosh, u / cosh

    def points(self, s: np.ndarray) -> np.ndarray:
        """Points at arc lengths ``s`` from the start, ``(..., 3)``."""
        x, z, _, _ = self._plane(s)
        return self.start + x[..., None] * self.horizontal + z[..., None] * self.up

    def tangents(self, s: np.ndarray) -> np.ndarray:
        """Unit tangents (pointing from start to end) at arc lengths ``s``, ``(..., 3)``."""
        _, _, tx, tz = self._plane(s)
        return tx[..., None] * self.horizontal + tz[..., None] * self.up

    def end_forces(self, weight_per_length: float) -> tuple[np.ndarray, np.ndarray]:
        """The forces the rope exerts on its two supports, ``(on start, on end)`` [N], each ``(3,)``.

        A perfectly flexible rope carries only its tension ``T(s)`` along its tangent; on a
        catenary of weight ``w`` per length the horizontal part is ``H = w a`` everywhere and
        ``T = H cosh((x - x0)/a)``, so the rope pulls the start along ``+T t(0)`` and the end
        along ``-T t(l)``: the vertical parts, ``w a sinh`` at each end, add up to the weight
        ``w l``. A folded rope hangs from each end by the weight of its piece below it.

        Parameters
        ----------
        weight_per_length:
            ``w = mu |g|`` [N/m], ``>= 0``.

        Raises
        ------
        ValueError
            For a straight rope with weight (exactly as long as its chord: the tension is infinite).
        """
        w = float(weight_per_length)
        if not (math.isfinite(w) and w >= 0):
            raise ValueError(f"weight per length must be finite and >= 0, got {w}")
        if w == 0.0:
            return np.zeros(3), np.zeros(3)
        if self.kind == "straight":
            raise ValueError("a rope as long as its chord has an infinite tension under its weight")
        if self.kind == "folded":
            drop = 0.5 * (self.length - self.rise)  # the piece hanging from the start
            return -w * drop * self.up, -w * (self.length - drop) * self.up
        H = w * self.a
        u0 = -math.sinh(self.x0 / self.a)
        u1 = self.length / self.a + u0
        on_start = H * (self.horizontal + u0 * self.up)
        on_end = -H * (self.horizontal + u1 * self.up)
        return on_start, on_end


def catenary(start, end, length: float, gravity=GRAVITY_DIRECTION, *, source: str = "") -> Catenary:
    """The hanging rope of ``length`` between ``start`` and ``end`` under ``gravity`` (a direction).

    Raises :class:`InputDataError` when the rope is shorter than the distance between its ends.
    """
    A, Bp = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    g = np.asarray(gravity, dtype=float)
    for name, v in (("start", A), ("end", Bp), ("gravity", g)):
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise InputDataError(f"expected a finite 3-vector, got {v!r}", source=source, field=name)
    if not np.linalg.norm(g) > 0:
        raise InputDataError("gravity direction has zero length", source=source, field="gravity")
    if not (math.isfinite(length) and length > 0):
        raise InputDataError(f"rope length must be positive, got {length}", source=source, field="length")
    up = -g / np.linalg.norm(g)
    chord = Bp - A
    rise = float(chord @ up)
    flat = chord - rise * up
    span = float(np.linalg.norm(flat))
    distance = math.hypot(span, rise)
    if length < distance * (1.0 - 1e-12):
        raise InputDataError(
            f"rope of length {length:.6g} cannot reach between points {distance:.6g} apart",
            source=source,
            field="length",
        )
    if span <= 1e-12 * length:
        horizontal = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
        horizontal /= np.linalg.norm(horizontal)
        if length <= abs(rise) * (1.0 + 1e-12):
            return Catenary(A, Bp, float(length), horizontal, up, 0.0, rise, math.inf, 0.0)
        return Catenary(A, Bp, float(length), horizontal, up, 0.0, rise, 0.0, 0.0)
    horizontal = flat / span
    if length <= distance * (1.0 + 1e-12):
        return Catenary(A, Bp, float(length), horizontal, up, span, rise, math.inf, 0.0)
    rho = math.sqrt(length * length - rise * rise) / span
    a = span / (2.0 * solve_sinhc(rho))
    x0 = 0.5 * span - a * math.atanh(rise / length)
    return Catenary(A, Bp, float(length), horizontal, up, span, rise, a, x0)
