"""Two arms controlled together: one QP per step over both arms' rates, for a rope they hold or for their tips.

Tasks. ``rope``: the two tips grip a rope of length ``L``; the task is the rope's lowest point
``P(G)`` (:class:`optikin.curves.catenary_sensitivity.CatenarySensitivity`, the exact catenary of
the grips ``G = (tip_1, tip_2)``), whose Jacobian is the chain rule through the implicit-function
derivative, ``J = dP/dG diag(J_tip,1, J_tip,2)`` (3 rows, ``n_1 + n_2`` columns). ``tips``: each
arm's own tip position reference (6 rows, block diagonal). The rope hangs quasi-statically: the
skipping-rope motion is its lowest point driven along a closed path in the vertical plane across
the grips (a real skipping rope also swings by its inertia, which a catenary does not have).

The QP of one step (``q = (q_1, q_2)``, period ``dt``)::

    min_qdot  ||J qdot - (xdot_ref + K e)||^2 + w ||qdot - k_p (q_nom - q)||^2 + lambda ||qdot||^2
    s.t.      lb <= qdot <= ub                        (both arms' limits, RateBounds)
              D qdot >= -gamma (d - margin)           (self-collision, TwoTubes)
              dc/dq qdot <= gamma (L - slack - c)     (rope task: grips kept slack, c = |G_2 - G_1|)
              dz/dq qdot >= -gamma (z - floor - margin)  (rope task with a floor: the lowest point above it)
              D_rope qdot >= -gamma (d_rope - rope margin)  (rope task: its samples off both tubes, RopeTubes)
              D_obs qdot >= -gamma (d_obs - margin) + ...   (obstacles off both tubes and the rope, two_arm_obstacles)

The posture term (weight ``w``) settles the motions the task leaves free (the lowest point fixes 3
of 12 rates). Keeping the grips at least ``slack`` closer than the rope's length keeps the rope
hanging (its sensitivity grows without bound as it goes taut). The floor row is exact for the
whole rope, not only its lowest point, when the floor is perpendicular to gravity. The task is a
least-squares objective (its slack is free); every row is hard, and with every barrier value
non-negative ``qdot = 0`` satisfies them all, so the QP stays feasible whatever the reference asks.

Baselines: the same QP without the self-collision rows, and the pseudo-inverse (per arm for the
tips task, of the 3-row rope Jacobian for the rope task), which knows no limits either.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal, Sequence

import numpy as np

from optikin.control.limits import RateBounds, limit_excess, periodic_mask, wrap_periodic
from optikin.control.self_collision import PlacedArm, TwoTubes
from optikin.curves.catenary_sensitivity import CatenarySensitivity, LowestPoint, RopeSamples
from optikin.errors import InputDataError
from optikin.interrupt import check_interrupted
from optikin.solvers.base import QPStepSolver
from optikin.solvers.qp.common import QPData, StepSolverFactory, upper_triangle_csc_indices
from optikin.status import Status

TwoArmTask = Literal["rope", "tips"]


def qp_factory(backend: str = "qp_daqp", **options: Any) -> StepSolverFactory:
    """The step-solver factory of ``qp`` backend ``backend`` with ``options`` (as a preset's), for code and tests."""
    from optikin.solvers import preset_of
    from optikin.spec import SolverSpec

    factory = preset_of(SolverSpec(name=backend, backend=backend, options=options)).build()
    if not isinstance(factory, StepSolverFactory):
        raise ValueError(f"{backend!r} is not a qp backend")
    return factory


@dataclass(frozen=True)
class TwoArmReference:
    """The reference at control instants ``t`` (uniform), ``value``/``rate`` ``(N, 3)`` (rope) or ``(N, 6)`` (tips)."""

    t: np.ndarray
    value: np.ndarray
    rate: np.ndarray
    task: TwoArmTask

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])


@dataclass
class Rope:
    """The rope held by the tips: its sensitivity, the slack kept, an optional floor (height along ``up``) [m], and
    the samples kept off the arms' tubes (``None``: none), from arc length ``exclusion`` [m] of each grip on."""

    sensitivity: CatenarySensitivity
    slack: float = 0.03
    floor: float | None = None
    samples: RopeSamples | None = None
    exclusion: float = 0.07


def rope_samples(
    sensitivity: CatenarySensitivity, exclusion: float, margin: float, compiled: bool = False
) -> RopeSamples:
    """Rope samples from arc length ``exclusion`` of each grip on, spaced at most ``margin / 2`` (:class:`RopeTubes`).

    Raises
    ------
    ValueError
        An exclusion that leaves no rope between the grips.
    """
    inner = sensitivity.length - 2.0 * exclusion
    if not inner > 0:
        raise ValueError(f"an exclusion of {exclusion} m at both grips leaves nothing of a {sensitivity.length} m rope")
    count = int(np.ceil(inner / (0.5 * margin) - 1e-9)) + 1
    return RopeSamples(sensitivity, np.linspace(exclusion, sensitivity.length - exclusion, count), compiled)


class TwoArmModel:
    """Both arms and the task: the task value ``x`` and Jacobian ``J`` at a configuration ``q = (q_1, q_2)``.

    Attributes
    ----------
    x, J:
        After :meth:`evaluate`: task value ``(m,)`` and Jacobian ``(m, n_1 + n_2)``.
    lowest:
        The rope's lowest point and its derivatives (rope task), else ``None``.
    """

    def __init__(self, arms: Sequence[PlacedArm], task: TwoArmTask, rope: Rope | None = None):
        if len(arms) != 2:
            raise ValueError(f"two arms needed, got {len(arms)}")
        if task == "rope" and rope is None:
            raise ValueError("the rope task needs a rope")
        self.arms, self.task, self.rope = tuple(arms), task, rope
        self.n1, self.n2 = arms[0].arm.n_config, arms[1].arm.n_config
        self.n = self.n1 + self.n2
        self.m = 3 if task == "rope" else 6
        self.x = np.zeros(self.m)
        self.J = np.zeros((self.m, self.n))
        self.lowest: LowestPoint | None = None

    def split(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return q[: self.n1], q[self.n1 :]

    def evaluate(self, q: np.ndarray) -> None:
        """Evaluate both arms and the task at ``q``."""
        first, second = self.arms
        q1, q2 = self.split(q)
        first.evaluate(q1)
        second.evaluate(q2)
        n1 = self.n1
        if self.task == "tips":
            self.x[:3], self.x[3:] = first.tip, second.tip
            self.J[:3, :n1], self.J[3:, n1:] = first.tip_jacobian, second.tip_jacobian
            return
        assert self.rope is not None
        low = self.lowest = self.rope.sensitivity.lowest_point(first.tip, second.tip)
        if self.rope.samples is not None:
            self.rope.samples.evaluate(first.tip, second.tip, low.a)
        self.x[:] = low.point
        self.J[:, :n1] = low.jacobian[:, :3] @ first.tip_jacobian
        self.J[:, n1:] = low.jacobian[:, 3:] @ second.tip_jacobian


class RopeTubes:
    """Barrier rows keeping the rope's samples ``margin`` off both arms' tubes (:mod:`optikin.control.self_collision`).

    For a rope sample ``p_i(G)`` (:class:`~optikin.curves.catenary_sensitivity.RopeSamples`, its derivative through
    the catenary's implicit function) and a backbone sample ``p_j(q_k)`` of arm ``k`` the clearance is
    ``d = |p_i - p_j| - r_k`` with ``d d / d q = n' (dp_i/dG dG/dq - dp_j/dq)``, ``dG/dq`` the tips' Jacobians.
    Per arm, each rope sample's nearest backbone sample, and of those the ``pairs`` nearest, enter the QP as
    ``(d d/d q) qdot >= -gamma (d - margin)``. The rope is sampled only from ``exclusion`` of each grip on (it
    leaves the tube of the arm holding it there), spaced at most ``margin / 2`` (:func:`rope_samples`), so
    between samples the rope keeps at least ``margin - (h_rope + h_arm) / 2`` off the tubes.

    Parameters
    ----------
    model:
        The two arms and the rope task (its rope holding :attr:`Rope.samples`).
    margin, gamma, dt, pairs:
        The clearance kept [m], the barrier rate [1/s], the control period [s], the rows per arm.
    """

    def __init__(self, model: "TwoArmModel", margin: float, gamma: float, dt: float, pairs: int = 2):
        rope = model.rope
        if rope is None or rope.samples is None:
            raise ValueError("rope rows need the rope's samples")
        if not (margin > 0 and 0 < gamma * dt <= 1 and pairs >= 1):
            raise ValueError(f"need margin > 0, 0 < gamma dt <= 1, pairs >= 1; got {margin}, {gamma * dt}, {pairs}")
        self.model, self.samples = model, rope.samples
        self.margin, self.gamma = float(margin), float(gamma)
        self.pairs = min(int(pairs), len(self.samples.arc_lengths))
        self.rows = 2 * self.pairs
        self.A, self.b = np.zeros((self.rows, model.n)), np.zeros(self.rows)
        self._rows = np.arange(len(self.samples.arc_lengths))

    def update(self) -> None:
        """The rows at the model's last :meth:`TwoArmModel.evaluate`."""
        m, R, JR = self.model, self.samples.P, self.samples.J
        first, second = m.arms
        k, rows_of_R = self.pairs, self._rows
        for arm, placed in enumerate(m.arms):
            squared = R @ placed.P.T
            squared *= -2.0
            squared += self.samples.squared[:, None]
            squared += placed.squared
            nearest = np.argmin(squared, axis=1)
            best = squared[rows_of_R, nearest]
            i = np.argpartition(best, k - 1)[:k] if k < len(best) else rows_of_R
            j = nearest[i]
            gap = R[i] - placed.P[j]
            length = np.sqrt(np.einsum("rk,rk->r", gap, gap))
            normal = gap / length[:, None]
            along = np.einsum("rk,rkg->rg", normal, JR[i])  # d d / d G, (k, 6)
            rows = slice(arm * k, arm * k + k)
            self.A[rows, : m.n1] = along[:, :3] @ first.tip_jacobian
            self.A[rows, m.n1 :] = along[:, 3:] @ second.tip_jacobian
            columns = slice(0, m.n1) if arm == 0 else slice(m.n1, m.n)
            self.A[rows, columns] -= np.einsum("rk,rkn->rn", normal, placed.J[j])
            self.b[rows] = -self.gamma * (length - placed.radius - self.margin)

    def clearance(self) -> float:
        """The least clearance of every rope sample to either tube at the model's last evaluation [m]."""
        R = self.samples.P
        return min(
            float(np.sqrt(((R[:, None, :] - placed.P[None, :, :]) ** 2).sum(axis=2)).min()) - placed.radius
            for placed in self.model.arms
        )


class TwoArmController:
    """What the two-arm simulator calls: ``command(q, x_ref, xdot_ref) -> qdot`` and a :attr:`status`."""

    name = "controller"

    def __init__(self, model: TwoArmModel, dt: float, gain: float = 10.0):
        if not dt > 0:
            raise ValueError(f"dt must be positive, got {dt}")
        if not gain >= 0:
            raise ValueError(f"gain must be non-negative, got {gain}")
        self.model, self.dt, self.gain = model, float(dt), float(gain)
        self.status: str = Status.OK
        self.v = np.zeros(model.m)

    def task_velocity(self, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        """``xdot_ref + K (x_ref - x)`` at the last evaluation."""
        np.subtract(x_ref, self.model.x, out=self.v)
        self.v *= self.gain
        self.v += xdot_ref
        return self.v

    def reset(self) -> None:
        """Start a run (the simulator calls it before the first step)."""
        self.status = Status.OK

    def command(self, q: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class TwoArmPseudoInverse(TwoArmController):
    """``qdot = J^+ (xdot_ref + K e)``: per arm for the tips task, of the rope Jacobian for the rope task; no limits.

    ``limits``: one :class:`~optikin.control.limits.RateBounds` per arm (the joint QP's): the command is then
    clipped into their boxes (the rate limits, and the configuration limits after the step), and the
    controller is named ``"pseudo-inverse (saturated)"``.
    """

    name = "pseudo-inverse"

    def __init__(
        self, model: TwoArmModel, dt: float, gain: float = 10.0, limits: Sequence[RateBounds] | None = None
    ) -> None:
        super().__init__(model, dt, gain)
        if limits is not None and len(limits) != len(model.arms):
            raise ValueError(f"limits need one box per arm ({len(model.arms)}), got {len(limits)}")
        self.limits = None if limits is None else list(limits)
        if self.limits is not None:
            self.name = f"{self.name} (saturated)"

    def command(self, q: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        m = self.model
        m.evaluate(q)
        v = self.task_velocity(x_ref, xdot_ref)
        if m.task == "rope":
            qdot = np.linalg.pinv(m.J, rcond=1e-10) @ v
        else:
            first = np.linalg.pinv(m.J[:3, : m.n1], rcond=1e-10) @ v[:3]
            second = np.linalg.pinv(m.J[3:, m.n1 :], rcond=1e-10) @ v[3:]
            qdot = np.concatenate([first, second])
        if self.limits is not None:
            for bounds, part, rate in zip(self.limits, m.split(q), m.split(qdot)):
                bounds.update(part)
                np.clip(rate, bounds.lb, bounds.ub, out=rate)
        return qdot


class TwoArmQP(TwoArmController):
    """The joint QP of both arms (module docstring).

    Parameters
    ----------
    model, dt, gain:
        The two arms and their task, the control period [s], ``K`` [1/s].
    factory:
        A ``qp`` backend's factory (:class:`optikin.solvers.qp.common.StepSolverFactory`, e.g. :func:`qp_factory`):
        the step solver is created for ``n_1 + n_2`` rates, :attr:`task_rows` task rows and :attr:`rows` rows.
        Every step writes the one :attr:`data` in place (``H`` column-major), so ``qp_daqp``
        (:class:`~optikin.solvers.qp.qp_daqp.ActiveSetStepSolver`) binds daqp to its arrays once and solves
        warm-started from the previous step's active set.
    damping:
        ``lambda``.
    posture, posture_weight, posture_gain:
        ``q_nom`` ``(n_1 + n_2,)``, ``w`` and ``k_p`` [1/s] of the posture term (``w = 0``: none).
    rate_limits, limit_margin:
        Of both arms (:class:`optikin.control.limits.RateBounds`).
    tubes:
        The self-collision rows; ``None``: the arms may pass through each other.
    rope_tubes:
        The rows keeping the rope off the arms' tubes (rope task); ``None``: none.
    obstacle_rows:
        The rows keeping both tubes and the rope off obstacles
        (:class:`optikin.control.two_arm_obstacles.TwoArmObstacleRows`); ``None``: none.
    gamma, margin:
        Barrier rate [1/s] and the margin of the floor row [m] (rope task).
    """

    name = "joint QP"

    def __init__(
        self,
        model: TwoArmModel,
        dt: float,
        gain: float = 10.0,
        *,
        factory: StepSolverFactory,
        damping: float = 1e-4,
        posture: np.ndarray | None = None,
        posture_weight: float = 0.0,
        posture_gain: float = 1.0,
        rate_limits=None,
        limit_margin: float = 1e-9,
        tubes: TwoTubes | None = None,
        rope_tubes: RopeTubes | None = None,
        obstacle_rows: Any = None,
        gamma: float = 20.0,
        margin: float = 0.01,
    ):
        super().__init__(model, dt, gain)
        if not (damping >= 0 and posture_weight >= 0 and posture_gain >= 0):
            raise ValueError("damping, posture_weight and posture_gain must be non-negative")
        if not 0 < gamma * dt <= 1:
            raise ValueError(f"gamma dt must be in (0, 1], got gamma {gamma} 1/s at dt {dt} s")
        n = model.n
        self.tubes, self.gamma, self.margin = tubes, float(gamma), float(margin)
        self.bounds = [
            RateBounds(placed.arm, dt, rate_limits, limit_margin) for placed in model.arms
        ]  # one box per arm, written into lb, ub
        self.periodic = np.concatenate([periodic_mask(placed.arm) for placed in model.arms])
        self.posture = np.zeros(n) if posture is None else np.asarray(posture, dtype=float).copy()
        self.posture_rows = n if posture_weight > 0 else 0
        self.root_weight, self.posture_gain = math.sqrt(posture_weight), float(posture_gain)
        self.task_rows = model.m + self.posture_rows
        rope = model.rope if model.task == "rope" else None
        self.rope_rows = 0 if rope is None else 1 + (rope.floor is not None)
        self.collision_rows = 0 if tubes is None else tubes.pairs
        self.rope_tubes = rope_tubes
        self.rope_tube_rows = 0 if rope_tubes is None else rope_tubes.rows
        self.obstacle_rows = obstacle_rows
        self.obstacle_row_count = 0 if obstacle_rows is None else int(obstacle_rows.rows)
        self.rows = self.collision_rows + self.rope_tube_rows + self.obstacle_row_count + self.rope_rows
        J, v = np.zeros((self.task_rows, n)), np.zeros(self.task_rows)
        if self.posture_rows:
            J[model.m :, :] = self.root_weight * np.eye(n)
        H = np.zeros((n, n), order="F")  # column-major like the task Functions' H: qp_daqp reads it without a copy
        self._upper = upper_triangle_csc_indices(n)
        A, b = np.zeros((self.rows, n)), np.zeros(self.rows)
        self.data = QPData(
            J, v, float(damping), H, np.zeros(len(self._upper[0])), np.zeros(n), np.zeros(n), np.zeros(n)
        )
        if self.rows:
            self.data.A, self.data.b = A, b
        self.solver: QPStepSolver = factory.create(n, self.task_rows, rows=self.rows)
        self.qdot = np.zeros(n)
        self._eye = float(damping) * np.eye(n)
        self.name = "joint QP" + ("" if tubes is not None else " without collision rows")

    def reset(self, posture: np.ndarray | None = None) -> None:
        """Start a run at ``t = 0`` (``posture``: a new ``q_nom``)."""
        self.status = Status.OK
        if posture is not None:
            self.posture[:] = posture
        if self.obstacle_rows is not None:
            self.obstacle_rows.reset()

    def command(self, q: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        m, d = self.model, self.data
        m.evaluate(q)
        d.J[: m.m] = m.J
        d.v[: m.m] = self.task_velocity(x_ref, xdot_ref)
        if self.posture_rows:
            error = self.posture - q
            wrap_periodic(error, self.periodic)
            d.v[m.m :] = (self.root_weight * self.posture_gain) * error
        np.matmul(d.J.T, d.J, out=d.H)
        d.H += self._eye
        np.matmul(d.J.T, d.v, out=d.g)
        d.g *= -1.0
        d.H_upper[:] = d.H[self._upper]
        for k, (bounds, part) in enumerate(zip(self.bounds, m.split(q))):
            bounds.update(part)
            where = slice(0, m.n1) if k == 0 else slice(m.n1, m.n)
            d.lb[where], d.ub[where] = bounds.lb, bounds.ub
        if self.tubes is not None:
            self.tubes.update()
            d.A[: self.collision_rows], d.b[: self.collision_rows] = self.tubes.A, self.tubes.b
        start = self.collision_rows
        if self.rope_tubes is not None:
            self.rope_tubes.update()
            d.A[start : start + self.rope_tube_rows] = self.rope_tubes.A
            d.b[start : start + self.rope_tube_rows] = self.rope_tubes.b
            start += self.rope_tube_rows
        if self.obstacle_rows is not None:
            self.obstacle_rows.update()
            d.A[start : start + self.obstacle_row_count] = self.obstacle_rows.A
            d.b[start : start + self.obstacle_row_count] = self.obstacle_rows.b
            start += self.obstacle_row_count
        if self.rope_rows:
            self._rope_rows(d.A[start:], d.b[start:])
        try:
            solution = self.solver.solve(d)
            failure = None if solution.status == Status.OK else f"no solution ({solution.message})"
        except Exception as exc:  # noqa: BLE001 - a solver crash must stop neither the loop nor the arms
            failure = f"solver raised {type(exc).__name__}: {exc}"
        if failure is None and np.all(np.isfinite(solution.x)):
            np.clip(solution.x, d.lb, d.ub, out=self.qdot)
            self.status = Status.OK
            return self.qdot
        np.clip(0.0, d.lb, d.ub, out=self.qdot)  # hold: the smallest rate inside the box
        self.status = f"fallback (hold): {failure or 'non-finite solution'}"
        return self.qdot

    def _rope_rows(self, A: np.ndarray, b: np.ndarray) -> None:
        """The grips kept ``slack`` inside the rope's length, and the lowest point above the floor."""
        m = self.model
        rope = m.rope
        assert rope is not None and m.lowest is not None
        first, second = m.arms
        chord = second.tip - first.tip
        c = math.sqrt(float(chord @ chord))
        u = chord / c
        A[0, : m.n1] = u @ first.tip_jacobian
        A[0, m.n1 :] = -(u @ second.tip_jacobian)
        b[0] = -self.gamma * (rope.sensitivity.length - rope.slack - c)
        if rope.floor is not None:
            up = rope.sensitivity.up
            A[1] = up @ m.J
            b[1] = -self.gamma * (float(up @ m.x) - rope.floor - self.margin)


@dataclass
class TwoArmRun:
    """One closed-loop run of ``N`` steps."""

    controller: str
    reference: TwoArmReference
    q: np.ndarray  # (N, n_1 + n_2) configurations
    qdot: np.ndarray  # (N, n_1 + n_2) commanded rates
    x: np.ndarray  # (N, m) task value (lowest point, or both tips)
    tips: np.ndarray  # (N, 2, 3) both tips
    step_time: np.ndarray  # (N,) [s]
    status: list[str]
    notes: list[str] = field(default_factory=list)

    @property
    def t(self) -> np.ndarray:
        return self.reference.t

    @property
    def error(self) -> np.ndarray:
        """Task position error per step [m]: of the lowest point, or the larger of the two tips'."""
        e = self.reference.value - self.x
        if self.reference.task == "rope":
            return np.linalg.norm(e, axis=1)
        return np.maximum(np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1))


def simulate_two_arms(
    controller: TwoArmController, reference: TwoArmReference, q0: np.ndarray, plant: TwoArmModel
) -> TwoArmRun:
    """Run ``controller`` along ``reference`` from ``q0`` on the kinematic plant ``plant`` (its own evaluator).

    Per step the plant's task value and tips are recorded, the command timed and held over the
    step (``q_{k+1} = q_k + dt qdot_k``, periodic variables wrapped).
    """
    if abs(reference.dt - controller.dt) > 1e-9 * reference.dt:
        raise ValueError(f"reference period {reference.dt} s differs from the controller's {controller.dt} s")
    N, n = len(reference.t), plant.n
    Q, Qdot, X = np.empty((N, n)), np.empty((N, n)), np.empty((N, plant.m))
    tips, step_time = np.empty((N, 2, 3)), np.empty(N)
    status: list[str] = []
    wrapped = np.concatenate([periodic_mask(placed.arm) for placed in plant.arms])
    notes: list[str] = []
    q = np.array(q0, dtype=float)
    controller.reset()
    for k in range(N):
        check_interrupted()
        try:
            plant.evaluate(q)
        except InputDataError as exc:  # the rope went taut: the run ends here, held at its last state
            if k == 0:
                raise
            notes.append(f"stopped at t = {reference.t[k]:.4g} s: {exc}")
            Q[k:], Qdot[k:], X[k:], tips[k:], step_time[k:] = Q[k - 1], 0.0, X[k - 1], tips[k - 1], np.nan
            status += ["failed: rope taut"] * (N - k)
            break
        X[k], tips[k, 0], tips[k, 1] = plant.x, plant.arms[0].tip, plant.arms[1].tip
        start = time.perf_counter()
        qdot = controller.command(q, reference.value[k], reference.rate[k])
        step_time[k] = time.perf_counter() - start
        Q[k], Qdot[k] = q, qdot
        status.append(controller.status)
        q = wrap_periodic(q + controller.dt * qdot, wrapped)
    return TwoArmRun(controller.name, reference, Q, Qdot, X, tips, step_time, status, notes)


def limit_excess_two(model: TwoArmModel, Q: np.ndarray) -> np.ndarray:
    """How far each configuration of both arms lies outside the limits, ``(N, n_1 + n_2)``."""
    return np.hstack(
        [limit_excess(model.arms[0].arm, Q[:, : model.n1]), limit_excess(model.arms[1].arm, Q[:, model.n1 :])]
    )
