"""Backend ``qp_qpsolvers``: ``qpsolvers.solve_qp(P, q, lb=lb, ub=ub, solver=...)``, one call per step, no state kept.

The rate box is handed over as bounds (not as inequality rows); the active rows
``A qdot >= b`` (finite ``b``) as ``G = -A``, ``h = -b``. With rows and solver daqp (and no
``settings``) daqp is called directly, ``blower <= [I; A] x <= bupper`` in buffers kept from step
to step: qpsolvers' conversion of the rows costs several times daqp's own solve. Where the solver
has tolerances, they default to tight ones (:data:`TIGHT`); ``settings`` adds or
overrides keyword arguments of the solver, in the solver's own names. Against
daqp (active set, exact) on closed-loop steps, proxqp at its own defaults and at
eps_abs 1e-9 stays off in the direction held by ``lambda`` alone, and is close
at 1e-12; Clarabel likewise needs 1e-10.

Preset::

    name: qp-daqp
    backend: qp_qpsolvers
    options: {solver: daqp}
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import scipy.sparse as sp
from pydantic import Field, field_validator

from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.qp.common import QPData, StepSolverFactory, failed
from optikin.spec import SolverSpec
from optikin.status import Status

TIGHT: dict[str, dict[str, Any]] = {
    "osqp": {"eps_abs": 1e-7, "eps_rel": 1e-7, "rho": 1.0, "polishing": False, "max_iter": 4000, "raise_error": False},
    "proxqp": {"eps_abs": 1e-12, "eps_rel": 0.0},
    "clarabel": {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10},
    "scs": {"eps_abs": 1e-8, "eps_rel": 1e-8},
}
"""Keyword arguments handed to a solver unless ``settings`` overrides them."""


def installed_solvers() -> list[str]:
    """The qpsolvers solvers importable here."""
    import qpsolvers

    return list(qpsolvers.available_solvers)


class QpsolversOptions(Options):
    """Which qpsolvers solver, and its keyword arguments."""

    solver: str = Field("daqp", description="a qpsolvers solver installed here (daqp, quadprog, proxqp, ...)")
    settings: dict[str, float | int | bool | str] = Field(
        default_factory=dict, description="keyword arguments of the solver, over the tight defaults (TIGHT)"
    )

    @field_validator("solver")
    @classmethod
    def _installed(cls, solver: str) -> str:
        available = installed_solvers()
        if solver not in available:
            raise ValueError(f"qpsolvers has no solver {solver!r} installed; available: {', '.join(available)}")
        return solver


class QpsolversStepSolver:
    """One ``qpsolvers.solve_qp`` call per step (dense or sparse ``P`` as the solver takes it)."""

    def __init__(self, n: int, m: int, options: QpsolversOptions, rows: int = 0):
        import qpsolvers

        self.n, self.solver, self.name = n, options.solver, f"qpsolvers-{options.solver}"
        self.options = {**TIGHT.get(options.solver, {}), **options.settings}
        self.sparse = options.solver in qpsolvers.sparse_solvers and options.solver not in qpsolvers.dense_solvers
        self._solve_qp = qpsolvers.solve_qp
        self._daqp = None
        if rows and options.solver == "daqp" and not options.settings:
            import daqp

            self._daqp = daqp.solve
            self._upper, self._lower = np.full(n + rows, _DAQP_INFINITY), np.empty(n + rows)
            self._sense = np.zeros(n + rows, dtype=np.intc)

    def solve(self, data: QPData) -> Solution:
        if self._daqp is not None:
            return self._solve_daqp(data)
        start = time.perf_counter()
        P = sp.csc_matrix(data.H) if self.sparse else data.H
        G = h = None
        active = np.isfinite(data.b)
        if active.any():  # A qdot >= b as G qdot <= h, active rows only
            G, h = -data.A[active], -data.b[active]
            if self.sparse:
                G = sp.csc_matrix(G)
        x = self._solve_qp(P, data.g, G, h, lb=data.lb, ub=data.ub, solver=self.solver, **self.options)
        seconds = time.perf_counter() - start
        if x is None:
            return failed(self.n, "no solution returned", seconds)
        return Solution(x, Status.OK, seconds=seconds)

    def _solve_daqp(self, data: QPData) -> Solution:
        """``daqp.solve(H, g, A, bupper, blower, sense)``, the box as daqp's simple bounds (its first rows)."""
        start = time.perf_counter()
        n = self.n
        self._lower[:n], self._upper[:n] = data.lb, data.ub
        np.maximum(data.b, -_DAQP_INFINITY, out=self._lower[n:])
        assert self._daqp is not None
        x, _, exitflag, _ = self._daqp(data.H, data.g, data.A, self._upper, self._lower, self._sense)
        seconds = time.perf_counter() - start
        if exitflag != 1:
            return failed(self.n, f"daqp exit flag {exitflag}", seconds)
        return Solution(np.asarray(x), Status.OK, seconds=seconds)


_DAQP_INFINITY = 1e30
"""A bound daqp takes for none."""


@register_backend("qp_qpsolvers", "qp", "qpsolvers.solve_qp with bounds, one call per step", options=QpsolversOptions)
def build(preset: SolverSpec, options: QpsolversOptions) -> StepSolverFactory[QpsolversOptions]:
    """The factory of qpsolvers step solvers for the preset's solver."""
    return StepSolverFactory(QpsolversStepSolver, options)
