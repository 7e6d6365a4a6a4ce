"""The checked-inputs policy of the Python API (``docs/conventions.md``, "Checked inputs").

One test per silent result a hostile-input run found: each call returned NaN, a wrong
number or garbage without an error, and must now raise a ValueError or TypeError that
names the argument. The expected facts are independent of optikin: a zero matrix is not a
rotation (``R^T R = 0``), ``2 I`` has ``det = 8``, the first CC section's theta is bounded
by 120 degrees, a section cannot have a negative arc length.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from optikin.algebra import (
    dq_log,
    dq_translation,
    quat_angle,
    quat_exp,
    quat_from_axis_angle,
    quat_from_matrix,
    quat_hemisphere_continuous,
    quat_normalize,
    quat_slerp,
)
from optikin.arms import CBHAArm, ConstantCurvatureArm
from optikin.arms.constant_curvature import section_angles_from_quaternion

CC = ConstantCurvatureArm()
CBHA = CBHAArm()
BENT = np.array([0.18, 0.6, 0.3, 0.17, -0.4, 1.2])
NAN_Q = np.array([np.nan, 0.0, 0.0, 0.0])


def _with(q: np.ndarray, index: int, value: float) -> np.ndarray:
    out = np.array(q, dtype=float)
    out[index] = value
    return out


# ------------------------------------------------------------------ NaN / inf in, NaN out
@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: CC.fk_dq(_with(BENT, 1, np.nan)), r"cc\.fk_dq: q: theta1 = nan is not a finite number"),
        (
            lambda: CC.evaluate("fk_dq", np.stack([BENT, _with(BENT, 3, np.inf)])),
            r"configurations\[1\]: S2 = inf is not a finite number",
        ),
        (lambda: CC.section_frames(_with(BENT, 2, np.nan)), r"q: phi1 = nan is not a finite number"),
        (lambda: quat_normalize(NAN_Q), r"q: \[nan, 0.0, 0.0, 0.0\] has a non-finite component"),
        (lambda: quat_exp(np.array([np.nan, 0.0, 0.0])), r"v: \[nan, 0.0, 0.0\] has a non-finite component"),
        (lambda: quat_exp(np.array([1e300, 0.0, 0.0])), r"v\[0\]: 1e\+300 rad is beyond the plausible magnitude"),
        (lambda: quat_slerp(np.array([1.0, 0, 0, 0]), np.array([0.0, 1, 0, 0]), np.nan), r"t: nan is not a finite"),
        (lambda: dq_log(np.zeros(8)), r"dq: real part \[0.0, 0.0, 0.0, 0.0\] has norm 0: not a unit dual quaternion"),
        (
            lambda: CBHA.evaluate("fk_position", _with(CBHA.straight_configuration(), 7, np.nan)),
            r"configurations: theta3 = nan is not a finite number",
        ),
    ],
    ids=[
        "fk_dq-nan",
        "evaluate-inf",
        "section_frames-nan",
        "quat_normalize-nan",
        "quat_exp-nan",
        "quat_exp-1e300",
        "quat_slerp-t-nan",
        "dq_log-zero",
        "cbha-evaluate-nan",
    ],
)
def test_non_finite_input_is_refused_naming_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ------------------------------------------------------------------ fk_dq: limits and layout
def test_fk_dq_refuses_theta_beyond_the_arm_limit():
    assert CC.theta_max == pytest.approx(2 * np.pi / 3)  # 120 degrees; 10 rad is more than a range past it
    with pytest.raises(ValueError, match=r"cc\.fk_dq: q: theta1 = 10 outside its bounds \[-2\.0944, 2\.0944\] by more"):
        CC.fk_dq(_with(BENT, 1, 10.0))
    CC.fk_dq(_with(BENT, 1, 2.2))  # a solver's trial point just past the bound is evaluated


def test_fk_dq_refuses_a_negative_arc_length():
    with pytest.raises(
        ValueError, match=r"cc\.fk_dq: q: S1 = -0\.18 is not positive \(a length; bounds \[0\.162, 0\.198\]\)"
    ):
        CC.fk_dq(_with(BENT, 0, -0.18))
    with pytest.raises(ValueError, match=r"configurations: S1 = -0\.18 is not positive"):
        CC.evaluate("fk_dq", _with(BENT, 0, -0.18))


def test_fk_dq_refuses_columns_as_a_batch_as_it_refuses_rows():
    Q = np.stack([BENT, CC.straight_configuration()])  # (2, 6): rows, the documented batch layout
    with pytest.raises(ValueError, match=r"got shape \(2, 6\); for a batch \(N, 6\) use arm\.evaluate\('fk_dq', Q\)"):
        CC.fk_dq(Q)
    with pytest.raises(ValueError, match=r"got shape \(6, 2\), a batch as columns; .*Q = q\.T"):
        CC.fk_dq(Q.T)
    # the documented way gives both poses, the same as two single calls
    np.testing.assert_allclose(CC.evaluate("fk_dq", Q)[1], np.asarray(CC.fk_dq(Q[1])).ravel(), atol=1e-15)


# ------------------------------------------------------------------ the algebra: not a rotation, no direction
@pytest.mark.parametrize(
    "R, match",
    [
        (np.zeros((3, 3)), r"R: not a rotation matrix: R\^T R differs from the identity by 1"),
        (2.0 * np.eye(3), r"R: not a rotation matrix: R\^T R differs from the identity by 3"),
    ],
    ids=["zeros", "2I"],
)
def test_quat_from_matrix_refuses_a_matrix_that_is_not_a_rotation(R, match):
    with pytest.raises(ValueError, match=match):
        quat_from_matrix(R)


def test_quat_from_matrix_refuses_a_reflection():
    with pytest.raises(ValueError, match=r"det R = -1: a reflection"):
        quat_from_matrix(np.diag([1.0, 1.0, -1.0]))


def test_quat_from_axis_angle_refuses_a_zero_axis():
    with pytest.raises(ValueError, match=r"axis: \[0.0, 0.0, 0.0\] has norm 0: not a unit vector"):
        quat_from_axis_angle(np.zeros(3), 0.5)


@pytest.mark.parametrize(
    "q, match",
    [
        (np.zeros(4), r"q: \[0.0, 0.0, 0.0, 0.0\] has norm 0: not a unit quaternion"),
        (np.array([2.0, 0.0, 0.0, 0.0]), r"q: \[2.0, 0.0, 0.0, 0.0\] has norm 2: not a unit quaternion"),
    ],
    ids=["zero", "non-unit"],
)
def test_quat_angle_refuses_a_quaternion_that_is_not_a_rotation(q, match):
    with pytest.raises(ValueError, match=match):
        quat_angle(q)


def test_dq_translation_refuses_a_zero_dual_quaternion():
    with pytest.raises(ValueError, match=r"dq: real part \[0.0, 0.0, 0.0, 0.0\] has norm 0"):
        dq_translation(np.zeros(8))


def test_section_angles_refuse_a_zero_quaternion():
    with pytest.raises(ValueError, match=r"q: \[0.0, 0.0, 0.0, 0.0\] has norm 0: not a unit quaternion"):
        section_angles_from_quaternion(np.zeros(4))


def test_the_cbha_refuses_an_all_zero_configuration():
    # Z_k = 0 puts vertebra k + 1 on vertebra k: shorter than every leg of Table I allows
    with pytest.raises(ValueError, match=r"cbha\.fk_position: q: Z1 = 0 is not positive \(a length; bounds \[0\.008"):
        CBHA.fk_position(np.zeros(CBHA.n_config))


def test_quat_hemisphere_continuous_refuses_a_zero_row():
    qs = np.array([[1.0, 0, 0, 0], [0.0, 0, 0, 0], [0.0, 1, 0, 0]])
    with pytest.raises(ValueError, match=r"qs\[1\]: \[0.0, 0.0, 0.0, 0.0\] has norm 0: not a unit quaternion"):
        quat_hemisphere_continuous(qs)


# ------------------------------------------------------------------ types
def test_theta_max_as_a_string_is_a_type_error_naming_it():
    with pytest.raises(TypeError, match=r"theta_max: expected one number, got str '1'"):
        ConstantCurvatureArm(theta_max="1")
    with pytest.raises(TypeError, match=r"section_lengths\.0: expected a number, got bool True"):
        ConstantCurvatureArm(section_lengths=[True, 0.18])


@pytest.mark.parametrize("bad", ["0.18, 0.6", None, np.full(6, 1 + 2j)], ids=["str", "None", "complex"])
def test_a_non_numeric_argument_to_an_arm_function_is_a_type_error_naming_q(bad):
    with pytest.raises(TypeError, match=r"cc\.fk_dq: q: expected (real )?numbers, got"):
        CC.fk_dq(bad)


# ------------------------------------------------------------------ physical bounds on arm parameters
def test_a_section_of_1e300_metres_is_refused_naming_the_entry():
    from optikin.arms import build_arm
    from optikin.errors import SpecError

    with pytest.raises(ValueError, match=r"section_lengths\.0: 1e\+300 m is beyond the physical bound 10 m"):
        ConstantCurvatureArm(section_lengths=[1e300, 0.18])
    with pytest.raises(SpecError, match=r"arm\.params\.section_lengths\.0: 1e\+300 m is beyond"):
        build_arm("constant_curvature", {"section_lengths": [1e300, 0.18]}, "arm.yaml")


def test_section_lengths_in_millimetres_get_a_unit_hint():
    with pytest.raises(ValueError, match=r"section_lengths\.0: 180 m .*millimetres given for metres"):
        ConstantCurvatureArm(section_lengths=[180.0, 180.0])


# ------------------------------------------------------------------ what still passes
def test_symbolic_calls_and_the_raw_function_are_unchecked():
    q = ca.SX.sym("q", CC.n_config)
    assert CC.fk_dq(q).shape == (8, 1)  # a symbolic call builds the expression
    out = np.asarray(CC.fk_dq.unchecked(_with(BENT, 1, np.nan)))  # the inner-loop path computes as given
    assert np.isnan(out).any()


def test_periodic_angles_and_unchecked_algebra_still_pass():
    q = _with(BENT, 2, BENT[2] + 4 * np.pi)  # phi1 two turns on
    np.testing.assert_allclose(np.asarray(CC.fk_dq(q)), np.asarray(CC.fk_dq(BENT)), atol=1e-12)
    assert np.isnan(quat_normalize(NAN_Q, check=False)).all()


def test_the_cbha_leg_lengths_take_any_finite_configuration():
    # a feasibility measure: solvers report the leg lengths of an infeasible configuration
    q = CBHA.straight_configuration()
    q[9] = -0.001  # Z4 below the vertebra under it
    assert np.isfinite(np.asarray(CBHA.leg_lengths(q))).all()
    with pytest.raises(ValueError, match=r"cbha\.leg_lengths: q: Z4 = nan is not a finite number"):
        CBHA.leg_lengths(_with(q, 9, np.nan))
    with pytest.raises(ValueError, match=r"cbha\.fk_position: q: Z4 = -0\.001 is not positive"):
        CBHA.fk_position(q)
