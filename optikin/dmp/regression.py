"""Fitting the forcing-term weights: least squares posed in cvxpy, the closed form, and LWR.

All three fit ``X W^T ~ F`` for the design matrix ``X`` (``K x n``, eq. 13)
and target forces ``F`` (``K x dim``, eqs. 16, 22) and return a :class:`Fit`
with the same residual measure and the wall time:

* :func:`fit_cvxpy` -- every weight of every dimension at once,
  ``min |X W^T - F|_F^2 + ridge |W|_F^2`` subject to optional bounds
  ``lower <= W <= upper``: a convex QP (Clarabel by default, any cvxpy solver).
* :func:`fit_lstsq` -- the closed form of the same problem without bounds: one Cholesky
  factorisation of the normal equations shared by every dimension, refined once on the residual
  (``numpy.linalg.lstsq`` on ``[X; sqrt(ridge) I]`` as the reference, and where ``X`` is
  ill-conditioned).
* :func:`fit_lwr` -- locally weighted regression, one weight per basis
  function from its own Gaussian-weighted fit (Ijspeert et al. 2013, eq. 2.14,
  the regression the DMP literature uses): ``w_j = sum psi_j s f / sum psi_j s^2``.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
import scipy.linalg

from optikin.errors import SolverError

Method = Literal["lstsq", "cvxpy", "lwr"]
"""A weight-regression method."""
METHODS: tuple[Method, ...] = get_args(Method)


@dataclass(frozen=True)
class Fit:
    """One fit of the forcing-term weights.

    Attributes
    ----------
    method:
        ``lstsq``, ``cvxpy`` or ``lwr``.
    weights:
        ``(dim, n)`` weights, one row per gap component.
    residual:
        ``rms(X W^T - F)`` in the units of the target forces (eqs. 16, 22).
    seconds:
        Wall time of the fit [s].
    status:
        The solver's status (``optimal`` for the closed forms).
    """

    method: str
    weights: np.ndarray
    residual: float
    seconds: float
    status: str = "optimal"


def _residual(X: np.ndarray, F: np.ndarray, W: np.ndarray) -> float:
    return float(np.sqrt(np.mean((X @ W.T - F) ** 2)))


CONDITION_LIMIT = 1e12
"""Largest condition number of the Gram matrix ``X^T X + ridge I`` the Cholesky path accepts; beyond it
(``cond(X)`` above about 1e6) :func:`fit_lstsq` solves by SVD."""


def fit_lstsq(X: np.ndarray, F: np.ndarray, ridge: float = 0.0, factorisation: str = "svd") -> Fit:
    """Closed-form (ridge) least squares ``min |X W^T - F|^2 + ridge |W|^2``.

    Every gap component shares the design matrix ``X``, so it is factorised once for all
    ``dim`` right-hand sides.

    Parameters
    ----------
    X:
        ``(K, n)`` design matrix (eq. 13).
    F:
        ``(K, dim)`` target forces (eqs. 16, 22).
    ridge:
        Weight of the ridge term, >= 0.
    factorisation:
        ``cholesky``: the normal equations ``(X^T X + ridge I) W^T = X^T F`` by one Cholesky
        factorisation and one step of iterative refinement on the residual, falling back to
        ``svd`` when the Gram matrix is singular or its estimated condition number exceeds
        :data:`CONDITION_LIMIT` (what :meth:`optikin.dmp.DMP.imitate` uses); ``svd``:
        ``numpy.linalg.lstsq`` on ``[X; sqrt(ridge) I]`` (the reference). The two agree to about
        ``cond(X)`` times the rounding error relative to the largest weight.

    Returns
    -------
    Fit
        Weights ``(dim, n)``.
    """
    if factorisation not in ("cholesky", "svd"):
        raise ValueError(f"unknown factorisation {factorisation!r}; choose cholesky or svd")
    start = time.perf_counter()
    solved = _normal_equations(X, F, ridge) if factorisation == "cholesky" else None
    if solved is not None:
        W, residual = solved
        return Fit("lstsq", W, residual, time.perf_counter() - start)
    if ridge > 0:
        n = X.shape[1]
        A = np.vstack([X, np.sqrt(ridge) * np.eye(n)])
        b = np.vstack([F, np.zeros((n, F.shape[1]))])
    else:
        A, b = X, F
    W = np.linalg.lstsq(A, b, rcond=None)[0].T
    seconds = time.perf_counter() - start
    return Fit("lstsq", W, _residual(X, F, W), seconds)


def _cholesky(X: np.ndarray, ridge: float) -> np.ndarray | None:
    """The upper Cholesky factor of ``X^T X + ridge I``, or ``None`` when it is not safely positive definite."""
    G = X.T @ X
    if ridge > 0:
        G[np.diag_indices_from(G)] += ridge
    norm = float(np.abs(G).sum(axis=0).max())
    factor, info = scipy.linalg.lapack.dpotrf(G, lower=0, clean=1)
    if info != 0:
        return None
    rcond, info = scipy.linalg.lapack.dpocon(factor, norm, uplo="U")
    if info != 0 or not rcond * CONDITION_LIMIT >= 1.0:
        return None
    return factor


CACHED_FACTORS = 8
"""Shared design matrices (:func:`share_design`) whose Cholesky factors are kept per process."""
_FACTORS: OrderedDict[int, tuple[np.ndarray, dict[float, np.ndarray | None]]] = OrderedDict()
_FACTORS_LOCK = threading.Lock()


def share_design(X: np.ndarray) -> None:
    """Mark a read-only design matrix as shared: :func:`fit_lstsq` factorises it once per ridge weight.

    For the design matrices :func:`optikin.dmp.imitation.design_matrix` caches. The cache holds ``X``
    (so its id stays its own) and drops the least recently used beyond :data:`CACHED_FACTORS`.

    Raises
    ------
    ValueError
        ``X`` is writeable (a factor kept for it could go stale).
    """
    if X.flags.writeable:
        raise ValueError("only a read-only design matrix can be shared")
    with _FACTORS_LOCK:
        if _FACTORS.get(id(X), (None,))[0] is not X:
            _FACTORS[id(X)] = (X, {})
        _FACTORS.move_to_end(id(X))
        while len(_FACTORS) > CACHED_FACTORS:
            _FACTORS.popitem(last=False)


def _shared_cholesky(X: np.ndarray, ridge: float) -> np.ndarray | None:
    """:func:`_cholesky`, computed once per ridge weight for a shared ``X`` (:func:`share_design`)."""
    with _FACTORS_LOCK:
        entry = _FACTORS.get(id(X))
        if entry is None or entry[0] is not X:
            entry = None
        elif float(ridge) in entry[1]:
            return entry[1][float(ridge)]
    factor = _cholesky(X, ridge)
    if entry is not None:
        with _FACTORS_LOCK:
            entry[1][float(ridge)] = factor
    return factor


def _normal_equations(X: np.ndarray, F: np.ndarray, ridge: float) -> tuple[np.ndarray, float] | None:
    """``W (dim, n)`` from one Cholesky factorisation ``R^T R = X^T X + ridge I`` (kept for a shared ``X``)
    and one refinement step, with ``rms(X W^T - F)``; ``None`` when the Gram matrix is not safely positive
    definite (see :data:`CONDITION_LIMIT`).

    The residual of the refined weights ``W0 + D`` comes from the refinement's own products, without another
    pass over ``X``: ``r1 = r0 - X D``, so ``|r1|^2 = |r0|^2 - 2 <D, X^T r0> + <D, X^T X D>`` with
    ``X^T X D = R^T (R D) - ridge D`` (the corrections are small against ``|r0|^2``: no cancellation)."""
    factor = _shared_cholesky(X, ridge)
    if factor is None:
        return None
    Wt = scipy.linalg.cho_solve((factor, False), X.T @ F, check_finite=False)
    r0 = F - X @ Wt
    c0 = X.T @ r0
    D = scipy.linalg.cho_solve((factor, False), c0 - ridge * Wt, check_finite=False)
    gram_D = factor.T @ (factor @ D) - ridge * D
    squares = float(np.sum(r0 * r0)) - 2.0 * float(np.sum(D * c0)) + float(np.sum(D * gram_D))
    return np.ascontiguousarray((Wt + D).T), float(np.sqrt(max(squares, 0.0) / F.size))


def fit_cvxpy(
    X: np.ndarray,
    F: np.ndarray,
    ridge: float = 0.0,
    lower: float | np.ndarray | None = None,
    upper: float | np.ndarray | None = None,
    solver: str = "CLARABEL",
) -> Fit:
    """All weights at once as a cvxpy least-squares problem with optional ridge term and bounds.

    Parameters
    ----------
    X, F, ridge:
        As :func:`fit_lstsq`.
    lower, upper:
        Bounds on the weights: scalars or ``(n, dim)`` arrays (``W^T``'s shape); ``None`` for none.
    solver:
        The cvxpy solver.

    Returns
    -------
    Fit
        Weights ``(dim, n)`` and the solver's status.

    Raises
    ------
    SolverError
        The solver failed or returned no optimal point.

    Notes
    -----

    The data term is first reduced exactly to ``n`` rows with a thin QR
    factorisation ``X = Q R``: ``|X W' - F|^2 = |R W' - Q'F|^2 + |F|^2 - |Q'F|^2``,
    so cvxpy canonicalises an ``n``-row problem whatever the number of samples
    (with the conditioning of ``X``, not of ``X'X``). The forces are scaled by
    their largest magnitude (the weights and bounds with them), which keeps
    the conic solver's tolerances relative to the data.
    """
    import cvxpy as cp  # here, not at the top: a second of import time the other fits do not need

    start = time.perf_counter()
    scale = float(np.max(np.abs(F))) or 1.0
    Q, R = np.linalg.qr(X)
    W = cp.Variable((X.shape[1], F.shape[1]))
    objective = cp.sum_squares(R @ W - Q.T @ (F / scale))
    if ridge > 0:
        objective = objective + ridge * cp.sum_squares(W)
    constraints = []
    if lower is not None:
        constraints.append(W >= np.asarray(lower, dtype=float).T / scale)
    if upper is not None:
        constraints.append(W <= np.asarray(upper, dtype=float).T / scale)
    problem = cp.Problem(cp.Minimize(objective), constraints)
    try:
        problem.solve(solver=solver)
    except cp.error.SolverError as exc:
        raise SolverError(f"cvxpy ({solver}) failed on the weight regression: {exc}") from None
    if W.value is None or problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        raise SolverError(f"cvxpy ({solver}) returned status {problem.status!r} on the weight regression")
    weights = W.value.T * scale
    seconds = time.perf_counter() - start
    return Fit("cvxpy", weights, _residual(X, F, weights), seconds, str(problem.status))


def fit_lwr(s: np.ndarray, psi: np.ndarray, X: np.ndarray, F: np.ndarray) -> Fit:
    """Locally weighted regression: ``w_j = sum_k psi_jk s_k F_k / sum_k psi_jk s_k^2`` for each basis ``j``.

    Parameters
    ----------
    s:
        ``(K,)`` phase of the rows.
    psi:
        ``(K, n)`` unnormalised activations (:func:`optikin.dmp.basis.activations`).
    X:
        ``(K, n)`` design matrix, only used to report the residual on the same footing as the other fits.
    F:
        ``(K, dim)`` target forces.

    Returns
    -------
    Fit
        Weights ``(dim, n)``.
    """
    start = time.perf_counter()
    s = np.asarray(s, dtype=float)
    weighted = psi * s[:, None]  # (K, n)
    W = (weighted.T @ F) / (weighted.T @ s)[:, None]
    W = W.T
    seconds = time.perf_counter() - start
    return Fit("lwr", W, _residual(X, F, W), seconds)
