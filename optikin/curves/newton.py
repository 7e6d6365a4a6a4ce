"""Newton iterations for the small minimum-energy problems, with the linear algebra inside CasADi.

The fast path of :mod:`optikin.curves.min_energy` calls one compiled Function per
iterate; that Function returns, as one flat vector of floats, everything the
Python loop needs (values, convergence measures and the Newton step), so the loop
does a handful of float comparisons and no numpy linear algebra.

* :func:`modified_newton_function` / :func:`modified_newton`: unconstrained, two
  variables; the Hessian's eigenvalues are floored (closed form for 2 x 2) so the
  step is a descent direction; Armijo backtracking on the energy. The outputs from a
  gradient and Hessian computed otherwise: :func:`modified_newton_outputs`; a step
  predicted to converge needs no Hessian at its end (:func:`converging_step`).
* :func:`kkt_newton_function` / :func:`kkt_newton`: ``min E s.t. S = L`` with
  simple bounds on some variables; null-space Newton (SQP) with the reduced
  Hessian shifted to positive definite where it is not, backtracking on an exact
  penalty function, fraction-to-boundary on the bounded variables.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from optikin.fastcall import BufferedFunction

ENERGY_NOISE = 1e-14
"""Relative rounding noise of an energy value: a line search accepts a step that raises E by less."""

SX = ca.SX | ca.DM
"""A CasADi expression (operations on SX may be typed DM)."""

MAX_ANGLE_STEP = 1.0
"""Largest change of the free angles in one Newton step (radians)."""

PREDICTION_SAFETY = 0.1
"""Factor on the tolerance a predicted gradient must meet (:func:`converging_step`)."""

CURVATURE_SAFETY = 20.0
"""Factor on the predicted change of the Hessian its smaller eigenvalue must exceed (:func:`converging_step`)."""


def modified_newton_function(energy: ca.SX, length: ca.SX, x: ca.SX, P: ca.SX) -> ca.Function:
    """``(x, P) -> [E, S, max|g|, lambda_min(H), p0, p1, g.p]`` for two variables ``x``."""
    g = ca.gradient(energy, x)
    H = ca.hessian(energy, x)[0]
    return ca.Function(
        "ph_modified_newton", [x, P], [modified_newton_outputs(energy, length, g, H[0, 0], H[0, 1], H[1, 1])]
    )


def modified_newton_outputs(energy: SX, length: SX, g: SX, h00: SX, h01: SX, h11: SX) -> ca.SX:
    """``[E, S, max|g|, lambda_min(H), p0, p1, g.p]`` from the energy, length, gradient ``g`` (2) and Hessian.

    The modified Newton step ``p = -(H + shift I)^-1 g``: the shift lifts the smaller eigenvalue
    of the symmetric ``H = [[h00, h01], [h01, h11]]`` (closed form) to ``1e-6 (|mean| + radius + 1)``
    where it is below, and ``p`` is cut to :data:`MAX_ANGLE_STEP`.
    """
    mean, half = 0.5 * (h00 + h11), 0.5 * (h00 - h11)
    radius = ca.sqrt(half * half + h01 * h01)
    lmin = mean - radius
    shift = ca.fmax(0.0, 1e-6 * (ca.fabs(mean) + radius + 1.0) - lmin)
    a, d = h00 + shift, h11 + shift
    det = a * d - h01 * h01
    p = ca.vertcat(-(d * g[0] - h01 * g[1]) / det, -(a * g[1] - h01 * g[0]) / det)
    p = p * ca.fmin(1.0, MAX_ANGLE_STEP / ca.norm_2(p))
    return ca.vertcat(energy, length, ca.mmax(ca.fabs(g)), lmin, p, ca.dot(g, p))


def converging_step(gmax: float, lmin: float, step: float, previous: float, tol: float, E: float) -> bool:
    """Whether the next full step lands where ``max|g| <= tol (1 + |E|)``, by quadratic convergence.

    ``gmax = max|g|`` and ``lmin`` (the Hessian's smaller eigenvalue) at the iterate, ``step`` the
    largest entry of its Newton step, ``previous`` that of the step that led to it. Newton's gradient
    falls as ``|g_next| ~ rho |p|^2``; ``rho = gmax / previous^2`` is measured on the last step (an
    overestimate where that step was not a pure Newton step). The step converges when
    ``rho step^2 <= PREDICTION_SAFETY tol (1 + |E|)``, and the Hessian stays positive definite over
    it when ``lmin > CURVATURE_SAFETY rho step`` (its change is about ``2 rho step``).
    """
    if not previous > 0:
        return False
    rho = gmax / (previous * previous)
    return rho * step * step <= PREDICTION_SAFETY * tol * (1.0 + abs(E)) and lmin > CURVATURE_SAFETY * rho * step


def modified_newton(fn: BufferedFunction, x0, tol: float, max_iterations: int):
    """Minimise from ``x0``; returns ``(x, E, S, iterations, converged)``.

    Converged: ``max|g| <= tol (1 + |E|)`` with a positive definite Hessian. Where the full step
    just taken was predicted to converge (:func:`converging_step`), the Hessian is taken as
    positive definite without a look at the new one: the exported C library then evaluates only
    ``E``, ``S`` and ``g`` there.
    """
    xin = fn.inputs[0]
    out = fn.outputs[0]
    x0_, x1_ = float(x0[0]), float(x0[1])
    xin[0], xin[1] = x0_, x1_
    fn()
    E, S, gmax, lmin, p0, p1, slope = out.tolist()
    previous, predicted = 0.0, False
    for it in range(max_iterations + 1):
        if gmax <= tol * (1.0 + abs(E)) and (predicted or lmin > 0):
            return np.array([x0_, x1_]), E, S, it, True
        if it == max_iterations:
            break
        size = max(abs(p0), abs(p1))
        predicted = converging_step(gmax, lmin, size, previous, tol, E)
        noise = ENERGY_NOISE * (1.0 + abs(E))
        step = 1.0
        for _ in range(30):
            xin[0], xin[1] = x0_ + step * p0, x1_ + step * p1
            fn()
            trial = out.tolist()
            if trial[0] <= E + 1e-4 * step * slope + noise:
                break
            step *= 0.5
            predicted = False
        else:
            break
        previous = step * size
        x0_, x1_ = x0_ + step * p0, x1_ + step * p1
        E, S, gmax, lmin, p0, p1, slope = trial
    return np.array([x0_, x1_]), E, S, it, False


def smallest_eigenvalue_3x3(M: ca.SX) -> ca.SX:
    """Smallest eigenvalue of a symmetric 3 x 3 matrix, closed form (trigonometric solution of the cubic)."""
    off = M[0, 1] ** 2 + M[0, 2] ** 2 + M[1, 2] ** 2
    q = (M[0, 0] + M[1, 1] + M[2, 2]) / 3.0
    spread = ca.sqrt(ca.fmax(((M[0, 0] - q) ** 2 + (M[1, 1] - q) ** 2 + (M[2, 2] - q) ** 2 + 2.0 * off) / 6.0, 1e-300))
    r = ca.fmin(1.0, ca.fmax(-1.0, ca.det((M - q * ca.DM.eye(3)) / spread) / 2.0))
    return q + 2.0 * spread * ca.cos(ca.acos(r) / 3.0 + 2.0 * math.pi / 3.0)


def kkt_newton_function(energy: ca.SX, constraint: ca.SX, length: ca.SX, x: ca.SX, P: ca.SX) -> ca.Function:
    """``(x, P) -> [E, S, c, max|grad L|, g.dx, pd, lam, dx, a/|a|^2]`` for ``min E s.t. c = 0``.

    ``lam = a.g / |a|^2`` is the least-squares multiplier at ``x`` (``a = grad c``),
    ``grad L = g - lam a``. Null-space Newton step: ``dx = -c a/|a|^2 + Z p`` with
    ``Z`` an orthonormal basis of ``a``'s complement (Householder) and
    ``(M + mu I) p = -Z'(g + W dx_r)``, where ``M = Z' W Z`` is the reduced Hessian
    of ``E - lam c``; ``mu = 0`` when ``M`` is positive definite (``pd = 1``,
    Sylvester's criterion), else twice the magnitude of its most negative
    eigenvalue (the eigenvalue is mirrored).
    """
    n = x.numel()
    g = ca.gradient(energy, x)
    a = ca.gradient(constraint, x)
    aa = ca.dot(a, a)
    lam = ca.dot(a, g) / aa
    W = ca.hessian(energy, x)[0] - lam * ca.hessian(constraint, x)[0]
    sign = ca.if_else(a[0] >= 0, 1.0, -1.0)
    v = a + sign * ca.sqrt(aa) * ca.DM.eye(n)[:, 0]
    Z = (ca.DM.eye(n) - 2.0 * ca.mtimes(v, v.T) / ca.dot(v, v))[:, 1:]
    M = ca.mtimes([Z.T, W, Z])
    minors = [M[0, 0], M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0], ca.det(M)]
    positive = minors[0] > 0
    for m in minors[1:]:
        positive = ca.logic_and(positive, m > 0)
    delta = 1e-8 * (1.0 + ca.mmax(ca.fabs(ca.diag(M))))
    mu = ca.if_else(positive, 0.0, delta - 2.0 * ca.fmin(0.0, smallest_eigenvalue_3x3(M)))
    dx_range = -constraint * a / aa
    p = -ca.solve(M + mu * ca.DM.eye(n - 1), ca.mtimes(Z.T, g + ca.mtimes(W, dx_range)))
    dx = dx_range + ca.mtimes(Z, p)
    grad_res = ca.mmax(ca.fabs(g - lam * a))
    out = ca.vertcat(energy, length, constraint, grad_res, ca.dot(g, dx), positive, lam, dx, a / aa)
    return ca.Function("ph_kkt_newton", [x, P], [out])


def kkt_newton(
    fn: BufferedFunction,
    x0,
    tol: float,
    length_scale: float,
    bounded: dict[int, tuple[float, float]],
    max_iterations: int,
):
    """Solve ``min E s.t. c = 0`` from ``x0``; returns ``(x, multiplier, E, S, iterations, converged)``.

    Steps of :func:`kkt_newton_function`, cut by a fraction-to-boundary rule on the
    bounded variables and by Armijo backtracking on the exact penalty
    ``E + nu |c|`` (``nu`` twice the largest multiplier seen). A full step the
    penalty rejects is retried with a second-order correction ``-c(x + dx) a/|a|^2``
    (the Maratos effect: on a curved constraint the full SQP step raises ``|c|`` to
    second order). Converged:
    ``max|grad L| <= tol (1 + |E|)``, ``|c| <= tol * length_scale``, reduced Hessian
    positive definite and no bounded variable on its bound (the caller then falls
    back to IPOPT, which handles active bounds).
    """
    xin = fn.inputs[0]
    out = fn.outputs[0]
    n = xin.size
    xin[:] = x0
    fn()
    vals = out.tolist()
    x = [float(v) for v in x0]
    penalty = 0.0
    for it in range(max_iterations + 1):
        E, S, c, grad_res, slope, positive, lam = vals[:7]
        if grad_res <= tol * (1.0 + abs(E)) and abs(c) <= tol * length_scale and positive > 0:
            inside = all(lo < x[k] < hi for k, (lo, hi) in bounded.items())
            return np.array(x), lam, E, S, it, inside
        if it == max_iterations:
            break
        dx, a_scaled = vals[7 : 7 + n], vals[7 + n :]
        penalty = max(penalty, 2.0 * abs(lam) + 1e-8)
        merit = E + penalty * abs(c)
        descent = slope - penalty * abs(c)
        step = 1.0
        for k, (lo, hi) in bounded.items():
            if dx[k] < 0:
                step = min(step, 0.9 * (x[k] - lo) / -dx[k])
            elif dx[k] > 0:
                step = min(step, 0.9 * (hi - x[k]) / dx[k])
        angle_step = math.hypot(dx[0], dx[1])
        if angle_step * step > MAX_ANGLE_STEP:
            step = MAX_ANGLE_STEP / angle_step
        noise = ENERGY_NOISE * (1.0 + abs(E))

        def accept(trial, step):
            return trial[0] + penalty * abs(trial[2]) <= merit + 1e-4 * step * min(descent, 0.0) + noise

        for attempt in range(31):
            for k in range(n):
                xin[k] = x[k] + step * dx[k]
            fn()
            trial = out.tolist()
            if accept(trial, step):
                x = [x[k] + step * dx[k] for k in range(n)]
                break
            if attempt == 0 and step == 1.0:
                corrected = [x[k] + dx[k] - trial[2] * a_scaled[k] for k in range(n)]
                xin[:] = corrected
                fn()
                trial = out.tolist()
                if accept(trial, 1.0):
                    x = corrected
                    break
            step *= 0.5
        else:
            break
        vals = trial
    return np.array(x), vals[6], vals[0], vals[1], it, False
