"""Backend ``qp_cvxpy_rebuild``: the tracking QP written anew in cvxpy every step (what a naive loop costs).

The slow reference of the benchmarks: same problem and options as ``qp_cvxpy``
(:class:`~optikin.solvers.qp.qp_cvxpy.CvxpyOptions`), but no Parameters, so cvxpy
canonicalises it again on every call.

Preset::

    name: qp-cvxpy-rebuild
    backend: qp_cvxpy_rebuild
    options: {solver: CLARABEL}
"""

from __future__ import annotations

import time

import numpy as np

from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.qp.common import QPData, StepSolverFactory, failed
from optikin.solvers.qp.qp_cvxpy import CvxpyOptions
from optikin.spec import SolverSpec
from optikin.status import Status


class CvxpyRebuildStepSolver:
    """A new cvxpy Problem for every step's data."""

    def __init__(self, n: int, m: int, options: CvxpyOptions, rows: int = 0):
        import cvxpy as cp

        self.cp, self.n = cp, n
        self.solver, self.name = options.solver.upper(), f"cvxpy_rebuild-{options.solver.lower()}"
        self.options = dict(options.settings)

    def solve(self, data: QPData) -> Solution:
        cp = self.cp
        start = time.perf_counter()
        x = cp.Variable(data.n)
        objective = cp.sum_squares(data.J @ x - data.v) + data.damping * cp.sum_squares(x)
        constraints = [x >= data.lb, x <= data.ub]
        active = np.isfinite(data.b)
        if active.any():
            constraints.append(data.A[active] @ x >= data.b[active])
        problem = cp.Problem(cp.Minimize(objective), constraints)
        problem.solve(solver=self.solver, **self.options)
        seconds = time.perf_counter() - start
        if problem.status != cp.OPTIMAL or x.value is None:
            return failed(self.n, str(problem.status), seconds)
        return Solution(x.value, Status.OK, seconds=seconds)


@register_backend("qp_cvxpy_rebuild", "qp", "cvxpy Problem rebuilt every step (slow reference)", options=CvxpyOptions)
def build(preset: SolverSpec, options: CvxpyOptions) -> StepSolverFactory[CvxpyOptions]:
    """The factory of rebuilding cvxpy step solvers for the preset's solver."""
    return StepSolverFactory(CvxpyRebuildStepSolver, options)
