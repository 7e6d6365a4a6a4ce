"""The MPC (one sparse QP per step) and its IPOPT reference.

Cross-checks are independent of the controllers' code: the QP step in closed form (damped least
squares) and by scipy's bounded-variable least squares, the horizon QP solved densely by cvxpy
(Clarabel), the horizon's predictions rebuilt from the arm's own Jacobian, and the MPC's
nonlinear reference by IPOPT.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.mpc import MPCController
from optikin.control.mpc_nlp import NonlinearMPCController
from optikin.control.obstacles import BarrierRows, Obstacle
from optikin.control.reference import minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import simulate
from optikin.errors import SpecError
from optikin.runner import solve

ARM = ConstantCurvatureArm()
DT = 0.01
GAIN = 10.0
DAMPING = 1e-4
Q0 = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0])
EXACT = dict(eps_abs=1e-12, eps_rel=1e-12, polishing=True, max_iter=20000)  # OSQP to the active-set answer


def tip(q):
    return np.asarray(ARM.fk_dq(q)).ravel()


def jacobian(q):
    return np.asarray(ARM.jac_dq(q))


def a_reference_step(offset, rates):
    """A measured pose at ``Q0`` and a reference at ``Q0 + offset`` moving with configuration rates ``rates``."""
    q_ref = Q0 + offset
    return tip(Q0), tip(q_ref), jacobian(q_ref) @ rates


@pytest.mark.parametrize(
    "offset, rates",
    [
        (np.array([0.002, 0.02, 0.03, -0.001, 0.02, 0.01]), np.array([0.01, 0.1, 0.1, 0.0, -0.1, 0.2])),
        (np.array([0.01, 0.3, -0.2, 0.01, 0.3, 0.2]), np.array([0.05, 1.0, 1.0, 0.0, -1.0, 2.0])),  # box active
    ],
    ids=["inside the box", "box active"],
)
def test_a_horizon_of_one_without_obstacles_is_the_qp_step(offset, rates):
    """N = 1: ``min 1/2 ||J u - v||^2 + 1/2 lambda ||u||^2`` over the box, ``lambda = effort_weight = damping``."""
    x, x_ref, xdot_ref = a_reference_step(offset, rates)
    mpc = MPCController(ARM, DT, "pose", GAIN, DAMPING, horizon=1, **EXACT)
    mpc.reset(Q0, x)
    u = mpc.command(Q0, x, x_ref, xdot_ref).copy()
    assert mpc.status == "ok"
    J, v = jacobian(Q0), xdot_ref + GAIN * (x_ref - x)
    rate = np.array([0.1, np.pi, 2 * np.pi] * 2)
    lb = np.clip((ARM.lower + 1e-9 - Q0) / DT, -rate, rate)
    ub = np.clip((ARM.upper - 1e-9 - Q0) / DT, -rate, rate)
    lb[[2, 5]], ub[[2, 5]] = -rate[[2, 5]], rate[[2, 5]]
    stacked = np.vstack([J, np.sqrt(DAMPING) * np.eye(6)])
    expected = lsq_linear(stacked, np.concatenate([v, np.zeros(6)]), bounds=(lb, ub), method="bvls", tol=1e-15).x
    if np.all((expected > lb + 1e-6) & (expected < ub - 1e-6)):
        np.testing.assert_allclose(expected, np.linalg.solve(J.T @ J + DAMPING * np.eye(6), J.T @ v), atol=1e-10)
    else:
        assert np.any(np.isclose(expected, lb) | np.isclose(expected, ub))
    np.testing.assert_allclose(u, expected, rtol=0, atol=1e-8)


def obstacle_run(horizon=8, rate=100.0, effort_weight=DAMPING, **options):
    """The MPC around the sphere of ``problems/mpc-obstacle.yaml`` along its path."""
    start, end = Q0, np.array([0.17, 1.0, 0.8, 0.19, -0.4, -0.5])
    t, Q, Qdot = minimum_jerk_path(np.array([start, end]), 1.0, rate, hold=0.3)
    reference = reference_from_configurations(ARM, t, Q, Qdot, "pose")
    barrier = BarrierRows(ARM, 1 / rate, [Obstacle("sphere", center=(0.1554, 0.1544, 0.2668), radius=0.02)])
    mpc = MPCController(
        ARM, 1 / rate, "pose", GAIN, effort_weight, horizon=horizon, barrier=barrier, preview=reference, **options
    )
    return mpc, reference, barrier


def test_the_sparse_horizon_qp_agrees_with_a_dense_solve_and_predicts_with_the_arms_jacobian():
    """With ``lambda = 1e-2``: the pose Jacobian has rank 5, so with the closed loop's ``1e-4`` one direction
    of each rate is held by ``lambda`` alone and a change of 1e-4 rad/s in it moves the cost by 1e-12."""
    cvxpy = pytest.importorskip("cvxpy")
    mpc, reference, barrier = obstacle_run(effort_weight=1e-2, **EXACT)
    run = simulate(mpc, reference, Q0)
    checked = 0
    for k in (30, 45, 60):  # approaching and along the sphere
        mpc.reset(run.q[k], run.x[k])
        mpc.k = barrier.step = k
        mpc.command(run.q[k], run.x[k], reference.value[k], reference.rate[k])
        assert mpc.status == "ok"
        P, A, lower, upper = mpc.qp.dense()
        z = cvxpy.Variable(P.shape[0])
        low, high = np.isfinite(lower), np.isfinite(upper)
        problem = cvxpy.Problem(
            cvxpy.Minimize(0.5 * cvxpy.quad_form(z, cvxpy.psd_wrap(P))),
            [A[low] @ z >= lower[low], A[high] @ z <= upper[high]],
        )
        problem.solve(solver="CLARABEL", tol_gap_abs=1e-11, tol_gap_rel=1e-11, tol_feas=1e-11)
        n, N = 6, mpc.N
        np.testing.assert_allclose(mpc.z[: N * n], z.value[: N * n], rtol=0, atol=1e-6)
        # the prediction: y_j = sum_{i<j} u_i, s_j = (w_j - x_j) / dt with x_{j+1} = x_j + dt J(qbar_j) u_j
        u = mpc.z[: N * n].reshape(N, n)
        y = mpc.z[N * n : 2 * N * n].reshape(N, n)
        np.testing.assert_allclose(y, np.cumsum(u, axis=0), atol=1e-9)
        x = run.x[k] + mpc.dt * np.cumsum([jacobian(qbar) @ uj for qbar, uj in zip(mpc.qbar, u)], axis=0)
        e = reference.value[k] - run.x[k]
        rates = reference.rate[np.minimum(k + np.arange(N), len(reference.t) - 1)]
        w = run.x[k] + mpc.dt * np.cumsum(rates + GAIN * e * (1 - mpc.dt * GAIN) ** np.arange(N)[:, None], axis=0)
        np.testing.assert_allclose(mpc.z[2 * N * n :].reshape(N, 8), (w - x) / mpc.dt, atol=1e-7)
        checked += int(np.any(A[mpc.qp.row_barrier :] @ mpc.z <= lower[mpc.qp.row_barrier :] + 1e-7))
    assert checked  # a barrier row is active on at least one of the steps


def test_the_mpc_keeps_the_whole_backbone_clear_in_the_shipped_scenario():
    result, _ = solve("mpc-obstacle", figures=False, overrides=[("baselines", ["mpc", "pseudo_inverse"])])
    rows = {row.method: row.metrics for row in result.comparison}
    assert result.criteria["no penetration (mpc)"] and result.criteria["no penetration"]
    spacing = 0.198 / 20  # S_max / ceil(S_max / margin): the samples' spacing
    for name in ("qp", "mpc"):
        assert result.arrays[f"clearance_{name}"].min() > spacing / 2  # between the samples too
        assert result.arrays[f"clearance_{name}"].min() >= 0.01 - 1e-3  # the margin, up to OSQP's eps / gamma
    assert rows["mpc (osqp)"]["penetrations"] == 0 and rows["mpc (osqp)"]["fallbacks"] == 0
    assert rows["pseudo-inverse"]["penetrations"] > 0 and rows["pseudo-inverse"]["depth [mm]"] > 5
    assert rows["mpc (osqp)"]["final [mm]"] < 0.05 and rows["mpc (osqp)"]["outside limits"] == 0


def test_ipopt_and_the_qp_path_agree_on_a_mild_problem():
    """Near the reference, away from obstacles and limits: the linearisation costs O(dt^2) per step."""
    offset, rates = np.array([0.001, 0.01, 0.02, -0.001, 0.01, 0.01]), np.array([0.01, 0.1, 0.1, 0.0, -0.1, 0.2])
    x, x_ref, xdot_ref = a_reference_step(offset, rates)
    commands = []
    for controller in (
        MPCController(ARM, DT, "pose", GAIN, DAMPING, horizon=5, **EXACT),
        NonlinearMPCController(ARM, DT, "pose", GAIN, DAMPING, horizon=5, tolerance=1e-12),
    ):
        controller.reset(Q0, x)
        commands.append(controller.command(Q0, x, x_ref, xdot_ref).copy())
        assert controller.status == "ok"
    scale = np.abs(commands[1]).max()
    assert scale > 0.05
    np.testing.assert_allclose(commands[0], commands[1], rtol=0, atol=0.01 * scale)


def test_a_horizon_of_zero_is_an_error_naming_the_field():
    with pytest.raises(SpecError) as error:
        solve("mpc-obstacle", figures=False, overrides=[("options.mpc.horizon", 0)])
    assert error.value.field == "options.mpc.horizon"
    with pytest.raises(ValueError, match="horizon must be"):
        MPCController(ARM, DT, horizon=0)
    with pytest.raises(SpecError) as error:
        solve("mpc-obstacle", figures=False, overrides=[("options.gain", 200.0)])
    assert error.value.field == "options.mpc" and "gain dt" in str(error.value)


def test_an_infeasible_horizon_is_a_reported_step_status():
    """A sphere rushing at the arm at 3 m/s: within the horizon no rate keeps its rows. While the
    present step's rows can be kept, they are (``first step``); once not even they can, the arm
    holds; every such step says so in its status."""
    rate = 100.0
    t, Q, Qdot = minimum_jerk_path(np.array([Q0, Q0]), 0.2, rate)
    reference = reference_from_configurations(ARM, t, Q, Qdot, "pose")
    points = BarrierRows(ARM, 1 / rate, [Obstacle("sphere", center=(1, 1, 1), radius=0.01)]).distances.points_at(Q0)
    away = points[:, points.shape[1] // 2] + np.array([0.3, 0.0, 0.0])  # 0.3 m beside the middle of the backbone
    rushing = Obstacle("sphere", center=tuple(away), radius=0.02, path=((0.0, 0.0, 0.0, 0.0), (0.1, -0.3, 0.0, 0.0)))
    barrier = BarrierRows(ARM, 1 / rate, [rushing], margin=0.01, gamma=20.0)
    mpc = MPCController(ARM, 1 / rate, "pose", GAIN, DAMPING, horizon=10, barrier=barrier, max_iter=400)
    run = simulate(mpc, reference, Q0)
    assert run.status[0].startswith("fallback (first step): horizon")  # the sphere is 0.2 m away: this step is fine
    assert any(s.startswith("fallback (hold): horizon") for s in run.status)
    assert all(s.startswith(("fallback (first step): horizon", "fallback (hold): horizon")) for s in run.status)
    assert run.metrics()["fallback steps"] == len(run.status)


def test_a_moving_obstacles_rows_along_the_horizon_follow_its_distances():
    """For the arm held at ``q``, the horizon's row ``j`` of sample ``i`` is the barrier at ``t_{k+j}``,
    ``-gamma (d_i(t_{k+j}) - d_safe) - (d_i(t_{k+j+1}) - d_i(t_{k+j})) / dt``, with the distances of the
    obstacle translated along its path (closed form), to first order in the translation: halving the
    obstacle's speed quarters the difference."""
    from optikin.control.mpc import HorizonBarrier

    k, N, gamma, margin = 20, 10, 20.0, 0.01

    def differences(speed):
        path = ((k * DT, 0.0, 0.0, 0.0), (k * DT + 1, -0.05 * speed, 0.02 * speed, 0.01 * speed))  # leaves at t_k
        mover = Obstacle("sphere", center=(0.12, 0.0, 0.2), radius=0.02, path=path)
        barrier = BarrierRows(ARM, DT, [mover], margin=margin, gamma=gamma)
        horizon = HorizonBarrier(barrier, N)
        barrier.step = k
        horizon.update(Q0)
        assert barrier.step == k + 1  # the barrier's clock counted the present step only
        points = barrier.distances.points_at(Q0)
        nearest = points[:, np.argsort(mover.distances(points, k * DT))[:3]]
        d = np.array([mover.distances(nearest, (k + j) * DT) for j in range(N + 1)])
        expected = -gamma * (d[:-1] - margin) - np.diff(d, axis=0) / DT
        return np.abs(np.sort(horizon.b, axis=1) - np.sort(expected, axis=1)).max(axis=1)

    full, half = differences(1.0), differences(0.5)
    assert 0 < full[-1] < 1e-2  # m/s
    np.testing.assert_allclose(full / half, 4.0, rtol=0.1)
