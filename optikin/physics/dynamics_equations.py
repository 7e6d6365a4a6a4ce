"""The Cosserat rod with inertia, one implicit time step as a boundary-value problem in arc length.

Till, Aloi and Rucker, "Real-time dynamics of soft and continuum robots based on
Cosserat rod models", IJRR 38(6), 2019: the rod's state along ``s`` is

* ``p`` (3), the orientation quaternion (4), as in :mod:`optikin.physics.rod`;
* ``N, M`` (3 + 3, global frame): the section wrench carried by the rod *and* the
  actuators inside it (tendons, chambers), ``N = n + sum tau R t``,
  ``M = m + sum (R r) x tau R t`` (:mod:`optikin.physics.tendons`), so that only
  external loads enter the balance laws and the wrench is continuous across disks;
* ``q``, ``w`` (3 + 3, material frame): linear and angular velocity of the section.

The partial differential equations (their eqs. 2-7, written with ``N, M``):

    p_s = R v,    R_s = R [u]x,
    N_s = rho A R (q_t + w x q) + R (C q |q|) - f,
    M_s = -p_s x N + rho R (J w_t + w x J w) - l,
    q_s = v_t - u x q + w x v,
    w_s = u_t - u x w,

with the Kelvin-Voigt constitutive law ``n = R (K_se (v - v*) + B_se v_t)``,
``m = R (K_bt (u - u*) + B_bt u_t)``, ``J = diag(I, I, J_polar)``, ``C`` the
air-drag coefficients (material frame, per unit length, quadratic in the velocity)
and ``f = rho A g + f_distributed``.

Every time derivative is replaced by the BDF-alpha formula (their eq. 9)

    y_t(t_i) = c0 y(t_i) + y_h,    y_h = c1 y(t_{i-1}) + c2 y(t_{i-2}) + d1 y_t(t_{i-1}),
    c0 = (1.5 + a) / (dt (1 + a)),  c1 = -2 / dt,  c2 = (0.5 + a) / (dt (1 + a)),  d1 = a / (1 + a),

for ``y = (v, u, q, w)``: ``a = 0`` is BDF2, ``a = -1/2`` the trapezoidal rule
(non-dissipative). The history ``y_h`` is known at the time step, so each step is
an ordinary BVP in ``s``: clamped base (``q = w = 0``, ``N(0), M(0)`` unknown) and
``N(L) = F_tip, M(L) = C_tip``. Its integration is the statics' (classical RK4 on
a fixed grid, the quaternion renormalised after each step); the history is kept
at every RK4 *stage* of every grid step (four points per step: the node, two at
the midpoint, the end), so a rod at rest has exactly zero time derivatives and its
equilibrium is the statics' own discrete equilibrium.

With actuators the strains are found from ``N, M`` by a fixed-point iteration on
the actuator terms, started from tangents along ``d3`` (a chamber's tangent is
``d3``, exact at once): the map contracts by about ``tau / (G A)`` and
``tau r^2 / (E I)``, so a few iterations reach rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from optikin.algebra import matrix_from_quat, quat_from_pure, quat_multiply
from optikin.physics.model import ArmEquations, RodArm
from optikin.physics.rod import E3

STATE_SIZE = 19
"""``x = (p (3), quaternion (4), N (3), M (3), q (3), w (3))``."""
RATE_SIZE = 12
"""``y = (v, u, q, w)`` (3 each): the quantities whose time derivatives the scheme approximates."""
STAGES = 4
"""RK4 stages per grid step, each keeping its own history."""
ENERGY_NAMES = ("kinetic", "elastic", "gravity")
"""The energy terms a step integrates along the rod [J]."""


@dataclass(frozen=True)
class Coefficients:
    """The BDF-alpha coefficients of a time step ``dt`` and parameter ``alpha``."""

    dt: float
    alpha: float

    @property
    def c0(self) -> float:
        """``(1.5 + alpha) / (dt (1 + alpha))`` [1/s]."""
        return (1.5 + self.alpha) / (self.dt * (1.0 + self.alpha))

    @property
    def c1(self) -> float:
        """``-2 / dt`` [1/s]."""
        return -2.0 / self.dt

    @property
    def c2(self) -> float:
        """``(0.5 + alpha) / (dt (1 + alpha))`` [1/s]."""
        return (0.5 + self.alpha) / (self.dt * (1.0 + self.alpha))

    @property
    def d1(self) -> float:
        """``alpha / (1 + alpha)`` [-]."""
        return self.alpha / (1.0 + self.alpha)


@dataclass(frozen=True)
class SegmentDamping:
    """Kelvin-Voigt damping and air drag of one segment (diagonals, material frame)."""

    B_se: tuple[float, float, float]
    B_bt: tuple[float, float, float]
    drag: tuple[float, float, float]


class DynamicEquations:
    """The semi-discrete (in time) equations of a :class:`~optikin.physics.RodArm` as ``SX``.

    Parameters
    ----------
    arm : RodArm
        The arm (``model="cosserat"`` rods).
    damping : sequence of SegmentDamping
        One per segment.
    coefficients : Coefficients
        ``dt`` and ``alpha``.
    actuator_iterations : int
        Fixed-point iterations of the strains on the tendon terms.
    """

    def __init__(
        self,
        arm: RodArm,
        damping: tuple[SegmentDamping, ...],
        coefficients: Coefficients,
        actuator_iterations: int,
    ) -> None:
        self.arm = arm
        self.damping = damping
        self.coefficients = coefficients
        self.actuator_iterations = actuator_iterations
        self.statics = ArmEquations(arm)
        self.n_loads = self.statics.n_loads

    def strains(
        self, k: int, s: ca.SX, R: ca.SX, N: ca.SX, M: ca.SX, vh: ca.SX, uh: ca.SX, P: ca.SX
    ) -> tuple[ca.SX, ca.SX]:
        """``v, u`` (material frame) of segment ``k`` from the section wrench and the strain history."""
        rod, damp, c0 = self.arm.segments[k].rod, self.damping[k], self.coefficients.c0
        kse, kbt = ca.DM(rod.K_se), ca.DM(rod.K_bt)
        bse, bbt = ca.DM(damp.B_se), ca.DM(damp.B_bt)
        nb = R.T @ N + kse * ca.DM(E3) - bse * vh
        mb = R.T @ M + kbt * ca.DM(rod.intrinsic_curvature) - bbt * uh
        dse, dbt = kse + c0 * bse, kbt + c0 * bbt
        acts = self.statics.actuators[k]
        if not acts:
            return nb / dse, mb / dbt
        v, u = ca.SX(E3), ca.SX.zeros(3)
        iterations = 1 + (self.actuator_iterations if any(a.tendon is not None for a in acts) else 0)
        for it in range(iterations):
            T, C = ca.SX.zeros(3), ca.SX.zeros(3)
            for a in acts:
                r, t = a.offset_and_tangent(v, u, s)
                if it == 0:
                    t = ca.SX(E3)
                T += a.tension(P) * t
                C += a.tension(P) * ca.cross(r, t)
            v, u = (nb - T) / dse, (mb - C) / dbt
        return v, u

    def rhs(self, k: int, s: ca.SX, x: ca.SX, h: ca.SX, P: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """``(dx/ds (19), y = (v, u, q, w) (12), energy densities (3))`` in segment ``k``, history ``h`` (12)."""
        rod, damp, c0 = self.arm.segments[k].rod, self.damping[k], self.coefficients.c0
        p, quat, N, M, q, w = x[0:3], x[3:7], x[7:10], x[10:13], x[13:16], x[16:19]
        R = matrix_from_quat(quat, check=False)
        v, u = self.strains(k, s, R, N, M, h[0:3], h[3:6], P)
        v_t, u_t, q_t, w_t = c0 * v + h[0:3], c0 * u + h[3:6], c0 * q + h[6:9], c0 * w + h[9:12]
        rho_a = rod.density * rod.A
        inertia = ca.DM([rod.I, rod.I, rod.J]) * rod.density
        f = rho_a * P[9:12] + P[6:9]
        dp = R @ v
        dquat = 0.5 * quat_multiply(quat, quat_from_pure(u))
        body_force = rho_a * (q_t + ca.cross(w, q))
        if any(damp.drag):
            body_force += ca.DM(damp.drag) * q * ca.fabs(q)
        dN = R @ body_force - f
        dM = -ca.cross(dp, N) + R @ (inertia * w_t + ca.cross(w, inertia * w))
        dq = v_t - ca.cross(u, q) + ca.cross(w, v)
        dw = u_t - ca.cross(u, w)
        dv, du = v - ca.DM(E3), u - ca.DM(rod.intrinsic_curvature)
        energy = ca.vertcat(
            0.5 * rho_a * ca.dot(q, q) + 0.5 * ca.dot(w, inertia * w),
            0.5 * ca.dot(dv, ca.DM(rod.K_se) * dv) + 0.5 * ca.dot(du, ca.DM(rod.K_bt) * du),
            -rho_a * ca.dot(P[9:12], p),
        )
        return ca.vertcat(dp, dquat, dN, dM, dq, dw), ca.vertcat(v, u, q, w), energy

    def rk4_step(self, k: int, h: float) -> ca.Function:
        """``(x, s, H (48), P) -> (x(s + h), Y (48), energy (3))``: one RK4 step with the history of its stages.

        ``H`` and ``Y`` stack the history and the values of ``(v, u, q, w)`` at the four
        stages (node, midpoint, midpoint, end); the energy is the step's RK4 quadrature.
        """
        s, x, P = ca.SX.sym("s"), ca.SX.sym("x", STATE_SIZE), ca.SX.sym("P", self.n_loads)
        H = ca.SX.sym("H", RATE_SIZE * STAGES)
        part = [H[RATE_SIZE * i : RATE_SIZE * (i + 1)] for i in range(STAGES)]
        k1, y1, e1 = self.rhs(k, s, x, part[0], P)
        k2, y2, e2 = self.rhs(k, s + h / 2, x + h / 2 * k1, part[1], P)
        k3, y3, e3 = self.rhs(k, s + h / 2, x + h / 2 * k2, part[2], P)
        k4, y4, e4 = self.rhs(k, s + h, x + h * k3, part[3], P)
        xn = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        xn = ca.vertcat(xn[0:3], xn[3:7] / ca.norm_2(xn[3:7]), xn[7:19])
        energy = h / 6 * (e1 + 2 * e2 + 2 * e3 + e4)
        return ca.Function(
            f"rod_dynamics_rk4_{k}",
            [x, s, H, P],
            [xn, ca.vertcat(y1, y2, y3, y4), energy],
            ["x", "s", "H", "P"],
            ["x_next", "Y", "energy"],
        )

    def tip_function(self, tip_mass: float) -> ca.Function:
        """``(x_tip, h (12), P) -> (residual (6), y (12), energy (3))`` at the tip, a point mass ``tip_mass`` there.

        The residual is ``N(L) - F_tip - m g + m a``, ``M(L) - C_tip`` (global frame), with the tip's
        acceleration ``a = R (q_t + w x q)`` and ``q_t = c0 q + h_q``; ``y`` are the tip's ``(v, u, q, w)``
        (their history ``h`` kept like a stage's), the energy the mass's kinetic and gravitational.
        """
        k = len(self.arm.segments) - 1
        x, h, P = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("h", RATE_SIZE), ca.SX.sym("P", self.n_loads)
        R = matrix_from_quat(x[3:7], check=False)
        s = ca.SX(float(self.arm.boundaries[-1]))
        v, u = self.strains(k, s, R, x[7:10], x[10:13], h[0:3], h[3:6], P)
        q, w = x[13:16], x[16:19]
        force = R @ P[0:3] if self.arm.tip_force_frame == "follower" else P[0:3]
        couple = R @ P[3:6] if self.arm.tip_couple_frame == "follower" else P[3:6]
        g = P[9:12]
        acceleration = R @ (self.coefficients.c0 * q + h[6:9] + ca.cross(w, q))
        residual = ca.vertcat(x[7:10] - force - tip_mass * g + tip_mass * acceleration, x[10:13] - couple)
        energy = ca.vertcat(0.5 * tip_mass * ca.dot(q, q), 0, -tip_mass * ca.dot(g, x[0:3]))
        return ca.Function(
            "rod_dynamics_tip",
            [x, h, P],
            [residual, ca.vertcat(v, u, q, w), energy],
            ["x", "h", "P"],
            ["residual", "y", "energy"],
        )

    def base_state(self, wrench: ca.MX) -> ca.MX:
        """``x(0)``: the clamped pose, the unknown wrench ``(N(0), M(0))``, zero velocities."""
        pose = ca.DM(list(self.arm.base_position) + list(self.arm.base_orientation))
        return ca.vertcat(pose, wrench, ca.DM.zeros(6))
