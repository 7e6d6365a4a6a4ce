"""Backend ``qp_cvxpy``: ``min ||J x - v||^2 + lambda ||x||^2`` s.t. ``lb <= x <= ub`` as one cvxpy Problem.

The problem is written once with Parameters and canonicalised once (disciplined
parametrized programming, DPP); each step sets the Parameter values and
re-solves warm-started.

Preset::

    name: qp-cvxpy
    backend: qp_cvxpy
    options: {solver: CLARABEL}
"""

from __future__ import annotations

import time

import numpy as np
from pydantic import Field, field_validator

from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.qp.common import QPData, StepSolverFactory, failed
from optikin.spec import SolverSpec
from optikin.status import Status


def installed_solvers() -> list[str]:
    """The cvxpy solvers importable here (upper case, as cvxpy names them)."""
    import cvxpy as cp

    return list(cp.installed_solvers())


class CvxpyOptions(Options):
    """Which cvxpy solver, and its keyword arguments."""

    solver: str = Field("CLARABEL", description="a cvxpy solver installed here (CLARABEL, OSQP, ...; any case)")
    settings: dict[str, float | int | bool | str] = Field(
        default_factory=dict, description="keyword arguments of Problem.solve, in the solver's own names"
    )

    @field_validator("solver")
    @classmethod
    def _installed(cls, solver: str) -> str:
        available = installed_solvers()
        if solver.upper() not in available:
            raise ValueError(f"cvxpy has no solver {solver!r} installed; available: {', '.join(available)}")
        return solver


class CvxpyStepSolver:
    """The tracking QP as a DPP cvxpy Problem with Parameters ``J``, ``v``, ``lambda``, ``lb``, ``ub``, ``A``, ``b``."""

    def __init__(self, n: int, m: int, options: CvxpyOptions, rows: int = 0):
        import cvxpy as cp

        self.cp, self.n = cp, n
        self.solver, self.name = options.solver.upper(), f"cvxpy-{options.solver.lower()}"
        self.options = dict(options.settings)
        self.x = cp.Variable(n)
        self.J, self.v = cp.Parameter((m, n)), cp.Parameter(m)
        self.damping = cp.Parameter(nonneg=True)
        self.lb, self.ub = cp.Parameter(n), cp.Parameter(n)
        objective = cp.sum_squares(self.J @ self.x - self.v) + self.damping * cp.sum_squares(self.x)
        constraints = [self.x >= self.lb, self.x <= self.ub]
        self.rows = rows
        if rows:
            self.A, self.b = cp.Parameter((rows, n)), cp.Parameter(rows)
            constraints.append(self.A @ self.x >= self.b)
        self.problem = cp.Problem(cp.Minimize(objective), constraints)
        if not self.problem.is_dpp():
            raise RuntimeError("the tracking QP is not DPP: cvxpy would re-canonicalise every step")

    def solve(self, data: QPData) -> Solution:
        start = time.perf_counter()
        self.J.value, self.v.value, self.damping.value = data.J, data.v, data.damping
        self.lb.value, self.ub.value = data.lb, data.ub
        if self.rows:  # an inactive row (b = -inf) as 0 >= -1: a Parameter takes finite values only
            active = np.isfinite(data.b)
            self.A.value = np.where(active[:, None], data.A, 0.0)
            self.b.value = np.where(active, data.b, -1.0)
        self.problem.solve(solver=self.solver, warm_start=True, **self.options)
        seconds = time.perf_counter() - start
        if self.problem.status != self.cp.OPTIMAL or self.x.value is None:
            return failed(self.n, str(self.problem.status), seconds)
        return Solution(self.x.value, Status.OK, seconds=seconds)


@register_backend("qp_cvxpy", "qp", "cvxpy Problem with Parameters (DPP), re-solved every step", options=CvxpyOptions)
def build(preset: SolverSpec, options: CvxpyOptions) -> StepSolverFactory[CvxpyOptions]:
    """The factory of DPP cvxpy step solvers for the preset's solver."""
    return StepSolverFactory(CvxpyStepSolver, options)
