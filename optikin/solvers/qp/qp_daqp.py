"""Backend ``qp_daqp``: DAQP's dual active-set method on the controller's own buffers, warm-started every step.

The tracking QPs are small and dense (``n`` rates, ``H`` full, the box plus a few rows):
once the active set is found the answer is exact up to rounding, and consecutive steps rarely
change it, so a step warm-started from the previous active set often takes one iteration and one
dense Cholesky factorisation of ``H``. :func:`optikin.control.qp.default_step_solver` chooses this
backend by structure when no preset names one.

Preset::

    name: qp-active-set
    backend: qp_daqp
    options: {}
"""

from __future__ import annotations

import time

import numpy as np

from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.qp.common import QPData, StepSolverFactory
from optikin.spec import SolverSpec

_DAQP_INFINITY = 1e30
"""daqp's ``DAQP_INF``: a bound at or beyond it is no bound."""


class DaqpOptions(Options):
    """Options of backend ``qp_daqp`` (none yet: daqp's own tolerances)."""


class ActiveSetStepSolver:
    """The per-step QP by DAQP's dual active-set method on the controller's own buffers, warm-started.

    DAQP (Arnstrom, Bemporad and Axehill 2022, "A dual active-set solver for embedded
    quadratic programming using recursive LDL' updates", IEEE TAC 67(8), doi:10.1109/TAC.2022.3176430)
    solves ``min 1/2 x'Hx + g'x`` s.t. ``lb <= x <= ub`` (simple bounds) and ``b <= A x``.
    One ``daqp.Model`` is set up at the first :meth:`solve` on the arrays of that
    :class:`~optikin.solvers.qp.common.QPData`: ``H`` (its transpose, the same symmetric
    matrix, C-ordered), ``g``, ``lb``, ``ub`` and ``A`` are handed over without a copy (daqp copies
    only arrays that are not contiguous ``float64``), so daqp reads the buffers the task Function
    writes. Each step then refreshes the model (``update``: the Cholesky factor of the new ``H``,
    the new bounds) and solves from the previous step's active set. With rows, the bounds go
    through two buffers ``[lb; b]``, ``[ub; inf]`` filled in place (``b`` clipped at daqp's
    infinity). After a failed solve the next one starts from the empty active set.

    The answer (:meth:`solve`) is one :class:`~optikin.solvers.base.Solution` updated in place
    every step: ``x`` a preallocated array, overwritten by the next call (copy what you keep);
    ``status`` ``"ok"`` or ``"failed"`` (``message`` daqp's exit flag, e.g. ``-1`` infeasible).

    Parameters
    ----------
    n:
        Number of rates.
    m:
        Number of task rows (unused; the signature of a ``qp`` step-solver factory).
    options:
        The preset's options (none: daqp's defaults).
    rows:
        Number of rows ``A qdot >= b``.
    """

    name = "daqp-active-set"

    def __init__(self, n: int, m: int = 0, options: DaqpOptions | None = None, rows: int = 0):
        import daqp

        self.n, self.rows = n, rows
        self._model = daqp.Model()
        self._update, self._solve = self._model.update, self._model.solve
        self._data: QPData | None = None
        self._sense = np.zeros(n + rows, dtype=np.intc)
        self._x = np.full(n, np.nan)
        self.solution = Solution(self._x, "ok")
        if rows:
            self._lower, self._upper = np.empty(n + rows), np.full(n + rows, _DAQP_INFINITY)
            self._lower_box, self._lower_rows, self._upper_box = self._lower[:n], self._lower[n:], self._upper[:n]

    def _setup(self, data: QPData) -> int:
        """Bind a daqp model to ``data``'s arrays; its exit flag (negative on failure)."""
        if data.H.shape != (self.n, self.n) or data.A.shape[0] != self.rows:
            raise ValueError(
                f"{self.name}: QP of {data.n} rates and {data.A.shape[0]} rows, set up for {self.n}, {self.rows}"
            )
        self._H = data.H.T  # H is symmetric and column-major: its transpose is the same matrix, C-ordered, no copy
        self._A = data.A if self.rows else np.zeros((0, self.n))
        if self.rows:
            self._fill_bounds(data)
            upper, lower = self._upper, self._lower
        else:
            upper, lower = data.ub, data.lb
        self._data, self._upper_now, self._lower_now = data, upper, lower
        self._sense.fill(0)  # no constraint assumed active
        flag, _ = self._model.setup(self._H, data.g, self._A, upper, lower, self._sense)
        return int(flag)

    def _fill_bounds(self, data: QPData) -> None:
        np.copyto(self._lower_box, data.lb)
        np.copyto(self._upper_box, data.ub)
        np.maximum(data.b, -_DAQP_INFINITY, out=self._lower_rows)

    def solve(self, data: QPData) -> Solution:
        """One warm-started solve of this step's QP (``data`` the same object every step)."""
        start = time.perf_counter()
        solution = self.solution
        if data is not self._data:
            flag = self._setup(data)
        elif self.rows:
            self._fill_bounds(data)
            flag = self._update(H=self._H, f=data.g, A=self._A, bupper=self._upper, blower=self._lower)
        else:
            flag = self._update(H=self._H, f=data.g, bupper=self._upper_now, blower=self._lower_now)
        iterations = -1
        if flag >= 0:  # set up or updated (the factorisation of H succeeded)
            x, _, flag, info = self._solve()
            iterations = info["iterations"]
        if flag == 1:
            np.copyto(self._x, x)
            solution.status, solution.message = "ok", ""
        else:
            self._x.fill(np.nan)
            solution.status, solution.message = "failed", f"daqp exit flag {flag}"
            self._data = None  # the next step sets the model up afresh: empty active set, new factorisation
        solution.iterations, solution.seconds = iterations, time.perf_counter() - start
        return solution


@register_backend(
    "qp_daqp", "qp", "DAQP's dual active set on the controller's buffers, warm-started every step", options=DaqpOptions
)
def build(preset: SolverSpec, options: DaqpOptions) -> StepSolverFactory[DaqpOptions]:
    """The factory of DAQP active-set step solvers."""
    return StepSolverFactory(ActiveSetStepSolver, options)
