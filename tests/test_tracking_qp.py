"""The per-step tracking QP: rate bounds from configuration limits, backend agreement, failures and fallbacks.

Cross-checks are independent of the controller's code: bounds recomputed by
hand, the QP solved by scipy's bounded-variable least squares (BVLS) on the
stacked system [J; sqrt(lambda) I] qdot = [v; 0] with J from the arm's
Jacobian, the unconstrained step from the damped least-squares formula, and
OSQP's public Python API. Every backend is reached through its registered
step solver (:mod:`optikin.solvers.qp`), answering ``solve(QPData) -> Solution``.
"""

from __future__ import annotations

import shutil

import numpy as np
import osqp
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.limits import RateBounds
from optikin.control.qp import QPController
from optikin.control.task import TaskModel, upper_triangle_csc_indices
from optikin.solvers.base import Solution
from optikin.solvers.qp import step_solver
from optikin.solvers.qp.qp_osqp import OSQPOptions, OSQPStepSolver
from optikin.solvers.qp.qp_qpsolvers import installed_solvers

ARM = ConstantCurvatureArm()
DT = 0.01
DAMPING = 1e-4
GAIN = 20.0


def tip(q):
    return np.asarray(ARM.fk_dq(q)).ravel()


def hand_bounds(q, dt=DT):
    """Rate box written out: default rate limits, limits 1e-9 inside, phi free, both ends clipped to the rates."""
    rate = np.array([0.1, np.pi, 2 * np.pi] * 2)
    lb = np.clip((ARM.lower + 1e-9 - q) / dt, -rate, rate)
    ub = np.clip((ARM.upper - 1e-9 - q) / dt, -rate, rate)
    lb[[2, 5]], ub[[2, 5]] = -rate[[2, 5]], rate[[2, 5]]
    return lb, ub


def bounded_least_squares(q, x_ref):
    """The QP solved independently: BVLS on [J; sqrt(lambda) I] with the hand-made bounds."""
    J = np.asarray(ARM.jac_dq(q))
    v = GAIN * (x_ref - tip(q))
    lb, ub = hand_bounds(q)
    A = np.vstack([J, np.sqrt(DAMPING) * np.eye(6)])
    b = np.concatenate([v, np.zeros(6)])
    return lsq_linear(A, b, bounds=(lb, ub), method="bvls", tol=1e-14).x, lb, ub


def outside_by(q):
    """Distance of each variable outside its limits (phi, periodic, never)."""
    excess = np.maximum(q - ARM.upper, 0.0) + np.maximum(ARM.lower - q, 0.0)
    excess[[2, 5]] = 0.0
    return excess


def near_limit_problems(count, seed=3):
    """Configurations next to the theta_1 limit with a reference pulling across it."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        q = ARM.sample_configurations(1, rng)[0]
        q[1] = ARM.upper[1] - 0.003
        q_ref = q + rng.normal(size=6) * np.array([0.01, 0.3, 0.3, 0.01, 0.3, 0.3])
        out.append((q, tip(q), tip(q_ref)))
    return out


def qp_controller(backend="qp_osqp", fallback="hold", **options):
    """The QP controller of the tests (pose task) with a step solver of ``backend`` and ``options``."""
    return QPController(
        ARM, DT, "pose", gain=GAIN, damping=DAMPING, fallback=fallback, solver=step_solver(backend, 6, 8, **options)
    )


def command(controller, q, x, x_ref):
    return controller.command(q, x, x_ref, np.zeros_like(x_ref)).copy()


# --------------------------------------------------------------------------- rate bounds


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-1.0, 2.0), min_size=6, max_size=6),
    st.floats(1e-3, 1e-2),
    st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6),
)
def test_rate_bounds_are_never_empty_and_never_let_a_limit_be_crossed(fractions, dt, pick):
    """Anywhere, also far outside the limits: lb <= ub, and any rate in the box keeps or brings q inside."""
    span = ARM.upper - ARM.lower
    q = ARM.lower + np.asarray(fractions) * span  # up to one span below / past the limits
    bounds = RateBounds(ARM, dt)
    bounds.update(q)
    assert np.all(bounds.lb <= bounds.ub)
    assert np.all(np.abs(bounds.lb) <= bounds.rate) and np.all(np.abs(bounds.ub) <= bounds.rate)
    qdot = bounds.lb + np.asarray(pick) * (bounds.ub - bounds.lb)
    before, after = outside_by(q), outside_by(q + dt * qdot)
    assert np.all(after[before == 0] == 0.0)
    outside = before > 0
    expected = np.maximum(before - bounds.rate * dt, 0.0)  # back at the full rate, never farther out
    assert np.all(after[outside] <= expected[outside] + 1e-12)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(-1.0, 2.0), min_size=6, max_size=6),
    st.floats(0.05, 1.0),
    st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6),
)
def test_a_limit_gain_below_one_still_never_takes_the_arm_farther_out(fractions, gain, pick):
    q = ARM.lower + np.asarray(fractions) * (ARM.upper - ARM.lower)
    bounds = RateBounds(ARM, DT, gain=gain)
    bounds.update(q)
    assert np.all(bounds.lb <= bounds.ub)
    qdot = bounds.lb + np.asarray(pick) * (bounds.ub - bounds.lb)
    before, after = outside_by(q), outside_by(q + DT * qdot)
    assert np.all(after[before == 0] == 0.0)
    assert np.all(after <= np.maximum((1 - gain) * before, before - bounds.rate * DT) + 1e-12)


def test_rate_bounds_reject_a_margin_that_closes_the_range():
    with pytest.raises(ValueError, match="margin"):
        RateBounds(ARM, DT, margin=0.05)


# --------------------------------------------------------------------------- backends


def backend_choices():
    choices = [("qp_osqp", {})] + [("qp_qpsolvers", {"solver": s}) for s in installed_solvers()]
    return choices + [
        ("qp_cvxpy", {"solver": "CLARABEL"}),
        ("qp_cvxpy", {"solver": "OSQP"}),
        ("qp_cvxpy_rebuild", {"solver": "CLARABEL"}),
    ]


@pytest.mark.parametrize("backend,options", backend_choices(), ids=lambda v: str(v))
def test_every_backend_gives_the_bounded_least_squares_step(backend, options):
    controller = qp_controller(backend, **options)
    active = 0
    for q, x, x_ref in near_limit_problems(4):
        expected, lb, ub = bounded_least_squares(q, x_ref)
        active += int(np.sum((expected <= lb + 1e-9) | (expected >= ub - 1e-9)))
        qdot = command(controller, q, x, x_ref)
        assert controller.status == "ok"
        assert isinstance(controller.solution, Solution) and controller.solution.ok
        assert controller.solution.seconds > 0
        assert np.all(qdot >= lb) and np.all(qdot <= ub)
        np.testing.assert_allclose(qdot, expected, atol=1e-4, rtol=0)
    assert active >= 4  # the data really exercise the bounds


def test_unconstrained_step_is_damped_least_squares():
    rng = np.random.default_rng(0)
    q = ARM.sample_configurations(1, rng)[0]
    q[[1, 4]] = 0.5, -0.7  # well inside every limit
    x_ref = tip(q + 1e-3 * rng.normal(size=6))
    x_dot_ref = tip(q + 1e-3) - tip(q)
    controller = qp_controller()
    qdot = controller.command(q, tip(q), x_ref, x_dot_ref)
    J = np.asarray(ARM.jac_dq(q))
    v = x_dot_ref + GAIN * (x_ref - tip(q))
    np.testing.assert_allclose(qdot, np.linalg.solve(J.T @ J + DAMPING * np.eye(6), J.T @ v), atol=1e-5)


@pytest.mark.parametrize("fast_path", [True, False])
def test_osqp_fast_path_matches_the_public_api(fast_path):
    """The backend's answers against a fresh osqp problem set up through the public API; without
    the private handle (``fast_path=False``: an osqp release without it) the backend uses that API."""
    rng = np.random.default_rng(1)
    n = 6
    backend = OSQPStepSolver(n, 8, OSQPOptions())
    if not fast_path:
        backend._solver = None
    rows, cols = upper_triangle_csc_indices(n)
    for _ in range(3):
        J = rng.normal(size=(8, n))
        H = J.T @ J + 1e-3 * np.eye(n)
        g, lb = rng.normal(size=n), -rng.uniform(0.1, 1, n)
        ub = rng.uniform(0.1, 1, n)
        data = type("Data", (), {"H_upper": H[rows, cols], "g": g, "lb": lb, "ub": ub})
        solution = backend.solve(data)
        assert solution.status == "ok" and solution.iterations > 0 and solution.seconds > 0
        assert set(solution.extras) == {"primal_residual", "dual_residual"}
        fast = solution.x.copy()
        public = osqp.OSQP()
        public.setup(
            sp.csc_matrix(np.triu(H)),
            g,
            sp.identity(n, format="csc"),
            lb,
            ub,
            verbose=False,
            eps_abs=1e-9,
            eps_rel=1e-9,
            polishing=False,
        )
        np.testing.assert_allclose(fast, public.solve(raise_error=True).x, atol=1e-5)


# --------------------------------------------------------------------------- failures


class RaisingSolver:
    name = "raising"

    def solve(self, data):
        raise RuntimeError("solver crashed")


class EmptySolver:
    name = "empty"

    def solve(self, data):
        return Solution(np.full(data.n, np.nan), "failed", message="no solution")


class NaNSolver:
    name = "nan"

    def solve(self, data):
        return Solution(np.full(data.n, np.nan), "ok")


@pytest.mark.parametrize(
    "solver,reason",
    [
        (RaisingSolver(), "raised RuntimeError: solver crashed"),
        (EmptySolver(), "no solution"),
        (NaNSolver(), "non-finite"),
    ],
)
@pytest.mark.parametrize("fallback", ["hold", "damped_least_squares"])
def test_a_failing_solver_is_reported_and_the_fallback_stays_inside_the_bounds(solver, reason, fallback):
    q, x, x_ref = near_limit_problems(1)[0]
    q_outside = q.copy()
    q_outside[3] = ARM.upper[3] + 0.01  # S2 past its limit: the fallback must steer back
    controller = QPController(ARM, DT, "pose", gain=GAIN, damping=DAMPING, solver=solver, fallback=fallback)
    for q_now in (q, q_outside):
        qdot = command(controller, q_now, tip(q_now), x_ref)
        assert controller.status.startswith(f"fallback ({fallback})") and reason in controller.status
        lb, ub = hand_bounds(q_now)
        assert np.all(qdot >= lb) and np.all(qdot <= ub)
        assert np.all(np.isfinite(qdot))
    assert qdot[3] == pytest.approx(-0.1)  # back at the full S rate
    if fallback == "hold":
        command(controller, q, x, x_ref)
        assert np.all(controller.qdot == 0.0)


def test_an_osqp_iteration_limit_is_a_reported_failure():
    q, x, x_ref = near_limit_problems(1)[0]
    controller = qp_controller(max_iter=1, check_termination=1)
    command(controller, q, x, x_ref)
    assert controller.status.startswith("fallback (hold)") and "maximum iterations" in controller.status
    solution = controller.solution
    assert solution.status == "failed" and "maximum iterations" in solution.message
    assert np.all(np.isnan(solution.x)) and solution.iterations == 1


def test_a_loose_osqp_tolerance_would_let_bounds_slip_and_the_projection_removes_it():
    """OSQP's default eps = 1e-3 returns rates outside the box by ~1e-4..1e-3; the chosen 1e-7 by < 1e-6."""
    loose = qp_controller(eps_abs=1e-3, eps_rel=1e-3)
    tight = qp_controller()
    loose_slips, tight_slips = [], []
    for q, x, x_ref in near_limit_problems(5):
        _, lb, ub = bounded_least_squares(q, x_ref)
        for controller, slips in ((loose, loose_slips), (tight, tight_slips)):
            qdot = command(controller, q, x, x_ref)
            slips.append(controller.slip)
            assert np.all(qdot >= lb) and np.all(qdot <= ub)
    assert max(loose_slips) > 1e-5
    assert max(tight_slips) < 1e-6


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs a C compiler")
def test_compiled_task_function_gives_the_same_qp_data_as_the_casadi_virtual_machine():
    q, x, x_ref = near_limit_problems(1)[0]
    data = []
    for compiled in (False, True):
        model = TaskModel(ARM, "pose", compiled=compiled)
        model.set_gains(np.arange(1.0, 9.0), DAMPING)
        model.evaluate(q, x, x_ref, 0.1 * x_ref)
        data.append([a.copy() for a in (model.J, model.e, model.v, model.H, model.H_upper, model.g)])
    for vm, compiled in zip(*data):
        np.testing.assert_allclose(compiled, vm, rtol=1e-13, atol=1e-15)
    J = np.asarray(ARM.jac_dq(q))
    np.testing.assert_allclose(data[0][0], J, atol=1e-15)
    rows, cols = upper_triangle_csc_indices(6)
    np.testing.assert_allclose(data[0][4], (J.T @ J + DAMPING * np.eye(6))[rows, cols], atol=1e-14)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs a C compiler")
@pytest.mark.parametrize("compiled", [False, True])
def test_the_rate_box_is_the_hand_made_one_also_compiled_and_read_in_place(compiled):
    """RateBounds against the box written out in numpy (the same operations, so the same bits), through
    update(q) and through refresh() on a configuration array the box reads in place."""
    rng = np.random.default_rng(8)
    bounds, shared = RateBounds(ARM, DT, compiled=compiled), RateBounds(ARM, DT, compiled=compiled)
    q_in = np.zeros(6)
    shared.read_configuration_from(q_in)
    for fractions in rng.uniform(-1.0, 2.0, size=(20, 6)):
        q = ARM.lower + fractions * (ARM.upper - ARM.lower)
        bounds.update(q)
        q_in[:] = q
        shared.refresh()
        lb, ub = hand_bounds(q)
        for box in (bounds, shared):
            np.testing.assert_array_equal(box.lb, lb)
            np.testing.assert_array_equal(box.ub, ub)
    with pytest.raises(ValueError, match="C-contiguous float64"):
        shared.read_configuration_from(np.zeros(12)[::2])


def test_the_tip_pose_of_the_two_section_arm_has_five_independent_directions():
    """Why J J^+ != I for the pose task (seed 000 eq. 39 assumes it): the 8 x 6 Jacobian has rank 5.

    Checked on central finite differences of fk_dq (not the symbolic Jacobian) at random configurations.
    """
    rng = np.random.default_rng(5)
    for q in ARM.sample_configurations(5, rng):
        J = np.array([(tip(q + h) - tip(q - h)) / 2e-6 for h in 1e-6 * np.eye(6)]).T
        s = np.linalg.svd(J, compute_uv=False)
        assert s[4] > 1e-2 and s[5] < 1e-8
        Jp = np.array(
            [
                (np.asarray(ARM.fk_position(q + h)).ravel() - np.asarray(ARM.fk_position(q - h)).ravel()) / 2e-6
                for h in 1e-6 * np.eye(6)
            ]
        ).T
        assert np.linalg.svd(Jp, compute_uv=False)[2] > 1e-2  # position: full rank 3, so J J^+ = I
