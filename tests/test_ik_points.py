"""IK to measured points along the arm: frames inside a section, residual rows, fits to noisy targets,
targets read in another frame and unit, and backends marked not applicable instead of failing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
import pytest
import yaml

from optikin.algebra import quat_from_axis_angle, quat_multiply, quat_rotate
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.errors import SpecError
from optikin.ik.formulation import Formulation, build_problem
from optikin.ik.points import MeasuredPoint, PointSet
from optikin.problems.ik.run import reference_of
from optikin.runner import solve
from optikin.solvers import build_preset, load_backends
from optikin.solvers.nonlinear import LeastSquaresProblem

TRUNK = {"section_lengths": [0.1058, 0.0949, 0.1144], "length_range": [1.0, 1.0], "theta_max": 1.5}
DISKS = {"d1": {"section": 1}, "d2": {"section": 2}, "d3": {"section": 3}}


def write_problem(tmp_path: Path, name: str = "points", **fields: Any) -> Path:
    spec: dict[str, Any] = {
        "name": name,
        "title": "test",
        "kind": "ik",
        "arm": {"type": "constant_curvature", "params": TRUNK},
        "data": {"source": "random", "seed": 3, "samples": 12},
        "solver": "gauss-newton",
        "options": {"target": "points", "points": DISKS, "restarts": 3},
    }
    for key, value in fields.items():
        spec[key] = spec[key] | value if isinstance(value, dict) and key in ("data", "options") else value
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def flat(value) -> np.ndarray:
    """A CasADi DM (or numpy array) as a flat numpy vector."""
    return np.asarray(value, dtype=float).ravel()


def arc_point(S: float, theta: float, phi: float, s: float) -> np.ndarray:
    """A point at arc length ``s`` of a circular arc of length ``S`` bending by ``theta`` in plane ``phi``."""
    radius = S / theta
    a = theta * s / S
    return np.array(
        [radius * (1 - np.cos(a)) * np.cos(phi), radius * (1 - np.cos(a)) * np.sin(phi), radius * np.sin(a)]
    )


def test_frame_at_a_fraction_lies_on_the_circular_arc():
    arm = ConstantCurvatureArm(section_lengths=[0.2])
    q = np.array([0.2, 1.1, 0.7])
    for f in (0.25, 0.5, 1.0):
        _, position = arm.frame_at(ca.DM(q), 0, f)
        assert np.allclose(flat(position), arc_point(0.2, 1.1, 0.7, f * 0.2), atol=1e-15)


def test_frame_at_the_end_of_a_section_is_its_end_frame_and_a_part_of_it_a_shorter_arm():
    arm = ConstantCurvatureArm(section_lengths=[0.15, 0.12])
    q = np.array([0.15, 0.8, -1.0, 0.12, 1.3, 2.0])
    quat, position = arm.frame_at(ca.DM(q), 1, 1.0)
    end_quat, end_position = arm.section_frames(ca.DM(q))[1]
    assert np.allclose(flat(quat), flat(end_quat)) and np.allclose(flat(position), flat(end_position))
    shorter = np.array([0.15, 0.8, -1.0, 0.4 * 0.12, 0.4 * 1.3, 2.0])
    _, position = arm.frame_at(ca.DM(q), 1, 0.4)
    assert np.allclose(flat(position), arm.evaluate("fk_position", shorter[None])[0], atol=1e-15)


def test_point_residual_vanishes_at_its_configuration_and_its_jacobian_matches_finite_differences():
    arm = ConstantCurvatureArm(section_lengths=[0.1, 0.1])
    points = PointSet(
        (
            MeasuredPoint("mid", 0, 0.5, (0.01, 0.0, 0.0)),
            MeasuredPoint("tip", 1, 1.0, (0.0, 0.005, 0.0), ("position", "orientation"), weight=2.0),
        )
    )
    q = np.array([0.1, 0.7, 0.3, 0.1, -0.9, 1.2])
    target = points.forward(arm, q[None])[0]
    r = points.residual(arm, 0.2)
    assert np.abs(np.asarray(r(q, target))).max() < 1e-15
    J = np.asarray(ca.Function("J", [x := ca.SX.sym("x", 6)], [ca.jacobian(r(x, target), x)])(q))
    h = 1e-6
    numeric = np.column_stack(
        [(np.asarray(r(q + h * e, target)) - np.asarray(r(q - h * e, target))).ravel() / (2 * h) for e in np.eye(6)]
    )
    assert np.allclose(J, numeric, atol=1e-8)


def test_exact_points_are_solved_to_the_tolerance_with_fixed_lengths(tmp_path):
    result, _ = solve(str(write_problem(tmp_path)), figures=False)
    assert result.status_counts() == {"ok": 12}
    X = result.arrays["solutions"]
    assert np.allclose(X[:, 0::3], TRUNK["section_lengths"])  # the fixed lengths are kept
    truth = result.arrays["true_configurations"]
    arm = ConstantCurvatureArm(**TRUNK)
    # the three disk centres and the tip recomputed with the arm's own forward kinematics
    assert np.abs(arm.evaluate("fk_position", X) - arm.evaluate("fk_position", truth)).max() < 1e-9


def test_noisy_points_are_fits_within_the_noise_and_unreachable_beyond(tmp_path):
    noisy = {"data": {"params": {"noise": 0.0003}}}
    result, _ = solve(str(write_problem(tmp_path, **noisy, options={"noise": 0.002})), figures=False)
    assert result.status_counts() == {"fit": 12}
    assert result.succeeded
    rms = result.arrays["rms_distance_gauss-newton"]
    # 9 measured coordinates, 6 unknowns: at the minimum E ||r||^2 = (9 - 6) sigma^2, so the RMS over the
    # three points is about sigma = 0.3 mm (the noise, not zero)
    assert 1e-4 < np.median(rms) < 6e-4
    strict, _ = solve(str(write_problem(tmp_path, "strict", **noisy, options={"noise": 1e-6})), figures=False)
    assert strict.status_counts() == {"unreachable": 12}
    assert not strict.succeeded


def test_tip_direction_without_twist_is_matched_whatever_the_twist(tmp_path):
    arm = ConstantCurvatureArm(**TRUNK)
    rng = np.random.default_rng(4)
    Q = arm.sample_configurations(6, rng)
    dq = arm.evaluate("fk_dq", Q)
    rotation = dq[:, :4]
    twisted = quat_multiply(rotation, quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), rng.uniform(-3, 3, 6)))
    direction = quat_rotate(twisted, np.array([0.0, 0.0, 1.0]))
    position = arm.evaluate("fk_position", Q)
    header = "tip_x,tip_y,tip_z,tip_dx,tip_dy,tip_dz"
    np.savetxt(tmp_path / "tips.csv", np.hstack([position, direction]), delimiter=",", header=header, comments="")
    options = {"points": {"tip": {"section": 3, "measure": ["position", "direction"]}}, "orientation_length": 0.1}
    path = write_problem(tmp_path, data={"source": "csv", "params": {"file": "tips.csv"}}, options=options)
    result, _ = solve(str(path), figures=False)
    assert result.status_counts() == {"ok": 6}


def test_points_in_a_y_up_millimetre_frame_are_brought_to_the_base_frame(tmp_path):
    arm = ConstantCurvatureArm(**TRUNK)
    Q = arm.sample_configurations(5, np.random.default_rng(8))
    points = PointSet(tuple(MeasuredPoint(f"d{k + 1}", k) for k in range(3)))
    base_values = points.forward(arm, Q)
    # the base hangs down in a y-up frame: base z axis along -y, origin at (0.1, 1.2, -0.3) m
    base_q = quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)
    origin = np.array([0.1, 1.2, -0.3])
    in_file = np.hstack([quat_rotate(base_q, base_values[:, 3 * k : 3 * k + 3]) + origin for k in range(3)]) * 1e3
    np.savetxt(tmp_path / "disks.csv", in_file, delimiter=",", header=",".join(points.columns()), comments="")
    assert np.allclose(quat_rotate(base_q, np.array([0.0, 0.0, 1.0])), [0.0, -1.0, 0.0])
    base = {"position": origin.tolist(), "quaternion": np.asarray(base_q).tolist()}
    data = {"source": "csv", "params": {"file": "disks.csv", "units": "mm", "base": base}}
    result, _ = solve(str(write_problem(tmp_path, data=data)), figures=False)
    assert result.status_counts() == {"ok": 5}
    assert np.abs(points.forward(arm, result.arrays["solutions"]) - base_values).max() < 1e-9


def test_rank_of_a_residual_jacobian():
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p", 2)
    residual = ca.Function("r", [x, p], [ca.vertcat(x[0] + x[1] - p[0], 2 * x[0] + 2 * x[1] - p[1])])
    problem = LeastSquaresProblem(residual, np.array([-1.0, -1.0]), np.array([1.0, 1.0]), np.zeros(2, dtype=bool))
    assert problem.jacobian_rank(np.array([[0.1, 0.2], [0.5, -0.3]]), np.zeros((2, 2))) == 1


def test_backends_that_cannot_solve_rank_deficient_pose_targets_are_not_applicable(tmp_path):
    spec = {
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "baselines": ["newton", "sqpmethod"],
        "data": {"samples": 3},
    }
    path = write_problem(tmp_path, **spec)
    problem = yaml.safe_load(path.read_text())
    problem["options"] = {"target": "pose", "restarts": 1}
    path.write_text(yaml.safe_dump(problem))
    result, _ = solve(str(path), figures=False)
    rows = {row.method: row.metrics for row in result.comparison}
    assert "rank-5 Jacobian" in rows["newton"]["not applicable"]
    assert "LICQ" in rows["sqpmethod"]["not applicable"]
    assert "not applicable" not in rows["gauss-newton"]


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"target": "position"}, "options.points"),
        ({"points": {"d9": {"section": 4}}}, "options.points.d9.section"),
        ({"points": {}}, "options.points"),
        ({"points": {"d": {"section": 1, "measure": ["direction", "orientation"]}}}, "options.points.d.measure"),
    ],
)
def test_bad_points_name_the_field(tmp_path, options, field):
    with pytest.raises(SpecError) as info:
        solve(str(write_problem(tmp_path, options=options)), figures=False)
    assert info.value.field == field, str(info.value)


def test_points_inside_a_section_need_a_continuum_arm(tmp_path):
    cbha = {"type": "cbha", "params": {}}
    options = {"points": {"mid": {"section": 1, "at": 0.5}}}
    with pytest.raises(SpecError) as info:
        solve(str(write_problem(tmp_path, arm=cbha, options=options)), figures=False)
    assert info.value.field == "options.points.mid.at"


def test_points_along_a_trajectory_draw_their_figures(tmp_path):
    path = write_problem(tmp_path, data={"source": "trajectory", "samples": 20})
    _, written = solve(str(path), out=tmp_path / "out")
    assert {"targets.png", "trajectory.png", "comparison.png"} <= {p.name for p in written.iterdir()}


def test_fits_within_the_calibrated_noise_level(tmp_path: Path):
    """A calibrated arm file carries the noise level its held-out postures set; noise: calibrated reads it, and
    every posture gets a residual and a status by it (fit within, unreachable beyond)."""
    source = Path(__file__).resolve().parent.parent / "problems" / "trunk-calibrate.yaml"
    spec = yaml.safe_load(source.read_text())
    spec["name"] = "cal"
    spec["data"]["samples"] = 80
    spec["data"]["params"]["corrupted_fraction"] = 0.0
    spec["options"] |= {"arm_file": "arm.yaml", "points_file": "points.csv", "base": {"starts": "data"}}
    (tmp_path / "cal.yaml").write_text(yaml.safe_dump(spec))
    calibrated, _ = solve(str(tmp_path / "cal.yaml"), figures=False)
    facts = yaml.safe_load((tmp_path / "arm.yaml").read_text())["calibration"]
    level = facts["noise_level"]
    assert calibrated.metrics["verdict"] == "ok" and 0.2e-3 < level < 2e-3
    base = {"position": facts["base_position"], "quaternion": facts["base_quaternion"]}
    path = write_problem(
        tmp_path,
        "refit",
        arm="arm.yaml",
        data={"source": "csv", "samples": 80, "params": {"file": "points.csv", "base": base}},
        options={"points": {"disk1": {"section": 1}, "disk2": {"section": 2}, "disk3": {"section": 3}}},
    )
    problem = yaml.safe_load(path.read_text())
    problem["options"]["noise"] = "calibrated"
    path.write_text(yaml.safe_dump(problem))
    result, _ = solve(str(path), figures=False)
    assert result.metrics["noise [m]"] == level
    assert set(result.status) <= {"fit", "unreachable"} and len(result.status) == 80
    # 95 % of held-out postures are within the level, so nearly all of the same postures refitted in sample are
    assert result.status.count("fit") >= 72
    # the table covers every posture: its largest RMS distance is that of the worst, fitted or not
    row = next(r for r in result.comparison if r.role == "solver").metrics
    assert row["max RMS point distance [mm]"] >= level * 1e3 or result.status.count("unreachable") == 0


def test_calibrated_noise_needs_a_calibrated_arm_file(tmp_path: Path):
    path = write_problem(tmp_path, options={"noise": "calibrated"})
    with pytest.raises(SpecError, match="options.noise"):
        solve(str(path), figures=False)


def test_a_points_fit_passes_no_reference_and_its_minimiser_does_not_depend_on_one():
    """``reference_of``: a fit to noisy points (9 rows, 6 free variables) is given no ``x_ref``, an exact
    problem the rest configuration; the minimisers of gauss-newton (Python loop with the reference, generated
    C without) and of newton (J^T r = 0) are the same with and without it."""
    load_backends()
    arm = ConstantCurvatureArm(**TRUNK)
    points = PointSet(tuple(MeasuredPoint(f"d{k + 1}", k) for k in range(3)))
    rng = np.random.default_rng(5)
    X = arm.sample_configurations(20, rng)
    targets = points.forward(arm, X) + rng.normal(0.0, 5e-4, (20, 9))
    span = arm.upper - arm.lower
    common: dict[str, Any] = dict(
        target="points",
        redundancy="rest",
        rest=arm.straight_configuration(),
        weights=1.0 / np.where(span > 0, span, 1.0),
        tolerance=1e-10,
        orientation_length=0.3,
        points=points,
    )
    fit = Formulation(**common, noise=1e-3)
    problem = build_problem(arm, fit)
    assert reference_of(fit, problem) is None
    exact = Formulation(**common)
    np.testing.assert_array_equal(reference_of(exact, build_problem(arm, exact)), exact.rest)
    gauss_newton = build_preset("gauss-newton")
    with_reference = gauss_newton.solve_many(problem, X[0], targets, warm_start=True, x_ref=fit.rest)
    without = gauss_newton.solve_many(problem, X[0], targets, warm_start=True)
    np.testing.assert_allclose(without.x, with_reference.x, rtol=0, atol=1e-12)
    assert without.status == with_reference.status
    newton = build_preset("newton")
    starts = X + rng.normal(0.0, 0.02, X.shape) * (span > 0)
    far = np.where(span > 0, arm.lower + 0.3 * span, arm.lower)
    for i in range(3):
        a = newton.solve(problem, starts[i], targets[i], x_ref=far)
        b = newton.solve(problem, starts[i], targets[i])
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
