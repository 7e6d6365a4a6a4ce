"""Backend ``gauss_newton``: damped, projected Gauss-Newton on the CasADi Jacobian, one sample or a batch.

Each iteration takes the Levenberg-Marquardt step of the linearised problem at
``x`` (``J = dr/dx`` by CasADi's automatic differentiation), scaled by
``D = W^2`` from the problem's redundancy weights (identity without them):

    dx = -(J^T J + lam D)^-1 J^T r  =  -D^-1 J^T (J D^-1 J^T + lam I)^-1 r,
    lam = mu ||r||^2 + 1e-10 tr(J D^-1 J^T)/m

(the second, ``m x m`` form when there are fewer residuals than variables).
``lam = mu ||r||^2`` is the choice of Yamashita & Fukushima (2001), which keeps
quadratic convergence where ``J`` loses rank; the small floor keeps the system
regular. As ``lam -> 0`` the step is the weighted minimum-norm (pseudo-inverse)
correction, so on a redundant problem the iteration lands on the solution
reached by minimum-norm corrections from the start point: start from the rest
configuration for "closest to rest", from the previous solution along a
trajectory for "closest to previous" (to first order). ``x_ref`` is not used.
Bounds: variables at a bound whose step points outward are frozen and the step
recomputed once (one active-set pass), then the point is clipped; angles with a
full-turn range are wrapped instead. A step is accepted when it lowers ``||r||``
(or reaches the tolerance); then ``mu`` shrinks ten-fold, else it grows
ten-fold and the step is recomputed (Nocedal & Wright 2006, sec. 10.3; Wampler
1986 and Nakamura & Hanafusa 1986 for damped least-squares inverse kinematics).

Gauss-Newton converges slowly to a minimum with a large residual (a target
outside the workspace): after ``SLOW_STEPS`` accepted steps in a row that each
keep more than ``SLOW_PROGRESS`` of ``||r||``, a sample switches to the Newton
model ``J^T J + sum_i r_i Hess r_i`` of ``1/2 ||r||^2`` (same damping; the
structured switch of Fletcher & Xu 1987), which reaches the stationary point
that flags the target ``unreachable``. Option ``second_order: false`` turns this off.
The Newton step Function is built the first time a sample needs it: for the whole
CBHA its Hessian makes it about five times the size of the Gauss-Newton step.

The step, ``||r||`` and a stationarity measure are one CasADi Function, so a
single solve costs one zero-copy ``Function.buffer()`` call per iteration, and
the batched path (:meth:`GaussNewton.solve_many` on independent samples) maps
that Function over all samples at once (:func:`optikin.batch.batched`), or
calls it compiled to C with one C loop over the samples (``compile: true``,
:class:`optikin.codegen.CompiledFunction`), with the acceptance rule vectorised
in numpy.

Preset options: :class:`GaussNewtonOptions`.
"""

from __future__ import annotations

import time
from typing import Any

import casadi as ca
import numpy as np
from pydantic import Field, StrictBool, StrictFloat

from optikin.batch import batched
from optikin.codegen import CompiledFunction, CompilerFlag
from optikin.fastcall import BufferedFunction
from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution, SolutionBatch
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter


LAMBDA_FLOOR = 1e-10
"""Smallest Levenberg parameter, relative to ``tr(J D^-1 J^T)/m``. The step's linear system is
solved without pivoting (symbolic QR, or sparse LDL^T / QR: :data:`SYMBOLIC_SOLVE_MAX`), which
loses the step when ``J`` is singular (the pose Jacobian of a two-section CC arm has rank 5) and
the system is nearly so; 1e-10 keeps it regular and costs nothing visible in the convergence (a
linear rate of about 1e-10/sigma_min^2)."""

SYMBOLIC_SOLVE_MAX = 12
"""Largest linear system of a step that is solved symbolically (CasADi's SX QR, expanded into the
step's instructions: cheap for small systems and fastest there, one flat SX Function). Larger
systems are solved numerically when the step is evaluated, by CasADi's sparse linear solvers
(:data:`GAUSS_NEWTON_SOLVER`, :data:`NEWTON_SOLVER`): the expanded QR grows as the cube of the
size (for the 48 x 48 CBHA system, twice expanded, it was twenty times the residual and Jacobian
together), the numeric one costs its flops only."""

GAUSS_NEWTON_SOLVER = "ldl"
NEWTON_SOLVER = "qr"
"""CasADi linear-solver plugins of the numeric solves (:data:`SYMBOLIC_SOLVE_MAX`): sparse LDL^T for
the Gauss-Newton models (symmetric positive definite for ``lam > 0``), sparse QR for the Newton
model (``J^T J + S`` may be indefinite). Both generate C, so ``compile: true`` keeps working."""


def _point_quantities(problem: LeastSquaresProblem, second_order: bool):
    """``x, p, r, J, J^T r, ||r||``, the active-bound masks and (``second_order``) the Hessian of
    ``1/2 ||r||^2``, as SX expressions of ``x`` and ``p``."""
    x, p, r, J = problem.symbols
    lower_active, upper_active = problem.active_bounds(x)
    hessian = ca.hessian(0.5 * ca.sumsqr(r), x)[0] if second_order else ca.SX(0, 0)
    return x, p, r, J, ca.mtimes(J.T, r), ca.norm_2(r), lower_active, upper_active, hessian


def step_function(problem: LeastSquaresProblem, second_order: bool = False) -> ca.Function:
    """``[x; p; mu] -> [x_new; ||r(x)||; stationarity]`` (module docstring).

    ``second_order`` adds ``S = sum_i r_i Hess r_i`` to ``J^T J`` (the Newton model of
    ``1/2 ||r||^2``). One packed input and output, so a batch is one array in and one array
    out, for :class:`~optikin.solvers.evaluation.CompiledFunction` and
    :func:`~optikin.solvers.evaluation.batched`.

    A linear system of at most :data:`SYMBOLIC_SOLVE_MAX` unknowns is solved symbolically and the
    step is one SX Function. A larger one gives an MX Function around one SX Function that
    evaluates ``r``, ``J`` (with CasADi's sparsity), ``J^T r`` and the bound masks (and, for
    ``second_order``, the Hessian) with their common subexpressions shared; ``J^T J`` (or
    ``J D^-1 J^T``) is a numeric sparse product, the system is solved numerically
    (:data:`GAUSS_NEWTON_SOLVER`, :data:`NEWTON_SOLVER`), and the second, bound-restricted solve is
    evaluated only when a bound blocks a component of the first step (it equals the first otherwise).
    """
    n, m = problem.n, problem.m
    numeric = (m if m < n and not second_order else n) > SYMBOLIC_SOLVE_MAX
    quantities: tuple[Any, ...] = _point_quantities(problem, second_order)  # SX, then MX for a numeric solve
    x, p, r, J, g, rn, lower_active, upper_active, hessian = quantities
    mu: Any = ca.SX.sym("mu")
    if numeric:
        names = ["r", "J", "g", "rn", "lower_active", "upper_active", "hessian"]
        parts = ca.Function(
            f"{problem.name}_gn_point", [x, p], [r, J, g, rn, lower_active, upper_active, hessian], ["x", "p"], names
        )
        x, p, mu = ca.MX.sym("x", n), ca.MX.sym("p", problem.n_data), ca.MX.sym("mu")
        r, J, g, rn, lower_active, upper_active, hessian = parts(x, p)
    lower, upper = ca.DM(problem.lower), ca.DM(problem.upper)
    periodic = ca.DM(problem.periodic.astype(float))
    scaling = ca.DM.ones(n) if problem.weights is None else ca.DM(problem.weights**2)
    # Levenberg parameter mu ||r||^2 (Yamashita & Fukushima 2001: quadratic convergence without full rank),
    # plus a floor relative to the trace of J D^-1 J^T that keeps the linear system regular (LAMBDA_FLOOR).
    trace = ca.dot(ca.sum1(J * J).T, 1 / scaling)
    lam = mu * rn * rn + LAMBDA_FLOOR * trace / m
    plugin = NEWTON_SOLVER if second_order else GAUSS_NEWTON_SOLVER

    def directions(M, v, lam):
        """The step restricted to the variables marked by ``free``, from ``M`` (the model's ``J^T J``, its
        Newton matrix, or ``J`` for the ``m x m`` form), ``v`` (``J^T r``, or ``r`` for the ``m x m`` form)
        and the Levenberg parameter."""

        def full(free):
            if not numeric:
                F = ca.diag(free)
                A = ca.mtimes(F, ca.mtimes(M, F)) + ca.diag(1 - free) + lam * ca.diag(scaling)
                return -free * ca.solve(A, free * v)
            if isinstance(free, ca.DM):  # the first direction: nothing masked
                return -ca.solve(M + ca.diag(lam * scaling), v, plugin)
            A = M * ca.mtimes(free, free.T) + ca.diag(1 - free + lam * scaling)
            return -free * ca.solve(A, free * v, plugin)

        def small(free):
            mf = free / scaling
            if not numeric:
                A = ca.mtimes(M, ca.mtimes(ca.diag(mf), M.T)) + lam * ca.DM.eye(m)
                return -mf * ca.mtimes(M.T, ca.solve(A, v))
            A = ca.mtimes(M * ca.repmat(mf.T, m, 1), M.T) + lam * ca.DM.eye(m)
            return -mf * ca.mtimes(M.T, ca.solve(A, v, plugin))

        return small if m < n and not second_order else full

    if second_order:
        model, vector = hessian, g
    elif m < n:
        model, vector = J, r
    else:
        model, vector = ca.mtimes(J.T, J), g
    first = directions(model, vector, lam)(ca.DM.ones(n))
    blocked = ca.logic_or(ca.logic_and(lower_active, first < 0), ca.logic_and(upper_active, first > 0))
    if numeric:
        # The bound-restricted solve only when a bound blocks a component (it equals ``first`` otherwise):
        # a switch between two Functions of the quantities already computed.
        M, v, l_, free, kept = (
            ca.MX.sym("M", model.sparsity()),
            ca.MX.sym("v", vector.sparsity()),
            ca.MX.sym("lam"),
            ca.MX.sym("free", n),
            ca.MX.sym("first", n),
        )
        args = [M, v, l_, free, kept]
        restrict = ca.Function.if_else(
            f"{problem.name}_gn_restrict",
            ca.Function("restricted", args, [directions(M, v, l_)(free)]),
            ca.Function("unrestricted", args, [kept]),
        )
        moved = x + restrict(ca.mmax(blocked) > 0, model, vector, lam, 1 - blocked, first)
    else:
        moved = x + directions(model, vector, lam)(1 - blocked)
    span = upper - lower
    wrapped = moved - span * ca.floor((moved - lower) / span)
    x_new = ca.if_else(periodic, wrapped, ca.fmin(ca.fmax(moved, lower), upper))
    outward = ca.logic_or(ca.logic_and(lower_active, g > 0), ca.logic_and(upper_active, g < 0))
    stationarity = ca.norm_2(ca.if_else(outward, 0, g)) / (ca.norm_fro(J) * rn + 1e-300)
    return ca.Function(
        f"{problem.name}_{'newton' if second_order else 'gn'}_step",
        [ca.vertcat(x, p, mu)],
        [ca.vertcat(x_new, rn, stationarity)],
        ["x_p_mu"],
        ["x_new_info"],
    )


SLOW_PROGRESS = 0.9
SLOW_STEPS = 3
"""``SLOW_STEPS`` accepted steps in a row that each leave more than ``SLOW_PROGRESS`` of ``||r||``
switch the sample to the second-order model (a large-residual minimum, e.g. a target outside
the workspace)."""


class GaussNewtonOptions(Options):
    """Preset options of backend ``gauss_newton``."""

    damping: StrictFloat = Field(
        10.0, gt=0, description="initial mu of the Levenberg parameter lam = mu ||r||^2 [1/(units of r)^2]"
    )
    damping_min: StrictFloat = Field(1e-12, gt=0, description="smallest mu [1/(units of r)^2]")
    damping_max: StrictFloat = Field(
        1e12, gt=0, description="largest mu; a sample whose mu grows above it stops (stuck) [1/(units of r)^2]"
    )
    second_order: StrictBool = Field(
        True, description="switch a stalled sample (large residual) to the Newton model J^T J + sum r_i Hess r_i"
    )
    compile: StrictBool = Field(False, description="code-generate the step Function and compile it to C")
    flags: tuple[CompilerFlag, ...] = Field(
        ("-O3",), description="C compiler flags of compile: true, from optikin.codegen.ALLOWED_FLAGS"
    )
    batch: StrictBool = Field(
        True, description="independent samples: one batched step evaluation per iteration for all of them"
    )


class GaussNewton(NonlinearAdapter):
    """Damped projected Gauss-Newton (module docstring)."""

    options: GaussNewtonOptions

    # ------------------------------------------------------------------ Functions
    def _key(self, what: str, second_order: bool) -> tuple:
        return (what, second_order, self.options.compile, *self.options.flags)

    def _function(self, problem: LeastSquaresProblem, second_order: bool) -> ca.Function:
        key = self._key("gn_function", second_order)
        if key not in problem.cache:
            problem.cache[key] = step_function(problem, second_order)
        return problem.cache[key]

    def _compiled(self, problem: LeastSquaresProblem, second_order: bool) -> CompiledFunction:
        key = self._key("gn_compiled", second_order)
        if key not in problem.cache:
            f = self._function(problem, second_order)
            problem.cache[key] = CompiledFunction(f, self.options.flags)
        return problem.cache[key]

    def step(self, problem: LeastSquaresProblem, second_order: bool = False) -> ca.Function:
        """A step Function of ``problem`` (compiled when the preset says so), built once."""
        if self.options.compile:
            return self._compiled(problem, second_order).external
        return self._function(problem, second_order)

    def _single(self, problem: LeastSquaresProblem, second_order: bool):
        """``(x, p, mu) -> (x_new, [||r(x)||, stationarity])`` for one sample through a
        :class:`~optikin.fastcall.BufferedFunction`; ``x_new`` is a view of its output (copy to keep)."""
        key = self._key("gn_single", second_order)
        if key not in problem.cache:
            call = BufferedFunction(self.step(problem, second_order))
            n, n_p = problem.n, problem.n_data
            packed, out = call.inputs[0], call.outputs[0]
            x_new, info = out[:n], out[n:]

            def single(x, p, mu):
                packed[:n] = x
                packed[n : n + n_p] = p
                packed[-1] = mu
                call()
                return x_new, info.tolist()

            problem.cache[key] = single
        return problem.cache[key]

    def _batch(self, problem: LeastSquaresProblem, second_order: bool):
        """``(X, P, mu) -> (X_new, info (2, N))`` over the rows of ``X``: one call into CasADi (or C)."""
        key = self._key("gn_batch", second_order)
        if key not in problem.cache:
            if self.options.compile:
                runner = self._compiled(problem, second_order).raw
            else:
                runner = batched(self._function(problem, second_order)).raw
            n = problem.n

            def batch(X, P, mu):
                out = runner(np.concatenate([X, P, mu[:, None]], axis=1))
                return out[:, :n], out[:, n:].T.copy()

            problem.cache[key] = batch
        return problem.cache[key]

    def _stop_tolerance(self, problem: LeastSquaresProblem) -> float:
        return min(problem.tolerance, self.limits.tolerance)

    # ------------------------------------------------------------------ one sample
    def solve_free(
        self, problem: LeastSquaresProblem, x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution:
        started = time.perf_counter()
        gauss_newton = step = self._single(problem, False)
        tol, stat_tol = self._stop_tolerance(problem), problem.stationarity_tolerance
        mu, mu_min, mu_max = self.options.damping, self.options.damping_min, self.options.damping_max
        max_calls = self.limits.max_iterations
        deadline = started + self.limits.time_limit
        x = problem.project(x0)
        slow = 0
        proposal, (rn, stationarity) = step(x, p, mu)
        proposal = proposal.copy()
        calls = 1
        while calls < max_calls:
            if not rn > tol or stationarity <= stat_tol or mu > mu_max or time.perf_counter() > deadline:
                break
            trial_mu = max(mu * 0.1, mu_min)
            next_proposal, (trial_rn, trial_stationarity) = step(proposal, p, trial_mu)
            calls += 1
            if trial_rn < rn or trial_rn <= tol:
                slow = slow + 1 if trial_rn > SLOW_PROGRESS * rn else 0
                if slow >= SLOW_STEPS and step is gauss_newton and self.options.second_order:
                    step = self._single(problem, True)  # built on first use: much larger than a Gauss-Newton step
                x, proposal, mu = proposal, next_proposal.copy(), trial_mu
                rn, stationarity = trial_rn, trial_stationarity
            elif calls < max_calls:
                mu *= 10.0
                proposal, (rn, stationarity) = step(x, p, mu)
                proposal = proposal.copy()
                calls += 1
        elapsed = time.perf_counter() - started
        if not np.isfinite(rn) or problem.constraints is not None:
            return self.finish(problem, x, p, calls, started)
        # x is inside the bounds (projected by every step) and (rn, stationarity) are its own.
        status, rn, message = problem.status_of(rn, stationarity, elapsed, self.limits.time_limit)
        return Solution(x, status, calls, rn, elapsed, message)

    # ------------------------------------------------------------------ many independent samples at once
    def solve_many(
        self,
        problem: LeastSquaresProblem,
        X0: np.ndarray,
        P: np.ndarray,
        warm_start: bool = False,
        x_ref: np.ndarray | None = None,
    ) -> SolutionBatch:
        """:meth:`NonlinearAdapter.solve_many` as one call of generated C where it applies
        (:mod:`optikin.native.ik`: bit-identical answers), else the Python path."""
        if x_ref is None:
            from optikin.native.ik import native_solve_many

            batch = native_solve_many(self, problem, X0, P, warm_start)
            if batch is not None:
                return batch
        return super().solve_many(problem, X0, P, warm_start, x_ref)

    def solve_many_free(
        self,
        problem: LeastSquaresProblem,
        X0: np.ndarray,
        P: np.ndarray,
        warm_start: bool = False,
        x_ref: np.ndarray | None = None,
    ) -> SolutionBatch:
        if warm_start or not self.options.batch:
            return super().solve_many_free(problem, X0, P, warm_start, x_ref)
        return self.solve_batch(problem, X0, P)

    def solve_batch(self, problem: LeastSquaresProblem, X0: np.ndarray, P: np.ndarray) -> SolutionBatch:
        """All samples at once: one batched step evaluation per iteration, acceptance vectorised.

        Every sample follows the rule of :meth:`solve` (the results agree to rounding); a sample
        whose last trial was rejected spends its next evaluation on a new proposal from its
        accepted point. Only running samples are evaluated. The time limit applies to the
        batch as a whole: ``limits.time_limit`` per sample.
        """
        started = time.perf_counter()
        P = np.atleast_2d(np.asarray(P, dtype=float))
        N, n = len(P), problem.n
        X = problem.project(np.broadcast_to(np.asarray(X0, dtype=float), (N, n)))
        tol, stat_tol = self._stop_tolerance(problem), problem.stationarity_tolerance
        mu_min, mu_max = self.options.damping_min, self.options.damping_max
        deadline = started + self.limits.time_limit * N
        gauss_newton = self._batch(problem, False)

        def evaluate(X_, P_, mu_, so_):
            """Each sample with its model: Gauss-Newton, or Newton once switched (``so_``; built on first use)."""
            if not so_.any():
                return gauss_newton(X_, P_, mu_)
            newton = self._batch(problem, True)
            out_x, out_info = np.empty_like(X_), np.empty((2, len(X_)))
            for model, rows in ((gauss_newton, ~so_), (newton, so_)):
                if rows.any():
                    out_x[rows], out_info[:, rows] = model(X_[rows], P_[rows], mu_[rows])
            return out_x, out_info

        mu = np.full(N, float(self.options.damping))
        so = np.zeros(N, dtype=bool)
        slow = np.zeros(N, dtype=int)
        proposal, info = evaluate(X, P, mu, so)
        calls = np.ones(N, dtype=int)
        testing = np.ones(N, dtype=bool)  # next evaluation: test ``proposal`` (else re-propose from X)
        idx = np.arange(N)
        timed_out = False
        while True:
            # Samples still running: not solved, not stationary, not stuck, under the iteration limit.
            rn, stationarity = info[0, idx], info[1, idx]
            idx = idx[
                (rn > tol) & (stationarity > stat_tol) & (mu[idx] <= mu_max) & (calls[idx] < self.limits.max_iterations)
            ]
            if idx.size == 0:
                break
            if time.perf_counter() > deadline:
                timed_out = True
                break
            test, mu_i, rn = testing[idx], mu[idx], info[0, idx]
            trial_mu = np.where(test, np.maximum(mu_i * 0.1, mu_min), mu_i)
            at = np.where(test[:, None], proposal[idx], X[idx])
            new_proposal, new_info = evaluate(at, P[idx], trial_mu, so[idx])
            calls[idx] += 1
            accept = test & ((new_info[0] < rn) | (new_info[0] <= tol))
            reject = test & ~accept
            update = accept | ~test
            slow[idx] = np.where(accept, np.where(new_info[0] > SLOW_PROGRESS * rn, slow[idx] + 1, 0), slow[idx])
            if self.options.second_order:
                so[idx[slow[idx] >= SLOW_STEPS]] = True
            X[idx[accept]] = proposal[idx[accept]]
            info[:, idx[update]] = new_info[:, update]
            proposal[idx[update]] = new_proposal[update]
            mu[idx] = np.where(accept, trial_mu, np.where(reject, mu_i * 10.0, mu_i))
            testing[idx] = ~reject

        limited = np.zeros(N, dtype=bool)
        limited[idx] = timed_out
        elapsed = time.perf_counter() - started
        status, residual, messages = problem.classify_many(X, P, limited=limited)
        return SolutionBatch(
            x=X,
            status=status,
            iterations=calls,
            residual=residual,
            seconds=np.full(N, elapsed / N),
            messages=messages,
            batched=True,
        )


register_backend(
    "gauss_newton",
    "nonlinear",
    "damped projected Gauss-Newton on CasADi Jacobians; batched over samples",
    options=GaussNewtonOptions,
)(GaussNewton)
