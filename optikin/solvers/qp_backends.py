"""QP backends (family ``qp``) for the per-step tracking QP of :mod:`optikin.control.qp`.

A preset names one of these backends; its ``options`` go to the solver, except
``solver``, which picks the solver behind ``qp_qpsolvers`` / ``qp_cvxpy``::

    name: qp-daqp
    backend: qp_qpsolvers
    options: {solver: daqp}

The adapter creates a fresh solver object per controller
(:meth:`QPBackendFactory.create`), since OSQP and cvxpy keep per-problem state.
"""

from __future__ import annotations

from typing import Any

from optikin.control.qp_backends import make_qp_backend
from optikin.errors import SpecError
from optikin.solvers import register_backend
from optikin.spec import SolverSpec


class QPBackendFactory:
    """Builds the per-controller solver object a preset describes."""

    def __init__(self, kind: str, preset: SolverSpec):
        self.kind, self.preset = kind, preset
        options = dict(preset.options)
        self.solver: str | None = options.pop("solver", None)
        self.options: dict[str, Any] = options

    def create(self, n: int, m: int):
        """A solver for ``n`` rates and ``m`` task rows; bad options raise naming the preset."""
        try:
            return make_qp_backend(self.kind, n, m, self.solver, self.options)
        except (ValueError, TypeError, ImportError) as exc:
            raise SpecError(self.preset.name, "options", str(exc)) from None


def _factory(kind: str):
    return lambda preset: QPBackendFactory(kind, preset)


register_backend("qp_osqp", "qp", "OSQP set up once, updated in place and warm-started every step", options=None)(_factory("osqp"))
register_backend("qp_qpsolvers", "qp", "qpsolvers.solve_qp with bounds, one call per step", options=None)(_factory("qpsolvers"))
register_backend("qp_cvxpy", "qp", "cvxpy Problem with Parameters (DPP), re-solved every step", options=None)(_factory("cvxpy"))
register_backend("qp_cvxpy_rebuild", "qp", "cvxpy Problem rebuilt every step (slow reference)", options=None)(
    _factory("cvxpy_rebuild"))
