"""Spatial quintic Pythagorean-hodograph (PH) curves in quaternion form, and their Hermite interpolants.

A spatial PH quintic has the hodograph (Farouki, "Pythagorean-Hodograph Curves",
Springer 2008, ch. 22; seed 002 eqs. 8-11 in component form)

    r'(t) = A(t) i A*(t),   A(t) = A0 (1-t)^2 + A1 2(1-t)t + A2 t^2,

with quaternion coefficients ``A0, A1, A2``. Writing ``A = u + v i + p j + q k``
gives seed 002 eqs. (8)-(10); the parametric speed is ``sigma = |r'| = |A|^2``
(eq. 11), so the Pythagorean condition (eq. 6) holds identically.

First-order Hermite data ``(p0, d0, p1, d1)`` with ``d0 = r'(0)``, ``d1 = r'(1)``
are met by (Farouki, al-Kandari & Sakkalis, Adv. Comput. Math. 17 (2002) 369-383,
section 3, re-derived here):

* ``A0 i A0* = d0`` and ``A2 i A2* = d1``: ``A0 = A0_bar exp(i phi0)``,
  ``A2 = A2_bar exp(i phi2)`` for any particular roots ``A0_bar``, ``A2_bar``;
* integrating the hodograph from 0 to 1 and completing the square gives the
  displacement equation ``(3A0 + 4A1 + 3A2) i (3A0 + 4A1 + 3A2)* = alpha`` with
  ``alpha = 120 (p1 - p0) - 15 (d0 + d1) + 5 (A0 i A2* + A2 i A0*)``, so
  ``A1 = (Q(alpha) exp(i phi1) - 3 (A0 + A2)) / 4``.

Multiplying all three coefficients on the right by ``exp(i theta)`` leaves the
hodograph unchanged, so one of ``(phi0, phi1, phi2)`` is redundant. This module
keeps all three in :meth:`HermiteFamily.member` and fixes ``phi1 = 0`` where two
free angles are needed (:mod:`optikin.curves.min_energy`).

Roots of ``A i A* = v``
-----------------------
The textbook root ``sqrt(|v|(1+lambda)/2) (-sin phi + i cos phi + j (mu cos phi +
nu sin phi)/(1+lambda) + k (nu cos phi - mu sin phi)/(1+lambda))`` with
``v/|v| = (lambda, mu, nu)`` divides by zero when ``v`` points along ``-i``. The
rotation ``e -> v/|v|`` about ``e x v`` gives a root for any "pole" ``e``:

    Q_e(v) = (|v| + e.v, e x v) / sqrt(2 (|v| + e.v)) * U_e,   U_e i U_e* = e,

which is singular only at ``v/|v| = -e``. Three choices follow from it:

* ``U0`` = :func:`preimage` of the unit start direction ``t0`` (pole ``+i`` or
  ``-i``, whichever is nearer, so it never divides by zero), and
  ``A0_bar = sqrt|d0| U0``;
* every other root is carried from ``(t0, U0)`` (:func:`preimage_from_reference`):
  pole ``t0``, or, for vectors within 25.8 degrees of ``-t0``, a pole ``m``
  orthogonal to ``t0`` (along ``t0 x (p1 - p0)``) whose root is carried from ``U0``.
  Replacing ``U0`` by another root ``U0 exp(i theta)`` multiplies all roots by
  ``exp(i theta)``, which (phases shifted together) leaves every member of the
  family at the same ``(phi0, phi2)``: the parametrisation does not depend on the
  coordinate frame nor on which root of ``t0`` was taken, and moves continuously
  with the data unless the end direction or the pole below crosses the 25.8-degree
  cone around ``-t0`` (bends beyond about 154 degrees);
* for ``Q(alpha)`` the pole must not change as ``phi2 - phi0`` varies, or the
  family would be cut in pieces. ``alpha`` moves on the ellipse
  ``c + a cos(phi0 - phi2) + b sin(phi0 - phi2)`` (``c = 120 (p1 - p0) - 15 (d0 + d1)``,
  ``|a|, |b| <= R = 10 sqrt(|d0| |d1|)``), so :func:`_displacement_pole` takes
  ``e = c/|c|`` when ``|c| > R`` (then ``e.alpha > 0`` everywhere), and otherwise a
  unit normal of the ellipse's plane on the side of ``c`` (then ``e.alpha = e.c >= 0``).

Either way the root is smooth in the free angles; only ``alpha = 0``, where the
family itself degenerates, remains.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra import quat_conjugate, quat_multiply, quat_vector
from optikin.algebra.backend import Array
from optikin.curves.bernstein import bernstein_combine
from optikin.curves.vectors import as_column, cross, dot, norm, scale
from optikin.errors import InputDataError

QUAT_I = np.array([0.0, 1.0, 0.0, 0.0])
QUAT_J = np.array([0.0, 0.0, 1.0, 0.0])
QUAT_K = np.array([0.0, 0.0, 0.0, 1.0])

_TINY = 1e-300
POLE_FLIP_COSINE = -0.9
"""Roots are carried from the start direction ``t0`` unless a vector is within 25.8 degrees of ``-t0``."""
# An end derivative shorter than this fraction of the data's scale is taken as zero.
ZERO_DERIVATIVE_RATIO = 1e-12


def _times_i_conj(A: Array, C: Array) -> Array:
    """``A i C*`` (a full quaternion)."""
    return quat_multiply(quat_multiply(A, QUAT_I), quat_conjugate(C))


def _phase(phi: Array) -> Array:
    """``exp(i phi) = cos phi + i sin phi``."""
    zero = 0.0 * phi
    return B.stack([B.cos(phi), B.sin(phi), zero, zero])


def _quat_scale(q: Array, s: Array) -> Array:
    return B.stack([s * c for c in B.components(q, 4)])


def preimage(v: Array) -> Array:
    """A quaternion ``A`` with ``A i A* = v`` (a root of the 3-vector ``v``), smooth away from ``v_x = 0``.

    Uses the pole ``+i`` when ``v_x >= 0`` and ``-i`` (with ``U = k``) otherwise,
    so the denominator ``sqrt(2 (|v| + |v_x|))`` vanishes only at ``v = 0``
    (where the root is 0). All roots are ``preimage(v) exp(i phi)``.
    """
    vx, vy, vz = B.components(v, 3)
    a = norm(v) + B.fabs(vx)
    den = B.sqrt(B.fmax(2.0 * a, _TINY))
    positive = vx >= 0
    # pole +i: (a, 0, -vz, vy)/den;  pole -i: (a, 0, vz, -vy)/den * k = (vy, vz, 0, a)/den
    w = B.where(positive, a, vy)
    x = B.where(positive, 0.0 * a, vz)
    y = B.where(positive, -vz, 0.0 * a)
    z = B.where(positive, vy, a)
    return B.stack([w / den, x / den, y / den, z / den])


def preimage_about_pole(v: Array, pole: Array, pole_root: Array) -> Array:
    """``Q_e(v) = (|v| + e.v, e x v) / sqrt(2(|v| + e.v)) * U_e`` for a unit pole ``e`` with root ``U_e``.

    ``U_e i U_e* = e``; ``(|v| + e.v, e x v)/sqrt(...)`` is ``sqrt|v|`` times the
    shortest-arc rotation taking ``e`` to ``v/|v|``. Singular only at ``v/|v| = -e``.
    """
    s = norm(v) + dot(pole, v)
    den = B.sqrt(B.fmax(2.0 * s, _TINY))
    ex, ey, ez = B.components(cross(pole, v), 3)
    rotation = B.stack([s / den, ex / den, ey / den, ez / den])
    return quat_multiply(rotation, pole_root)


def preimage_from_reference(v: Array, reference: Array, reference_root: Array, side: Array) -> Array:
    """A root of ``A i A* = v`` carried from the root ``U`` of a unit ``reference`` direction ``e``.

    ``Q_e(v)`` (above) with the root ``U``, unless ``v`` points within
    ``arccos(-POLE_FLIP_COSINE)`` of ``-e``; there ``Q_m(v)`` with the unit ``side``
    direction ``m`` (orthogonal to ``e``) and its root ``Q_e(m)``. Both are ``U``
    multiplied on the left by rotations that do not depend on ``U``, so replacing
    ``U`` by ``U exp(i theta)`` multiplies every such root by ``exp(i theta)``.
    """
    flip = dot(reference, v) < POLE_FLIP_COSINE * norm(v)
    side_root = preimage_about_pole(side, reference, reference_root)
    pole = _select(flip, side, reference)
    root = B.stack([B.where(flip, a, b) for a, b in zip(B.components(side_root, 4), B.components(reference_root, 4))])
    return preimage_about_pole(v, pole, root)


def _side_direction(t0: Array, chord: Array) -> Array:
    """A unit vector orthogonal to ``t0``: along ``t0 x chord``, or ``t0 x`` a coordinate axis if the chord is
    along ``t0``."""
    across = cross(t0, chord)
    ux = B.components(t0, 3)[0]
    axis = _select(B.fabs(ux) < 0.9, QUAT_I[1:] + 0.0 * t0, QUAT_J[1:] + 0.0 * t0)
    use_chord = dot(across, across) > 0.01 * dot(chord, chord)
    return _unit(_select(use_chord, across, cross(t0, axis)))


def _safe_norm(v: Array) -> Array:
    """``|v|``, floored so that neither it nor its derivative is infinite at ``v = 0``.

    The unused branches of :func:`_displacement_pole` are differentiated too (their
    adjoint is zero, and ``0 * inf`` would poison the used branch).
    """
    return B.sqrt(B.fmax(dot(v, v), _TINY))


def _unit(v: Array) -> Array:
    return scale(v, 1.0 / _safe_norm(v))


def _select(condition: Array, a: Array, b: Array) -> Array:
    """Component-wise ``a if condition else b`` for vectors."""
    return B.stack([B.where(condition, ai, bi) for ai, bi in zip(B.components(a, 3), B.components(b, 3))])


def _displacement_pole(c: Array, a: Array, b: Array, radius: Array) -> Array:
    """A unit pole ``e`` with ``e.alpha >= 0`` on the whole ellipse ``c + a cos + b sin`` (module docstring).

    ``c/|c|`` if ``|c| > radius``; else the normal ``a x b`` on the side of ``c``;
    for a flat ellipse (``a`` parallel to ``b``, e.g. parallel end directions) a unit
    vector orthogonal to its line, towards ``c`` when ``c`` is off that line.
    """
    c2, a2, b2 = dot(c, c), dot(a, a), dot(b, b)
    normal = cross(a, b)
    side = B.where(dot(normal, c) < 0, -1.0, 1.0)
    e_normal = scale(_unit(normal), side)
    along = _unit(_select(a2 >= b2, a, b))
    c_across = c - scale(along, dot(c, along))
    ux = B.components(along, 3)[0]
    helper = _select(B.fabs(ux) < 0.9, QUAT_I[1:] + 0.0 * c, QUAT_J[1:] + 0.0 * c)
    e_flat = _select(dot(c_across, c_across) > 1e-24 * c2, _unit(c_across), _unit(cross(along, helper)))
    e_inside = _select(dot(normal, normal) > 1e-18 * a2 * b2, e_normal, e_flat)
    return _select(c2 > radius * radius, _unit(c), e_inside)


@dataclass(frozen=True)
class PHQuintic:
    """The spatial PH quintic ``r(t) = p0 + int_0^t A i A* dt`` of coefficients ``A0, A1, A2``.

    numpy coefficients are ``(..., 4)`` (a batch of curves), ``p0`` ``(..., 3)``;
    CasADi ones are ``4 x 1`` and ``3 x 1``. Evaluation at numpy ``t`` of shape
    ``T`` gives ``(..., *T, 3)``; at a CasADi scalar or ``1 x M`` row, ``3 x M``.
    """

    p0: Array
    A0: Array
    A1: Array
    A2: Array

    # -- the preimage A(t) and its derivatives --------------------------------
    def preimage(self, t: Array) -> Array:
        """``A(t)`` (quadratic, Bernstein form)."""
        return bernstein_combine([self.A0, self.A1, self.A2], t)

    def preimage_derivative(self, t: Array) -> Array:
        """``A'(t) = 2 (A1 - A0)(1 - t) + 2 (A2 - A1) t``."""
        return bernstein_combine([2.0 * (self.A1 - self.A0), 2.0 * (self.A2 - self.A1)], t)

    def preimage_second_derivative(self, t: Array) -> Array:
        """``A'' = 2 (A0 - 2 A1 + A2)``, broadcast over ``t``."""
        return bernstein_combine([2.0 * (self.A0 - 2.0 * self.A1 + self.A2)], t)

    # -- hodograph and derivatives ---------------------------------------------
    def hodograph(self, t: Array) -> Array:
        """``r'(t) = A(t) i A*(t)``."""
        A = self.preimage(t)
        return quat_vector(_times_i_conj(A, A))

    def derivatives(self, t: Array) -> tuple[Array, Array, Array]:
        """``(r', r'', r''')`` at ``t``: ``r'' = 2 vec(A' i A*)``, ``r''' = 2 vec(A'' i A*) + 2 A' i A'*``."""
        A, dA, ddA = self.preimage(t), self.preimage_derivative(t), self.preimage_second_derivative(t)
        d1 = quat_vector(_times_i_conj(A, A))
        d2 = 2.0 * quat_vector(_times_i_conj(dA, A))
        d3 = 2.0 * quat_vector(_times_i_conj(ddA, A)) + 2.0 * quat_vector(_times_i_conj(dA, dA))
        return d1, d2, d3

    def hodograph_coefficients(self) -> list[Array]:
        """Quartic Bernstein coefficients ``w0..w4`` of ``r'(t)`` (Farouki 2008, eq. 22.9 re-derived).

        ``w0 = A0 i A0*``, ``w1 = vec(A0 i A1*)``, ``w2 = (2 A1 i A1* + vec(A0 i A2*))/3``,
        ``w3 = vec(A1 i A2*)``, ``w4 = A2 i A2*``.
        """
        A0, A1, A2 = self.A0, self.A1, self.A2
        v = lambda P, C: quat_vector(_times_i_conj(P, C))  # noqa: E731
        return [v(A0, A0), v(A0, A1), (2.0 * v(A1, A1) + v(A0, A2)) / 3.0, v(A1, A2), v(A2, A2)]

    def control_points(self) -> list[Array]:
        """Bezier control points ``P0..P5`` (seed 002 eqs. 12-13): ``P_{k+1} = P_k + w_k / 5``."""
        points = [self.p0]
        for w in self.hodograph_coefficients():
            points.append(points[-1] + w / 5.0)
        return points

    def point(self, t: Array) -> Array:
        """``r(t)`` from the control points (seed 002 eq. 12)."""
        return bernstein_combine(self.control_points(), t)

    # -- speed and arc length --------------------------------------------------
    def speed_coefficients(self) -> list[Array]:
        """Quartic Bernstein coefficients of ``sigma(t) = |A(t)|^2`` (seed 002 eq. 11).

        ``sigma0 = |A0|^2``, ``sigma1 = A0.A1``, ``sigma2 = (2|A1|^2 + A0.A2)/3``,
        ``sigma3 = A1.A2``, ``sigma4 = |A2|^2`` (``.`` is the 4-D dot product).
        """
        A0, A1, A2 = self.A0, self.A1, self.A2
        d = _qdot
        return [d(A0, A0), d(A0, A1), (2.0 * d(A1, A1) + d(A0, A2)) / 3.0, d(A1, A2), d(A2, A2)]

    def parametric_speed(self, t: Array) -> Array:
        """``sigma(t) = |r'(t)| = |A(t)|^2`` (numpy: shape ``(..., *T)``; CasADi: ``1 x M``)."""
        A = self.preimage(t)
        return B.sum_squares(B.components(A, 4))

    def arc_length(self) -> Array:
        """Total arc length ``S = (sigma0 + ... + sigma4)/5`` (seed 002 eq. 7 in closed form)."""
        s = self.speed_coefficients()
        return (s[0] + s[1] + s[2] + s[3] + s[4]) / 5.0

    def arc_length_at(self, t: Array) -> Array:
        """``s(t) = int_0^t sigma``: quintic with Bernstein coefficients ``S_k = (sigma_0 + ... + sigma_{k-1})/5``."""
        sigmas = self.speed_coefficients()
        cumulative = [0.0 * sigmas[0]]
        for sk in sigmas:
            cumulative.append(cumulative[-1] + sk / 5.0)
        if B.any_casadi(*cumulative) or B.is_casadi(t):
            return bernstein_combine([ca.DM(c) if not B.is_casadi(c) else c for c in cumulative], t)
        return bernstein_combine([np.asarray(c)[..., None] for c in cumulative], t)[..., 0]

    # -- curvature, torsion, frames --------------------------------------------
    def curvature(self, t: Array) -> Array:
        """``kappa = |r' x r''| / |r'|^3``."""
        d1, d2, _ = self.derivatives(t)
        sigma = norm(d1)
        return norm(cross(d1, d2)) / (sigma * sigma * sigma)

    def torsion(self, t: Array) -> Array:
        """``tau = (r' x r'').r''' / |r' x r''|^2`` (undefined where the curvature vanishes)."""
        d1, d2, d3 = self.derivatives(t)
        c = cross(d1, d2)
        return dot(c, d3) / dot(c, c)

    def frame(self, t: Array) -> Array:
        """Euler-Rodrigues frame as unit quaternions ``A(t)/|A(t)|``.

        The frame maps ``(i, j, k)`` to ``(A i A*, A j A*, A k A*)/sigma``: its first
        axis is the unit tangent (Farouki 2008, section 22.4).
        """
        A = self.preimage(t)
        return _quat_scale(A, 1.0 / B.sqrt(B.sum_squares(B.components(A, 4))))

    def frame_vectors(self, t: Array) -> tuple[Array, Array, Array]:
        """The Euler-Rodrigues frame ``(e1, e2, e3)``, ``e1`` the unit tangent."""
        A = self.preimage(t)
        inv_sigma = 1.0 / B.sum_squares(B.components(A, 4))
        out = []
        for unit in (QUAT_I, QUAT_J, QUAT_K):
            out.append(scale(quat_vector(quat_multiply(quat_multiply(A, unit), quat_conjugate(A))), inv_sigma))
        return out[0], out[1], out[2]


def _qdot(P: Array, C: Array) -> Array:
    return sum(p * c for p, c in zip(B.components(P, 4), B.components(C, 4)))


@dataclass(frozen=True)
class HermiteFamily:
    """All PH quintics interpolating ``(p0, d0, p1, d1)``: the data-only part of the construction.

    ``A0_bar``, ``A2_bar`` are particular roots of ``d0``, ``d1``; ``center``,
    ``axis_cos``, ``axis_sin`` describe the ellipse swept by ``alpha`` as
    ``phi0 - phi2`` varies; ``pole`` and ``pole_root`` fix the root ``Q(alpha)``.
    Build it with :func:`hermite_family`; :meth:`member` picks one curve.
    """

    p0: Array
    p1: Array
    d0: Array
    d1: Array
    A0_bar: Array
    A2_bar: Array
    center: Array
    axis_cos: Array
    axis_sin: Array
    pole: Array
    pole_root: Array

    def member(self, phi0: Array = 0.0, phi2: Array = 0.0, phi1: Array = 0.0) -> PHQuintic:
        """The interpolant of free angles ``(phi0, phi1, phi2)`` (Farouki et al. 2002, eqs. re-derived above).

        Adding one angle to all three gives the same curve.
        """
        fam = self
        if B.any_casadi(phi0, phi1, phi2) and not B.is_casadi(self.A0_bar):
            fam = _family_to_casadi(self)
        A0 = quat_multiply(fam.A0_bar, _phase(phi0))
        A2 = quat_multiply(fam.A2_bar, _phase(phi2))
        alpha = fam.center + 10.0 * quat_vector(_times_i_conj(A0, A2))
        Q = quat_multiply(preimage_about_pole(alpha, fam.pole, fam.pole_root), _phase(phi1))
        A1 = 0.25 * (Q - 3.0 * (A0 + A2))
        return PHQuintic(fam.p0, A0, A1, A2)


def _family_to_casadi(f: HermiteFamily) -> HermiteFamily:
    sizes = dict(p0=3, p1=3, d0=3, d1=3, A0_bar=4, A2_bar=4, center=3, axis_cos=3, axis_sin=3, pole=3, pole_root=4)
    return HermiteFamily(**{k: as_column(getattr(f, k), n) for k, n in sizes.items()})


def validate_hermite_data(p0, d0, p1, d1, *, source: str = "") -> tuple[np.ndarray, ...]:
    """Check numpy Hermite data: shapes ``(..., 3)`` that broadcast, finite, non-zero end derivatives.

    Raises :class:`InputDataError` naming the field (and the sample of a batch).
    Coincident end points are allowed: they give closed PH loops.
    """
    arrays = {}
    for name, x in (("p0", p0), ("d0", d0), ("p1", p1), ("d1", d1)):
        x = np.asarray(x, dtype=float)
        if x.shape[-1:] != (3,):
            raise InputDataError(f"expected 3-vectors (last axis 3), got shape {x.shape}", source=source, field=name)
        arrays[name] = x
    try:
        batch = np.broadcast_shapes(*(x.shape[:-1] for x in arrays.values()))
    except ValueError as exc:
        raise InputDataError(f"batch shapes do not broadcast: {exc}", source=source) from None
    out = {k: np.array(np.broadcast_to(v, batch + (3,))) for k, v in arrays.items()}
    for name, x in out.items():
        bad = ~np.all(np.isfinite(x), axis=-1)
        if np.any(bad):
            raise InputDataError("not finite", source=source, field=name, sample=_first(bad))
    chord = np.linalg.norm(out["p1"] - out["p0"], axis=-1)
    size0, size1 = np.linalg.norm(out["d0"], axis=-1), np.linalg.norm(out["d1"], axis=-1)
    scale_ = np.maximum(np.maximum(chord, size0), size1)
    for name, size in (("d0", size0), ("d1", size1)):
        bad = ~(size > ZERO_DERIVATIVE_RATIO * scale_)
        if np.any(bad):
            raise InputDataError(
                "end derivative has zero length: a PH quintic needs a direction and a non-zero speed at each end",
                source=source,
                field=name,
                sample=_first(bad),
            )
    return out["p0"], out["d0"], out["p1"], out["d1"]


def _first(mask: np.ndarray) -> int | None:
    if mask.ndim == 0:
        return None
    return int(np.flatnonzero(mask.reshape(-1))[0])


def hermite_family(p0: Array, d0: Array, p1: Array, d1: Array, *, source: str = "") -> HermiteFamily:
    """The two-parameter family of PH quintics with ``r(0)=p0, r(1)=p1, r'(0)=d0, r'(1)=d1``.

    numpy data are validated (:func:`validate_hermite_data`); CasADi data are taken as given.
    """
    if not B.any_casadi(p0, d0, p1, d1):
        p0, d0, p1, d1 = validate_hermite_data(p0, d0, p1, d1, source=source)
    elif not all(B.is_casadi(x) for x in (p0, d0, p1, d1)):
        p0, d0, p1, d1 = (as_column(x, 3) for x in (p0, d0, p1, d1))
    speed0 = norm(d0)
    t0 = scale(d0, 1.0 / speed0)
    U0 = preimage(t0)
    A0_bar = _quat_scale(U0, B.sqrt(speed0))
    side = _side_direction(t0, p1 - p0)
    A2_bar = preimage_from_reference(d1, t0, U0, side)
    center = 120.0 * (p1 - p0) - 15.0 * (d0 + d1)
    axis_cos = 10.0 * quat_vector(_times_i_conj(A0_bar, A2_bar))
    axis_sin = -10.0 * quat_vector(quat_multiply(A0_bar, quat_conjugate(A2_bar)))
    radius = 10.0 * B.sqrt(speed0 * norm(d1))
    pole = _displacement_pole(center, axis_cos, axis_sin, radius)
    pole_root = preimage_from_reference(pole, t0, U0, side)
    return HermiteFamily(p0, p1, d0, d1, A0_bar, A2_bar, center, axis_cos, axis_sin, pole, pole_root)


def ph_quintic_hermite(
    p0: Array,
    d0: Array,
    p1: Array,
    d1: Array,
    phi0: Array = 0.0,
    phi2: Array = 0.0,
    phi1: Array = 0.0,
    *,
    source: str = "",
) -> PHQuintic:
    """The PH quintic Hermite interpolant of ``(p0, d0, p1, d1)`` with free angles ``(phi0, phi1, phi2)``."""
    return hermite_family(p0, d0, p1, d1, source=source).member(phi0, phi2, phi1)
