"""Backbone obstacles: signed distances against closed forms, the distance Jacobian against finite
differences, the barrier QP against an independent solver, and bad obstacle input."""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.obstacles import BackboneDistances, BarrierRows, Obstacle, sampling_density
from optikin.errors import OptikinError
from optikin.solvers.qp.common import QPData, upper_triangle_csc_indices
from optikin.solvers.qp.qp_osqp import OSQPOptions, OSQPStepSolver

ARM = ConstantCurvatureArm()
Q = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0])
OBSTACLES = [
    Obstacle("sphere", center=(0.1, 0.0, 0.25), radius=0.04),
    Obstacle("capsule", a=(-0.1, 0.05, 0.1), b=(-0.1, -0.05, 0.3), radius=0.02),
    Obstacle("box", center=(0.0, 0.15, 0.2), half_extents=(0.03, 0.03, 0.05), path=((0, 0, 0, 0), (1, 0.1, 0, 0))),
    Obstacle("halfspace", point=(0.0, 0.0, -0.01), normal=(0.0, 0.0, 2.0)),
]


def test_signed_distances_match_closed_forms():
    p = np.array([[0.3, 0.0, 0.25], [0.1, 0.0, 0.26], [-0.1, -0.1, 0.45], [0.0, 0.15, 0.2], [0.0, 0.0, 0.5]]).T
    sphere, capsule, box, plane = OBSTACLES
    np.testing.assert_allclose(sphere.distances(p), np.linalg.norm(p.T - [0.1, 0, 0.25], axis=1) - 0.04, atol=1e-11)
    # capsule: beyond the end b, the distance is to b
    assert capsule.distances(p[:, 2:3])[0] == pytest.approx(np.linalg.norm([0, -0.05, 0.15]) - 0.02, abs=1e-11)
    # box moving +0.1 m in x over 1 s: at t = 1 its centre is (0.1, 0.15, 0.2); the point (0, 0.15, 0.2) is 0.07 out
    assert box.distances(p[:, 3:4], 0.0)[0] == pytest.approx(-0.03, abs=1e-11)
    assert box.distances(p[:, 3:4], 1.0)[0] == pytest.approx(0.07, abs=1e-11)
    np.testing.assert_allclose(plane.distances(p), p[2] + 0.01, atol=1e-12)


def test_distance_jacobian_matches_finite_differences():
    d = BackboneDistances(ARM, OBSTACLES, 10)
    offsets = d.offsets(0.4)
    d.evaluate(Q, offsets)
    flat = np.arange(len(OBSTACLES) * d.samples)
    D = d.jacobian(flat)
    fd = np.empty_like(D)
    for i in range(ARM.n_config):
        step = np.zeros(ARM.n_config)
        step[i] = 1e-6
        d.evaluate(Q + step, offsets)
        up = d.d.ravel().copy()
        d.evaluate(Q - step, offsets)
        fd[:, i] = (up - d.d.ravel()) / 2e-6
    np.testing.assert_allclose(D, fd, atol=1e-7)


def test_sampling_density_keeps_half_the_spacing_within_half_the_margin():
    pps = sampling_density(ARM, 0.01)
    assert ARM.upper[0] / pps / 2 <= 0.005 < ARM.upper[0] / (pps - 1) / 2


def test_barrier_rows_with_osqp_match_daqp_and_hold_the_linearised_barrier():
    qpsolvers = pytest.importorskip("qpsolvers")
    barrier = BarrierRows(ARM, 0.002, OBSTACLES[:3], margin=0.01, gamma=20.0)
    barrier.update(Q)
    rng = np.random.default_rng(1)
    J, v = rng.standard_normal((8, 6)), 5.0 * rng.standard_normal(8)
    H, g = J.T @ J + 1e-4 * np.eye(6), -J.T @ v
    rows, cols = upper_triangle_csc_indices(6)
    data = QPData(J, v, 1e-4, H, H[rows, cols], g, -np.full(6, 3.0), np.full(6, 3.0), barrier.A, barrier.b)
    x = OSQPStepSolver(6, 8, OSQPOptions(), rows=barrier.rows).solve(data).x
    active = np.isfinite(barrier.b)
    ref = qpsolvers.solve_qp(H, g, -barrier.A[active], -barrier.b[active], lb=data.lb, ub=data.ub, solver="daqp")
    np.testing.assert_allclose(x, ref, atol=1e-5)
    assert np.all(barrier.A @ x >= barrier.b - 1e-6)


@pytest.mark.parametrize(
    "obstacle, words",
    [
        ({"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 0.02}, "base"),
        ({"type": "sphere", "center": [0.05, 0.015, 0.169], "radius": 0.02}, "start configuration"),
        ({"type": "sphere", "center": [0.5, 0.5, 0.5]}, "radius"),
        ({"type": "box", "center": [0.5, 0.5, 0.5], "half_extents": [0.1, 0.1, 0.1], "radius": 0.1}, "radius"),
    ],
)
def test_bad_obstacles_are_errors_naming_the_field(obstacle, words):
    from optikin.runner import solve

    with pytest.raises(OptikinError, match=r"options\.obstacles\.0") as info:
        solve("track-obstacle-sphere", figures=False, overrides=[("options.obstacles", [obstacle])])
    assert words in str(info.value)


@pytest.mark.parametrize("name", ["track-obstacle-sphere", "track-obstacle-moving"])
def test_shipped_scenarios_keep_the_whole_backbone_clear_and_report_the_baselines_penetrations(name):
    from optikin.runner import solve

    result, _ = solve(name, figures=False)
    assert result.status_counts() == {"ok": result.samples}
    assert result.criteria["no penetration"]
    margin = 0.01
    # every sample, every step: outside the obstacles; between samples too (spacing/2 < least sample distance)
    clearance = result.arrays["clearance_qp"]
    assert clearance.min() > 0.198 / 20 / 2  # S_max 0.198 m, sampling density ceil(S_max / margin) = 20 per section
    assert clearance.min() >= margin - 1e-4  # the barrier holds the margin up to its linearisation
    rows = {row.method: row.metrics for row in result.comparison}
    for method in ("mrac", "pseudo-inverse", "damped least squares"):
        assert rows[method]["penetrations"] > 0  # they know no obstacle; counted, not hidden
        assert any(note.startswith(f"{method}: backbone inside an obstacle") for note in result.notes)


def test_a_moving_obstacles_row_accounts_for_its_own_step():
    """``d(q, t + dt) - d(q, t)`` against the row's obstacle term ``G' dc`` (to first order in ``dt``)."""
    mover = Obstacle("sphere", center=(0.1, 0.0, 0.2), radius=0.02, path=((0, 0, 0, 0), (1, -0.05, 0.02, 0.01)))
    dt = 1e-3
    barrier = BarrierRows(ARM, dt, [mover], margin=0.01, gamma=20.0)
    static = BarrierRows(ARM, dt, [Obstacle("sphere", center=(0.1, 0.0, 0.2), radius=0.02)], margin=0.01, gamma=20.0)
    barrier.step = static.step = 0
    barrier.update(Q)
    static.update(Q)
    points = barrier.distances.points_at(Q)
    change = mover.distances(points, dt) - mover.distances(points, 0.0)
    nearest = np.argsort(mover.distances(points, 0.0))[:3]
    # b_moving - b_static = -(d(t + dt) - d(t)) / dt for the same samples
    np.testing.assert_allclose(np.sort(barrier.b - static.b), np.sort(-change[nearest] / dt), rtol=1e-3, atol=1e-6)


def test_the_direct_daqp_path_with_rows_matches_qpsolvers():
    qpsolvers = pytest.importorskip("qpsolvers")
    from optikin.solvers.qp.qp_qpsolvers import QpsolversOptions, QpsolversStepSolver

    rng = np.random.default_rng(4)
    rows, cols = upper_triangle_csc_indices(6)
    for _ in range(5):
        J, v = rng.standard_normal((8, 6)), 5.0 * rng.standard_normal(8)
        H, g = J.T @ J + 1e-4 * np.eye(6), -J.T @ v
        A, b = rng.standard_normal((9, 6)), rng.standard_normal(9) - 1.0
        data = QPData(J, v, 1e-4, H, H[rows, cols], g, -np.ones(6), np.ones(6), A, b)
        solver = QpsolversStepSolver(6, 8, QpsolversOptions(solver="daqp"), rows=9)
        assert solver._daqp is not None  # the direct path is the one under test
        ref = qpsolvers.solve_qp(H, g, -A, -b, lb=data.lb, ub=data.ub, solver="daqp")
        np.testing.assert_allclose(solver.solve(data).x, ref, atol=1e-10)
