"""The short Python entry points: the module's example runs, and bad calls say what is wrong."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

import optikin
import optikin.api
from optikin.arms import ConstantCurvatureArm


def test_the_docstring_example_runs():
    result = doctest.testmod(optikin.api, raise_on_error=False)
    assert result.attempted >= 8 and result.failed == 0


def test_tip_position_ik_reaches_a_reachable_target():
    arm = ConstantCurvatureArm()
    q = np.array([0.18, 0.7, 0.4, 0.17, -0.5, 2.0])
    tip = arm.evaluate("fk_position", q[None])[0]
    solution = optikin.solve_ik(arm, tip)
    assert solution.status == "ok"
    assert np.linalg.norm(arm.evaluate("fk_position", solution.configuration[None])[0] - tip) < 1e-9


def test_a_target_of_the_wrong_size_is_refused():
    arm = ConstantCurvatureArm()
    with pytest.raises(ValueError, match="position \\(3\\) or a dual quaternion \\(8\\)"):
        optikin.solve_ik(arm, np.zeros(5))
    with pytest.raises(ValueError, match="need 6 values"):
        optikin.solve_ik(arm, np.zeros(5), points={"a": {"section": 1}, "b": {"section": 2}})


def test_a_preset_of_another_family_is_refused():
    with pytest.raises(ValueError, match="not nonlinear"):
        optikin.solve_ik(ConstantCurvatureArm(), np.array([0.0, 0.0, 0.3]), preset="qp-osqp")


# ---------------------------------------------------------------------------- reconstruct_backbone
def _fitted_derivative(curve, degree: int = 5):
    """``r'(t)`` as polynomials (one per axis) fitted to sampled points: a quintic is fitted exactly."""
    t = np.linspace(0.0, 1.0, 31)
    points = np.asarray(curve.point(t))
    return [np.polynomial.Polynomial.fit(t, points[:, k], degree, domain=[0, 1]).deriv() for k in range(3)]


def test_backbone_meets_both_poses_and_the_length_with_a_pythagorean_hodograph():
    arm = ConstantCurvatureArm()
    q = np.array([0.17, 0.9, 0.4, 0.19, -0.7, 2.2])
    base, tip = np.eye(4), arm.transform_of(q)
    length = q[0] + q[3]
    backbone = optikin.reconstruct_backbone(base, tip, length=length, samples=41)
    assert backbone.status == "ok"
    curve = backbone.curve
    np.testing.assert_allclose(np.asarray(curve.point(0.0)), base[:3, 3], atol=1e-12)
    np.testing.assert_allclose(np.asarray(curve.point(1.0)), tip[:3, 3], atol=1e-12)
    derivative = _fitted_derivative(curve)
    for t, frame in ((0.0, base), (1.0, tip)):
        d = np.array([p(t) for p in derivative])
        np.testing.assert_allclose(d / np.linalg.norm(d), frame[:3, 2], atol=1e-8)  # leaves / arrives along z
    # |r'|^2 is a perfect square: its square root, sampled, is a polynomial of degree 4 (degree 8 otherwise)
    t = np.linspace(0.0, 1.0, 40)
    speed = np.sqrt(sum(p(t) ** 2 for p in derivative))
    sigma = np.polynomial.Polynomial.fit(t, speed, 4, domain=[0, 1])
    assert np.max(np.abs(sigma(t) - speed)) < 1e-8 * speed.max()
    assert sigma.integ()(1.0) - sigma.integ()(0.0) == pytest.approx(length, rel=1e-9)
    assert backbone.arc_length == pytest.approx(length, rel=1e-9)
    steps = np.linalg.norm(np.diff(backbone.points, axis=0), axis=1)  # equal arc-length fractions
    assert backbone.points.shape == (41, 3) and np.ptp(steps) < 1e-3 * steps.mean()
    np.testing.assert_allclose(backbone.points[[0, -1]], [base[:3, 3], tip[:3, 3]], atol=1e-14)


def test_backbone_of_a_quarter_circle_has_the_circle_s_energy():
    # a planar quarter circle of radius r: kappa = 1/r over the length pi r / 2, E = (pi/2)^2 / L
    r = 0.2
    tip = np.array([[0.0, 0, 1, r], [0, 1, 0, 0], [-1, 0, 0, r], [0, 0, 0, 1]])
    backbone = optikin.reconstruct_backbone(np.eye(4), tip)  # length: the arc's
    assert backbone.arc_length == pytest.approx(np.pi * r / 2, rel=1e-9)
    assert backbone.energy == pytest.approx((np.pi / 2) ** 2 / (np.pi * r / 2), rel=1e-5)
    radii = np.linalg.norm(backbone.points - [r, 0.0, 0.0], axis=1)
    np.testing.assert_allclose(radii, r, rtol=2e-3)


def test_backbone_poses_as_dual_quaternions_equal_transforms():
    arm = ConstantCurvatureArm()
    q = np.array([0.18, 0.5, -0.3, 0.18, 0.8, 1.0])
    from_dq = optikin.reconstruct_backbone(np.array([1.0, 0, 0, 0, 0, 0, 0, 0]), np.asarray(arm.fk_dq(q)).ravel())
    from_transform = optikin.reconstruct_backbone(np.eye(4), arm.transform_of(q))
    np.testing.assert_allclose(from_dq.points, from_transform.points, atol=1e-10)


def test_backbone_bad_poses_and_lengths_are_refused():
    tip = np.eye(4)
    tip[:3, 3] = [0.0, 0.0, 0.3]
    with pytest.raises(optikin.errors.InputDataError, match="more than the backbone length"):
        optikin.reconstruct_backbone(np.eye(4), tip, length=0.2)
    with pytest.raises(ValueError, match="unit dual quaternion \\(8,\\) or a 4x4 transform"):
        optikin.reconstruct_backbone(np.zeros(7), tip)
    with pytest.raises(ValueError, match="not a rotation"):
        optikin.reconstruct_backbone(2 * np.eye(4), tip)


# ---------------------------------------------------------------------------- track
def test_track_follows_a_reachable_position_reference_given_as_an_array():
    arm = ConstantCurvatureArm()
    rate, seconds = 200.0, 1.5
    t = np.arange(int(rate * seconds) + 1) / rate
    blend = 0.5 - 0.5 * np.cos(np.pi * np.clip(t / 1.0, 0.0, 1.0))  # smooth, then held for 0.5 s
    qa, qb = np.array([0.18, 0.3, 0.1, 0.18, 0.4, 0.0]), np.array([0.17, 0.7, 0.6, 0.185, 0.5, 1.2])
    Q = qa + blend[:, None] * (qb - qa)
    positions = arm.evaluate("fk_position", Q)
    result = optikin.track(arm, positions, rate=rate)
    assert result.t.shape == (len(t),) and result.q.shape == (len(t), 6)
    assert result.statuses == ["ok"] * len(t)
    error = np.linalg.norm(arm.evaluate("fk_position", result.q) - positions, axis=1)  # from the configurations
    assert error.max() < 1e-3 and error[-1] < 1e-5
    np.testing.assert_allclose(result.error, error, atol=1e-12)
    assert result.orientation_error is None


def test_track_waypoints_pose_task_converges_from_an_offset_start():
    arm = ConstantCurvatureArm()
    waypoints = [[0.18, 0.3, 0.0, 0.18, 0.3, 0.0], [0.17, 0.6, 0.4, 0.18, 0.5, 1.0]]
    offset = np.array([0.002, 0.05, 0.0, -0.002, 0.0, 0.05])
    result = optikin.track(
        arm,
        {"waypoints": waypoints, "rate": 200, "segment_time": 1.0, "hold": 1.0},
        start=np.array(waypoints[0]) + offset,
    )
    reference = arm.evaluate("fk_dq", np.array(waypoints[-1]))
    final = arm.evaluate("fk_dq", result.q[-1])
    tip_error = np.linalg.norm(final[4:] - reference[4:]) if final[:4] @ reference[:4] > 0 else np.inf
    assert np.linalg.norm(arm.evaluate("fk_position", result.q[-1]) - arm.evaluate("fk_position", waypoints[-1])) < 1e-5
    assert tip_error < 1e-5 and result.error[0] > 1e-3  # started away, ended on it
    assert result.orientation_error is not None and result.orientation_error[-1] < 1e-4


def test_track_with_the_mpc_follows_the_path_it_previews():
    arm = ConstantCurvatureArm()
    waypoints = [[0.18, 0.3, 0.0, 0.18, 0.3, 0.0], [0.17, 0.6, 0.4, 0.18, 0.5, 1.0]]
    ref = {"waypoints": waypoints, "task": "position", "rate": 100, "segment_time": 1.0, "hold": 0.5}
    result = optikin.track(arm, ref, "mpc", horizon=10)
    tip = arm.evaluate("fk_position", result.q)
    path = arm.evaluate("fk_position", waypoints[-1])
    assert result.controller.startswith("mpc")
    assert np.linalg.norm(tip[-1] - path) < 1e-4  # on the last waypoint, by the arm's own FK
    assert result.error.max() < 1e-3 and set(result.statuses) == {"ok"}


def test_track_refuses_unknown_controllers_and_presets():
    arm = ConstantCurvatureArm()
    ref = {"waypoints": [[0.18, 0.3, 0.0, 0.18, 0.3, 0.0]] * 2, "task": "position", "rate": 100, "hold": 0.0}
    with pytest.raises(ValueError, match="unknown controller 'lqr'; known: qp, mpc,"):
        optikin.track(arm, ref, "lqr")
    with pytest.raises(ValueError, match="not qp"):
        optikin.track(arm, ref, preset="gauss-newton")
    with pytest.raises(ValueError, match="\\(N, 3\\) positions or \\(N, 8\\)"):
        optikin.track(arm, np.zeros((10, 5)))
    with pytest.raises(optikin.errors.SpecError, match="track: reference.segment_tme"):
        optikin.track(arm, ref | {"segment_tme": 1.0})
    with pytest.raises(ValueError, match="rows of 6 values"):
        optikin.track(arm, ref | {"waypoints": [[0.18, 0.3, 0.0]] * 2})


# ---------------------------------------------------------------------------- arm Functions
def test_help_of_an_arm_function_is_optikin_s_docstring():
    import pydoc

    arm = ConstantCurvatureArm()
    text = pydoc.render_doc(arm.fk_dq, renderer=pydoc.plaintext)
    for phrase in ("unit dual quaternion", "8 x 1", "[m]", "base frame", "arm.evaluate"):
        assert phrase in text
    assert len(text.splitlines()) < 40 and "sparsity_jac" not in text  # not casadi.Function's help
    for name in ("fk_position", "jac_dq", "jac_position", "backbone", "section_dq", "fk_transform"):
        doc = pydoc.render_doc(arm.function(name), renderer=pydoc.plaintext)
        assert "DM" in doc and "sparsity_jac" not in doc, name
    q = np.array([0.18, 0.6, 0.3, 0.17, 0.0, 0.0])
    value = arm.fk_dq(q)  # what the README says: a DM, 8 x 1, equal to the batch path
    assert value.shape == (8, 1) and type(value).__name__ == "DM"
    np.testing.assert_allclose(np.asarray(value).ravel(), arm.evaluate("fk_dq", q), atol=1e-15)


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda arm: optikin.solve_ik(arm, [0.1, np.nan, 0.3]), ValueError, r"target\[1\]: nan is not a finite"),
        (lambda arm: optikin.solve_ik(arm, [0.1, 1e300, 0.3]), ValueError, r"target\[1\]: 1e\+300 m is beyond"),
        (lambda arm: optikin.solve_ik(arm, "0.1 0.2 0.3"), TypeError, r"target: expected numbers, got str"),
        (
            lambda arm: optikin.solve_ik(arm, np.r_[2.0, 0, 0, 0, 0, 0, 0, 0]),
            ValueError,
            r"target: real part .* norm 2",
        ),
        (lambda arm: optikin.solve_ik("cc", [0.1, 0.0, 0.3]), TypeError, r"arm: expected an ArmModel .*, got str"),
        (lambda arm: optikin.solve_ik(arm, [0.1, 0.0, 0.3], noise=-1.0), ValueError, r"noise: must not be negative"),
        (
            lambda arm: optikin.solve_ik(arm, [0.1, 0.0, 0.3], start=np.full(6, np.nan)),
            ValueError,
            r"start: S1 = nan is not a finite number",
        ),
        (lambda arm: optikin.reconstruct_backbone(np.eye(4), np.eye(4), samples=1.5), TypeError, r"samples: expected"),
        (
            lambda arm: optikin.reconstruct_backbone(np.eye(4), 2 * np.eye(4)),
            ValueError,
            r"tip_pose\[:3, :3\]: not a rotation matrix",
        ),
        (lambda arm: optikin.track(arm, np.zeros((5, 3)), rate=0.0), ValueError, r"rate: must be positive"),
        (
            lambda arm: optikin.track(arm, np.full((5, 3), np.inf)),
            ValueError,
            r"reference\[0, 0\]: inf is not a finite",
        ),
    ],
)
def test_entry_points_name_the_bad_argument(call, error, match):
    with pytest.raises(error, match=match):
        call(ConstantCurvatureArm())


@pytest.mark.parametrize(
    "points, error, match",
    [
        ({"d1": {"section": "1"}}, TypeError, r"points\.d1\.section: expected an integer"),
        ({"d1": {"section": 1, "offset": [0.0, np.nan, 0.0]}}, ValueError, r"points\.d1\.offset\[1\]: nan"),
        ({"d1": {"section": 1, "at": 0.0}}, ValueError, r"points\.d1\.at: must be positive"),
        ({"d1": {"at": 0.5}}, ValueError, r"points\.d1: expected a mapping with a section"),
    ],
)
def test_point_set_names_the_bad_field(points, error, match):
    with pytest.raises(error, match=match):
        optikin.api.point_set(points)
