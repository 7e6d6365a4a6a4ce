"""Damped Gauss-Newton IK of an unconstrained least-squares problem in the exported C, a batch per C call.

:func:`solve_many` is :meth:`GaussNewton.solve_many <optikin.solvers.gauss_newton.GaussNewton>` (the
``gauss_newton`` backend) with every target solved by the C of ``optikin export --what ik-step`` /
``ik-trajectory`` (:func:`optikin.export.ik_library`: the same iteration, damping rule, acceptance,
switch to the Newton model and limits), compiled once per problem and adapter options into the
per-user cache (:mod:`optikin.native`). Along a trajectory each target starts from the previous
solution with finite entries, before any from its own row of ``X0``, as
:meth:`~optikin.solvers.nonlinear.NonlinearAdapter.solve_many_free` does; independent targets start
from their rows of ``X0``. Statuses are decided as the Python paths decide them (``status_of`` along a
trajectory, ``verdict`` for independent targets, with their messages); a sample whose residual became
non-finite is classified from its returned point by the problem itself.

The C solves the step's linear system by LU with partial pivoting where the Python step uses CasADi's
symbolic QR, so iterates agree to rounding: on the constant-curvature position targets the solutions
agree to 1e-12 with the same statuses and iterations (``tests/test_ik_fast_c.py``). Where the Jacobian
has a null direction at the solution (pose targets of a two-section arm) rounding decides where along
it each path lands.

Covered: problems without constraints with at most :data:`MAX_VARIABLES` free variables, finite starts
and targets, solved by a :class:`~optikin.solvers.gauss_newton.GaussNewton` adapter; anything else
(and ``OPTIKIN_NATIVE=0``, or no ``gcc``) runs the adapter's own :meth:`solve_many`. The C has no time
limit: its iterations are bounded by the preset's ``max_iterations``.
"""

from __future__ import annotations

import ctypes
import time
from dataclasses import dataclass
from string import Template
from typing import Any

import casadi as ca
import numpy as np

from optikin.interrupt import check_interrupted
from optikin.native import CHUNK, load_library, native_enabled, pointer, report_fallback
from optikin.solvers.base import SolutionBatch
from optikin.solvers.nonlinear import BOUND_TOLERANCE

STEM = "optikin_native_ik"

_DRIVER = r"""
/* ---- optikin.native.ik: the iteration of optikin.solvers.gauss_newton around its step Functions ---- */
#include <stdlib.h>
#define NX $n
#define NP $n_p
static const double lower[NX] = {$lower};
static const double upper[NX] = {$upper};
static const int periodic[NX] = {$periodic};
static const double stop_tolerance = $stop_tolerance, stationarity_tolerance = $stationarity_tolerance;
static const double damping = $damping, damping_min = $damping_min, damping_max = $damping_max;
static const double slow_progress = $slow_progress;
static const int slow_steps = $slow_steps, max_calls = $max_calls, second_order = $second_order;

typedef struct {
  const casadi_real* arg[$sz_arg];
  casadi_real* res[$sz_res];
  casadi_int iw[$sz_iw];
  casadi_real w[$sz_w];
  double in[NX + NP + 1];
  double out[NX + 2];
} native_work;

/* numpy's float mod (npy_divmod): the remainder with the divisor's sign. */
static double py_mod(double a, double b) {
  double mod = fmod(a, b);
  if (mod != 0.0) {
    if ((b < 0) != (mod < 0)) mod += b;
  } else {
    mod = copysign(0.0, b);
  }
  return mod;
}

/* LeastSquaresProblem.project: periodic variables wrapped into [lower, upper), the others clipped; a point
   inside the box unchanged unless always (the 2-D case, which wraps every periodic entry). */
static void project(const double* x0, double* x, int always) {
  int i, inside = 1;
  for (i = 0; i < NX; ++i) inside = inside && x0[i] >= lower[i] && x0[i] <= upper[i];
  for (i = 0; i < NX; ++i) {
    if (inside && !always) x[i] = x0[i];
    else if (periodic[i]) x[i] = lower[i] + py_mod(x0[i] - lower[i], upper[i] - lower[i]);
    else x[i] = fmin(fmax(x0[i], lower[i]), upper[i]);
  }
}

/* One evaluation of the step Function (Gauss-Newton or Newton): x_new, ||r(x)||, stationarity of x. */
static void step(native_work* w, int newton, const double* x, const double* p, double mu, double* x_new, double* rn,
                 double* st) {
  int i;
  for (i = 0; i < NX; ++i) w->in[i] = x[i];
  for (i = 0; i < NP; ++i) w->in[NX + i] = p[i];
  w->in[NX + NP] = mu;
  w->arg[0] = w->in;
  w->res[0] = w->out;
  if (newton) optikin_native_ik_newton(w->arg, w->res, w->iw, w->w, 0);
  else optikin_native_ik_gn(w->arg, w->res, w->iw, w->w, 0);
  for (i = 0; i < NX; ++i) x_new[i] = w->out[i];
  *rn = w->out[NX];
  *st = w->out[NX + 1];
}

static void copy(double* to, const double* from) {
  int i;
  for (i = 0; i < NX; ++i) to[i] = from[i];
}

/* GaussNewton.solve_free from x0: x, ||r(x)|| and stationarity of x, step evaluations. */
static void solve_one(native_work* w, const double* x0, const double* p, double* x, double* rn_out, double* st_out,
                      int* calls_out) {
  double proposal[NX], next[NX];
  double mu = damping, trial_mu, rn, st, trial_rn, trial_st;
  int calls, slow = 0, newton = 0;
  project(x0, x, 0);
  step(w, newton, x, p, mu, proposal, &rn, &st);
  calls = 1;
  while (calls < max_calls) {
    if (!(rn > stop_tolerance) || st <= stationarity_tolerance || mu > damping_max) break;
    trial_mu = fmax(mu * 0.1, damping_min);
    step(w, newton, proposal, p, trial_mu, next, &trial_rn, &trial_st);
    calls += 1;
    if (trial_rn < rn || trial_rn <= stop_tolerance) {
      slow = trial_rn > slow_progress * rn ? slow + 1 : 0;
      if (slow >= slow_steps && !newton && second_order) newton = 1;
      copy(x, proposal);
      copy(proposal, next);
      mu = trial_mu;
      rn = trial_rn;
      st = trial_st;
    } else if (calls < max_calls) {
      mu *= 10.0;
      step(w, newton, x, p, mu, proposal, &rn, &st);
      calls += 1;
    }
  }
  *rn_out = rn;
  *st_out = st;
  *calls_out = calls;
}

/* One sample of GaussNewton.solve_batch (its per-sample rule, the acceptance one evaluation per pass). */
static void solve_batched(native_work* w, const double* x0, const double* p, double* x, double* rn_out,
                          double* st_out, int* calls_out) {
  double proposal[NX], fresh[NX];
  double mu = damping, trial_mu, rn, st, new_rn, new_st;
  int calls, slow = 0, newton = 0, testing = 1, accept, reject;
  project(x0, x, 1);
  step(w, newton, x, p, mu, proposal, &rn, &st);
  calls = 1;
  while (rn > stop_tolerance && st > stationarity_tolerance && mu <= damping_max && calls < max_calls) {
    trial_mu = testing ? fmax(mu * 0.1, damping_min) : mu;
    step(w, newton, testing ? proposal : x, p, trial_mu, fresh, &new_rn, &new_st);
    calls += 1;
    accept = testing && (new_rn < rn || new_rn <= stop_tolerance);
    reject = testing && !accept;
    if (accept) slow = new_rn > slow_progress * rn ? slow + 1 : 0;
    if (second_order && slow >= slow_steps) newton = 1;
    if (accept) copy(x, proposal);
    if (accept || !testing) {
      rn = new_rn;
      st = new_st;
      copy(proposal, fresh);
    }
    mu = accept ? trial_mu : reject ? mu * 10.0 : mu;
    testing = !reject;
  }
  *rn_out = rn;
  *st_out = st;
  *calls_out = calls;
}

/* LeastSquaresProblem.check of x (finite) and p: ||r||, stationarity, the largest bound violation. */
static void check(native_work* w, const double* x, const double* p, double* out) {
  int i;
  for (i = 0; i < NX; ++i) w->in[i] = x[i];
  for (i = 0; i < NP; ++i) w->in[NX + i] = p[i];
  w->arg[0] = w->in;
  w->res[0] = out;
  optikin_native_ik_check(w->arg, w->res, w->iw, w->w, 0);
}

/* Targets k = 0..n-1 (rows of P); info (n x 3) receives ||r||, stationarity and (independent targets) the
   bound violation of each returned point. Independent (warm = 0): each from row k of X0 (stride 0: one start
   for all), by solve_batch's rule, checked as classify_many checks (NaN when the point is not finite).
   Warm-started: by solve_free's rule, each from the last solution with finite entries (previous, in/out, valid
   when *have_previous), before any from its row of X0. Returns 0, or -1 when the work structure cannot be
   allocated. */
long long optikin_native_ik_many(const double* X0, long long stride, const double* P, long long n, int warm,
                                 double* previous, int* have_previous, double* X, double* info, int* calls) {
  long long k;
  int i, finite;
  double* out;
  native_work* w = (native_work*) malloc(sizeof(native_work));
  if (!w) return -1;
  for (k = 0; k < n; ++k) {
    double* x = X + k * NX;
    out = info + 3 * k;
    if (!warm) {
      solve_batched(w, X0 + k * stride, P + k * NP, x, out, out + 1, calls + k);
      finite = 1;
      for (i = 0; i < NX && finite; ++i) finite = isfinite(x[i]);
      if (finite) check(w, x, P + k * NP, out);
      else out[0] = out[1] = out[2] = NAN;
      continue;
    }
    out[2] = 0.0;
    solve_one(w, *have_previous ? previous : X0 + k * stride, P + k * NP, x, out, out + 1, calls + k);
    finite = 1;
    for (i = 0; i < NX && finite; ++i) finite = isfinite(x[i]);
    if (finite) {
      copy(previous, x);
      *have_previous = 1;
    }
  }
  free(w);
  return 0;
}
"""


STATUSES = ("ok", "unreachable", "not_converged", "failed")
"""Statuses by code: :data:`OK`, :data:`UNREACHABLE`, :data:`NOT_CONVERGED`, :data:`FAILED` (and
:data:`OUTSIDE`, ``failed`` with the bound violated named)."""
OK, UNREACHABLE, NOT_CONVERGED, FAILED, OUTSIDE = range(5)
STATIONARY = "stationary point of the residual: closest reachable configuration"
"""The message of an ``unreachable`` target along a trajectory (``status_of``)."""


@dataclass
class NativeIK:
    """The compiled iteration of one problem (no fixed variables) and adapter settings:
    ``many(...)`` is ``optikin_native_ik_many``."""

    many: Any


def not_covered(adapter, problem) -> str | None:
    """Why the C path does not solve ``problem`` for ``adapter`` (None when it does)."""
    from optikin.solvers.gauss_newton import SYMBOLIC_SOLVE_MAX, GaussNewton

    if not native_enabled():
        return "turned off"
    if not isinstance(adapter, GaussNewton):
        return f"backend {type(adapter).__name__} is not gauss_newton"
    if problem.constraints is not None:
        return "the problem has constraints"
    n = problem.reduced.n
    if n == 0:
        return "every variable is fixed"
    if n > SYMBOLIC_SOLVE_MAX:
        return f"{n} free variables: the step solves its system numerically (at most {SYMBOLIC_SOLVE_MAX} in C)"
    return None


def _named(f: ca.Function, name: str) -> ca.Function:
    """One-input SX Function ``f`` under the C identifier ``name`` (the same operations on the same operands)."""
    x = ca.SX.sym("x", f.sparsity_in(0))
    return ca.Function(name, [x], f.call([x]), ["x"], ["y"])


def source(adapter, problem) -> str:
    """The C translation unit of the iteration of ``adapter`` on ``problem`` (no fixed variables): the
    Gauss-Newton and Newton step Functions of :func:`~optikin.solvers.gauss_newton.step_function` and the
    problem's ``packed_check`` generated by CasADi, and the loops of ``solve_free`` and ``solve_batch`` around
    them (:data:`_DRIVER`)."""
    from optikin.export import _numbers
    from optikin.solvers.gauss_newton import SLOW_PROGRESS, SLOW_STEPS, step_function

    functions = [
        _named(step_function(problem, False), f"{STEM}_gn"),
        _named(step_function(problem, True), f"{STEM}_newton"),
        _named(problem.packed_check, f"{STEM}_check"),
    ]
    generator = ca.CodeGenerator(f"{STEM}.c", {"with_header": False, "with_export": False})
    for f in functions:
        generator.add(f)
    options, limits = adapter.options, adapter.limits
    driver = Template(_DRIVER).substitute(
        n=problem.n,
        n_p=problem.n_data,
        lower=_numbers(problem.lower),
        upper=_numbers(problem.upper),
        periodic=", ".join(str(int(v)) for v in problem.periodic),
        stop_tolerance=repr(float(min(problem.tolerance, limits.tolerance))),
        stationarity_tolerance=repr(float(problem.stationarity_tolerance)),
        damping=repr(float(options.damping)),
        damping_min=repr(float(options.damping_min)),
        damping_max=repr(float(options.damping_max)),
        slow_progress=repr(SLOW_PROGRESS),
        slow_steps=int(SLOW_STEPS),
        max_calls=int(limits.max_iterations),
        second_order=int(options.second_order),
        sz_arg=max(max(f.sz_arg() for f in functions), 1),
        sz_res=max(max(f.sz_res() for f in functions), 1),
        sz_iw=max(max(f.sz_iw() for f in functions), 1),
        sz_w=max(max(f.sz_w() for f in functions), 1),
    )
    return generator.dump() + driver


def native_ik(adapter, problem) -> NativeIK | None:
    """The compiled iteration of ``problem`` (no fixed variables) for ``adapter``, built once per problem and
    adapter settings (kept in ``problem.cache``); None when no compiler is there."""
    key = ("native_ik", adapter.options, adapter.limits)  # frozen models: hashable, equal by value
    if key in problem.cache:
        return problem.cache[key]
    loaded = load_library(STEM, source(adapter, problem))
    native = None
    if loaded is not None:
        many = loaded.optikin_native_ik_many
        many.argtypes = (ctypes.c_void_p, ctypes.c_longlong, ctypes.c_void_p, ctypes.c_longlong, ctypes.c_int) + (
            ctypes.c_void_p,
        ) * 5
        many.restype = ctypes.c_longlong
        native = NativeIK(many)
    problem.cache[key] = native
    return native


def native_solve_many(
    adapter, problem, X0: np.ndarray, P: np.ndarray, warm_start: bool = False
) -> SolutionBatch | None:
    """:meth:`solve_many` of ``adapter`` on ``problem`` in C, or None where the C path does not apply (module
    docstring; the reason is logged once).

    Parameters
    ----------
    adapter:
        A :class:`~optikin.solvers.gauss_newton.GaussNewton` adapter.
    problem:
        The :class:`~optikin.solvers.nonlinear.LeastSquaresProblem`.
    X0:
        Start configurations ``(n,)`` or ``(N, n)``.
    P:
        Targets ``(N, n_data)`` (or one ``(n_data,)``).
    warm_start:
        Along a trajectory: each target from the previous solution.
    """
    reason = not_covered(adapter, problem)
    if reason is not None:
        if reason != "turned off":
            report_fallback("gauss_newton IK", reason)
        return None
    P = np.ascontiguousarray(np.atleast_2d(np.asarray(P, dtype=float)))
    X0 = np.asarray(X0, dtype=float)
    if P.ndim != 2 or P.shape[1] != problem.n_data or X0.ndim not in (1, 2) or X0.shape[-1] != problem.n:
        return None  # the reference path names the mismatch
    if X0.ndim == 2 and len(X0) not in (1, len(P)):
        return None
    if not (np.isfinite(P).all() and np.isfinite(X0).all()):
        return None  # the reference path decides what a non-finite input gives
    reduced = problem.reduced
    native = native_ik(adapter, reduced)
    if native is None:
        return None
    started = time.perf_counter()
    starts = np.ascontiguousarray(problem.free_part(np.atleast_2d(X0)))
    stride = 0 if len(starts) == 1 else reduced.n
    N = len(P)
    X = np.empty((N, reduced.n))
    info = np.empty((N, 3))
    calls = np.empty(N, dtype=np.intc)
    previous = np.empty(reduced.n)
    have_previous = np.zeros(1, dtype=np.intc)
    for begin in range(0, N, CHUNK):
        end = min(begin + CHUNK, N)
        code = native.many(
            pointer(starts[begin if stride else 0 :]),
            stride,
            pointer(P[begin:]),
            end - begin,
            int(bool(warm_start)),
            pointer(previous),
            pointer(have_previous),
            pointer(X[begin:]),
            pointer(info[begin:]),
            pointer(calls[begin:]),
        )
        if code != 0:
            report_fallback("gauss_newton IK", "the C could not allocate its work structure")
            return None
        check_interrupted()
    verdicts = _trajectory_verdicts if warm_start else _batch_verdicts
    status, residual, messages = verdicts(adapter, reduced, X, info, P)
    elapsed = time.perf_counter() - started
    return SolutionBatch(
        x=problem.expand(X) if reduced is not problem else X,
        status=status,
        iterations=calls.astype(int),
        residual=residual,
        seconds=np.full(N, elapsed / max(N, 1)),
        messages=messages,
        batched=True,
    )


def _trajectory_verdicts(adapter, problem, X: np.ndarray, info: np.ndarray, P: np.ndarray):
    """Statuses, residuals and messages as ``solve_free`` decides them from ``||r||`` and the stationarity
    of each returned point (``status_of``); a point whose residual is not finite is classified by the problem
    (``finish``), its point wrapped."""
    rn, stationarity = info[:, 0].copy(), info[:, 1]
    code = np.select(
        [~np.isfinite(rn), rn <= problem.tolerance, stationarity <= problem.stationarity_tolerance],
        [FAILED, OK, UNREACHABLE if problem.exact else OK],
        NOT_CONVERGED,
    )
    status = np.array(STATUSES, dtype=object)[code].tolist()
    messages = np.array(["", STATIONARY, "", ""], dtype=object)[code].tolist()
    time_limit = adapter.limits.time_limit
    for k in np.flatnonzero(code == FAILED):
        X[k] = problem.wrap(X[k])
        status[k], rn[k], messages[k] = problem.classify(X[k], P[k], 0.0, time_limit)
    return status, rn, messages


def _batch_verdicts(adapter, problem, X: np.ndarray, info: np.ndarray, P: np.ndarray):
    """Statuses, residuals and messages as ``classify_many`` (``verdict``) decides them from the checks of the
    returned points, which the C evaluated with the problem's own ``packed_check``."""
    rn, stationarity, outside = info.T
    rn = rn.copy()
    code = np.select(
        [
            ~np.isfinite(rn),
            outside > BOUND_TOLERANCE,
            rn <= problem.tolerance,
            stationarity <= problem.stationarity_tolerance,
        ],
        [FAILED, OUTSIDE, OK, UNREACHABLE if problem.exact else OK],
        NOT_CONVERGED,
    )
    status = np.array(STATUSES + ("failed",), dtype=object)[code].tolist()
    messages = np.array(["", "closest reachable configuration", "", "non-finite solution", ""], dtype=object)[
        code
    ].tolist()
    for k in np.flatnonzero(code == OUTSIDE):
        messages[k] = problem.violation_message(X[k])
    return status, rn, messages


def solve_many(
    adapter, problem, X0: np.ndarray, P: np.ndarray, warm_start: bool = False, x_ref: np.ndarray | None = None
) -> SolutionBatch:
    """``adapter.solve_many(problem, X0, P, warm_start, x_ref)``, in C where :func:`native_solve_many` applies."""
    batch = native_solve_many(adapter, problem, X0, P, warm_start)
    if batch is not None:
        return batch
    return adapter.solve_many(problem, X0, P, warm_start=warm_start, x_ref=x_ref)
