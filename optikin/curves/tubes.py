"""Tube lengths of the CBHA from a PH backbone: the inverse kinematics of seed 002, section V.B.

Seed 002: "Three tubes are attached (constrained) to the backbone of the CBHA arm.
Therefore the lengths L1, L2 and L3 of the entire tubes of the CBHA arm are computed
from the backbone length". Here tube ``m`` is the offset curve

    r_m(t) = r(t) + rho(t) (cos(a_m) f2(t) + sin(a_m) f3(t)),

of the backbone ``r(t)`` (a :class:`~optikin.curves.ph_quintic.PHQuintic`), where
``(f1 = tangent, f2, f3)`` is a frame carried along the curve with ``f2(0)`` the
reference normal ``n0`` at the base, ``a_m`` the tube's angle about the tangent and
``rho`` the offset radius; ``L_m = int_0^1 |r_m'(t)| dt``.

Which frame
-----------
The seed says the CBHA "is not able to make a torsion movement around its
longitudinal axis" and that the tubes are "attached (constrained) to the backbone":
a tube keeps its place around the backbone without turning about the tangent, which
is the rotation-minimising frame (RMF; Bishop 1975, Farouki 2008 ch. 20), whose
angular velocity has no component along the tangent. That is the default. The
Euler-Rodrigues (ER) frame ``A/|A|`` native to PH curves turns about the tangent
at the rate ``2 g_i / sigma`` (``G = A* A'``, :func:`optikin.curves.energy.rotation_rate_coefficients`),
which is set by the hodograph, not by the arm; it is offered for comparison
(``frame="euler_rodrigues"``). The RMF is the ER frame turned about the tangent by
``gamma(t) = -int_0^t 2 g_i / sigma dt``; the integrand is rational, and
``gamma`` at every node ``t_j`` is computed by the same Gauss-Legendre rule mapped to
``[0, t_j]``.

The integrand
-------------
With ``omega = 2 (g_i, g_j, g_k) / sigma`` the ER frame's angular velocity in its own
axes and ``beta_m(t) = a_m + gamma0 + gamma(t)`` the tube's angle from the ER frame's
second axis (``gamma0``: the angle of ``n0`` at ``t = 0``; ``gamma = 0`` for the ER
frame), ``r_m' = F ((sigma, 0, 0) + omega_eff x u + rho' u / rho)`` with
``u = rho (0, cos beta, sin beta)`` and ``omega_eff = omega + gamma' i``; the cross
terms cancel and

    |r_m'|^2 = (sigma + rho (omega_j sin beta - omega_k cos beta))^2 + (rho omega_t)^2 + rho'^2,

``omega_t = 0`` for the RMF and ``omega_i`` for the ER frame. The first term is
``sigma (1 - rho kappa cos(angle from the principal normal))``: a circular arc of
radius ``R`` through ``theta`` gives ``L = (R - rho cos(angle)) theta``; the second is
the winding of a tube about a twisting frame, the third the taper.

Offset radius
-------------
Seed 002 gives none. The CBHA model (seed 004 eq. 2, :mod:`optikin.arms.cbha`) puts
the tubes' attachment points at ``r_n`` from the vertebra centres, tapering linearly
from ``r_max = 40 mm`` at the base to ``r_min = 29 mm`` at the tip (both assumptions,
see :class:`~optikin.arms.cbha.CBHAGeometry`). The default follows it, linear in arc
length: ``rho(s) = rho0 + (rho1 - rho0) s / S`` (the vertebrae are about evenly
spaced along the backbone); a constant radius is ``rho0 = rho1``. The angles default
to the CBHA's ``u_m`` (:data:`~optikin.arms.cbha.LEG_DIRECTIONS`): 180, 60 and -60
degrees from the base frame's x axis about its z axis (the backbone), so ``n0`` is
the base x axis.

Everything works on a numpy batch of curves (coefficients ``(..., 4)``, lengths
``(..., 3)``) and on CasADi symbols (``3 x 1``), so the tube lengths can join the
compiled Functions of :mod:`optikin.curves.min_energy`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra import quat_conjugate, quat_multiply, quat_vector
from optikin.algebra.backend import Array
from optikin.arms.cbha import LEG_DIRECTIONS, CBHAGeometry
from optikin.curves.bernstein import bernstein_basis, gauss_legendre_unit
from optikin.curves.energy import rotation_rate_coefficients
from optikin.curves.ph_quintic import QUAT_J, QUAT_K, PHQuintic
from optikin.curves.vectors import dot
from optikin.errors import InputDataError

DEFAULT_TUBE_NODES = 32
"""Gauss-Legendre nodes of the tube-length quadrature: converged to 1e-12 relative up to rho kappa = 0.87
(tests/test_ph_tubes.py); the integrand grows a kink as rho kappa -> 1, where a tube would fold."""

FRAMES = ("rmf", "euler_rodrigues")

CBHA_TUBE_ANGLES = tuple(float(math.atan2(u[1], u[0])) for u in LEG_DIRECTIONS)
"""Angles of the CBHA's tubes ``u_1, u_2, u_3`` from the base x axis about the backbone: 180, 60, -60 degrees."""


@dataclass(frozen=True)
class TubeLayout:
    """Where the tubes run around the backbone, and which frame carries them (module docstring).

    Attributes
    ----------
    radius_start, radius_end:
        Offset radius at the base and at the tip, metres; linear in arc length between.
        Default: the CBHA vertebra radii ``r_max``, ``r_min`` of :class:`CBHAGeometry`.
    angles:
        Angle of each tube about the tangent from the reference normal ``n0`` (radians).
    frame:
        ``"rmf"`` (rotation-minimising, the default) or ``"euler_rodrigues"``.
    """

    radius_start: float = CBHAGeometry.r_max
    radius_end: float = CBHAGeometry.r_min
    angles: tuple[float, ...] = CBHA_TUBE_ANGLES
    frame: str = "rmf"

    def __post_init__(self):
        object.__setattr__(self, "angles", tuple(float(a) for a in self.angles))
        if not (self.radius_start >= 0 and self.radius_end >= 0 and math.isfinite(self.radius_start + self.radius_end)):
            raise ValueError(
                f"offset radii must be finite and non-negative, got {self.radius_start}, {self.radius_end}"
            )
        if self.frame not in FRAMES:
            raise ValueError(f"frame must be one of {', '.join(FRAMES)}, got {self.frame!r}")
        if not self.angles or not all(math.isfinite(a) for a in self.angles):
            raise ValueError(f"need at least one finite tube angle, got {self.angles}")

    @classmethod
    def cbha(cls, geometry: CBHAGeometry | None = None, frame: str = "rmf") -> "TubeLayout":
        """The tubes of a CBHA model: radii ``r_max`` to ``r_min``, angles of ``u_1, u_2, u_3``."""
        g = geometry or CBHAGeometry()
        return cls(g.r_max, g.r_min, CBHA_TUBE_ANGLES, frame)

    def with_frame(self, frame: str) -> "TubeLayout":
        return TubeLayout(self.radius_start, self.radius_end, self.angles, frame)


# ------------------------------------------------------------------------------ polynomials at fixed points
def _basis(degree: int, points: np.ndarray) -> np.ndarray:
    """``(M, degree + 1)`` Bernstein basis at the given points."""
    return np.stack(bernstein_basis(degree, np.asarray(points, dtype=float).ravel()), axis=-1)


@lru_cache(maxsize=None)
def _rule_basis(degree: int, nodes: int, nested: bool) -> np.ndarray:
    """The basis at the Gauss-Legendre nodes ``t_j`` (or at ``t_j x_k``, :func:`_nested_points`), kept."""
    t, _ = gauss_legendre_unit(nodes)
    basis = _basis(degree, _nested_points(t, nodes) if nested else t)
    basis.setflags(write=False)
    return basis


def _nested_points(t: np.ndarray, nodes: int) -> np.ndarray:
    """``t_j x_k`` for every ``t_j`` (rows) and Gauss-Legendre node ``x_k`` (columns), flattened."""
    x, _ = gauss_legendre_unit(nodes)
    return np.outer(t, x).ravel()


def _values(coefficients: list[Array], basis: np.ndarray) -> Array:
    """A scalar Bernstein polynomial at the points of ``basis``: numpy ``(..., M)``, CasADi ``M x 1``."""
    if B.any_casadi(*coefficients):
        return ca.mtimes(ca.DM(basis), ca.vertcat(*coefficients))
    return np.stack(np.broadcast_arrays(*coefficients), axis=-1) @ basis.T


def rmf_angle(curve: PHQuintic, t: np.ndarray | None = None, nodes: int = DEFAULT_TUBE_NODES) -> Array:
    """``gamma(t) = -int_0^t 2 g_i / sigma``: the RMF is the ER frame turned by ``gamma`` about the tangent.

    ``t`` a 1-D numpy array of parameters (default: the ``nodes`` Gauss-Legendre nodes,
    the only choice for CasADi curves); each integral is the ``nodes``-point rule mapped
    to ``[0, t_j]``. numpy ``(..., T)``, CasADi ``nodes x 1``.
    """
    x, w = gauss_legendre_unit(nodes)
    on_nodes = t is None
    t = x if on_nodes else np.asarray(t, dtype=float).ravel()
    gi, _, _ = rotation_rate_coefficients(curve)
    sigmas = curve.speed_coefficients()
    if on_nodes:
        rate = 2.0 * _values(gi, _rule_basis(3, nodes, True)) / _values(sigmas, _rule_basis(4, nodes, True))
    else:
        inner = _nested_points(t, nodes)
        rate = 2.0 * _values(gi, _basis(3, inner)) / _values(sigmas, _basis(4, inner))
    if B.is_casadi(rate):
        if not on_nodes:
            raise ValueError("CasADi curves: the RMF angle is available at the Gauss-Legendre nodes only")
        return -ca.mtimes(ca.DM(np.kron(np.diag(t), w[None, :])), rate)
    return -(rate.reshape(rate.shape[:-1] + (t.size, nodes)) @ w) * t


def _arc_length_coefficients(curve: PHQuintic) -> list[Array]:
    """Quintic Bernstein coefficients of ``s(t) = int_0^t sigma`` (``S_k = (sigma_0 + ... + sigma_{k-1})/5``)."""
    out = [0.0 * curve.speed_coefficients()[0]]
    for sk in curve.speed_coefficients():
        out.append(out[-1] + sk / 5.0)
    return out


def reference_angle(curve: PHQuintic, reference_normal: Array, *, source: str = "") -> Array:
    """``gamma0``: the angle of ``n0`` from the ER frame's second axis ``A0 j A0* / |A0|^2`` about the tangent.

    numpy data are checked: ``n0`` must not be parallel to the start tangent.
    """
    A0 = curve.A0
    e2 = quat_vector(quat_multiply(quat_multiply(A0, QUAT_J), quat_conjugate(A0)))
    e3 = quat_vector(quat_multiply(quat_multiply(A0, QUAT_K), quat_conjugate(A0)))
    c, s = dot(reference_normal, e2), dot(reference_normal, e3)
    if not B.any_casadi(c, s):
        across = np.hypot(c, s)
        size = np.linalg.norm(np.asarray(reference_normal, dtype=float), axis=-1) * np.sum(np.square(A0), axis=-1)
        bad = ~(across > 1e-6 * size)
        if np.any(bad):
            sample = int(np.flatnonzero(np.ravel(bad))[0]) if np.ndim(bad) else None
            raise InputDataError(
                "the reference normal is parallel to the start tangent (or zero): it must point across the backbone",
                source=source,
                sample=sample,
                field="reference_normal",
            )
    return B.atan2(s, c)


# ------------------------------------------------------------------------------ tube lengths
def tube_lengths(
    curve: PHQuintic,
    reference_normal: Array,
    layout: TubeLayout = TubeLayout(),
    nodes: int = DEFAULT_TUBE_NODES,
    *,
    source: str = "",
) -> Array:
    """Lengths ``L_m`` of the tubes of ``layout`` along ``curve`` (module docstring).

    numpy ``(..., M)``, CasADi ``M x 1``.

    ``reference_normal`` ``n0`` fixes where angle 0 lies at the base (only its part
    across the start tangent matters).
    """
    _, w = gauss_legendre_unit(nodes)
    sigma = _values(curve.speed_coefficients(), _rule_basis(4, nodes, False))
    gi, gj, gk = (_values(g, _rule_basis(3, nodes, False)) for g in rotation_rate_coefficients(curve))
    omega_j, omega_k = 2.0 * gj / sigma, 2.0 * gk / sigma
    rho0, rho1 = layout.radius_start, layout.radius_end
    taper = rho1 - rho0
    if taper:
        S = curve.arc_length()
        if not B.is_casadi(S):
            S = np.asarray(S)[..., None]
        rho = rho0 + taper * _values(_arc_length_coefficients(curve), _rule_basis(5, nodes, False)) / S
        drho2 = (taper * sigma / S) ** 2
    else:
        rho, drho2 = rho0 + 0.0 * sigma, 0.0 * sigma
    gamma0 = reference_angle(curve, reference_normal, source=source)
    if layout.frame == "rmf":
        turn = rmf_angle(curve, None, nodes)
        twist2 = 0.0 * sigma
    else:
        turn = 0.0 * sigma
        twist2 = (rho * 2.0 * gi / sigma) ** 2
    if not B.is_casadi(turn):
        gamma0 = np.asarray(gamma0)[..., None]
    lengths = []
    for a in layout.angles:
        beta = a + gamma0 + turn
        along = sigma + rho * (omega_j * B.sin(beta) - omega_k * B.cos(beta))
        speed = B.sqrt(along * along + twist2 + drho2)
        lengths.append(ca.dot(speed, ca.DM(w)) if B.is_casadi(speed) else speed @ w)
    return B.stack(lengths) if B.any_casadi(*lengths) else np.stack(lengths, axis=-1)


def carried_frame(
    curve: PHQuintic, reference_normal: Array, t: np.ndarray, frame: str = "rmf", nodes: int = DEFAULT_TUBE_NODES
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The frame ``(f1, f2, f3)`` that carries the tubes, at numpy parameters ``t`` (numpy curves only).

    ``f1`` is the unit tangent, ``f2(0)`` the part of ``n0`` across the start tangent;
    each vector ``(..., T, 3)``.
    """
    if frame not in FRAMES:
        raise ValueError(f"frame must be one of {', '.join(FRAMES)}, got {frame!r}")
    t = np.asarray(t, dtype=float).ravel()
    e1, e2, e3 = curve.frame_vectors(t)
    angle = np.asarray(reference_angle(curve, reference_normal))[..., None]
    if frame == "rmf":
        angle = angle + rmf_angle(curve, t, nodes)
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    return e1, c * e2 + s * e3, c * e3 - s * e2


def tube_points(
    curve: PHQuintic,
    reference_normal: Array,
    t: np.ndarray,
    layout: TubeLayout = TubeLayout(),
    nodes: int = DEFAULT_TUBE_NODES,
) -> np.ndarray:
    """Points of every tube at numpy parameters ``t``: ``(..., M, T, 3)`` (numpy curves only)."""
    t = np.asarray(t, dtype=float).ravel()
    _, f2, f3 = carried_frame(curve, reference_normal, t, layout.frame, nodes)
    S = curve.arc_length()
    fraction = np.asarray(curve.arc_length_at(t)) / np.asarray(S)[..., None]
    rho = (layout.radius_start + (layout.radius_end - layout.radius_start) * fraction)[..., None]
    r = curve.point(t)
    return np.stack([r + rho * (np.cos(a) * f2 + np.sin(a) * f3) for a in layout.angles], axis=-3)
