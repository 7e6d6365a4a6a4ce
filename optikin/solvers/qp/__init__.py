"""Backends of family ``qp``: the per-step tracking QP of :mod:`optikin.control.qp`, one module per backend.

==========================  ====================================================
``qp_daqp``                 DAQP's dual active set on the controller's buffers,
                            warm-started from the previous step's active set
``qp_osqp``                 OSQP set up once; each step updates ``P``'s values,
                            ``q``, ``l``, ``u`` in place and solves warm-started
``qp_qpsolvers``            ``qpsolvers.solve_qp`` with bounds as bounds (daqp,
                            quadprog, proxqp, clarabel, highs, osqp, scs ...)
``qp_cvxpy``                one cvxpy Problem with Parameters (DPP), re-solved
``qp_cvxpy_rebuild``        a new cvxpy Problem every step (the slow reference)
==========================  ====================================================

Each is registered with its options model; a preset's adapter is a
:class:`~optikin.solvers.qp.common.StepSolverFactory` (``create(n, m)``), and the
step solver it creates answers ``solve(QPData) -> Solution``. :func:`step_solver`
builds one in code (tests, notebooks) through the same validation as a preset.
"""

from __future__ import annotations

from typing import Any

from optikin.solvers import import_all, preset_of
from optikin.solvers.base import QPStepSolver
from optikin.solvers.qp.common import QPData, StepSolverFactory
from optikin.spec import SolverSpec

import_all(__name__, __path__)

__all__ = ["QPData", "StepSolverFactory", "step_solver"]


def step_solver(backend: str, n: int, m: int, **options: Any) -> QPStepSolver:
    """A step solver of the ``qp`` backend ``backend`` for ``n`` rates and ``m`` task rows.

    Parameters
    ----------
    backend:
        A registered ``qp`` backend (``qp_daqp``, ``qp_osqp``, ``qp_qpsolvers``, ``qp_cvxpy``, ``qp_cvxpy_rebuild``).
    n, m:
        Number of joint rates and of task rows.
    **options:
        The backend's options, as a preset's ``options:`` would give them.

    Raises
    ------
    SpecError
        An unknown backend, one of another family, or options its model refuses.
    """
    from optikin.errors import SpecError

    preset = preset_of(SolverSpec(name=backend, backend=backend, options=options))
    if preset.backend.family != "qp":
        raise SpecError(str(preset.path), "backend", f"{backend!r} is a {preset.backend.family} backend, not qp")
    factory: StepSolverFactory = preset.build()
    return factory.create(n, m)
