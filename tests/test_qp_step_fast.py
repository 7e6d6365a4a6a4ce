"""The structure-chosen QP step (dense active set on the controller's buffers) against a slow, obvious reference.

The reference builds the same QP from scratch for every step: the Jacobian and the tip
pose from the arm's own CasADi ``jac_dq``/``fk_dq`` called the ordinary way, ``v``, ``H`` and
``g`` in numpy, the rate box written out by hand, and solves it with quadprog (Goldfarb-Idnani
dual active set, exact up to rounding) through ``qpsolvers.solve_qp``, or with daqp set up from
scratch (``daqp.solve``). The controller's default path is daqp warm-started on preallocated
buffers, called through its C functions (``DirectDaqp``); every answer is exact, so they agree to
1e-9 rad/s or m/s. Cases: random states stepped through in sequence (the warm start then starts
from an unrelated active set), states next to the configuration limits (rate bounds active), a
closed loop from outside the limits (the box shut to one rate, ``lb = ub``, then opening), rows
``A qdot >= b`` cutting the box-only optimum (rows active), rows that no rate in the box satisfies
(infeasible: the hold fallback and its status, then recovery), and the backbone barrier rows of three
obstacles along a closed-loop run. The direct calls give the bits of ``daqp.Model`` (daqp's own Python
class) on all of these, and the projection onto the box those of ``np.clip`` whatever array the solver
returns.
"""

from __future__ import annotations

import logging
from importlib import metadata

import daqp
import numpy as np
import pytest
import qpsolvers

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.qp import ACTIVE_SET_MAX_RATES, ACTIVE_SET_MAX_ROWS, QPController, default_step_solver
from optikin.solvers import load_preset
from optikin.solvers.qp import step_solver
from optikin.solvers.base import Solution
from optikin.solvers.qp.qp_daqp import DIRECT_VERSIONS, ActiveSetStepSolver, DirectDaqp, ModelDaqp
from optikin.solvers.qp.qp_osqp import OSQPStepSolver

DT, GAIN, DAMPING, MARGIN = 0.01, 20.0, 1e-4, 1e-9
TOLERANCE = 1e-9
ROWS = 3


def arm_of(sections: int) -> ConstantCurvatureArm:
    return ConstantCurvatureArm(section_lengths=(0.18,) * sections)


def rates_of(arm: ConstantCurvatureArm) -> np.ndarray:
    return np.array([0.1, np.pi, 2 * np.pi] * arm.n_sections)


class GivenRows:
    """Rows ``A qdot >= b`` set by the test before each step (the controller's barrier interface)."""

    def __init__(self, n: int, rows: int):
        self.rows = rows
        self.A, self.b = np.zeros((rows, n)), np.full(rows, -np.inf)
        self.next = (self.A.copy(), self.b.copy())

    def reset(self) -> None:
        pass

    def update(self, q: np.ndarray) -> None:
        self.A[:], self.b[:] = self.next


def controller(arm, rows=None):
    return QPController(
        arm, DT, "pose", gain=GAIN, damping=DAMPING, rate_limits=rates_of(arm), margin=MARGIN, barrier=rows
    )


def tip(arm, q):
    return np.asarray(arm.fk_dq(q)).ravel()


def box(arm, q, dt=DT):
    """The rate box by hand: every limit reached in one step at most, clipped to the rates; phi free."""
    rate = rates_of(arm)
    lb = np.clip((arm.lower + MARGIN - q) / dt, -rate, rate)
    ub = np.clip((arm.upper - MARGIN - q) / dt, -rate, rate)
    free = arm.periodic
    lb[free], ub[free] = -rate[free], rate[free]
    return lb, ub


def reference_qp(arm, q, x, x_ref, xdot_ref):
    """``H``, ``g`` of ``min ||J qdot - v||^2 + lambda ||qdot||^2`` from the arm's Jacobian, the short way round."""
    J = np.asarray(arm.jac_dq(q))
    sign = -1.0 if x_ref[:4] @ x[:4] < 0 else 1.0
    v = sign * xdot_ref + GAIN * (sign * x_ref - x)
    return J.T @ J + DAMPING * np.eye(arm.n_config), -J.T @ v


def reference_step(arm, q, x, x_ref, xdot_ref, A=None, b=None):
    """quadprog's answer (None when infeasible), the box and ``(H, g)``."""
    H, g = reference_qp(arm, q, x, x_ref, xdot_ref)
    lb, ub = box(arm, q)
    G = h = None
    if A is not None:
        active = np.isfinite(b)
        G, h = -A[active], -b[active]
    return qpsolvers.solve_qp(H, g, G, h, lb=lb, ub=ub, solver="quadprog"), lb, ub


def random_states(arm, count, rng, near_limits=False):
    """Configurations (optionally next to their limits), their tips and references pulling away from them."""
    n = arm.n_config
    out = []
    for _ in range(count):
        q = arm.sample_configurations(1, rng)[0]
        if near_limits:
            pick = rng.random(n) < 0.5
            side = np.where(rng.random(n) < 0.5, arm.lower + 1e-3, arm.upper - 1e-3)
            q = np.where(pick & ~arm.periodic, side, q)
        q_ref = q + rng.normal(size=n) * np.tile([0.01, 0.3, 0.3], arm.n_sections)
        xdot_ref = rng.normal(size=8) * 0.1
        out.append((q, tip(arm, q), tip(arm, q_ref) * rng.choice([-1.0, 1.0]), xdot_ref))
    return out


def at_bound(qdot, lb, ub):
    return int(np.count_nonzero((np.abs(qdot - lb) < 1e-12) | (np.abs(qdot - ub) < 1e-12)))


@pytest.fixture(scope="module", params=[2, 4, 8], ids=lambda s: f"{s}-sections")
def arm(request):
    return arm_of(request.param)


def test_default_is_the_active_set_and_agrees_with_quadprog(arm):
    rng = np.random.default_rng(arm.n_sections)
    qp = controller(arm)
    assert isinstance(qp.solver, ActiveSetStepSolver) and qp.name == "qp (daqp-active-set)"
    states = random_states(arm, 12, rng) + random_states(arm, 12, rng, near_limits=True)
    qp.reset(states[0][0], states[0][1])
    bounded = 0
    for state in states:  # one controller through all: each warm start begins at an unrelated active set
        qdot = qp.command(*state)
        expected, lb, ub = reference_step(arm, *state)
        assert qp.status == "ok" and qp.solution is not None and qp.solution.status == "ok"
        assert np.abs(qdot - expected).max() < TOLERANCE
        assert qp.slip < 1e-10  # a bound overshot by rounding only
        bounded += at_bound(expected, lb, ub)
    assert bounded >= len(states)  # rate bounds are active: on average at least one per step


def test_a_smooth_sequence_is_solved_from_the_previous_active_set(arm):
    """Along a slowly moving reference the active set rarely changes: daqp then needs one iteration, and is exact."""
    rng = np.random.default_rng(10 + arm.n_sections)
    qp = controller(arm)
    q, x, x_ref, xdot_ref = random_states(arm, 1, rng, near_limits=True)[0]
    qp.reset(q, x)
    iterations = []
    for k in range(20):
        state = (q, x, x_ref + 1e-4 * k, xdot_ref)
        qdot = qp.command(*state)
        assert np.abs(qdot - reference_step(arm, *state)[0]).max() < TOLERANCE
        iterations.append(qp.solution.iterations)
    assert np.median(iterations[1:]) <= 1 < iterations[0]


def test_active_rows_and_the_infeasible_step(arm):
    rng = np.random.default_rng(20 + arm.n_sections)
    n = arm.n_config
    rows = GivenRows(n, ROWS)
    qp = controller(arm, rows)
    assert isinstance(qp.solver, ActiveSetStepSolver)
    states = random_states(arm, 16, rng, near_limits=True)
    qp.reset(states[0][0], states[0][1])
    active_rows = infeasible = 0
    for k, state in enumerate(states):
        box_only, lb, ub = reference_step(arm, *state)
        inside = lb + rng.uniform(0.2, 0.8, n) * (ub - lb)  # a rate in the box that every row admits
        A = rng.normal(size=(ROWS, n))
        A *= np.sign(A @ inside - A @ box_only)[:, None]  # each row cuts the box-only optimum off
        b = A @ inside
        b[2] = -np.inf  # an inactive row
        reach = np.maximum(A * lb, A * ub).sum(axis=1)  # the largest A qdot over the box, row by row
        if k % 4 == 3:
            b[0] = reach[0] + 1.0  # no rate in the box satisfies row 0
        rows.next = (A, b)
        qdot = qp.command(*state)
        expected = reference_step(arm, *state, A, b)[0]
        if k % 4 == 3:
            infeasible += 1
            assert expected is None
            assert qp.status.startswith("fallback (hold): no solution (daqp exit flag")
            assert qp.solution is not None and qp.solution.status == "failed"
            assert np.array_equal(qdot, np.clip(0.0, lb, ub))  # hold: stop inside the limits, steer back outside
            continue
        assert qp.status == "ok", qp.status
        assert np.abs(qdot - expected).max() < TOLERANCE  # also on the step after an infeasible one
        active_rows += int(np.count_nonzero(np.abs(A[:2] @ expected - b[:2]) < 1e-9))
    assert infeasible == 4 and active_rows >= len(states) - infeasible


def test_damped_least_squares_fallback_on_an_infeasible_step():
    arm = arm_of(4)
    rows = GivenRows(arm.n_config, 1)
    qp = QPController(
        arm, DT, gain=GAIN, damping=DAMPING, rate_limits=rates_of(arm), fallback="damped_least_squares", barrier=rows
    )
    state = random_states(arm, 1, np.random.default_rng(5))[0]
    lb, ub = box(arm, state[0])
    rows.next = (np.ones((1, arm.n_config)), np.array([ub.sum() + 1.0]))
    qdot = qp.command(*state)
    H, g = reference_qp(arm, *state)
    assert qp.status.startswith("fallback (damped_least_squares): no solution")
    assert np.abs(qdot - np.clip(np.linalg.solve(H, -g), lb, ub)).max() < 1e-9


def test_the_method_is_chosen_by_structure():
    assert isinstance(default_step_solver(ACTIVE_SET_MAX_RATES, 8), ActiveSetStepSolver)
    assert isinstance(default_step_solver(6, 8, ACTIVE_SET_MAX_ROWS), ActiveSetStepSolver)
    assert isinstance(default_step_solver(ACTIVE_SET_MAX_RATES + 3, 8), OSQPStepSolver)
    assert isinstance(default_step_solver(6, 8, ACTIVE_SET_MAX_ROWS + 1), OSQPStepSolver)
    arm = arm_of(2)
    explicit = QPController(arm, DT, solver=step_solver("qp_osqp", arm.n_config, 8))
    assert explicit.name == "qp (osqp)"  # a preset's solver is used as given


def test_backbone_barrier_rows_from_obstacles():
    """Real barrier rows (a sphere on the reference path, a capsule, a box) along a closed-loop run: some are active."""
    from optikin.control.obstacles import BarrierRows, Obstacle
    from optikin.control.reference import minimum_jerk_path, reference_from_configurations
    from optikin.control.simulate import simulate

    arm, dt = arm_of(2), 1e-3
    obstacles = [
        Obstacle("sphere", center=(0.1554, 0.1544, 0.2668), radius=0.02),
        Obstacle("capsule", a=(-0.1, 0.05, 0.1), b=(-0.1, -0.05, 0.3), radius=0.02),
        Obstacle("box", center=(0.0, -0.15, 0.2), half_extents=(0.03, 0.03, 0.05)),
    ]

    def barrier_qp():
        barrier = BarrierRows(arm, dt, obstacles, margin=0.01, gamma=20.0)
        return QPController(arm, dt, gain=GAIN, damping=DAMPING, rate_limits=rates_of(arm), barrier=barrier)

    start, end = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0]), np.array([0.17, 1.0, 0.8, 0.19, -0.4, -0.5])
    t, Q, Qdot = minimum_jerk_path(np.array([start, end]), 1.5, 1 / dt)
    ref = reference_from_configurations(arm, t, Q, Qdot, "pose")
    run = simulate(barrier_qp(), ref, start)
    qp = barrier_qp()
    assert isinstance(qp.solver, ActiveSetStepSolver) and qp.barrier is not None
    qp.reset(run.q[600], run.x[600])
    active = 0
    for k in range(600, 900, 3):
        qp.barrier.step = k
        state = (run.q[k], run.x[k], ref.value[k], ref.rate[k])
        qdot = qp.command(*state)
        A, b = qp.barrier.A, qp.barrier.b  # the rows as the barrier made them for this step
        H, g = reference_qp(arm, *state)
        lb, ub = box(arm, run.q[k], dt)
        rows = np.isfinite(b)
        expected = qpsolvers.solve_qp(H, g, -A[rows], -b[rows], lb=lb, ub=ub, solver="quadprog")
        assert qp.status == "ok" and np.abs(qdot - expected).max() < TOLERANCE
        active += int(np.any(np.abs(A[rows] @ expected - b[rows]) < 1e-9))
    assert active >= 20, active  # the sphere holds the backbone back in about a quarter of these steps


def test_the_qp_active_set_preset_builds_the_structural_default():
    factory = load_preset("qp-active-set").build()
    solver = factory.create(6, 8, 3)
    assert isinstance(solver, ActiveSetStepSolver) and (solver.n, solver.rows) == (6, 3)
    assert isinstance(step_solver("qp_daqp", 6, 8), ActiveSetStepSolver)


def scratch_daqp(H, g, lb, ub, A=None, b=None):
    """daqp set up from scratch for this one QP (``daqp.solve``): the answer, or None when it finds none."""
    n = len(g)
    A = np.zeros((0, n)) if A is None else A[np.isfinite(b)]
    upper = np.concatenate([ub, np.full(len(A), 1e30)])
    lower = np.concatenate([lb, np.zeros(0) if b is None else b[np.isfinite(b)]])
    x, _, exitflag, _ = daqp.solve(np.ascontiguousarray(H), g, np.ascontiguousarray(A), upper, lower)
    return np.asarray(x) if exitflag == 1 else None


def test_the_installed_daqp_is_called_directly_where_its_structures_are_known():
    """A release DirectDaqp was checked against takes the direct path; any other falls back to daqp.Model."""
    known = metadata.version("daqp") in DIRECT_VERSIONS
    assert DirectDaqp.available() == known
    qp = controller(arm_of(2))
    state = random_states(qp.arm, 1, np.random.default_rng(0))[0]
    qp.command(*state)
    assert isinstance(qp.solver, ActiveSetStepSolver)
    assert isinstance(qp.solver.daqp, DirectDaqp if known else ModelDaqp)
    undirected = ActiveSetStepSolver(6, direct=False)
    assert not undirected._direct


def test_from_outside_the_limits_the_shut_box_opens_and_the_step_stays_exact(arm):
    """Closed loop from past theta_1's and S_2's limits: while the box of a variable is shut to one rate (lb = ub)
    daqp takes it as an equality; every step matches daqp set up from scratch and quadprog, also once it opens."""
    from optikin.control.reference import minimum_jerk_path, reference_from_configurations
    from optikin.control.simulate import simulate

    n = arm.n_config
    start = np.tile([0.18, 0.6, 0.3], arm.n_sections)
    start[2::3] = np.linspace(0.3, -1.0, arm.n_sections)
    inside = start + np.tile([-0.01, 0.4, 0.5], arm.n_sections)
    q0 = start.copy()
    q0[1] = arm.theta_max + 0.3
    q0[3] = arm.lower[3] - 0.004
    t, Q, Qdot = minimum_jerk_path(np.array([start, inside]), 0.5, 1 / DT, hold=0.2)
    ref = reference_from_configurations(arm, t, Q, Qdot, "pose")
    run = simulate(controller(arm), ref, q0)
    qp, model = (
        controller(arm),
        QPController(
            arm, DT, gain=GAIN, damping=DAMPING, rate_limits=rates_of(arm), solver=ActiveSetStepSolver(n, direct=False)
        ),
    )
    qp.reset(run.q[0], run.x[0])
    model.reset(run.q[0], run.x[0])
    shut = opened = 0
    for k in range(len(t) - 1):
        state = (run.q[k], run.x[k], ref.value[k], ref.rate[k])
        qdot = qp.command(*state).copy()
        assert qp.status == "ok"
        assert np.array_equal(qdot, model.command(*state)) and qp.solution.iterations == model.solution.iterations
        H, g = reference_qp(arm, *state)
        lb, ub = box(arm, run.q[k])
        assert np.abs(qdot - scratch_daqp(H, g, lb, ub)).max() < TOLERANCE
        closed = lb == ub
        shut += int(closed.any())
        if not closed.any():
            assert np.abs(qdot - qpsolvers.solve_qp(H, g, lb=lb, ub=ub, solver="quadprog")).max() < TOLERANCE
            opened += shut > 0
    assert shut >= 8 and opened >= 50


def test_another_daqp_release_falls_back_to_daqp_model_with_the_same_command(monkeypatch, caplog):
    from optikin.solvers.qp import qp_daqp

    qp = controller(arm_of(2))
    state = random_states(qp.arm, 1, np.random.default_rng(1))[0]
    expected = qp.command(*state).copy()
    monkeypatch.setattr(qp_daqp.metadata, "version", lambda name: "99.0.0")
    qp_daqp._library.cache_clear()
    try:
        with caplog.at_level(logging.INFO, logger="optikin.solvers.qp.qp_daqp"):
            fallback = controller(arm_of(2))
            qdot = fallback.command(*state)
        assert isinstance(fallback.solver.daqp, ModelDaqp)
        assert np.abs(qdot - expected).max() <= 1e-12
        assert "daqp 99.0.0: DirectDaqp was written for" in caplog.text
    finally:
        qp_daqp._library.cache_clear()


@pytest.mark.skipif(not DirectDaqp.available(), reason="DirectDaqp was not checked against this daqp release")
@pytest.mark.parametrize("rows", [0, ROWS])
def test_the_direct_calls_give_the_bits_of_daqp_model(arm, rows):
    """Random states (bounds active), given rows cutting the optimum and infeasible steps: DirectDaqp and
    daqp.Model answer with the same bits, exit flags and iterations, and both recover after a failure."""
    rng = np.random.default_rng(30 + arm.n_sections + rows)
    n = arm.n_config
    given = [GivenRows(n, rows), GivenRows(n, rows)] if rows else [None, None]
    direct = controller(arm, given[0])
    model = QPController(
        arm,
        DT,
        gain=GAIN,
        damping=DAMPING,
        rate_limits=rates_of(arm),
        margin=MARGIN,
        barrier=given[1],
        solver=ActiveSetStepSolver(n, rows=rows, direct=False),
    )
    states = random_states(arm, 8, rng) + random_states(arm, 12, rng, near_limits=True)
    failures = 0
    for k, state in enumerate(states):
        if rows:
            box_only, lb, ub = reference_step(arm, *state)
            inside = lb + rng.uniform(0.2, 0.8, n) * (ub - lb)
            A = rng.normal(size=(rows, n))
            A *= np.sign(A @ inside - A @ box_only)[:, None]
            b = A @ inside
            if k % 5 == 4:
                b[0] = np.maximum(A[0] * lb, A[0] * ub).sum() + 1.0  # infeasible
            for rows_now in given:
                rows_now.next = (A, b)
        qdot = direct.command(*state).copy()
        assert np.array_equal(qdot, model.command(*state))
        assert (direct.status, direct.slip) == (model.status, model.slip)
        assert direct.solution.iterations == model.solution.iterations
        failures += direct.status != "ok"
    assert isinstance(direct.solver.daqp, DirectDaqp) and isinstance(model.solver.daqp, ModelDaqp)
    assert failures == (4 if rows else 0)


class Scripted:
    """A step solver answering with given rates, as an array of its own, a new one, a view or a list."""

    name = "scripted"

    def __init__(self, n):
        self.kept, self.answers = np.zeros(n), []

    def solve(self, data):
        x, how = self.answers.pop(0)
        if how == "kept":
            self.kept[:] = x
            x = self.kept
        elif how == "strided":
            x = np.repeat(x, 2)[::2]
        elif how == "float32":
            x = x.astype(np.float32)
        elif how == "list":
            x = list(x)
        return Solution(x, "ok")


def test_the_projection_onto_the_box_is_np_clip_whatever_array_the_solver_returns():
    arm = arm_of(2)
    n = arm.n_config
    solver = Scripted(n)
    qp = QPController(arm, DT, gain=GAIN, damping=DAMPING, rate_limits=rates_of(arm), solver=solver)
    rng = np.random.default_rng(7)
    states = random_states(arm, 12, rng, near_limits=True)
    hows = ["kept", "kept", "new", "strided", "kept", "float32", "list", "new", "kept", "new", "kept", "strided"]
    for state, how in zip(states, hows):
        lb, ub = box(arm, state[0])
        x = lb + rng.uniform(-0.5, 1.5, n) * (ub - lb)  # some rates outside the box
        solver.answers.append((x, how))
        qdot = qp.command(*state)
        x_read = x.astype(np.float32).astype(float) if how == "float32" else x
        assert qp.status == "ok" and np.array_equal(qdot, np.clip(x_read, lb, ub))
        assert qp.slip == np.abs(np.clip(x_read, lb, ub) - x_read).max()
    x = np.zeros(n)
    x[2] = np.inf
    solver.answers.append((x, "kept"))
    qp.command(*states[0])
    assert qp.status == "fallback (hold): non-finite solution" and qp.slip == 0.0
