"""Misuse of the Python API: batches where one configuration is expected, NaN and non-unit inputs.

Every bad call raises a ValueError that names the argument (and the method that takes
batches); the numpy-facing methods accept one configuration or a batch.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.algebra import (
    dq_from_rotation_translation,
    matrix_from_quat,
    quat_inverse,
    quat_log,
    quat_normalize,
    quat_rotate,
    rpy_from_quat,
)
from pytransform3d.transformations import transform_from_dual_quaternion

from optikin.arms import CBHAArm, ConstantCurvatureArm
from optikin.checks import check_configuration, check_dual_quaternion, check_quaternion

ARM = ConstantCurvatureArm()
BENT = np.array([0.18, 0.6, 0.3, 0.17, -0.4, 1.2])


@pytest.mark.parametrize("name", ["fk_dq", "fk_position", "fk_transform", "jac_position", "jac_dq", "backbone"])
def test_a_batch_through_a_single_configuration_function_names_evaluate(name):
    with pytest.raises(ValueError, match=rf"{name}.*\(6,\).*arm\.evaluate\('{name}', Q\)"):
        ARM.function(name)(np.stack([BENT, BENT, BENT]))


def test_a_configuration_of_the_wrong_length_is_a_value_error():
    with pytest.raises(ValueError, match=r"shape \(6,\), got shape \(5,\)"):
        ARM.fk_dq(BENT[:5])
    with pytest.raises(ValueError, match=r"configurations: expected shape \(N, 6\)"):
        ARM.evaluate("fk_dq", np.zeros((4, 5)))


def test_one_configuration_still_goes_through_the_function():
    T = np.asarray(ARM.fk_transform(ARM.straight_configuration()))
    np.testing.assert_allclose(T[:3, 3], [0.0, 0.0, 0.36], atol=1e-15)  # straight: the tip on the z axis


def test_transform_of_takes_a_batch_and_agrees_with_pytransform3d():
    Q = np.stack([BENT, ARM.straight_configuration(), BENT * [1, -1, 1, 1, 0.5, 1]])
    T = ARM.transform_of(Q)
    assert T.shape == (3, 4, 4)
    dq = ARM.evaluate("fk_dq", Q)
    for k in range(3):
        # optikin's dual quaternion (Q_r, Q_d) with Q_d = 0.5 (0, p) Q_r is pytransform3d's layout
        np.testing.assert_allclose(T[k], transform_from_dual_quaternion(dq[k]), atol=1e-12)
    np.testing.assert_allclose(ARM.transform_of(BENT), T[0])


@pytest.mark.parametrize(
    "q, match",
    [
        (np.full(6, np.nan), r"q: S1 = nan is not a finite number"),
        (BENT * [1, 1, 1, 1, np.inf, 1], r"q: theta2 = -inf is not a finite number"),
        (BENT * [1, 10, 1, 1, 1, 1], r"q: theta1 = 6 outside its bounds"),
        (BENT * [10, 1, 1, 1, 1, 1], r"q: S1 = 1.8 outside its bounds"),
    ],
)
def test_transform_of_rejects_bad_configurations(q, match):
    with pytest.raises(ValueError, match=match):
        ARM.transform_of(q)
    ARM.transform_of(q, check=False)  # the opt-out computes without looking


def test_evaluate_checks_by_default_naming_the_sample():
    Q = np.stack([BENT, BENT, BENT])
    Q[2, 4] = np.nan
    with pytest.raises(ValueError, match=r"configurations\[2\]: theta2 = nan"):
        ARM.evaluate("fk_position", Q)
    assert np.isnan(ARM.evaluate("fk_position", Q, check=False)[2]).all()  # the opt-out: a failed sample stays failed


def test_evaluate_refuses_implausible_values_and_on_request_values_outside_the_bounds():
    Q = np.stack([BENT, BENT * [1, 1.5, 1, 1, 1, 1]])  # theta1 = 0.9: inside the bounds
    Q[1, 1] = 2.5  # past theta_max = 2.094: a solver's overshoot, evaluated by default
    assert ARM.evaluate("fk_position", Q).shape == (2, 3)
    with pytest.raises(ValueError, match=r"configurations\[1\]: theta1 = 2.5 outside its bounds"):
        ARM.evaluate("fk_position", Q, bounds=True)
    Q[1, 3] = 170.0  # S2 in millimetres
    with pytest.raises(ValueError, match=r"configurations\[1\]: S2 = 170 is far outside its bounds .*unit mistake"):
        ARM.evaluate("fk_position", Q)


def test_periodic_angles_are_not_bound_checked():
    q = BENT.copy()
    q[2] += 4 * np.pi  # phi1 two turns on: the same pose
    np.testing.assert_allclose(ARM.transform_of(q), ARM.transform_of(BENT), atol=1e-12)


def test_check_configuration_of_a_cbha_names_the_platform_variable():
    arm = CBHAArm()
    q = arm.straight_configuration()
    q[4] = 1.0
    with pytest.raises(ValueError, match=r"q: theta2 = 1 outside its bounds"):
        check_configuration(arm, q)


@pytest.mark.parametrize(
    "q, unit, match",
    [
        ([1.0, 0.0, 0.0], True, r"q: expected quaternions .* got shape \(3,\)"),
        ([0.0, 0.0, 0.0, 0.0], False, r"q: .* a zero quaternion"),
        ([0.0, 0.0, 0.0, 0.0], True, r"q: .* norm 0: not a unit quaternion"),
        ([[1.0, 0, 0, 0], [1.0, 1.0, 0, 0]], True, r"q\[1\]: .* norm 1.41421: not a unit quaternion"),
        ([[1.0, 0, 0, 0], [np.nan, 0, 0, 0]], True, r"q\[1\]: .* non-finite"),
    ],
)
def test_check_quaternion(q, unit, match):
    with pytest.raises(ValueError, match=match):
        check_quaternion(q, unit=unit)


def test_check_quaternion_accepts_pytransform3d_rotations():
    from pytransform3d.rotations import quaternion_from_axis_angle

    q = quaternion_from_axis_angle([0.3, -0.5, 0.8, 1.1])
    np.testing.assert_array_equal(check_quaternion(q), q)


def test_check_dual_quaternion():
    from pytransform3d.transformations import dual_quaternion_from_transform

    T = ARM.transform_of(BENT)
    dq = dual_quaternion_from_transform(T)
    np.testing.assert_array_equal(check_dual_quaternion(dq), dq)
    bad = dq.copy()
    bad[4:] += 0.1 * dq[:4]  # a dual part with a component along the real part
    with pytest.raises(ValueError, match=r"target: Q_r \. Q_d = 0.1: not a unit dual quaternion"):
        check_dual_quaternion(bad, name="target")
    with pytest.raises(ValueError, match=r"dq: real part .* norm 2"):
        check_dual_quaternion(2 * dq)
    with pytest.raises(ValueError, match=r"dq: expected dual quaternions"):
        check_dual_quaternion(dq[:7])


# ------------------------------------------------------------------------------ arm parameters
@pytest.mark.parametrize(
    "params, field",
    [
        ({"section_lengths": [float("nan"), 0.18]}, "section_lengths.0: not a finite number"),
        ({"section_lengths": [0.18, float("inf")]}, "section_lengths.1: not a finite number"),
        ({"section_lengths": [0.18, -0.1]}, "section_lengths.1: must be positive"),
        ({"length_range": [0.9, float("nan")]}, "length_range.1: not a finite number"),
        ({"length_range": [0.9, -1.0]}, "length_range.1: must be positive"),
        ({"theta_max": float("nan")}, "theta_max: not a finite number"),
        ({"theta_max": 4.0}, r"theta_max: 4 rad is beyond the physical bound 3.14159 rad"),
        ({"length_range": [0.9, 50.0]}, "length_range.1: 50 is beyond the physical bound 10"),
        ({"length_range": [1.1, 0.9]}, r"length_range: must satisfy 0 < low <= high"),
        ({"theta_max": [1.0, 2.0]}, r"theta_max: expected one number, got \[1.0, 2.0\]"),
        ({"backbone_points_per_section": 2.5}, "backbone_points_per_section: must be a positive integer"),
    ],
)
def test_constant_curvature_parameters_are_named(params, field):
    from optikin.arms import build_arm
    from optikin.errors import SpecError

    with pytest.raises(ValueError, match=field):
        ConstantCurvatureArm(**params)
    with pytest.raises(SpecError, match=rf"arm\.yaml: arm\.params\.{field}"):
        build_arm("constant_curvature", params, "arm.yaml")


@pytest.mark.parametrize(
    "geometry, field",
    [
        ({"r_max": float("nan")}, "geometry.r_max: not a finite number"),
        ({"tool_offset": float("inf")}, "geometry.tool_offset: not a finite number"),
        ({"leg_min": [0.0085] * 15 + [float("nan")]}, "geometry.leg_min.15: not a finite number"),
        ({"leg_max": [0.02] * 3}, r"geometry.leg_max: leg_min and leg_max need one value per platform \(16\)"),
        ({"r_max": 40.0}, r"geometry.r_max: 40 m is beyond the physical bound 1 m \(millimetres given for metres\?\)"),
        ({"tool_offset": "0.1"}, r"geometry.tool_offset: expected one number, got str"),
        ({"n_vertebrae": 10**6}, r"geometry.n_vertebrae: must be an integer in \[2, 1000\]"),
    ],
)
def test_cbha_geometry_fields_are_named(geometry, field):
    from optikin.arms import build_arm
    from optikin.errors import SpecError

    with pytest.raises(SpecError, match=rf"arm\.params\.{field}"):
        build_arm("cbha", {"geometry": geometry}, "arm.yaml")


def test_a_nan_section_length_in_a_problem_file_is_blamed_on_the_arm(tmp_path, capsys):
    import yaml

    from optikin.cli import main

    spec = {
        "name": "nan-arm",
        "title": "an arm with a NaN section length",
        "description": "misuse",
        "kind": "ik",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [float("nan"), 0.18]}},
        "data": {"source": "random", "seed": 1, "samples": 2},
        "solver": "gauss-newton",
        "options": {"target": "position"},
    }
    path = tmp_path / "nan-arm.yaml"
    path.write_text(yaml.safe_dump(spec))
    assert main(["solve", str(path), "--no-figures", "--out", str(tmp_path / "out")]) == 2
    assert "nan-arm.yaml: arm.params.section_lengths.0: not a finite number" in capsys.readouterr().err


@pytest.mark.parametrize(
    "call",
    [
        lambda q: quat_normalize(q),
        lambda q: quat_inverse(q),
        lambda q: quat_log(q),
        lambda q: matrix_from_quat(q),
        lambda q: rpy_from_quat(q),
        lambda q: quat_rotate(q, np.array([1.0, 0.0, 0.0])),
        lambda q: dq_from_rotation_translation(q, np.zeros(3)),
    ],
)
def test_a_zero_quaternion_is_refused_by_the_algebra(call):
    with pytest.raises(ValueError, match=r"q: \[0.0, 0.0, 0.0, 0.0\] has norm 0: "):
        call(np.zeros(4))


@pytest.mark.parametrize("fn", [quat_log, matrix_from_quat, rpy_from_quat])
def test_a_non_unit_quaternion_is_refused_where_a_rotation_is_needed(fn):
    with pytest.raises(ValueError, match=r"q\[1\]: .* has norm 2: not a unit quaternion"):
        fn(np.array([[1.0, 0, 0, 0], [2.0, 0, 0, 0]]))
    assert np.isfinite(fn(np.array([2.0, 0, 0, 0]), check=False)).all()  # the inner-loop opt-out


def test_nan_rows_are_refused_unless_unchecked():
    q = np.array([[1.0, 0, 0, 0], [np.nan, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"q\[1\]: \[nan, 0.0, 0.0, 0.0\] has a non-finite component"):
        matrix_from_quat(q)
    out = matrix_from_quat(q, check=False)  # the opt-out propagates NaN, as numpy arithmetic does
    assert np.allclose(out[0], np.eye(3)) and np.isnan(out[1]).any()
