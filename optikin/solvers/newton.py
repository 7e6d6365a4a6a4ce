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
a root outside them is reported ``failed``. ANCHORS.md: the rootfinder may
return a non-converged iterate silently, so every result is classified from
its own residual (:mod:`optikin.solvers.nonlinear`).

Preset options: ``plugin`` (``newton`` or ``fast_newton``), ``abstolStep``,
``line_search`` (``newton`` only). ``limits.max_iterations`` and
``limits.tolerance`` become ``max_iter`` and ``abstol``.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from optikin.errors import SolverError
from optikin.solvers import register_backend
from optikin.fastcall import BufferedFunction
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter, SolveReport

PLUGINS = ("newton", "fast_newton")


def optimality_system(problem: LeastSquaresProblem) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(z, parameters, G(z))``: the square system Newton solves (module docstring)."""
    x, p, r, J = problem.symbols
    x_ref = ca.SX.sym("x_ref", problem.n)
    if not problem.exact:
        return x, ca.vertcat(p, x_ref), ca.mtimes(J.T, r)
    if problem.m == problem.n:
        return x, ca.vertcat(p, x_ref), r
    if problem.m > problem.n:
        raise SolverError(f"{problem.name}: Newton's method needs at most as many residuals ({problem.m}) "
                          f"as variables ({problem.n}); use a least-squares backend")
    if problem.weights is None:
        raise SolverError(f"{problem.name}: {problem.m} residuals for {problem.n} variables and no redundancy "
                          f"weights: the Newton system is not square")
    y = ca.SX.sym("y", problem.m)
    periodic = ca.DM(problem.periodic.astype(float))
    grad = ca.if_else(periodic, ca.sin(x - x_ref), x - x_ref)
    stationarity = ca.DM(problem.weights**2) * grad + ca.mtimes(J.T, y)
    return ca.vertcat(x, y), ca.vertcat(p, x_ref), ca.vertcat(stationarity, r)


class Newton(NonlinearAdapter):
    """CasADi rootfinder (module docstring)."""

    defaults = {"plugin": "newton", "abstolStep": 1e-14, "line_search": True}

    def __init__(self, preset):
        super().__init__(preset)
        if self.options["plugin"] not in PLUGINS:
            raise self.option_error("plugin", f"{self.options['plugin']!r} is not one of {', '.join(PLUGINS)}")

    def rootfinder(self, problem: LeastSquaresProblem) -> BufferedFunction:
        key = ("rootfinder", self)
        if key not in problem.cache:
            z, parameters, G = optimality_system(problem)
            g = ca.Function(f"{problem.name}_newton_system", [z, parameters], [G])
            opts = {"max_iter": self.limits.max_iterations, "abstol": self.limits.tolerance,
                    "abstolStep": self.options["abstolStep"], "error_on_fail": False,
                    "show_eval_warnings": False}
            if self.options["plugin"] == "newton":
                opts["line_search"] = self.options["line_search"]
            try:
                solver = ca.rootfinder(f"{problem.name}_newton", self.options["plugin"], g, opts)
            except RuntimeError as exc:
                raise SolverError(f"{self.preset.name}: building the rootfinder failed: {exc}") from None
            problem.cache[key] = BufferedFunction(solver)
        return problem.cache[key]

    def solve(self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray,
              x_ref: np.ndarray | None = None) -> SolveReport:
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


register_backend("newton", "nonlinear", "CasADi rootfinder (Newton) on r = 0 or its optimality system")(Newton)
