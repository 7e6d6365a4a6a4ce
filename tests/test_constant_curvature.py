"""Constant-curvature arm: cross-checks against independent constructions.

References used here, none of them the code under test:
- homogeneous transforms built from scipy rotations, Rz(phi) Ry(theta) Rz(-phi), and the arc formula;
- the printed 5th-order Taylor form of seed 000 eq. (2);
- central finite differences of the tip position / dual quaternion;
- pytransform3d's dual quaternion of the chained transform.
"""

from __future__ import annotations

import numpy as np
import pytest
from pytransform3d.transformations import dual_quaternion_from_transform
from scipy.spatial.transform import Rotation

from optikin.algebra import dq_translation, quat_from_rpy, quat_multiply
from optikin.arms.constant_curvature import (
    ConstantCurvatureArm,
    relative_section_quaternions,
    section_angles_from_quaternion,
    section_quaternion,
)
from optikin.errors import InputDataError


def reference_section_transform(S: float, theta: float, phi: float) -> np.ndarray:
    """Rz(phi) Ry(theta) Rz(-phi) and the arc end point, written from the textbook (Webster & Jones 2010)."""
    R = (Rotation.from_euler("z", phi) * Rotation.from_euler("y", theta) * Rotation.from_euler("z", -phi)).as_matrix()
    if abs(theta) > 1e-6:
        r = S / theta
        p = np.array([r * (1 - np.cos(theta)) * np.cos(phi), r * (1 - np.cos(theta)) * np.sin(phi), r * np.sin(theta)])
    else:
        p = np.array([0.0, 0.0, S])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def reference_tip_transform(q: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    for S, theta, phi in q.reshape(-1, 3):
        T = T @ reference_section_transform(S, theta, phi)
    return T


@pytest.fixture(scope="module")
def arm() -> ConstantCurvatureArm:
    return ConstantCurvatureArm()


@pytest.fixture(scope="module")
def three_section_arm() -> ConstantCurvatureArm:
    return ConstantCurvatureArm(section_lengths=(0.2, 0.15, 0.1))


def _bent(arm: ConstantCurvatureArm, rng: np.random.Generator, n: int) -> np.ndarray:
    Q = arm.sample_configurations(n, rng)
    Q[:, 1::3] = np.where(np.abs(Q[:, 1::3]) < 1e-2, 0.3, Q[:, 1::3])  # keep away from the reference's switch
    return Q


@pytest.mark.parametrize("arm_name", ["arm", "three_section_arm"])
def test_tip_transform_matches_chained_textbook_transforms(arm_name, request):
    arm = request.getfixturevalue(arm_name)
    rng = np.random.default_rng(0)
    for q in _bent(arm, rng, 20):
        np.testing.assert_allclose(arm.transform_of(q), reference_tip_transform(q), atol=1e-14)


def test_tip_dual_quaternion_matches_pytransform3d(arm):
    rng = np.random.default_rng(1)
    Q = _bent(arm, rng, 20)
    ours = arm.evaluate("fk_dq", Q)
    for q, dq in zip(Q, ours):
        ref = dual_quaternion_from_transform(reference_tip_transform(q))
        ref = ref if ref[0] * dq[0] >= 0 else -ref
        np.testing.assert_allclose(dq, ref, atol=1e-14)


def test_straight_arm_points_up(arm):
    p = np.asarray(arm.fk_position(arm.straight_configuration())).ravel()
    np.testing.assert_allclose(p, [0, 0, 0.36], atol=1e-15)


def test_seed_eq2_taylor_form_is_this_convention_with_phi_plus_pi():
    """Seed 000 eq. (2) bends towards -x for phi = 0: it equals p(S, theta, phi + pi) to O(theta^5)."""
    arm = ConstantCurvatureArm(section_lengths=(0.18,))
    for S, theta, phi in [(0.18, 0.05, 0.3), (0.17, -0.02, 2.0), (0.19, 0.08, -1.2)]:
        seed = np.array(
            [
                S * theta * np.cos(phi) * (theta**2 - 12) / 24,
                S * theta * np.sin(phi) * (theta**2 - 12) / 24,
                -S * (theta**2 - 6) / 6,
            ]
        )
        ours = np.asarray(arm.fk_position([S, theta, phi + np.pi])).ravel()
        assert np.abs(ours - seed).max() < S * theta**4 / 100


def _central_difference(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = []
    for j in range(len(q)):
        e = np.zeros_like(q)
        e[j] = h
        cols.append((np.asarray(f(q + e)).ravel() - np.asarray(f(q - e)).ravel()) / (2 * h))
    return np.array(cols).T


@pytest.mark.parametrize("theta_offset", [0.0, 1e-8, -3e-9, 5e-4, 1e-3, 2e-3, 0.7])
def test_jacobians_match_finite_differences_including_straight_sections(arm, theta_offset):
    rng = np.random.default_rng(2)
    for q in arm.sample_configurations(5, rng):
        q[1] = theta_offset
        q[4] = -theta_offset / 2
        for fk, jac in (("fk_position", "jac_position"), ("fk_dq", "jac_dq")):
            J = np.asarray(getattr(arm, jac)(q))
            J_fd = _central_difference(getattr(arm, fk), q)
            assert np.all(np.isfinite(J))
            scale = max(np.abs(J_fd).max(), 1.0)
            assert np.abs(J - J_fd).max() / scale < 1e-6, (fk, q)


def test_jacobian_at_exactly_straight_section_has_closed_form(arm):
    """d p / d theta_1 at theta = 0 is S_1/2 along (cos phi, sin phi) plus the lever of section 2."""
    S1, phi1, S2 = 0.18, 0.4, 0.17
    q = np.array([S1, 0.0, phi1, S2, 0.0, 0.0])
    J = np.asarray(arm.jac_position(q))
    # bending section 1 by d theta tilts section 2 (length S2) by the same angle about the same axis
    expected = (S1 / 2 + S2) * np.array([np.cos(phi1), np.sin(phi1), 0.0])
    np.testing.assert_allclose(J[:, 1], expected, atol=1e-15)
    np.testing.assert_allclose(J[:, 0], [0, 0, 1], atol=1e-15)


def test_backbone_ends_at_tip_and_starts_at_base(arm):
    rng = np.random.default_rng(3)
    Q = arm.sample_configurations(10, rng)
    pts = arm.evaluate("backbone", Q)
    np.testing.assert_allclose(pts[:, :, 0], 0.0, atol=1e-15)
    np.testing.assert_allclose(pts[:, :, -1], arm.evaluate("fk_position", Q), atol=1e-15)
    # consecutive points on a CC arc are equally spaced chords of length 2 r sin(dtheta / 2)
    S, theta = Q[0, 0], Q[0, 1]
    n = arm.backbone_points_per_section
    chord = np.linalg.norm(np.diff(pts[0, :, : n + 1], axis=1), axis=0)
    expected = 2 * S / abs(theta) * np.sin(abs(theta) / (2 * n))
    np.testing.assert_allclose(chord, expected, rtol=1e-12)


def test_section_dq_last_column_is_tip(arm):
    rng = np.random.default_rng(4)
    Q = arm.sample_configurations(5, rng)
    sections = arm.evaluate("section_dq", Q)
    np.testing.assert_allclose(sections[:, :, -1], arm.evaluate("fk_dq", Q), atol=1e-15)
    first = np.array([reference_section_transform(*q[:3])[:3, 3] for q in Q])
    np.testing.assert_allclose(dq_translation(sections[:, :, 0]), first, atol=1e-14)


def test_numpy_and_casadi_paths_agree(three_section_arm):
    rng = np.random.default_rng(5)
    Q = three_section_arm.sample_configurations(50, rng)
    quat, pos = three_section_arm.section_frames(Q)[-1]
    np.testing.assert_allclose(pos, three_section_arm.evaluate("fk_position", Q), atol=1e-15)


def test_imu_round_trip_configuration_quaternion_angles():
    """q -> section quaternion -> (theta, phi) -> q, for theta in (0, pi) (seed 000 eqs. 6-8)."""
    rng = np.random.default_rng(6)
    theta = rng.uniform(1e-6, np.pi - 1e-6, 200)
    phi = rng.uniform(-np.pi + 1e-9, np.pi, 200)
    quat = section_quaternion(theta, phi)
    th, ph = section_angles_from_quaternion(quat)
    np.testing.assert_allclose(th, theta, atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (ph - phi))), 0.0, atol=1e-9)


def test_imu_angles_ignore_twist_about_the_tip_axis():
    theta, phi = 0.8, -2.1
    twisted = quat_multiply(section_quaternion(theta, phi), quat_from_rpy(0.0, 0.0, 0.9))
    th, ph = section_angles_from_quaternion(twisted)
    assert th == pytest.approx(theta, abs=1e-12)
    assert ph == pytest.approx(phi, abs=1e-12)


def test_relative_imu_quaternions_recover_both_sections(arm):
    """Two IMUs in the base frame -> eq. (7) relative quaternion -> each section's angles."""
    q = np.array([0.18, 0.7, 0.3, 0.18, 1.1, -2.0])
    sections = arm.evaluate("section_dq", q[None])[0]
    imu = sections[:4].T  # the orientation part of each section end, in the base frame
    rel = relative_section_quaternions(imu)
    for i in range(2):
        th, ph = section_angles_from_quaternion(rel[i])
        assert th == pytest.approx(q[3 * i + 1], abs=1e-12)
        assert ph == pytest.approx(q[3 * i + 2], abs=1e-12)


def test_validate_names_sample_and_variable(arm):
    Q = np.tile(arm.straight_configuration(), (4, 1))
    Q[2, 4] = 3.0  # theta2 beyond 120 degrees
    with pytest.raises(InputDataError, match=r"sample 2: theta2: 3 outside"):
        arm.validate(Q, source="test")
    Q[2, 4] = np.nan
    with pytest.raises(InputDataError, match=r"sample 2: theta2: nan is not a finite number"):
        arm.validate(Q, source="test")
    with pytest.raises(InputDataError, match=r"expected shape \(N, 6\)"):
        arm.validate(np.zeros((3, 5)), source="test")


@pytest.mark.parametrize(
    "bad",
    [dict(section_lengths=()), dict(section_lengths=(0.1, -0.2)), dict(theta_max=4.0), dict(length_range=(1.2, 1.1))],
)
def test_invalid_geometry_rejected(bad):
    with pytest.raises(ValueError):
        ConstantCurvatureArm(**bad)


def test_non_unit_imu_quaternion_is_rejected_naming_the_sample():
    imu = np.tile([1.0, 0.0, 0.0, 0.0], (5, 2, 1))
    imu[3, 1] = [0.9, 0.1, 0.0, 0.0]
    with pytest.raises(InputDataError, match=r"imu.csv: sample 3: quaternion \[1\]: .* is not a unit quaternion"):
        relative_section_quaternions(imu, source="imu.csv")
    imu[3, 1] = [np.nan, 0, 0, 1]
    with pytest.raises(InputDataError, match=r"sample 3: quaternion \[1\]"):
        relative_section_quaternions(imu, source="imu.csv")
