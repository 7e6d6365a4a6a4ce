"""Backends ``lm`` and ``trf``: ``scipy.optimize.least_squares`` with the CasADi residual and Jacobian.

``lm`` is MINPACK's Levenberg-Marquardt, which takes no bounds: bounded
variables are solved for through the smooth map ``x = lower + (upper - lower)
(1 + sin z)/2`` (the transform MINUIT and lmfit use for bounded LM fits);
``trf`` is scipy's trust-region reflective method with the bounds. Periodic
angles are left free and wrapped afterwards. Variables are scaled by the
problem's weights (``x_scale: weights``, the default), i.e. by their ranges.

Redundancy: scipy's steps from the start point are (scaled) minimum-norm
corrections, so like ``gauss_newton`` the answer is the solution reached from
``x0``. ``regularisation > 0`` appends Tikhonov rows ``sqrt(regularisation)
W (x - x_ref)`` instead (periodic differences wrapped): a pull towards ``x_ref``
that leaves ``||r||`` at about ``regularisation`` times the weighted distance
and slows convergence (off by default). MINPACK needs as many rows as
variables; an underdetermined residual is padded with rows of zeros.

Reproducibility: the C translation of MINPACK's QR factorisation (``qrfac``)
in scipy 1.17.1 recomputes the norm of a column whose norm has collapsed,
which every rank-deficient Jacobian (a padded redundant problem) triggers,
over one entry too many: for the last column, the double just past the
Jacobian buffer, whatever the heap held there, so the same solve gave
different iterates in different processes. ``lm`` therefore appends a guard:
a dummy variable ``g`` (starting at 0) with its own residual row
``GUARD g``, ``GUARD = 1e-150`` far below the nonzero column norms of any
double-precision Jacobian met in practice. That column is orthogonal to the others, so its norm
never collapses and is never recomputed, and it is pivoted last; the entry
read past the column before it is the guard's first entry, 0. Its step is
exactly 0 (its component of ``Q^T r`` is 0) and it changes no other
operation: the iterates are those MINPACK computes when that double is 0,
bit-identical whatever the process did before.

Residual and Jacobian come from one zero-copy CasADi call per new ``x``. The
iteration limit is scipy's ``max_nfev`` (``limits.max_iterations``); the time
limit is enforced inside the residual callback, which stops the solve and
keeps the best point seen.

Preset options: :class:`LeastSquaresOptions` (``lm``) and :class:`TrfOptions` (``trf``).
"""

from __future__ import annotations

import time
from typing import Any, Literal

import numpy as np
from pydantic import Field, StrictFloat, field_validator
from pydantic_core import PydanticCustomError
from scipy.optimize import least_squares

from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter

EPS = float(np.finfo(float).eps)
GUARD = 1e-150


class LeastSquaresOptions(Options):
    """Preset options of backend ``lm`` (and, with ``tr_solver``, ``trf``): scipy's tolerances and scaling."""

    ftol: StrictFloat = Field(1e-15, ge=EPS, description="relative change of the cost that stops the solve")
    xtol: StrictFloat = Field(1e-15, ge=EPS, description="relative change of the scaled variables that stops it")
    gtol: StrictFloat = Field(1e-15, ge=EPS, description="scaled gradient norm that stops it")
    x_scale: Literal["weights", "jac"] | StrictFloat = Field(
        "weights",
        description="scale of the variables: 'weights' (their ranges, 1/W), 'jac' (scipy's Jacobian "
        "scaling) or a positive number (units of x)",
    )
    regularisation: StrictFloat = Field(
        0.0, ge=0, description="Tikhonov rows sqrt(regularisation) W (x - x_ref) on a redundant problem (dimensionless)"
    )

    @field_validator("x_scale", mode="wrap")
    @classmethod
    def _scale(cls, value: Any, handler: Any) -> Any:
        error = PydanticCustomError(
            "x_scale", "expected 'weights', 'jac' or a positive number, got {value}", {"value": repr(value)}
        )
        try:
            scale = handler(value)
        except ValueError:
            raise error from None
        if isinstance(scale, float) and not scale > 0:
            raise error
        return scale


class TrfOptions(LeastSquaresOptions):
    """Preset options of backend ``trf``."""

    tr_solver: Literal["exact", "lsmr"] = Field("exact", description="scipy's trust-region subproblem solver")


class _TimeLimit(Exception):
    pass


class _Residual:
    """``fun`` and ``jac`` for scipy with one CasADi evaluation per distinct ``x``; keeps the best point."""

    def __init__(
        self,
        problem: LeastSquaresProblem,
        p: np.ndarray,
        x_ref: np.ndarray,
        regularisation: float,
        deadline: float,
        transform: bool = False,
        guard: bool = False,
    ):
        self.call = problem.fast("residual_jacobian")
        self.guard = guard
        self.transformed = ~problem.periodic if transform else np.zeros(problem.n, dtype=bool)
        self.problem, self.p, self.x_ref, self.deadline = problem, np.ravel(p), x_ref, deadline
        n, m = problem.n, problem.m
        self.rows: np.ndarray | None
        if problem.weights is not None and m < n:
            self.rows = np.sqrt(regularisation) * problem.weights
        elif m < n:
            self.rows = np.zeros(n)
        else:
            self.rows = None
        self.z: np.ndarray | None = None
        self.evaluations = 0
        self.best_x: np.ndarray | None = None
        self.best_cost = np.inf

    def to_x(self, z: np.ndarray) -> np.ndarray:
        """Solver variables -> configuration (the sine map on bounded variables; the guard variable dropped)."""
        z = z[: self.problem.n]
        lo, span = self.problem.lower, self.problem.upper - self.problem.lower
        return np.where(self.transformed, lo + 0.5 * span * (1.0 + np.sin(z)), z)

    def to_z(self, x: np.ndarray) -> np.ndarray:
        """Configuration -> solver variables (with the guard variable, 0, last)."""
        lo, span = self.problem.lower, self.problem.upper - self.problem.lower
        ratio = np.clip(2.0 * (x - lo) / span - 1.0, -1.0, 1.0)
        z = np.where(self.transformed, np.arcsin(ratio), x)
        return np.append(z, 0.0) if self.guard else z

    def _evaluate(self, z: np.ndarray) -> None:
        if self.z is not None and np.array_equal(z, self.z):
            return
        if self.z is not None and time.perf_counter() > self.deadline:
            raise _TimeLimit
        x = self.to_x(z)
        r, J = self.call(x, self.p)
        self.evaluations += 1
        self.z = z.copy()
        self.r = r.copy()
        self.J = J.reshape(self.problem.n, self.problem.m).T.copy()  # column-major m x n
        dx_dz = np.where(
            self.transformed, 0.5 * (self.problem.upper - self.problem.lower) * np.cos(z[: self.problem.n]), 1.0
        )
        self.J *= dx_dz
        cost = float(self.r @ self.r)
        if cost < self.best_cost:
            self.best_x, self.best_cost = x, cost
        if self.rows is not None:
            d = x - self.x_ref
            d = np.where(self.problem.periodic, np.arctan2(np.sin(d), np.cos(d)), d)
            self.r = np.concatenate([self.r, self.rows * d])
            self.J = np.vstack([self.J, np.diag(self.rows * dx_dz)])
        if self.guard:  # the row GUARD g of the guard variable g (module docstring)
            rows, n = len(self.r), self.problem.n
            guarded = np.zeros((rows + 1, n + 1))
            guarded[:rows, :n] = self.J
            guarded[rows, n] = GUARD
            self.J = guarded
            self.r = np.append(self.r, GUARD * z[n])

    def fun(self, x: np.ndarray) -> np.ndarray:
        self._evaluate(x)
        return self.r

    def jac(self, x: np.ndarray) -> np.ndarray:
        self._evaluate(x)
        return self.J


class ScipyLeastSquares(NonlinearAdapter):
    """``scipy.optimize.least_squares`` with method :attr:`method` (module docstring)."""

    method = ""
    transform_bounds = False
    guard = False
    options: LeastSquaresOptions

    def extra(self, problem: LeastSquaresProblem) -> dict:
        return {}

    def x_scale(self, residual: _Residual) -> np.ndarray | str | float:
        """Scale of the solver variables: the variables' ranges (``1/W``), 1 for sine-mapped ones and the guard."""
        scale = self.options.x_scale
        if scale != "weights":
            return scale
        problem = residual.problem
        ranges = np.ones(problem.n) if problem.weights is None else 1.0 / problem.weights
        scales = np.where(residual.transformed, 1.0, ranges)
        return np.append(scales, 1.0) if residual.guard else scales

    def solve_free(
        self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution:
        started = time.perf_counter()
        x0 = problem.project(x0)
        reference = x0 if x_ref is None else np.asarray(x_ref, dtype=float)
        residual = _Residual(
            problem,
            p,
            reference,
            self.options.regularisation,
            started + self.limits.time_limit,
            transform=self.transform_bounds,
            guard=self.guard,
        )
        try:
            result = least_squares(
                residual.fun,
                residual.to_z(x0),
                jac=residual.jac,
                method=self.method,
                ftol=self.options.ftol,
                xtol=self.options.xtol,
                gtol=self.options.gtol,
                x_scale=self.x_scale(residual),
                max_nfev=self.limits.max_iterations,
                **self.extra(problem),
            )
            x, iterations = residual.to_x(result.x), result.nfev
        except _TimeLimit:  # the best point seen (the start if no residual was finite)
            x = x0 if residual.best_x is None else residual.best_x
            iterations = residual.evaluations
        except (ValueError, np.linalg.LinAlgError) as exc:
            return self.finish(problem, x0, p, 0, started, error=f"least_squares ({self.method}): {exc}")
        return self.finish(problem, problem.project(x), p, iterations, started)


class LevenbergMarquardt(ScipyLeastSquares):
    """MINPACK's Levenberg-Marquardt, bounds through the sine map (module docstring)."""

    method = "lm"
    transform_bounds = True
    guard = True


class TrustRegionReflective(ScipyLeastSquares):
    """scipy's trust-region reflective method with the bounds (module docstring)."""

    method = "trf"
    options: TrfOptions

    def extra(self, problem: LeastSquaresProblem) -> dict:
        lower = np.where(problem.periodic, -np.inf, problem.lower)
        upper = np.where(problem.periodic, np.inf, problem.upper)
        return {"bounds": (lower, upper), "tr_solver": self.options.tr_solver}


register_backend("lm", "nonlinear", "scipy least_squares, MINPACK Levenberg-Marquardt", options=LeastSquaresOptions)(
    LevenbergMarquardt
)
register_backend("trf", "nonlinear", "scipy least_squares, trust-region reflective with bounds", options=TrfOptions)(
    TrustRegionReflective
)
