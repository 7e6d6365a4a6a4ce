"""Constrained tracking: one small QP per control step (beyond the MRAC of Seleem et al. 2020, sections V-VI).

Each step solves

    min_qdot  ||J(q) qdot - (xdot_ref + K e)||^2 + lambda ||qdot||^2
    s.t.      lb <= qdot <= ub,   A qdot >= b  (optional: the backbone barrier)

where ``J`` is the task Jacobian of the arm's own model (Seleem et al. 2020 eq. 33 for the
dual-quaternion pose), ``e = x_ref - x`` and ``K = diag(k)`` as in Seleem et al. 2020
eq. (34), and the box (:class:`optikin.control.limits.RateBounds`) keeps every
configuration limit after integrating the rate over the step and respects the
rate limits, also when the arm starts outside a limit (it steers back at the
full rate; the box is never empty). Without active bounds the solution is the
damped least-squares step ``(J'J + lambda I)^-1 J' (xdot_ref + K e)``.

With obstacles (``barrier``, :class:`optikin.control.obstacles.BarrierRows`) the rows
``A qdot >= b`` are the discrete-time barrier of the backbone samples nearest to each
obstacle; the task stays a least-squares objective (its slack is free), the barrier is hard.

Which QP method. The QP is solved by a step solver (``solve(QPData) -> Solution``): a ``qp``
backend's (:mod:`optikin.solvers.qp`) when a preset names one, e.g. ``qp-osqp``; otherwise
(``solver=None``) it is chosen by the QP's structure (:func:`default_step_solver`). These QPs are
small and dense (``n`` rates, ``H`` full, the box plus a few rows), so for ``n <=``
:data:`ACTIVE_SET_MAX_RATES` and at most :data:`ACTIVE_SET_MAX_ROWS` rows the default is a
dual active-set method (DAQP, Arnstrom, Bemporad and Axehill 2022,
:class:`~optikin.solvers.qp.qp_daqp.ActiveSetStepSolver`, backend ``qp_daqp``, preset
``qp-active-set``): exact up to rounding once the active set is found, warm-started with the previous
step's active set (consecutive steps rarely change it: often one iteration), one
dense Cholesky factorisation of ``H`` per step. ADMM (OSQP) stops at its tolerance, and on the
redundant arms (more rates than task rows: the null space of ``J`` is held by ``lambda`` alone) its
error there is about the tolerance over ``lambda``; it is the default only beyond those sizes, where
a dense factorisation per step grows as ``n^3`` and OSQP's sparse one pays.

Failure handling. If the solver raises, answers with a status other than
``"ok"``, or returns a non-finite vector, the step is reported (:attr:`QPController.status` starts
with ``"fallback"``) and a safe command is applied instead:

* ``fallback="hold"`` (default): the smallest rate inside the box, i.e. stop
  (``qdot = 0``) inside the limits, steer back at the full rate outside;
* ``fallback="damped_least_squares"``: the unconstrained QP solution projected
  onto the box.

Both lie in the box, so a failing solver can never push a limit. A returned
solution is itself projected onto the box (a no-op for an exact solver); the
amount removed is kept in :attr:`QPController.slip`, the bound violation the
solver's tolerance would otherwise have let through.

Per step, in place. Every array of the step lives in a buffer allocated once: the task Function
(:class:`~optikin.control.task.TaskModel`) writes ``J, v, H, g``, the rate box reads the configuration
from the task Function's own input (:meth:`~optikin.control.limits.RateBounds.read_configuration_from`),
the step solver reads the QP from those buffers, and one more CasADi Function on the buffers
projects its answer onto the box and measures what the projection removed (largest and summed
``|qdot - x|``: the sum is not finite exactly when the answer is not). Without obstacles a step is
thus five calls out of Python (task Function, box, daqp's refresh and solve, projection, with the
default solver) and no numpy temporary.
"""

from __future__ import annotations

import math
from typing import Any, Literal, Sequence, cast

import casadi as ca
import numpy as np

from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.control.limits import RateBounds
from optikin.control.obstacles import BarrierRows
from optikin.control.task import Task
from optikin.interrupt import calls_casadi
from optikin.solvers.base import QPStepSolver, Solution
from optikin.solvers.qp.common import QPData
from optikin.solvers.qp.qp_daqp import ActiveSetStepSolver
from optikin.status import Status

Fallback = Literal["hold", "damped_least_squares"]
FALLBACKS = ("hold", "damped_least_squares")

ACTIVE_SET_MAX_RATES = 24
"""Up to this many rates (8 three-variable sections) the default QP method is the dense active set."""
ACTIVE_SET_MAX_ROWS = 96
"""Up to this many rows ``A qdot >= b`` besides the box the default QP method is the dense active set."""


def default_step_solver(n: int, m: int, rows: int = 0) -> QPStepSolver:
    """The QP method chosen by structure (module docstring): dense active set when small, else OSQP.

    Parameters
    ----------
    n, m, rows:
        Rates, task rows and rows ``A qdot >= b`` of the per-step QP.

    Returns
    -------
    QPStepSolver
        :class:`~optikin.solvers.qp.qp_daqp.ActiveSetStepSolver` for ``n <=`` :data:`ACTIVE_SET_MAX_RATES`
        and ``rows <=`` :data:`ACTIVE_SET_MAX_ROWS`; otherwise the ``qp_osqp`` backend's step solver at its defaults.
    """
    if n <= ACTIVE_SET_MAX_RATES and rows <= ACTIVE_SET_MAX_ROWS:
        return ActiveSetStepSolver(n, m, rows=rows)
    from optikin.solvers import preset_of
    from optikin.spec import SolverSpec

    factory = preset_of(SolverSpec(name="qp-osqp", backend="qp_osqp", options={})).build()
    return factory.create(n, m, rows)


class QPController(Controller):
    """Tracking by a bounded least-squares QP per step.

    Parameters
    ----------
    arm, dt, task, gain:
        See :class:`optikin.control.base.Controller`; ``gain`` is ``K`` (1/s).
    damping:
        ``lambda``, weight of ``||qdot||^2`` (keeps ``H`` positive definite at singular configurations).
    solver:
        The step solver (``solve(QPData) -> Solution``), e.g. a ``qp`` preset's
        ``create(arm.n_config, task rows)`` or :func:`optikin.solvers.qp.step_solver`;
        ``None``: chosen by the QP's structure (:func:`default_step_solver`, module docstring).
    rate_limits, margin, periodic, limit_gain:
        See :class:`optikin.control.limits.RateBounds` (``limit_gain`` is its ``gain``).
    fallback:
        What to command when the solver fails (see the module docstring).
    compiled:
        Compile the per-step CasADi Functions (task, rate box, projection) with a C compiler.
    barrier:
        The backbone barrier rows (its step solver must be created for ``barrier.rows`` rows); ``None``: no obstacles.
    """

    name = "qp"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain: float | Sequence[float] = 10.0,
        damping: float = 1e-4,
        *,
        solver: QPStepSolver | None = None,
        rate_limits=None,
        margin: float | Sequence[float] = 1e-9,
        periodic: Sequence[str] | None = None,
        limit_gain: float = 1.0,
        fallback: Fallback = "hold",
        compiled: bool = False,
        barrier: BarrierRows | None = None,
    ):
        super().__init__(arm, dt, task, gain, compiled)
        if not damping >= 0:
            raise ValueError(f"damping must be non-negative, got {damping}")
        if fallback not in FALLBACKS:
            raise ValueError(f"unknown fallback {fallback!r}; known: {', '.join(FALLBACKS)}")
        self.damping, self.fallback = float(damping), fallback
        self.model.set_gains(self.gain, self.damping)
        self.bounds = RateBounds(arm, dt, rate_limits, margin, periodic, gain=limit_gain, compiled=compiled)
        m = self.model
        self.data = QPData(m.J, m.v, self.damping, m.H, m.H_upper, m.g, self.bounds.lb, self.bounds.ub)
        self.barrier = barrier
        if barrier is not None:
            self.data.A, self.data.b = barrier.A, barrier.b
        if solver is None:
            solver = default_step_solver(arm.n_config, m.m, 0 if barrier is None else barrier.rows)
        self.solver = solver
        self.name = f"qp ({getattr(solver, 'name', type(solver).__name__)})"
        self.bounds.read_configuration_from(m.q)
        self.qdot = np.zeros(arm.n_config)
        self.slip = 0.0
        self.solution: Solution | None = None
        self._projection = _BoxProjection(self.bounds.lb, self.bounds.ub, self.qdot, compiled)

    def reset(self, q: np.ndarray, x: np.ndarray) -> None:
        super().reset(q, x)
        if self.barrier is not None:
            self.barrier.reset()

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        self.model.evaluate(q, x, x_ref, xdot_ref)
        self.bounds.refresh()  # at the q just written into the task Function's input
        if self.barrier is not None:
            self.barrier.update(q)
        try:
            solution = self.solution = self.solver.solve(self.data)
            failure = None if solution.status == Status.OK else f"no solution ({solution.message})"
        except Exception as exc:  # noqa: BLE001 - a solver crash must stop neither the loop nor the arm
            self.solution, failure = None, f"solver raised {type(exc).__name__}: {exc}"
        if failure is None:
            slip, removed = self._projection(solution.x)  # writes self.qdot
            if math.isfinite(removed):  # NaN or inf anywhere in the solution makes the sum non-finite
                self.slip = slip
                self.status = Status.OK
                return self.qdot
            failure = "non-finite solution"
        self.slip = 0.0
        self._fall_back()
        self.status = f"fallback ({self.fallback}): {failure}"
        return self.qdot

    def _fall_back(self) -> None:
        if self.fallback == "hold":
            self.qdot[:] = 0.0
        else:
            self.qdot[:] = np.linalg.solve(self.model.H, -self.model.g)
        np.maximum(self.qdot, self.bounds.lb, out=self.qdot)
        np.minimum(self.qdot, self.bounds.ub, out=self.qdot)


class _BoxProjection:
    """``qdot = min(max(x, lb), ub)`` and ``(max, sum)`` of ``|qdot - x|``, one CasADi call on given arrays.

    ``lb``, ``ub`` and ``qdot`` (``(n,)``, C-contiguous ``float64``) are read and written in place;
    the answer ``x`` is read where the solver left it (the same array every step for a solver that
    keeps one, else rebound, or copied when it is not a contiguous ``float64`` vector). CasADi's
    ``fmax``/``fmin`` pass over a NaN, so a NaN in ``x`` shows in the sum, never in ``qdot``.
    ``compiled``: evaluate C code of the Function (gcc, cached) instead of CasADi's virtual machine.
    """

    def __init__(self, lb: np.ndarray, ub: np.ndarray, qdot: np.ndarray, compiled: bool = False):
        n = qdot.shape[0]
        x, low, high = (ca.SX.sym(name, n) for name in ("x", "lb", "ub"))
        projected = ca.fmin(ca.fmax(x, low), high)
        removed = ca.fabs(projected - x)
        amounts = ca.vertcat(ca.mmax(removed), ca.sum1(removed))
        self.function = ca.Function(f"box_projection_{n}", [x, low, high], [projected, amounts])
        if compiled:
            from optikin.codegen import compile_function

            self.function = compile_function(self.function)
        self._copy, self._amounts = np.zeros(n), np.zeros(2)
        self._read: np.ndarray = self._copy
        self._buffer, self._trigger = cast(Any, self.function.buffer())  # CasADi's stub asks for a byte count
        for i, array in enumerate((self._copy, lb, ub)):
            self._buffer.set_arg(i, array.data)
        self._buffer.set_res(0, qdot.data)
        self._buffer.set_res(1, self._amounts.data)

    @calls_casadi
    def __call__(self, x: np.ndarray) -> tuple[float, float]:
        """Project ``x``; the largest and the summed amount removed."""
        if x is not self._read:
            self._bind(x)
        self._trigger()
        slip, removed = self._amounts.tolist()
        return slip, removed

    def _bind(self, x: np.ndarray) -> None:
        if isinstance(x, np.ndarray) and x.shape == self._copy.shape and x.dtype == np.float64 and x.flags.c_contiguous:
            self._read = x
        else:
            self._copy[...] = x
            self._read = self._copy
        self._buffer.set_arg(0, self._read.data)
