"""Nonlinear least squares over all postures at once: Levenberg-Marquardt on the Schur complement.

The unknowns are one small vector ``x_k`` per posture (its configuration) and the
shared parameters ``beta`` (:mod:`optikin.calibration.model`). The residual of
marker ``j`` in posture ``k`` is ``r_kj = f_j(x_k, beta) - y_kj`` (3 components,
metres) and the cost

    F = 1/2 sum_kj c^2 rho(|r_kj|^2 / c^2) + 1/2 sum_i (s (beta_i - mu_i) / sigma_i)^2

with a robust loss ``rho`` of scale ``c`` (``linear``: ``rho(s) = s``; ``huber``:
``s`` for ``s <= 1``, ``2 sqrt(s) - 1`` beyond; ``soft_l1``: ``2 (sqrt(1 + s) - 1)``;
Triggs et al. 2000 sec. 3.3, the losses of scipy's ``least_squares``) on whole
marker errors, and Gaussian priors on chosen shared parameters, weighed against the data with
the expected marker noise ``s`` (both terms are then ``s^2`` times a negative log-likelihood). Each iteration
takes the weights ``w_kj = rho'(s_kj)`` (iteratively reweighted least squares: the
gradient of ``F`` is exactly ``sum w J^T r``) and solves the damped Gauss-Newton
system, whose ``x`` block is block diagonal, by eliminating the per-posture blocks
(the Schur complement on ``beta``; Triggs et al. 2000 sec. 6.1):

    S = C - sum_k B_k^T A_k^-1 B_k,   S d_beta = -(g_beta - sum_k B_k^T A_k^-1 g_k),
    d_x_k = -A_k^-1 (g_k + B_k d_beta),

``A_k = J_xk^T W J_xk``, ``B_k = J_xk^T W J_beta,k``, ``C = sum_k J_beta,k^T W J_beta,k``
(plus the prior), each diagonal damped by ``lambda (diag + eps)`` (Marquardt 1963), and each
posture's step clipped to :data:`MAX_POSTURE_STEP`. The
cost of an iteration is linear in the number of postures: one mapped CasADi call for
the residuals and exact Jacobians, batched ``n_x x n_x`` solves, one ``n_beta`` solve.

Bounds on the shared parameters (:attr:`Problem.lower`, :attr:`Problem.upper`; the section lengths of a
calibration) are kept by projecting every trial step onto them; a parameter that ends on its bound is
named by :mod:`optikin.calibration.identifiability`.

At the solution, the covariance of the free shared parameters is
``sigma^2 S^-1`` (``S`` undamped, with the robust weights), with
``sigma^2 = sum w |r|^2 / (n_residuals - n_unknowns)``: the marginal of
``sigma^2 (J^T W J)^-1`` (Triggs et al. 2000 sec. 6.2).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from optikin.calibration.model import MarkerModel

Loss = Literal["linear", "huber", "soft_l1"]

MAX_POSTURE_STEP = 0.25
"""Largest change of any per-posture variable in one step [rad, m]: a posture far from the model, whose robust
weight is tiny, would otherwise take huge steps in its own block."""


def loss_value(s: np.ndarray, loss: Loss) -> np.ndarray:
    """``rho(s)`` of the module docstring, ``s = |r|^2 / c^2``."""
    if loss == "linear":
        return s
    if loss == "huber":
        return np.where(s <= 1.0, s, 2.0 * np.sqrt(s) - 1.0)
    return 2.0 * (np.sqrt(1.0 + s) - 1.0)


def loss_weight(s: np.ndarray, loss: Loss) -> np.ndarray:
    """``rho'(s)``: the weight of a marker error in the reweighted Gauss-Newton step."""
    if loss == "linear":
        return np.ones_like(s)
    if loss == "huber":
        return np.where(s <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(s, 1.0)))
    return 1.0 / np.sqrt(1.0 + s)


@dataclass(eq=False)
class Problem:
    """One calibration problem: the model, the measurements and what is estimated.

    Attributes
    ----------
    model : MarkerModel
        Marker positions as functions of ``(x, beta, R_ref)``.
    measured : numpy.ndarray
        ``(N, M, 3)`` measured marker positions [m]; NaN where a marker was not seen.
    ref : numpy.ndarray
        ``(3, 3)`` reference base orientation ``R_ref``.
    free : numpy.ndarray
        ``(n_beta,)`` bool: shared parameters estimated (the others stay at their value).
    prior_mean, prior_sigma : numpy.ndarray
        ``(n_beta,)`` Gaussian prior on the shared parameters; ``inf`` sigma for none.
    loss : str
        ``linear``, ``huber`` or ``soft_l1``.
    loss_scale : float
        ``c`` [m]: marker errors well below it count quadratically.
    noise : float
        Expected marker noise per coordinate [m]: the priors are weighed against the data
        with it (their residuals are ``noise (beta - mu) / sigma``).
    actuators : numpy.ndarray, optional
        ``(N, n_a)`` actuator readings minus their reference, for a layout with an actuator map.
    lower, upper : numpy.ndarray, optional
        ``(n_beta,)`` bounds on the shared parameters (default none): every step is projected onto them.
    """

    model: MarkerModel
    measured: np.ndarray
    ref: np.ndarray
    free: np.ndarray
    prior_mean: np.ndarray
    prior_sigma: np.ndarray
    loss: Loss = "soft_l1"
    loss_scale: float = 1e-3
    noise: float = 3e-4
    actuators: np.ndarray | None = None
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    @property
    def seen(self) -> np.ndarray:
        """``(N, M)``: markers measured."""
        return np.all(np.isfinite(self.measured), axis=2)

    def subset(self, postures: np.ndarray) -> "Problem":
        """The same problem on some postures."""
        return Problem(
            self.model,
            self.measured[postures],
            self.ref,
            self.free,
            self.prior_mean,
            self.prior_sigma,
            self.loss,
            self.loss_scale,
            self.noise,
            None if self.actuators is None else self.actuators[postures],
            self.lower,
            self.upper,
        )

    def held(self, loss: Loss | None = None) -> "Problem":
        """The same problem with every shared parameter held (and, given, another loss): per-posture fits."""
        return Problem(
            self.model,
            self.measured,
            self.ref,
            np.zeros_like(self.free),
            self.prior_mean,
            self.prior_sigma,
            self.loss if loss is None else loss,
            self.loss_scale,
            self.noise,
            self.actuators,
            self.lower,
            self.upper,
        )

    def project(self, beta: np.ndarray) -> np.ndarray:
        """``beta`` clipped to the bounds."""
        if self.lower is not None:
            beta = np.maximum(beta, self.lower)
        if self.upper is not None:
            beta = np.minimum(beta, self.upper)
        return beta


@dataclass(eq=False)
class Fit:
    """The solution of :func:`solve`.

    Attributes
    ----------
    X : numpy.ndarray
        ``(N, n_x)`` per-posture configurations.
    beta : numpy.ndarray
        ``(n_beta,)`` shared parameters.
    errors : numpy.ndarray
        ``(N, M)`` marker errors ``|r_kj|`` [m] (NaN where not seen).
    weights : numpy.ndarray
        ``(N, M)`` robust weights ``rho'`` at the solution.
    covariance : numpy.ndarray
        ``(n_beta, n_beta)``: ``sigma^2 S^-1`` on the free parameters, zero elsewhere.
    sigma : float
        Residual standard deviation per coordinate [m] (weighted).
    cost : float
        ``F`` at the solution.
    iterations : int
        Accepted steps.
    converged : bool
        The relative decrease of ``F`` (or the step) fell below the tolerance.
    seconds : float
        Wall time.
    """

    X: np.ndarray
    beta: np.ndarray
    errors: np.ndarray
    weights: np.ndarray
    covariance: np.ndarray
    sigma: float
    cost: float
    iterations: int
    converged: bool
    seconds: float = 0.0
    history: list[float] = field(default_factory=list)

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of the shared parameters (0 for fixed ones)."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))


class _State:
    """Residuals, weights and cost at one point."""

    def __init__(self, problem: Problem, X: np.ndarray, beta: np.ndarray, jacobians: bool) -> None:
        lay = problem.model.layout
        markers, self.Jx, self.Jb = problem.model.evaluate(X, beta, problem.ref, jacobians, problem.actuators)
        N, M = len(X), lay.n_markers
        seen = problem.seen
        r = markers.reshape(N, M, 3) - np.where(seen[..., None], problem.measured, 0.0)
        r = np.where(seen[..., None], r, 0.0)
        self.r = r
        c2 = problem.loss_scale**2
        s = np.sum(r * r, axis=2) / c2
        self.w = np.where(seen, loss_weight(s, problem.loss), 0.0)
        prior = np.isfinite(problem.prior_sigma)
        scaled = problem.noise * (beta - problem.prior_mean) / np.where(prior, problem.prior_sigma, 1.0)
        self.prior = np.where(prior, scaled, 0.0)
        self.posture_cost = 0.5 * c2 * np.sum(np.where(seen, loss_value(s, problem.loss), 0.0), axis=1)
        self.cost = float(np.sum(self.posture_cost)) + 0.5 * float(self.prior @ self.prior)
        self.finite = bool(np.isfinite(self.cost))


def _normal_equations(
    problem: Problem, state: _State
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``A (N, nx, nx)``, ``B (N, nx, nf)``, ``C (nf, nf)``, ``g_x (N, nx)``, ``g_beta (nf,)`` on the free ``beta``."""
    assert state.Jx is not None and state.Jb is not None
    N = len(state.r)
    W = np.repeat(state.w, 3, axis=1)  # (N, 3M)
    r = state.r.reshape(N, -1)
    Jx, Jb = state.Jx, state.Jb[:, :, problem.free]
    WJx = W[:, :, None] * Jx
    A = np.einsum("nki,nkj->nij", WJx, Jx)
    B = np.einsum("nki,nkj->nij", WJx, Jb)
    C = np.einsum("nki,nk,nkj->ij", Jb, W, Jb)
    gx = np.einsum("nki,nk->ni", WJx, r)
    gb = np.einsum("nki,nk->i", Jb, W * r)
    sigma = problem.prior_sigma[problem.free]
    has_prior = np.isfinite(sigma)
    inv = np.where(has_prior, problem.noise / np.where(has_prior, sigma, 1.0), 0.0)
    C = C + np.diag(inv * inv)
    gb = gb + inv * state.prior[problem.free]
    return A, B, C, gx, gb


def _step(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, gx: np.ndarray, gb: np.ndarray, lam: float
) -> tuple[np.ndarray, np.ndarray]:
    """The damped Gauss-Newton step ``(d_x (N, nx), d_beta (nf,))`` through the Schur complement."""
    nx = A.shape[1]
    if nx == 0:  # no per-posture unknowns (an actuator map): the shared step alone
        S = C + lam * (np.diag(np.diag(C)) + 1e-12 * np.eye(len(C)))
        return np.zeros(gx.shape), -np.linalg.solve(S, gb)
    eye = np.eye(nx)
    Ad = A + lam * (np.diagonal(A, axis1=1, axis2=2)[:, :, None] * eye + 1e-12 * eye)
    rhs = np.concatenate([gx[:, :, None], B], axis=2)
    solved = np.linalg.solve(Ad, rhs)
    Ainv_g, Ainv_B = solved[:, :, 0], solved[:, :, 1:]
    if B.shape[2] == 0:
        return -Ainv_g, np.zeros(0)
    S = C + lam * (np.diag(np.diag(C)) + 1e-12 * np.eye(len(C))) - np.einsum("nki,nkj->ij", B, Ainv_B)
    db = -np.linalg.solve(S, gb - np.einsum("nki,nk->i", B, Ainv_g))
    dx = -(Ainv_g + np.einsum("nij,j->ni", Ainv_B, db))
    return dx, db


def solve(
    problem: Problem,
    X0: np.ndarray,
    beta0: np.ndarray,
    max_iterations: int = 100,
    tolerance: float = 1e-10,
    step_tolerance: float = 1e-10,
) -> Fit:
    """Minimise the cost of the module docstring from ``(X0, beta0)`` by Levenberg-Marquardt.

    Parameters
    ----------
    problem : Problem
        The measurements and what is estimated.
    X0 : numpy.ndarray
        ``(N, n_x)`` starting configurations.
    beta0 : numpy.ndarray
        ``(n_beta,)`` starting shared parameters (fixed ones keep their value).
    max_iterations : int
        Accepted steps at most.
    tolerance : float
        Stop when an accepted step lowers ``F`` by less than ``tolerance F``.
    step_tolerance : float
        Or when it moves no free shared parameter by more than this [m, rad] (the per-posture
        configurations of postures far from the model, which a robust loss hardly weighs, may
        creep on long after the shared parameters have settled).

    Returns
    -------
    Fit
        The solution, its marker errors and the covariance of the free parameters.
    """
    started = time.perf_counter()
    if not problem.free.any():
        return solve_postures(problem, X0, beta0, max_iterations, tolerance, step_tolerance)
    X, beta = np.array(X0, dtype=float), problem.project(np.array(beta0, dtype=float))
    free = problem.free
    state = _State(problem, X, beta, True)
    if not state.finite:
        raise ValueError("the starting point gives a non-finite cost")
    lam, iterations, converged = 1e-3, 0, False
    history = [state.cost]
    while iterations < max_iterations:
        A, B, C, gx, gb = _normal_equations(problem, state)
        accepted = stalled = False
        while lam < 1e12:
            dx, db = _step(A, B, C, gx, gb, lam)
            if dx.shape[1]:
                largest = np.max(np.abs(dx), axis=1, keepdims=True)
                dx = dx * np.minimum(1.0, MAX_POSTURE_STEP / np.maximum(largest, 1e-300))
            X_new = X + dx
            beta_new = beta.copy()
            beta_new[free] += db
            beta_new = problem.project(beta_new)
            db = (beta_new - beta)[free]
            trial = _State(problem, X_new, beta_new, True)  # Jacobians too: most trials are accepted
            if trial.finite and trial.cost <= state.cost:
                accepted = True
                break
            if trial.finite and trial.cost - state.cost <= tolerance * state.cost:
                stalled = True  # the step changes F by less than the tolerance: rounding, not a worse point
                break
            lam *= 10.0
        if not accepted:
            converged = stalled or lam >= 1e12
            break
        decrease = state.cost - trial.cost
        X, beta = X_new, beta_new
        previous = state.cost
        state = trial
        history.append(state.cost)
        iterations += 1
        lam = max(lam * 0.3, 1e-9)
        shared_settled = free.any() and float(np.max(np.abs(db))) <= step_tolerance
        if decrease <= tolerance * max(previous, 1e-300) or shared_settled:
            converged = True
            break
    covariance, sigma = _covariance(problem, state, len(X))
    errors = np.where(problem.seen, np.linalg.norm(state.r, axis=2), np.nan)
    return Fit(
        X,
        beta,
        errors,
        state.w,
        covariance,
        sigma,
        state.cost,
        iterations,
        converged,
        time.perf_counter() - started,
        history,
    )


def solve_postures(
    problem: Problem,
    X0: np.ndarray,
    beta: np.ndarray,
    max_iterations: int = 100,
    tolerance: float = 1e-10,
    step_tolerance: float = 1e-10,
) -> Fit:
    """Every posture's configuration with all shared parameters held: ``N`` independent Levenberg-Marquardt
    solves, batched, each with its own damping and its own stop (a posture far from the model does not hold
    the others back).

    Parameters and returns as :func:`solve` (the covariance is zero: nothing shared is estimated); a posture
    stops when a step lowers its cost by less than ``tolerance`` times it or moves none of its variables by
    more than ``step_tolerance``.
    """
    started = time.perf_counter()
    X = np.array(X0, dtype=float)
    beta = np.asarray(beta, dtype=float)
    N = len(X)
    lam = np.full(N, 1e-3)
    active = np.ones(N, dtype=bool)
    iterations = np.zeros(N, dtype=int)
    state = _State(problem, X, beta, True)
    if not state.finite:
        raise ValueError("the starting point gives a non-finite cost")
    cost = state.posture_cost.copy()
    Jx, r, w = state.Jx, state.r, state.w
    assert Jx is not None
    eye = np.eye(X.shape[1])
    if X.shape[1] == 0:
        active[:] = False  # nothing per posture to solve for: the shared parameters predict every posture
    while active.any() and iterations.max() < max_iterations:
        idx = np.flatnonzero(active)
        W = np.repeat(w[idx], 3, axis=1)
        WJ = W[:, :, None] * Jx[idx]
        A = np.einsum("nki,nkj->nij", WJ, Jx[idx])
        g = np.einsum("nki,nk->ni", WJ, r[idx].reshape(len(idx), -1))
        damped = A + lam[idx, None, None] * (np.diagonal(A, axis1=1, axis2=2)[:, :, None] * eye + 1e-12 * eye)
        dx = -np.linalg.solve(damped, g[:, :, None])[:, :, 0]
        largest = np.max(np.abs(dx), axis=1, keepdims=True)
        dx = dx * np.minimum(1.0, MAX_POSTURE_STEP / np.maximum(largest, 1e-300))
        X_trial = X.copy()
        X_trial[idx] += dx  # every posture evaluated: one batch size, one cached map
        trial = _State(problem, X_trial, beta, True)
        new_cost = np.where(np.isfinite(trial.posture_cost[idx]), trial.posture_cost[idx], np.inf)
        better = new_cost <= cost[idx]
        stalled = ~better & (new_cost - cost[idx] <= tolerance * cost[idx])
        small = np.max(np.abs(dx), axis=1) <= step_tolerance
        done = (better & ((cost[idx] - new_cost <= tolerance * cost[idx]) | small)) | stalled | (lam[idx] >= 1e12)
        take = idx[better]
        X[take] = X_trial[take]
        cost[take] = new_cost[better]
        assert trial.Jx is not None and Jx is not None
        Jx[take], r[take], w[take] = trial.Jx[take], trial.r[take], trial.w[take]
        iterations[take] += 1
        lam[take] = np.maximum(lam[take] * 0.3, 1e-9)
        lam[idx[~better]] *= 10.0
        active[idx[done]] = False
    seen = problem.seen
    errors = np.where(seen, np.linalg.norm(r, axis=2), np.nan)
    dof = 3 * int(seen.sum()) - N * problem.model.layout.n_x
    weighted = float(np.sum(w * np.sum(r * r, axis=2)))
    sigma = float(np.sqrt(weighted / dof)) if dof > 0 else float("nan")
    n_beta = len(beta)
    return Fit(
        X,
        beta.copy(),
        errors,
        w,
        np.zeros((n_beta, n_beta)),
        sigma,
        float(np.sum(cost)),
        int(iterations.max()) if N else 0,
        not active.any(),
        time.perf_counter() - started,
    )


def information(problem: Problem, X: np.ndarray, beta: np.ndarray) -> tuple[np.ndarray, float]:
    """The information on the free shared parameters at ``(X, beta)``, and the weighted residual sum.

    The Schur complement ``S = C - sum_k B_k^T A_k^+ B_k`` of the undamped normal equations (module docstring,
    with the robust weights at that point and the priors), each posture's block by pseudo-inverse so that a
    posture whose own configuration is undetermined (a disk never seen) adds nothing spurious.

    Returns
    -------
    tuple
        ``S (n_free, n_free)`` [1 / unit^2, unit^2 of the data: metres] and ``sum w |r|^2`` [m^2].
    """
    state = _State(problem, np.asarray(X, dtype=float), np.asarray(beta, dtype=float), True)
    A, B, C, _, _ = _normal_equations(problem, state)
    S = C
    if A.shape[1] and B.shape[2]:
        S = C - np.einsum("nki,nkj->ij", B, np.linalg.pinv(A, rcond=1e-12, hermitian=True) @ B)
    return 0.5 * (S + S.T), float(np.sum(state.w * np.sum(state.r * state.r, axis=2)))


def _covariance(problem: Problem, state: _State, N: int) -> tuple[np.ndarray, float]:
    """``sigma^2 S^-1`` on the free parameters (module docstring) and ``sigma`` [m]."""
    free = problem.free
    n_beta = len(free)
    dof = 3 * int(problem.seen.sum()) - N * problem.model.layout.n_x - int(free.sum())
    weighted = float(np.sum(state.w * np.sum(state.r * state.r, axis=2)))
    sigma2 = weighted / dof if dof > 0 else float("nan")
    covariance = np.zeros((n_beta, n_beta))
    if free.any():
        A, B, C, _, _ = _normal_equations(problem, state)
        if A.shape[1]:
            Ainv_B = np.linalg.solve(A + 1e-12 * np.eye(A.shape[1]), B)
            S = C - np.einsum("nki,nkj->ij", B, Ainv_B)
        else:
            S = C
        try:
            inverse = np.linalg.inv(S)
        except np.linalg.LinAlgError:
            inverse = np.linalg.pinv(S)
        covariance[np.ix_(free, free)] = sigma2 * inverse
    return covariance, float(np.sqrt(sigma2)) if sigma2 == sigma2 else float("nan")
