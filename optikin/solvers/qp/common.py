"""What every backend of the per-step tracking QP shares: the QP's data, the factory, the options base.

The QP of one control step (:mod:`optikin.control.qp`) is

    min_qdot  1/2 qdot' H qdot + g' qdot    s.t.  lb <= qdot <= ub,  A qdot >= b,

with ``H = J'J + lambda I`` and ``g = -J'v``; equivalently
``min ||J qdot - v||^2 + lambda ||qdot||^2`` over the rate box. :class:`QPData`
holds views of the arrays the controller refreshes in place every step; a
backend reads what it needs (OSQP ``H_upper``, ``g``, ``lb``, ``ub``; qpsolvers
``H``; cvxpy ``J``, ``v``, ``damping``). The rows ``A qdot >= b`` (``p`` of them, none by
default: the backbone barrier of :mod:`optikin.control.obstacles`) have a fixed count per
controller; a row with ``b = -inf`` is inactive this step.

A backend is registered once (:func:`optikin.solvers.register_backend`, family
``qp``) with a pydantic options model; its adapter is a :class:`StepSolverFactory`
whose ``create(n, m, rows)`` returns a fresh step solver for one controller (OSQP and
cvxpy keep per-problem state), keeping :class:`optikin.solvers.base.QPBackend`.
A step solver's ``solve(data)`` answers with a :class:`~optikin.solvers.base.Solution`:
``x`` the joint rates (NaN when the solver returned none), ``status`` ``"ok"`` or
``"failed"``, ``message`` the solver's own status when it failed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Generic, TypeVar

import numpy as np

from optikin.options import Options
from optikin.solvers.base import QPStepSolver, Solution
from optikin.status import Status

OptionsT = TypeVar("OptionsT", bound=Options)


@dataclass
class QPData:
    """The per-step QP; every array is a view the controller refreshes in place.

    Attributes
    ----------
    J, v:
        Task Jacobian ``(m, n)`` and requested task velocity ``(m,)``.
    damping:
        ``lambda``, the weight of ``||qdot||^2``.
    H, H_upper, g:
        ``H = J'J + lambda I`` ``(n, n)``, its upper triangle in compressed-column
        order (:func:`upper_triangle_csc_indices`) and ``g = -J'v`` ``(n,)``.
    lb, ub:
        The rate box ``(n,)`` [m/s, rad/s].
    A, b:
        Inequality rows ``A qdot >= b``, ``(p, n)`` and ``(p,)``; ``b = -inf`` marks a row inactive.
    """

    J: np.ndarray
    v: np.ndarray
    damping: float
    H: np.ndarray
    H_upper: np.ndarray
    g: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    A: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    b: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        return int(self.H.shape[0])


def upper_triangle_csc_indices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of each entry of an ``n x n`` upper triangle in compressed-column order."""
    rows = np.array([i for j in range(n) for i in range(j + 1)])
    cols = np.array([j for j in range(n) for _ in range(j + 1)])
    return rows, cols


def failed(
    n: int, message: str, seconds: float = 0.0, iterations: int = -1, extras: dict[str, Any] | None = None
) -> Solution:
    """A failed step: ``x`` all NaN, ``message`` the solver's reason."""
    return Solution(
        np.full(n, np.nan), Status.FAILED, iterations, seconds=seconds, message=message, extras=extras or {}
    )


class StepSolverFactory(Generic[OptionsT]):
    """The adapter of a ``qp`` backend: ``create(n, m, rows)`` builds one controller's step solver.

    Parameters
    ----------
    make:
        ``make(n, m, options, rows=p) -> step solver``.
    options:
        The preset's validated options.
    """

    def __init__(self, make: Callable[[int, int, OptionsT], QPStepSolver], options: OptionsT):
        self.make, self.options = make, options

    def create(self, n: int, m: int, rows: int = 0) -> QPStepSolver:
        """A fresh step solver for ``n`` rates, ``m`` task rows and ``rows`` inequality rows ``A qdot >= b``."""
        if rows:
            return self.make(n, m, self.options, rows=rows)  # type: ignore[call-arg]
        return self.make(n, m, self.options)
