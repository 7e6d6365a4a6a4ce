"""Exact solvers the networks of seed 004 are measured against, and the realisation of commanded lengths.

Seed 004 replaces the numerical solution of the inverse kinematic equations
(7)-(9) by networks because "least square, Newton-Raphson methods [...] are
usually computationally intensive" (section IV-A). These are those methods:

Forward (leg lengths -> ``(Z_k, theta_k, psi_k)``, eq. 10):

* :class:`PlatformNewton`: a CasADi ``newton`` rootfinder on the three equations
  ``|Q_{m,k}| = q_{m,k}`` of one platform, mapped over all platforms of a batch
  in one call; started from the linearisation ``q_1 - (q_2 + q_3)/2 ~ 3/2 r_{k+1}
  sin theta``, ``q_2 - q_3 ~ sqrt(3) r_{k+1} sin psi cos theta``, ``Z ~ mean(q)``.
* :func:`platform_least_squares`: scipy ``least_squares`` (MINPACK
  Levenberg-Marquardt) on the 48 equations of an arm, one call per sample.

Inverse (tip position -> 48 platform variables, hyper-redundant):

* :class:`TipIpopt`: IPOPT through CasADi ``nlpsol``: the admissible configuration
  closest to the straight mid-range pose, ``min 1/2 ||(q - q_rest) / range||^2``
  subject to ``p_tip(q) = p*``, every leg within Table I and every upper attachment
  point above its lower vertebra (the conditions of the learning database).
* :func:`tip_least_squares`: scipy ``least_squares`` (trust-region reflective,
  box bounds only) on ``(p_tip(q) - p*, mu (q - q_rest)/range)``.

:func:`realise` is how every inverse method is scored: the leg lengths it
commands (eqs. 7-9 of its configuration) are clipped to Table I, as the
actuators would, the pose they produce is found by :class:`PlatformNewton`, and
its tip by the exact chain of eq. (5).

The IK solvers of :mod:`optikin.solvers` were not committed when this was
written; these self-contained ones stand in for them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from optikin.arms.cbha import PLATFORM_LEG_LENGTHS, CBHAArm, platform_leg_vectors
from optikin.batch import batch_evaluate

NEWTON_TOLERANCE = 1e-13
"""Largest ``|q(x) - q|`` [m] over the three legs counted as solved."""
CLIP_TOLERANCE = 1e-9
"""A commanded length counts as clipped when it leaves Table I by more than this [m] (a solver's
constraint tolerance is not a clip)."""


def initial_platform_guess(q1, q2, q3, r_upper):
    """Linearised solution of eqs. (7)-(9) (module docstring); numpy or CasADi."""
    mod = ca if isinstance(q1, (ca.SX, ca.MX)) else np
    clip = (lambda v: ca.fmin(ca.fmax(v, -0.9), 0.9)) if mod is ca else (lambda v: np.clip(v, -0.9, 0.9))
    theta = mod.arcsin(clip((q1 - 0.5 * (q2 + q3)) / (1.5 * r_upper)))
    psi = mod.arcsin(clip((q2 - q3) / (np.sqrt(3.0) * r_upper * mod.cos(theta))))
    return (q1 + q2 + q3) / 3.0, theta, psi


class PlatformNewton:
    """Newton's method on each platform's equations (7)-(9), batched over platforms and samples."""

    def __init__(self, arm: CBHAArm, max_iterations: int = 50, tolerance: float = NEWTON_TOLERANCE):
        self.arm = arm
        self.max_iterations = int(max_iterations)
        self.tolerance = float(tolerance)

    @cached_property
    def function(self) -> ca.Function:
        """``[q_1, q_2, q_3, r_k, r_{k+1}] -> [Z, theta, psi, max_m |q_m(x) - q_m|]``."""
        x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 5)
        g = PLATFORM_LEG_LENGTHS(x[0], x[1], x[2], p[3], p[4]) - p[:3]
        rf = ca.rootfinder("cbha_platform_newton", "newton", ca.Function("g", [x, p], [g]),
                           {"max_iter": self.max_iterations, "abstol": self.tolerance * 1e-2,
                            "error_on_fail": False, "show_eval_warnings": False})
        w = ca.SX.sym("w", 5)
        x0 = ca.vertcat(*initial_platform_guess(w[0], w[1], w[2], w[4]))
        solution = rf(x0, w)
        residual = ca.mmax(ca.fabs(PLATFORM_LEG_LENGTHS(solution[0], solution[1], solution[2], w[3], w[4]) - w[:3]))
        return ca.Function("cbha_platform_forward", [w], [ca.vertcat(solution, residual)])

    def solve(self, legs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(configurations (n, 48), largest leg residual per sample [m])`` from leg lengths ``(n, 48)``."""
        legs = np.atleast_2d(np.asarray(legs, dtype=float))
        n, n_platforms = len(legs), self.arm.geometry.n_platforms
        r = self.arm.geometry.radii
        W = np.empty((n, n_platforms, 5))
        W[:, :, :3] = legs.reshape(n, n_platforms, 3)
        W[:, :, 3], W[:, :, 4] = r[:-1], r[1:]
        out = batch_evaluate(self.function, W.reshape(-1, 5)).reshape(n, n_platforms, 4)
        return out[:, :, :3].reshape(n, -1), out[:, :, 3].max(axis=1)


def linearised_configurations(arm: CBHAArm, legs: np.ndarray) -> np.ndarray:
    """The starting points of :class:`PlatformNewton` for a batch ``(n, 48)`` of leg lengths."""
    n = len(legs)
    L = legs.reshape(n, -1, 3)
    Z, theta, psi = initial_platform_guess(L[..., 0], L[..., 1], L[..., 2], arm.geometry.radii[1:])
    return np.stack([Z, theta, psi], axis=-1).reshape(n, -1)


def platform_least_squares(arm: CBHAArm, legs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """scipy Levenberg-Marquardt on the 48 leg equations of each sample; same outputs as
    :meth:`PlatformNewton.solve`."""
    legs = np.atleast_2d(np.asarray(legs, dtype=float))
    fun, jac = _leg_functions(arm)
    X0 = linearised_configurations(arm, legs)
    Q, residual = np.empty_like(X0), np.empty(len(legs))
    with threadpool_limits(1):  # small dense algebra: BLAS threads only add overhead
        for i, (target, x0) in enumerate(zip(legs, X0)):
            sol = least_squares(lambda q: fun(q).full().ravel() - target, x0, jac=lambda q: jac(q).full(),
                                method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
            Q[i], residual[i] = sol.x, np.abs(sol.fun).max()
    return Q, residual


def _leg_functions(arm: CBHAArm) -> tuple[ca.Function, ca.Function]:
    q = ca.SX.sym("q", arm.n_config)
    legs = arm.leg_length_expressions(q)
    return ca.Function("legs", [q], [legs]), ca.Function("legs_jac", [q], [ca.jacobian(legs, q)])


# ---------------------------------------------------------------------------------------- inverse
def upright_expressions(arm: CBHAArm, q: ca.SX) -> ca.SX:
    """Heights ``Q_{m,k,z}`` of every upper attachment point above its lower vertebra (eq. 4)."""
    r = arm.geometry.radii
    return ca.vertcat(*[Q[2] for k in range(arm.geometry.n_platforms)
                        for Q in platform_leg_vectors(q[3 * k], q[3 * k + 1], q[3 * k + 2], r[k], r[k + 1])])


def rest_configuration(arm: CBHAArm) -> np.ndarray:
    """The straight pose with every leg at mid elongation, where the inverse solvers start."""
    return arm.straight_configuration(0.5)


@dataclass
class IKReport:
    configurations: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    seconds: np.ndarray


class TipIpopt:
    """IPOPT on the admissible tip-position IK closest to the rest pose (module docstring)."""

    def __init__(self, arm: CBHAArm, tolerance: float = 1e-10, max_iterations: int = 200):
        self.arm = arm
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)

    @cached_property
    def solver(self) -> ca.Function:
        arm = self.arm
        q, target = ca.SX.sym("q", arm.n_config), ca.SX.sym("p", 3)
        span = arm.upper - arm.lower
        cost = 0.5 * ca.sumsqr((q - rest_configuration(arm)) / span)
        g = ca.vertcat(arm.fk_position(q) - target, arm.leg_length_expressions(q), upright_expressions(arm, q))
        opts = {"ipopt": {"print_level": 0, "tol": self.tolerance, "max_iter": self.max_iterations,
                          "constr_viol_tol": self.tolerance, "sb": "yes"},
                "print_time": False, "error_on_fail": False}
        return ca.nlpsol("cbha_tip_ipopt", "ipopt", {"x": q, "p": target, "f": cost, "g": g}, opts)

    @cached_property
    def constraint_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.arm.leg_limits()
        n_legs = len(lo)
        return (np.concatenate([np.zeros(3), lo, np.zeros(n_legs)]),
                np.concatenate([np.zeros(3), hi, np.full(n_legs, np.inf)]))

    def solve(self, targets: np.ndarray) -> IKReport:
        targets = np.atleast_2d(np.asarray(targets, dtype=float))
        n, x0 = len(targets), rest_configuration(self.arm)
        lbg, ubg = self.constraint_bounds
        solver = self.solver  # built before the clock starts
        Q, converged = np.empty((n, self.arm.n_config)), np.zeros(n, dtype=bool)
        iterations, seconds = np.zeros(n, dtype=int), np.zeros(n)
        for i, target in enumerate(targets):
            start = time.perf_counter()
            sol = solver(x0=x0, p=target, lbx=self.arm.lower, ubx=self.arm.upper, lbg=lbg, ubg=ubg)
            seconds[i] = time.perf_counter() - start
            stats = solver.stats()
            Q[i] = np.clip(np.asarray(sol["x"]).ravel(), self.arm.lower, self.arm.upper)
            converged[i], iterations[i] = bool(stats["success"]), int(stats.get("iter_count", -1))
        return IKReport(Q, converged, iterations, seconds)


def tip_least_squares(arm: CBHAArm, targets: np.ndarray, regularisation: float = 1e-10) -> IKReport:
    """scipy trust-region reflective on ``(p_tip(q) - p*, mu (q - q_rest)/range)`` within the box bounds.

    Table I and the upright condition are not imposed: :func:`realise` clips what it commands.
    """
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    q = ca.SX.sym("q", arm.n_config)
    span, rest = arm.upper - arm.lower, rest_configuration(arm)
    fun = ca.Function("f", [q], [arm.fk_position(q)])
    jac = ca.Function("J", [q], [ca.jacobian(arm.fk_position(q), q)])
    mu = np.sqrt(regularisation)
    Q, converged = np.empty((len(targets), arm.n_config)), np.zeros(len(targets), dtype=bool)
    iterations, seconds = np.zeros(len(targets), dtype=int), np.zeros(len(targets))
    with threadpool_limits(1):
        for i, target in enumerate(targets):
            start = time.perf_counter()
            sol = least_squares(lambda x: np.concatenate([fun(x).full().ravel() - target, mu * (x - rest) / span]),
                                rest, jac=lambda x: np.vstack([jac(x).full(), np.diag(mu / span)]),
                                bounds=(arm.lower, arm.upper), method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12)
            seconds[i] = time.perf_counter() - start
            Q[i], converged[i], iterations[i] = sol.x, sol.status > 0, sol.nfev
    return IKReport(Q, converged, iterations, seconds)


@dataclass
class Realised:
    """What the robot does with the leg lengths a method commands (``clipped``: per sample, whether a
    length left Table I by more than :data:`CLIP_TOLERANCE`)."""

    commanded: np.ndarray
    clipped: np.ndarray
    configurations: np.ndarray
    tip: np.ndarray
    newton_residual: np.ndarray


def realise(arm: CBHAArm, configurations: np.ndarray, newton: PlatformNewton) -> Realised:
    """Leg lengths of ``configurations`` (eqs. 7-9) clipped to Table I, the pose they produce, its tip."""
    configurations = np.atleast_2d(configurations)
    commanded = arm.evaluate("leg_lengths", configurations).reshape(len(configurations), -1)
    lo, hi = arm.leg_limits()
    applied = np.clip(commanded, lo, hi)
    Q, residual = newton.solve(applied)
    return Realised(commanded=commanded, clipped=np.any(np.abs(applied - commanded) > CLIP_TOLERANCE, axis=1),
                    configurations=Q, tip=arm.evaluate("fk_position", Q), newton_residual=residual)
