"""The ``nonlinear`` backend family: bounded nonlinear least squares ``min 1/2 ||r(x, p)||^2``.

A :class:`LeastSquaresProblem` carries a CasADi residual ``r(x, p)`` (``p``
holds the data of one sample, e.g. a target position), the bounds of ``x``,
which variables are angles that wrap (a full-turn range), the tolerance on
``||r||`` that counts as solved, and an optional redundancy preference: among
the configurations with ``r = 0`` prefer the one closest to a reference
``x_ref`` in the weighted norm ``||W (x - x_ref)||``.

A problem is *exact* (the default) when its solutions have ``r = 0``: inverse
kinematics as root finding. A problem with ``exact=False`` is a minimisation
whose minimum need not be zero, e.g. a tip error plus a penalty as in seed 004
eq. (11): its solution is the stationary point of ``1/2 ||r||^2`` and the
backends treat it so (the NLP backends minimise ``1/2 ||r||^2`` instead of
imposing ``r = 0``; Newton solves ``J^T r = 0``).

Every adapter of the family offers

``solve(problem, x0, p, x_ref=None) -> Solution``
    one solve from ``x0`` (``x_ref`` defaults to ``x0``);
``solve_many(problem, X0, P, warm_start=False, x_ref=None) -> SolutionBatch``
    many samples; with ``warm_start`` sample ``k`` starts from the solution of
    sample ``k - 1`` (a trajectory), and ``x_ref=None`` then means "closest to
    the previous solution".

How a solve went is decided here, by the same rule for every backend, from
the returned point alone (a backend's own success flag is not trusted:
CasADi's Newton rootfinder can return a non-converged iterate silently):

``ok``             ``||r|| <= tolerance`` and ``x`` inside the bounds; for a problem
                   that is not exact, also a stationary point of ``||r||^2``
                   within the bounds (its minimiser);
``unreachable``    an exact problem with ``||r|| > tolerance`` at a stationary point of
                   ``||r||^2`` within the bounds (the projected gradient ``J^T r``
                   vanishes): the closest reachable configuration, e.g. a target
                   outside the workspace;
``timeout``        the preset's ``limits.time_limit`` was exceeded;
``failed``         non-finite values, a point outside the bounds, or a solver error;
``not_converged``  anything else (e.g. the iteration limit was reached).

Fixed variables: a variable whose bounds coincide (``lower = upper``, e.g. the length
of an inextensible section) is not solved for. The adapters' ``solve`` and
``solve_many`` hand the backend :attr:`LeastSquaresProblem.reduced`, the problem
over the free variables with the fixed ones substituted by their value, and put
the fixed values back into the answer; so no backend sees a zero-width range.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from optikin.algebra.angles import wrap_periodic
from optikin.batch import batched
from optikin.fastcall import BufferedFunction
from optikin.interrupt import check_interrupted
from optikin.options import Options
from optikin.solvers.base import Solution, SolutionBatch
from optikin.spec import SolverSpec
from optikin.status import Status

FAMILY = "nonlinear"
BOUND_TOLERANCE = 1e-9
"""How far (relative to the variable's range) a returned point may sit outside the bounds."""


@dataclass(eq=False)
class LeastSquaresProblem:
    """``min 1/2 ||r(x, p)||^2`` subject to ``lower <= x <= upper``.

    Parameters
    ----------
    residual:
        CasADi Function ``(x, p) -> r`` built from SX expressions.
    lower, upper:
        Bounds of ``x``. Periodic variables are wrapped into ``[lower, upper)`` instead of clipped.
    periodic:
        Mask of the variables that are angles with a full-turn range.
    tolerance:
        ``||r||`` at or below which a sample counts as solved (units of ``r``).
    weights:
        Diagonal ``W`` of the redundancy preference ``||W (x - x_ref)||``; ``None``: no preference.
    stationarity_tolerance:
        ``||P J^T r|| / (||J||_F ||r||)`` below which an unsolved point counts as a stationary point
        of the residual (``P`` drops the components blocked by active bounds; limits on
        ``constraints`` are not accounted for).
    exact:
        True: a solution has ``r = 0`` (root finding). False: a solution minimises
        ``1/2 ||r||^2`` and is ``ok`` at a stationary point (module docstring).
    constraints, constraint_lower, constraint_upper, constraint_names:
        Optional limits ``constraint_lower <= c(x) <= constraint_upper`` on a CasADi Function
        ``c(x)`` (e.g. the CBHA's leg lengths within Table I). The NLP backends impose them;
        every backend's result is checked against them and reported ``failed`` outside.
    """

    residual: ca.Function
    lower: np.ndarray
    upper: np.ndarray
    periodic: np.ndarray
    tolerance: float = 1e-10
    weights: np.ndarray | None = None
    stationarity_tolerance: float = 1e-5
    exact: bool = True
    name: str = "least_squares"
    variable_names: tuple[str, ...] = ()
    constraints: ca.Function | None = None
    constraint_lower: np.ndarray | None = None
    constraint_upper: np.ndarray | None = None
    constraint_names: tuple[str, ...] = ()
    cache: dict[Any, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.lower = np.asarray(self.lower, dtype=float)
        self.upper = np.asarray(self.upper, dtype=float)
        self.periodic = np.asarray(self.periodic, dtype=bool)
        if self.lower.shape != (self.n,) or self.upper.shape != (self.n,) or self.periodic.shape != (self.n,):
            raise ValueError(f"{self.name}: lower, upper and periodic must have {self.n} entries")
        if not np.all(self.lower <= self.upper):
            j = int(np.argmax(~(self.lower <= self.upper)))
            raise ValueError(f"{self.name}: bounds of variable {j} are not lower <= upper")
        if self.weights is not None:
            self.weights = np.asarray(self.weights, dtype=float)
            if self.weights.shape != (self.n,) or not np.all(np.isfinite(self.weights) & (self.weights > 0)):
                raise ValueError(f"{self.name}: weights must be {self.n} positive finite numbers")
        if not self.variable_names:
            self.variable_names = tuple(f"x{i}" for i in range(self.n))
        if self.constraints is not None:
            k = self.constraints.size1_out(0)
            self.constraint_lower = np.broadcast_to(np.asarray(self.constraint_lower, dtype=float), (k,))
            self.constraint_upper = np.broadcast_to(np.asarray(self.constraint_upper, dtype=float), (k,))
            self.constraint_names = self.constraint_names or tuple(f"c{i}" for i in range(k))

    # ------------------------------------------------------------------ sizes and symbols
    @property
    def n(self) -> int:
        return self.residual.size1_in(0)

    @property
    def n_data(self) -> int:
        return self.residual.size1_in(1)

    @property
    def m(self) -> int:
        return self.residual.size1_out(0)

    @property
    def fixed(self) -> np.ndarray:
        """Mask of the fixed variables, ``lower = upper`` (module docstring)."""
        return self.lower == self.upper

    @property
    def span(self) -> np.ndarray:
        """``upper - lower``, with 1 for a fixed variable: the scale of bound violations."""
        return np.where(self.fixed, 1.0, self.upper - self.lower)

    @cached_property
    def reduced(self) -> LeastSquaresProblem:
        """The problem over the free variables, the fixed ones substituted by their value.

        The same problem when no variable is fixed; otherwise residual ``r_f(x_f, p) = r(E x_f + c, p)``
        and constraints likewise (``E`` inserts the free variables, ``c`` holds the fixed values),
        with the bounds, wrapping, weights and names of the free variables. Its own cache.
        """
        fixed = self.fixed
        if not fixed.any():
            return self
        free = ~fixed
        x_free, p = ca.SX.sym("x", int(free.sum())), ca.SX.sym("p", self.n_data)
        slots = iter(range(x_free.numel()))
        x = ca.vertcat(*[x_free[next(slots)] if free[j] else ca.SX(self.lower[j]) for j in range(self.n)])
        residual = ca.Function(f"{self.name}_free", [x_free, p], [self.residual(x, p)], ["x", "p"], ["r"])
        constraints = None
        if self.constraints is not None:
            constraints = ca.Function(f"{self.name}_free_constraints", [x_free], [self.constraints(x)])
        return LeastSquaresProblem(
            residual,
            self.lower[free],
            self.upper[free],
            self.periodic[free],
            tolerance=self.tolerance,
            weights=None if self.weights is None else self.weights[free],
            stationarity_tolerance=self.stationarity_tolerance,
            exact=self.exact,
            name=self.name,
            variable_names=tuple(v for v, f in zip(self.variable_names, free) if f),
            constraints=constraints,
            constraint_lower=self.constraint_lower,
            constraint_upper=self.constraint_upper,
            constraint_names=self.constraint_names,
        )

    def free_part(self, x: np.ndarray) -> np.ndarray:
        """The free variables of points ``x (..., n)`` (the variables of :attr:`reduced`)."""
        return np.asarray(x, dtype=float)[..., ~self.fixed]

    def expand(self, x_free: np.ndarray) -> np.ndarray:
        """Points ``(..., n)`` from points of :attr:`reduced` ``(..., n_free)``, the fixed variables at their value."""
        x_free = np.asarray(x_free, dtype=float)
        x = np.empty(x_free.shape[:-1] + (self.n,))
        x[..., ~self.fixed] = x_free
        x[..., self.fixed] = self.lower[self.fixed]
        return x

    @property
    def constraint_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(constraint_lower, constraint_upper)``, each ``(k,)``; only for a problem with ``constraints``."""
        if self.constraint_lower is None or self.constraint_upper is None:
            raise ValueError(f"{self.name}: no constraints")
        return self.constraint_lower, self.constraint_upper

    @cached_property
    def symbols(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """``x, p, r(x, p), J(x, p)`` as SX."""
        x = ca.SX.sym("x", self.n)
        p = ca.SX.sym("p", self.n_data)
        r = self.residual(x, p)
        return x, p, r, ca.jacobian(r, x)

    @cached_property
    def residual_jacobian(self) -> ca.Function:
        """``(x, p) -> (r, J)``."""
        x, p, r, J = self.symbols
        return ca.Function(f"{self.name}_rJ", [x, p], [r, ca.densify(J)], ["x", "p"], ["r", "J"])

    def jacobian_rank(self, X: np.ndarray, P: np.ndarray) -> int:
        """The largest numerical rank of ``dr/dx`` (free variables) over the points ``(X[k], P[k])``.

        Rank counted as the singular values above ``1e-9`` times the largest; a problem whose rank stays
        below its number of residuals at every point has rank-deficient equality constraints ``r = 0``
        (Newton's system singular, LICQ violated), whatever the target.
        """
        reduced = self.reduced
        X = np.atleast_2d(X)
        rank = 0
        for x, p in zip(X, np.atleast_2d(P)):
            J = np.asarray(reduced.residual_jacobian(self.free_part(x), p)[1])
            if J.size:
                singular = np.linalg.svd(J, compute_uv=False)
                rank = max(rank, int(np.sum(singular > 1e-9 * singular[0])) if singular[0] > 0 else 0)
        return rank

    @cached_property
    def check(self) -> ca.Function:
        """``(x, p) -> [||r||, stationarity, bound violation]`` (see the class docstring)."""
        x, p, r, J = self.symbols
        rn = ca.norm_2(r)
        g = ca.mtimes(J.T, r)
        lower_active, upper_active = self.active_bounds(x)
        # A descent step -g that would leave the box is blocked by the bound.
        blocked = ca.logic_or(ca.logic_and(lower_active, g > 0), ca.logic_and(upper_active, g < 0))
        projected = ca.if_else(blocked, 0, g)
        stationarity = ca.norm_2(projected) / (ca.norm_fro(J) * rn + 1e-300)
        outside = ca.fmax(ca.DM(self.lower) - x, x - ca.DM(self.upper)) / ca.DM(self.span)
        outside = ca.mmax(ca.if_else(ca.DM(self.periodic & ~self.fixed), 0, outside))
        if self.constraints is not None:
            c = self.constraints(x)
            lower, upper = self.constraint_bounds
            span = ca.DM(np.maximum(upper - lower, 1e-300))
            violation = ca.fmax(ca.DM(lower) - c, c - ca.DM(upper)) / span
            outside = ca.fmax(outside, ca.mmax(violation))
        return ca.Function(f"{self.name}_check", [x, p], [ca.vertcat(rn, stationarity, outside)])

    @cached_property
    def packed_check(self) -> ca.Function:
        """:attr:`check` with one packed input ``[x; p]`` (for zero-copy batches)."""
        x, p, _, _ = self.symbols
        return ca.Function(f"{self.name}_check_packed", [ca.vertcat(x, p)], [self.check(x, p)])

    def active_bounds(self, x: ca.SX, margin: float = 1e-12) -> tuple[ca.SX, ca.SX]:
        """Masks of the non-periodic variables at their lower / upper bound (a fixed variable is at both)."""
        span = ca.DM(self.upper - self.lower)
        bounded = ca.DM(~self.periodic | self.fixed)
        return (
            ca.logic_and(bounded, x <= ca.DM(self.lower) + margin * span),
            ca.logic_and(bounded, x >= ca.DM(self.upper) - margin * span),
        )

    # ------------------------------------------------------------------ numeric helpers
    def fast(self, name: str) -> BufferedFunction:
        """A zero-copy caller of the Function attribute ``name`` (built once per problem)."""
        key = ("buffered", name)
        if key not in self.cache:
            self.cache[key] = BufferedFunction(getattr(self, name))
        return self.cache[key]

    def project(self, x: np.ndarray) -> np.ndarray:
        """Wrap periodic variables into ``[lower, upper)`` and clip the others to the bounds."""
        x = np.array(x, dtype=float)
        if x.ndim == 1 and ((x >= self.lower) & (x <= self.upper)).all():
            return x  # the common case, a warm start: nothing to do
        with np.errstate(invalid="ignore"):  # a fixed periodic variable is clipped
            wrapped = wrap_periodic(x, self.lower, self.upper)
        return np.where(self.periodic & ~self.fixed, wrapped, np.clip(x, self.lower, self.upper))

    def wrap(self, x: np.ndarray) -> np.ndarray:
        """Wrap periodic variables only (a point outside the bounds stays outside; NaN stays NaN)."""
        x = np.array(x, dtype=float)
        if not self.periodic.any():
            return x
        with np.errstate(invalid="ignore"):
            wrapped = wrap_periodic(x, self.lower, self.upper)
        return np.where(self.periodic & ~self.fixed, wrapped, x)

    def classify(
        self, x: np.ndarray, p: np.ndarray, elapsed: float, time_limit: float, error: str = ""
    ) -> tuple[str, float, str]:
        """``(status, ||r||, message)`` of a returned point ``x`` (module docstring)."""
        if error:
            return Status.FAILED, float("nan"), error
        x = self.wrap(x)
        if not np.all(np.isfinite(x)):
            return Status.FAILED, float("nan"), "non-finite solution"
        rn, stationarity, outside = self.fast("check")(x, p)[0]
        if not np.isfinite(rn):
            return Status.FAILED, float("nan"), "non-finite residual"
        if outside > BOUND_TOLERANCE:
            return Status.FAILED, float(rn), self.violation_message(x)
        return self.status_of(float(rn), float(stationarity), elapsed, time_limit)

    def violation_message(self, x: np.ndarray) -> str:
        """Which bound or constraint ``x`` violates most (relative to its range)."""
        bounds = np.maximum(self.lower - x, x - self.upper) / self.span * (~self.periodic | self.fixed)
        worst = int(np.argmax(bounds))
        message = f"{self.variable_names[worst]} = {x[worst]:.6g} outside its bounds"
        if self.constraints is not None:
            constraints = getattr(self.constraints, "unchecked", self.constraints)  # x may be far outside
            c = np.asarray(constraints(x)).ravel()
            lower, upper = self.constraint_bounds
            violation = np.maximum(lower - c, c - upper) / np.maximum(upper - lower, 1e-300)
            j = int(np.argmax(violation))
            if violation[j] > bounds[worst]:
                message = f"{self.constraint_names[j]} = {c[j]:.6g} outside [{lower[j]:.6g}, {upper[j]:.6g}]"
        return message

    def status_of(self, rn: float, stationarity: float, elapsed: float, time_limit: float) -> tuple[str, float, str]:
        """:meth:`classify` of a finite point inside the bounds whose ``||r||`` and stationarity are known."""
        if rn <= self.tolerance:
            return Status.OK, rn, ""
        if elapsed > time_limit:
            return Status.TIMEOUT, rn, f"time limit {time_limit:g} s exceeded"
        if stationarity <= self.stationarity_tolerance:
            if not self.exact:
                return Status.OK, rn, ""
            return Status.UNREACHABLE, rn, "stationary point of the residual: closest reachable configuration"
        return Status.NOT_CONVERGED, rn, ""

    def classify_many(
        self, X: np.ndarray, P: np.ndarray, limited: np.ndarray | None = None
    ) -> tuple[list[str], np.ndarray, list[str]]:
        """:meth:`classify` for a batch (rows of ``X`` and ``P``, ``X`` already wrapped);
        ``limited`` marks samples cut off by a limit."""
        N = len(X)
        finite = np.all(np.isfinite(X), axis=1)
        packed = np.concatenate([np.where(finite[:, None], X, self.lower), np.asarray(P, dtype=float)], axis=1)
        rn, stationarity, outside = batched(self.packed_check).raw(packed).T
        rn = np.where(finite, rn, np.nan)
        limited = np.zeros(N, dtype=bool) if limited is None else limited
        verdicts = [
            self.verdict(float(rn[i]), float(stationarity[i]), float(outside[i]), X[i], bool(limited[i]))
            for i in range(N)
        ]
        return [v[0] for v in verdicts], rn, [v[1] for v in verdicts]

    def verdict(self, rn: float, stationarity: float, outside: float, x: np.ndarray, limited: bool) -> tuple[str, str]:
        """``(status, message)`` of one sample of :meth:`classify_many` from its checks."""
        if not np.isfinite(rn):
            return Status.FAILED, "non-finite solution"
        if outside > BOUND_TOLERANCE:
            return Status.FAILED, self.violation_message(x)
        if rn <= self.tolerance:
            return Status.OK, ""
        if limited:
            return Status.TIMEOUT, ""
        if stationarity <= self.stationarity_tolerance:
            return (Status.OK, "") if not self.exact else (Status.UNREACHABLE, "closest reachable configuration")
        return Status.NOT_CONVERGED, ""


class NonlinearAdapter:
    """Common part of the ``nonlinear`` adapters: the preset, its limits and typed options, the sample loop.

    Parameters
    ----------
    preset:
        The solver preset (its ``limits`` bound every solve).
    options:
        The preset's ``options`` validated against the backend's options model.

    :meth:`solve` and :meth:`solve_many` remove the fixed variables (module docstring) and call
    the backend's :meth:`solve_free` and :meth:`solve_many_free` on a problem without any;
    subclasses implement :meth:`solve_free`, and :meth:`solve_many_free` loops over samples
    unless overridden.
    """

    def __init__(self, preset: SolverSpec, options: Options):
        self.preset = preset
        self.limits = preset.limits
        self.options = options

    def not_applicable(self, problem: LeastSquaresProblem, X: np.ndarray, P: np.ndarray) -> str | None:
        """Why this backend cannot solve ``problem``'s formulation at all, judged at sample points
        ``(X[k], P[k])`` (:meth:`LeastSquaresProblem.jacobian_rank`); None when it can. Least-squares
        backends solve every formulation; those that impose ``r = 0`` exactly say otherwise."""
        return None

    def solve(
        self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution:
        """One solve from ``x0`` (``x_ref`` defaults to ``x0``); see the module docstring."""
        reduced = problem.reduced
        if reduced is problem:
            return self.solve_free(problem, x0, p, x_ref)
        if reduced.n == 0:
            return self.finish(problem, problem.expand(np.zeros(0)), p, 0, time.perf_counter())
        ref = None if x_ref is None else problem.free_part(x_ref)
        solution = self.solve_free(reduced, problem.free_part(x0), p, ref)
        return replace(solution, x=problem.expand(solution.x))

    def solve_many(
        self,
        problem: LeastSquaresProblem,
        X0: np.ndarray,
        P: np.ndarray,
        warm_start: bool = False,
        x_ref: np.ndarray | None = None,
    ) -> SolutionBatch:
        """Solve every row of ``P``; see the module docstring for ``warm_start`` and ``x_ref``."""
        reduced = problem.reduced
        if reduced is problem:
            return self.solve_many_free(problem, X0, P, warm_start, x_ref)
        if reduced.n == 0:
            x = problem.expand(np.zeros(0))
            P = np.atleast_2d(np.asarray(P, dtype=float))
            return SolutionBatch.of([self.finish(problem, x, p, 0, time.perf_counter()) for p in P], problem.n)
        ref = None if x_ref is None else problem.free_part(x_ref)
        batch = self.solve_many_free(reduced, problem.free_part(X0), P, warm_start, ref)
        return replace(batch, x=problem.expand(batch.x))

    def solve_free(
        self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution:
        """:meth:`solve` on a problem without fixed variables (the backend's own)."""
        raise NotImplementedError

    def solve_many_free(
        self,
        problem: LeastSquaresProblem,
        X0: np.ndarray,
        P: np.ndarray,
        warm_start: bool = False,
        x_ref: np.ndarray | None = None,
    ) -> SolutionBatch:
        """:meth:`solve_many` on a problem without fixed variables: one :meth:`solve_free` per sample."""
        P = np.atleast_2d(np.asarray(P, dtype=float))
        X0 = np.broadcast_to(np.asarray(X0, dtype=float), (len(P), problem.n))
        reports: list[Solution] = []
        previous = None
        for k in range(len(P)):
            check_interrupted()
            start = X0[k] if previous is None else previous
            report = self.solve_free(problem, start, P[k], x_ref)
            reports.append(report)
            if warm_start and (report.status != Status.FAILED or np.all(np.isfinite(report.x))):
                previous = report.x
        return SolutionBatch.of(reports, problem.n)

    def finish(
        self,
        problem: LeastSquaresProblem,
        x: np.ndarray,
        p: np.ndarray,
        iterations: int,
        started: float,
        error: str = "",
    ) -> Solution:
        """Classify the returned point and package the report."""
        elapsed = time.perf_counter() - started
        x = problem.wrap(np.asarray(x, dtype=float).ravel())
        status, rn, message = problem.classify(x, p, elapsed, self.limits.time_limit, error)
        return Solution(x, status, int(iterations), rn, elapsed, message)
