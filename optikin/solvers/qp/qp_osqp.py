"""Backend ``qp_osqp``: OSQP set up once per controller, then updated in place and warm-started every step.

Tolerances. OSQP's own ``eps_abs = eps_rel = 1e-3`` can leave a bound violated
by about 1e-4; a rate bound of ``r`` then slips by up to ``eps_abs + eps_rel r``.
The defaults here are ``1e-7`` (a slip below 1e-6 rad/s or m/s, below a nanometre
or nano-radian per millisecond step) without polishing (OSQP 1.1 prints a line on
every polished solve). Whatever the backend returns, the controller still
projects it onto the box and reports the slip it removed.

``rho = 1`` (OSQP's default is 0.1): on the closed-loop pose task it takes as
many iterations warm-started at eps 1e-7 and lands much closer to the exact
active-set answer (daqp): ``H = J'J + lambda I`` is ill-conditioned (the
dual-quaternion Jacobian has rank 5, so one direction is held by ``lambda``
alone) and ADMM's error in that direction is about eps / lambda.

Preset::

    name: qp-osqp
    backend: qp_osqp
    options: {eps_abs: 1.0e-7, eps_rel: 1.0e-7, rho: 1.0, max_iter: 4000, check_termination: 5}
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from pydantic import Field

from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.qp.common import QPData, StepSolverFactory, upper_triangle_csc_indices
from optikin.spec import SolverSpec
from optikin.status import Status


_INFINITY = 1e30
"""OSQP's ``OSQP_INFTY``: a bound at or beyond it is no bound."""


class OSQPOptions(Options):
    """OSQP settings (Stellato et al. 2020); the unset optional ones keep OSQP's own defaults."""

    eps_abs: float = Field(1e-7, gt=0, description="absolute tolerance of the primal and dual residuals")
    eps_rel: float = Field(1e-7, ge=0, description="relative tolerance of the primal and dual residuals")
    rho: float = Field(1.0, gt=0, description="ADMM step size (OSQP's own default 0.1)")
    max_iter: int = Field(4000, ge=1, description="ADMM iterations per step before the step counts as failed")
    polishing: bool = Field(False, description="refine the ADMM answer by an active-set solve")
    check_termination: int = Field(5, ge=0, description="iterations between termination checks (0: never)")
    warm_starting: bool = Field(True, description="start each step from the previous step's answer")
    sigma: float | None = Field(None, gt=0, description="regularisation of the linear system (None: OSQP's)")
    alpha: float | None = Field(None, gt=0, lt=2, description="ADMM relaxation (None: OSQP's 1.6)")
    adaptive_rho: bool | None = Field(None, description="adapt rho during the solve (None: OSQP's)")
    scaling: int | None = Field(None, ge=0, description="Ruiz scaling iterations (None: OSQP's 10)")
    time_limit: float | None = Field(None, ge=0, description="seconds per solve, 0 for none (None: OSQP's)")

    def settings(self) -> dict[str, Any]:
        """The keyword arguments of ``osqp.OSQP.setup`` (optional settings only where given)."""
        return {k: v for k, v in self.model_dump().items() if v is not None} | {"verbose": False}


class OSQPStepSolver:
    """OSQP set up once for ``n`` rates, then per step: new ``P`` values, ``q``, ``l``, ``u``, warm-started solve.

    The per-step calls go to the compiled solver object that ``osqp.OSQP.setup``
    creates (``OSQP._solver``): the Python wrapper's ``update``/``solve`` add tens
    of microseconds of bookkeeping per step (an info namespace, derivative caches),
    more than the solve itself. The tests check both paths agree. An osqp release
    without that handle gets the public ``update``/``solve`` (same answers, slower).
    """

    name = "osqp"

    def __init__(self, n: int, m: int, options: OSQPOptions, rows: int = 0):
        import osqp

        self.n, self.rows = n, rows
        self.settings = options.settings()
        upper_rows, upper_cols = upper_triangle_csc_indices(n)
        pattern = sp.csc_matrix((np.ones(len(upper_rows)), (upper_rows, upper_cols)), shape=(n, n))
        # Constraints [I; A] with A dense (its values change every step, its pattern never).
        constraints = sp.vstack([sp.identity(n), sp.csc_matrix(np.ones((rows, n)))], format="csc")
        self._A_values = np.empty(constraints.nnz)
        self._diagonal = np.cumsum(np.r_[0, np.full(n - 1, rows + 1)])  # where I's entries sit, column-major
        self._rows_at = np.setdiff1d(np.arange(constraints.nnz), self._diagonal)
        self._A_values[self._diagonal] = 1.0
        self._l, self._u = np.empty(n + rows), np.full(n + rows, _INFINITY)
        self.problem = osqp.OSQP()
        self.problem.setup(
            pattern + n * sp.identity(n, format="csc"),
            np.zeros(n),
            constraints,
            -np.ones(n + rows),
            np.ones(n + rows),
            **self.settings,
        )
        self._solver = getattr(self.problem, "_solver", None)  # the fast path (class docstring)
        self._solved = osqp.SolverStatus.OSQP_SOLVED
        self._interrupted = osqp.SolverStatus.OSQP_SIGINT

    def solve(self, data: QPData) -> Solution:
        """One warm-started solve; ``extras`` holds OSQP's primal and dual residuals."""
        solver = self._solver
        if self.rows:
            return self._solve_with_rows(data)
        if solver is None:
            self.problem.update(Px=data.H_upper, q=data.g, l=data.lb, u=data.ub)
            result = self.problem.solve(raise_error=False)
            info, x = result.info, result.x
        else:
            solver.update_data_mat(P_x=data.H_upper, P_i=None, A_x=None, A_i=None)
            solver.update_data_vec(q=data.g, l=data.lb, u=data.ub)
            solver.solve()
            info, x = solver.info, solver.solution.x
        return self._answer(info, x)

    def _solve_with_rows(self, data: QPData) -> Solution:
        """The QP with the rows ``A qdot >= b`` under the box: the update also sets ``A``'s values."""
        n, solver = self.n, self._solver
        self._A_values[self._rows_at] = data.A.ravel(order="F")
        self._l[:n], self._u[:n] = data.lb, data.ub
        np.maximum(data.b, -_INFINITY, out=self._l[n:])  # the compiled solver takes OSQP's infinity, not inf
        if solver is None:
            self.problem.update(Px=data.H_upper, q=data.g, Ax=self._A_values, l=self._l, u=self._u)
            result = self.problem.solve(raise_error=False)
            return self._answer(result.info, result.x)
        solver.update_data_mat(P_x=data.H_upper, P_i=None, A_x=self._A_values, A_i=None)
        solver.update_data_vec(q=data.g, l=self._l, u=self._u)
        solver.solve()
        return self._answer(solver.info, solver.solution.x)

    def _answer(self, info: Any, x: np.ndarray) -> Solution:
        extras = {"primal_residual": info.prim_res, "dual_residual": info.dual_res}
        if info.status_val == self._solved:
            return Solution(x, Status.OK, info.iter, seconds=info.run_time, extras=extras)
        if info.status_val == self._interrupted:
            raise KeyboardInterrupt  # OSQP catches SIGINT itself during a solve; honour it once it returned
        return Solution(
            np.full(self.n, np.nan), Status.FAILED, info.iter, seconds=info.run_time, message=info.status, extras=extras
        )


@register_backend(
    "qp_osqp", "qp", "OSQP set up once, updated in place and warm-started every step", options=OSQPOptions
)
def build(preset: SolverSpec, options: OSQPOptions) -> StepSolverFactory[OSQPOptions]:
    """The factory of OSQP step solvers with the preset's settings."""
    return StepSolverFactory(OSQPStepSolver, options)
