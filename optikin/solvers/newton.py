"""Backend ``newton``: CasADi ``rootfinder`` (Newton's method) on a square system.

A square problem (as many residuals as variables, e.g. full-pose IK of a
two-section CC arm) is solved as ``r(x, p) = 0``. A redundant one (fewer
residuals than variables, with weights ``W``) is solved through its optimality
conditions for ``min 1/2 sum W_i^2 dist(x_i, x_ref,i)^2 s.t. r(x, p) = 0``,

    W^2 grad dist(x, x_ref) + J^T y = 0,    r(x, p) = 0,

a square system in ``(x, y)`` whose Jacobian CasADi differentiates exactly
(``dist`` is ``x - x_ref``, and ``2 sin((x - x_ref)/2)`` for angles that wrap, so
``grad`` of its square is ``sin(x - x_ref)``). A problem that is not exact (a
penalised one, e.g. seed 004 eq. 11) is solved through ``J^T r = 0``, the
stationarity of ``1/2 ||r||^2``, whose Jacobian is the full Hessian. Newton's method knows no bounds:
a root outside them is reported ``failed``. CasADi's rootfinder may
return a non-converged iterate silently, so every result is classified from
its own residual (:mod:`optikin.solvers.nonlinear`).

Many independent samples (``solve_many`` without ``warm_start``) are solved in
one call: the rootfinder is mapped over the samples (:func:`optikin.batch.batched`),
as CasADi evaluates a ``map`` of it, and the points are classified together. A
mapped rootfinder keeps no per-sample statistics, so a batch reports its
iterations as -1 (unknown), and its time limit applies to the batch as a whole
(``limits.time_limit`` per sample, checked after the call).

Preset options: :class:`NewtonOptions`. ``limits.max_iterations`` and
``limits.tolerance`` become ``max_iter`` and ``abstol``.
"""

from __future__ import annotations

import time
from typing import Literal

import casadi as ca
import numpy as np
from pydantic import Field, StrictBool, StrictFloat

from optikin.batch import batched
from optikin.errors import SolverError
from optikin.fastcall import BufferedFunction
from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution, SolutionBatch
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter


class NewtonOptions(Options):
    """Preset options of backend ``newton``."""

    plugin: Literal["newton", "fast_newton"] = Field("newton", description="CasADi rootfinder plugin")
    abstolStep: StrictFloat = Field(
        1e-14, ge=0, description="stop when the Newton step's max-norm is at or below this (units of x)"
    )
    line_search: StrictBool = Field(True, description="backtracking line search (plugin newton only)")


def optimality_system(problem: LeastSquaresProblem) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(z, parameters, G(z))``: the square system Newton solves (module docstring)."""
    x, p, r, J = problem.symbols
    x_ref = ca.SX.sym("x_ref", problem.n)
    if not problem.exact:
        return x, ca.vertcat(p, x_ref), ca.mtimes(J.T, r)
    if problem.m == problem.n:
        return x, ca.vertcat(p, x_ref), r
    if problem.m > problem.n:
        raise SolverError(
            f"{problem.name}: Newton's method needs at most as many residuals ({problem.m}) "
            f"as variables ({problem.n}); use a least-squares backend"
        )
    if problem.weights is None:
        raise SolverError(
            f"{problem.name}: {problem.m} residuals for {problem.n} variables and no redundancy "
            f"weights: the Newton system is not square"
        )
    y = ca.SX.sym("y", problem.m)
    periodic = ca.DM(problem.periodic.astype(float))
    grad = ca.if_else(periodic, ca.sin(x - x_ref), x - x_ref)
    stationarity = ca.DM(problem.weights**2) * grad + ca.mtimes(J.T, y)
    return ca.vertcat(x, y), ca.vertcat(p, x_ref), ca.vertcat(stationarity, r)


class Newton(NonlinearAdapter):
    """CasADi rootfinder (module docstring)."""

    options: NewtonOptions

    def not_applicable(self, problem: LeastSquaresProblem, X: np.ndarray, P: np.ndarray) -> str | None:
        """An exact problem whose residual Jacobian is rank-deficient at every sample point: its Newton
        system (``r = 0``, or the optimality system with ``J^T y``) is singular."""
        m = problem.m
        if not problem.exact or m > problem.reduced.n:
            return None
        rank = problem.jacobian_rank(X, P)
        if rank >= m:
            return None
        return (
            f"the {m} residuals have a rank-{rank} Jacobian at all {len(X)} sampled points: "
            "Newton's system is singular for this formulation"
        )

    def rootfinder_function(self, problem: LeastSquaresProblem) -> ca.Function:
        """``(z0, [p; x_ref]) -> z``: CasADi's rootfinder on the system of :func:`optimality_system`."""
        key = ("rootfinder", self)
        if key not in problem.cache:
            z, parameters, G = optimality_system(problem)
            g = ca.Function(f"{problem.name}_newton_system", [z, parameters], [G])
            opts = {
                "max_iter": self.limits.max_iterations,
                "abstol": self.limits.tolerance,
                "abstolStep": self.options.abstolStep,
                "error_on_fail": False,
                "show_eval_warnings": False,
            }
            if self.options.plugin == "newton":
                opts["line_search"] = self.options.line_search
            try:
                problem.cache[key] = ca.rootfinder(f"{problem.name}_newton", self.options.plugin, g, opts)
            except RuntimeError as exc:
                raise SolverError(f"{self.preset.name}: building the rootfinder failed: {exc}") from None
        return problem.cache[key]

    def rootfinder(self, problem: LeastSquaresProblem) -> BufferedFunction:
        """A zero-copy caller of :meth:`rootfinder_function` (one sample per call)."""
        key = ("rootfinder_buffered", self)
        if key not in problem.cache:
            problem.cache[key] = BufferedFunction(self.rootfinder_function(problem))
        return problem.cache[key]

    def packed_rootfinder(self, problem: LeastSquaresProblem) -> ca.Function:
        """``[x0; p; x_ref] -> x``: one packed input per sample, for a mapped batch."""
        key = ("rootfinder_packed", self)
        if key not in problem.cache:
            solver = self.rootfinder_function(problem)
            n, n_z = problem.n, solver.size1_in(0)
            w = ca.MX.sym("w", 2 * n + problem.n_data)
            z0 = ca.vertcat(w[:n], ca.MX.zeros(n_z - n))
            z = solver(z0, w[n:])
            problem.cache[key] = ca.Function(f"{problem.name}_newton_packed", [w], [z[:n]])
        return problem.cache[key]

    def solve_free(
        self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution:
        started = time.perf_counter()
        call = self.rootfinder(problem)
        x0 = np.asarray(x0, dtype=float)
        reference = x0 if x_ref is None else np.asarray(x_ref, dtype=float)
        z0 = np.concatenate([x0, np.zeros(len(call.inputs[0]) - problem.n)])
        try:
            z = call(z0, np.concatenate([np.ravel(p), reference]))[0]
        except RuntimeError as exc:
            return self.finish(problem, x0, p, 0, started, error=f"rootfinder: {exc}")
        iterations = call.stats().get("iter_count", -1)
        return self.finish(problem, z[: problem.n].copy(), p, iterations, started)

    def solve_many_free(
        self,
        problem: LeastSquaresProblem,
        X0: np.ndarray,
        P: np.ndarray,
        warm_start: bool = False,
        x_ref: np.ndarray | None = None,
    ) -> SolutionBatch:
        if warm_start:
            return super().solve_many_free(problem, X0, P, warm_start, x_ref)
        return self.solve_batch(problem, X0, P, x_ref)

    def solve_batch(
        self, problem: LeastSquaresProblem, X0: np.ndarray, P: np.ndarray, x_ref: np.ndarray | None = None
    ) -> SolutionBatch:
        """Every row of ``P`` in one mapped call (module docstring); ``x_ref`` defaults to each start."""
        mapped = batched(self.packed_rootfinder(problem))  # built before the clock starts
        started = time.perf_counter()
        P = np.atleast_2d(np.asarray(P, dtype=float))
        N, n = len(P), problem.n
        X0 = np.broadcast_to(np.asarray(X0, dtype=float), (N, n))
        reference = X0 if x_ref is None else np.broadcast_to(np.asarray(x_ref, dtype=float), (N, n))
        try:
            X = problem.wrap(mapped.raw(np.concatenate([X0, P, reference], axis=1)))
        except RuntimeError as exc:
            raise SolverError(f"{self.preset.name}: the mapped rootfinder failed: {exc}") from None
        elapsed = time.perf_counter() - started
        limited = np.full(N, elapsed > self.limits.time_limit * N)
        status, residual, messages = problem.classify_many(X, P, limited=limited)
        return SolutionBatch(
            x=X,
            status=status,
            iterations=np.full(N, -1),
            residual=residual,
            seconds=np.full(N, elapsed / N),
            messages=messages,
            batched=True,
        )


register_backend(
    "newton", "nonlinear", "CasADi rootfinder (Newton) on r = 0 or its optimality system", options=NewtonOptions
)(Newton)
