"""Solvers of the per-step tracking QP, all behind one call: ``backend.solve(data) -> qdot or None``.

The QP (see :mod:`optikin.control.qp`) is ``min 1/2 qdot'H qdot + g'qdot`` s.t.
``lb <= qdot <= ub`` with ``H = J'J + lambda I`` and ``g = -J'v``; equivalently
``min ||J qdot - v||^2 + lambda ||qdot||^2``. :class:`QPData` holds views of the
arrays the controller updates in place each step; a backend reads what it needs.

==========================  ====================================================
``osqp``                    OSQP set up once; each step updates ``P``'s values,
                            ``q``, ``l``, ``u`` in place and solves warm-started
``qpsolvers`` (+ solver)    ``qpsolvers.solve_qp`` with bounds as bounds (daqp,
                            quadprog, proxqp, clarabel, highs, osqp, scs ...)
``cvxpy`` (+ solver)        one cvxpy Problem with Parameters (DPP), re-solved
``cvxpy_rebuild``           a new cvxpy Problem every step (the slow reference)
==========================  ====================================================

Tolerances. OSQP's default ``eps_abs = eps_rel = 1e-3`` can leave a bound
violated by ~1e-4 (``../shared/ANCHORS.md``); a rate bound of ``r`` then slips by
up to ``eps_abs + eps_rel r``. The defaults here are ``1e-7`` (a slip below
``1e-6`` rad/s or m/s, i.e. below a nanometre or nano-radian per millisecond step)
without polishing (OSQP 1.1.3 prints a line on every polished solve). Whatever the
backend returns, the controller still projects it onto the box and reports the
slip it removed, so no tolerance can let a configuration limit slip.

A backend signals failure by returning ``None`` (with :attr:`last_status` saying
why) or by raising; the controller then applies its fallback.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import scipy.sparse as sp

from optikin.control.task import upper_triangle_csc_indices


@dataclass
class QPData:
    """The per-step QP; arrays are views the controller refreshes in place."""

    J: np.ndarray
    v: np.ndarray
    damping: float
    H: np.ndarray
    H_upper: np.ndarray
    g: np.ndarray
    lb: np.ndarray
    ub: np.ndarray

    @property
    def n(self) -> int:
        return self.H.shape[0]


class OSQPBackend:
    """OSQP set up once, then per step: new values of ``P``, ``q``, ``l``, ``u`` and a warm-started solve.

    The per-step calls go to the compiled solver object that ``osqp.OSQP.setup``
    creates (``OSQP._solver``): the Python wrapper's ``update``/``solve`` add about
    35 us of bookkeeping per step (an info namespace of 20 fields, derivative
    caches), more than the solve itself. The test suite checks both paths agree. An
    osqp release without that handle gets the public ``update``/``solve`` instead
    (same answers, slower).

    ``rho = 1`` (OSQP's default is 0.1): on the closed-loop pose task it takes as
    many iterations (median 35 warm-started at eps 1e-7) and lands 20 times closer
    to the exact active-set answer (daqp): ``H = J'J + lambda I`` is ill-conditioned
    (the dual-quaternion Jacobian has rank 5, so one direction is held by
    ``lambda = 1e-4`` alone) and ADMM's error in that direction is about eps / lambda.
    """

    name = "osqp"
    DEFAULTS: dict[str, Any] = {"eps_abs": 1e-7, "eps_rel": 1e-7, "rho": 1.0, "max_iter": 4000,
                                "polishing": False, "check_termination": 5, "warm_starting": True}

    def __init__(self, n: int, options: Mapping[str, Any] | None = None):
        import osqp

        self.settings = {**self.DEFAULTS, **dict(options or {}), "verbose": False}
        rows, cols = upper_triangle_csc_indices(n)
        pattern = sp.csc_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
        self.problem = osqp.OSQP()
        self.problem.setup(pattern + n * sp.identity(n, format="csc"), np.zeros(n), sp.identity(n, format="csc"),
                           -np.ones(n), np.ones(n), **self.settings)
        self._solver = getattr(self.problem, "_solver", None)  # the fast path (class docstring)
        self._solved = osqp.SolverStatus.OSQP_SOLVED
        self.last_status = "not run"
        self.iterations = 0

    def solve(self, data: QPData) -> np.ndarray | None:
        solver = self._solver
        if solver is None:
            self.problem.update(Px=data.H_upper, q=data.g, l=data.lb, u=data.ub)
            result = self.problem.solve(raise_error=False)
            info, x = result.info, result.x
        else:
            solver.update_data_mat(P_x=data.H_upper, P_i=None, A_x=None, A_i=None)
            solver.update_data_vec(q=data.g, l=data.lb, u=data.ub)
            solver.solve()
            info, x = solver.info, solver.solution.x
        self.last_status, self.iterations = info.status, info.iter
        return x if info.status_val == self._solved else None


class QpsolversBackend:
    """``qpsolvers.solve_qp(P, q, lb=lb, ub=ub, solver=...)``: one call per step, no state kept.

    Options default to tight tolerances where the solver has them (``TIGHT``). On
    the benchmark's 400 closed-loop steps, against daqp (active set, exact): proxqp
    is 1.4e-3 off at its defaults and at eps_abs 1e-9 (the ill-conditioned direction
    held by ``lambda`` alone), 2e-8 at 1e-12; Clarabel 8e-4 at its defaults, 1e-5 at 1e-10.
    """

    TIGHT: dict[str, dict[str, Any]] = {
        "osqp": {"eps_abs": 1e-7, "eps_rel": 1e-7, "rho": 1.0, "polishing": False, "max_iter": 4000,
                 "raise_error": False},
        "proxqp": {"eps_abs": 1e-12, "eps_rel": 0.0},
        "clarabel": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10},
        "scs": {"eps_abs": 1e-8, "eps_rel": 1e-8},
    }

    def __init__(self, solver: str, options: Mapping[str, Any] | None = None):
        import qpsolvers

        if solver not in qpsolvers.available_solvers:
            raise ValueError(f"qpsolvers has no solver {solver!r} installed; available: "
                             f"{', '.join(qpsolvers.available_solvers)}")
        self.solver, self.name = solver, f"qpsolvers-{solver}"
        self.options = {**self.TIGHT.get(solver, {}), **dict(options or {})}
        self.sparse = solver in qpsolvers.sparse_solvers and solver not in qpsolvers.dense_solvers
        self._solve_qp = qpsolvers.solve_qp
        self.last_status = "not run"

    def solve(self, data: QPData) -> np.ndarray | None:
        P = sp.csc_matrix(data.H) if self.sparse else data.H
        x = self._solve_qp(P, data.g, lb=data.lb, ub=data.ub, solver=self.solver, **self.options)
        self.last_status = "solved" if x is not None else "no solution returned"
        return x


class CvxpyBackend:
    """``min ||J x - v||^2 + lambda ||x||^2`` s.t. ``lb <= x <= ub`` as one cvxpy Problem with Parameters.

    The problem is canonicalised once (DPP); each step sets the Parameter values and re-solves.
    """

    def __init__(self, n: int, m: int, solver: str = "CLARABEL", options: Mapping[str, Any] | None = None):
        import cvxpy as cp

        self.cp, self.solver, self.name = cp, solver.upper(), f"cvxpy-{solver.lower()}"
        self.options = dict(options or {})
        self.x = cp.Variable(n)
        self.J, self.v = cp.Parameter((m, n)), cp.Parameter(m)
        self.damping = cp.Parameter(nonneg=True)
        self.lb, self.ub = cp.Parameter(n), cp.Parameter(n)
        objective = cp.sum_squares(self.J @ self.x - self.v) + self.damping * cp.sum_squares(self.x)
        self.problem = cp.Problem(cp.Minimize(objective), [self.x >= self.lb, self.x <= self.ub])
        if not self.problem.is_dpp():
            raise RuntimeError("the tracking QP is not DPP: cvxpy would re-canonicalise every step")
        self.last_status = "not run"

    def solve(self, data: QPData) -> np.ndarray | None:
        self.J.value, self.v.value, self.damping.value = data.J, data.v, data.damping
        self.lb.value, self.ub.value = data.lb, data.ub
        self.problem.solve(solver=self.solver, warm_start=True, **self.options)
        self.last_status = self.problem.status
        return self.x.value if self.problem.status == self.cp.OPTIMAL else None


class CvxpyRebuildBackend:
    """The same problem written anew in cvxpy every step (what a naive loop costs)."""

    def __init__(self, solver: str = "CLARABEL", options: Mapping[str, Any] | None = None):
        import cvxpy as cp

        self.cp, self.solver, self.name = cp, solver.upper(), f"cvxpy_rebuild-{solver.lower()}"
        self.options = dict(options or {})
        self.last_status = "not run"

    def solve(self, data: QPData) -> np.ndarray | None:
        cp = self.cp
        x = cp.Variable(data.n)
        objective = cp.sum_squares(data.J @ x - data.v) + data.damping * cp.sum_squares(x)
        problem = cp.Problem(cp.Minimize(objective), [x >= data.lb, x <= data.ub])
        problem.solve(solver=self.solver, **self.options)
        self.last_status = problem.status
        return x.value if problem.status == cp.OPTIMAL else None


BACKEND_KINDS = ("osqp", "qpsolvers", "cvxpy", "cvxpy_rebuild")


def make_qp_backend(kind: str, n: int, m: int, solver: str | None = None, options: Mapping[str, Any] | None = None):
    """A backend of ``kind`` (one of :data:`BACKEND_KINDS`) for ``n`` rates and ``m`` task rows."""
    if kind == "osqp":
        return OSQPBackend(n, options)
    if kind == "qpsolvers":
        return QpsolversBackend(solver or "daqp", options)
    if kind == "cvxpy":
        return CvxpyBackend(n, m, solver or "CLARABEL", options)
    if kind == "cvxpy_rebuild":
        return CvxpyRebuildBackend(solver or "CLARABEL", options)
    raise ValueError(f"unknown QP backend {kind!r}; known: {', '.join(BACKEND_KINDS)}")


def installed_qpsolvers() -> list[str]:
    """The qpsolvers backends importable here."""
    import qpsolvers

    return list(qpsolvers.available_solvers)
