"""CBHA vertebra model (seed 004): cross-checks against independent constructions.

References used here, none of them the code under test:
- seed 004 Table I, typed in again below from the paper (millimetres);
- eq. (2) written out for its end points; eqs. (3)-(5) written out in numpy, and pytransform3d's
  rotations and dual quaternions for the chained transforms;
- the printed eqs. (7)-(9), term by term;
- central finite differences of the tip position;
- scipy SLSQP probing the extremes of every platform's feasible set.
"""

from __future__ import annotations

import numpy as np
import pytest
from pytransform3d.rotations import active_matrix_from_angle
from pytransform3d.transformations import transform_from, transform_from_dual_quaternion
from scipy.optimize import minimize

from optikin.arms.cbha import (
    PLATFORM_LEG_LENGTHS,
    CBHAArm,
    CBHAGeometry,
    platform_transform,
    printed_leg_lengths,
)
from optikin.errors import InputDataError

Q_MIN_MM = [8.5, 8.5, 8.5, 7, 7, 7, 8.5, 10, 6.5, 8, 8, 7.5, 7.5, 7, 7, 6.5]
Q_MAX_MM = [19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5, 20.5, 19, 19, 18, 18, 16]
SQ3 = np.sqrt(3.0)
U = np.array([[-1.0, 0.0, 0.0], [0.5, SQ3 / 2, 0.0], [0.5, -SQ3 / 2, 0.0]])  # eq. (3) divided by r


def radii(g: CBHAGeometry) -> np.ndarray:
    """Eq. (2) with vertebra 1 at r_max and vertebra N at r_min: a straight taper."""
    return np.linspace(g.r_max, g.r_min, g.n_vertebrae)


def rotation(theta: float, psi: float) -> np.ndarray:
    return active_matrix_from_angle(1, theta) @ active_matrix_from_angle(0, psi)


def reference_legs(Z: float, theta: float, psi: float, r_k: float, r_k1: float) -> np.ndarray:
    """|T A_{m,k+1} - A_{m,k}| (eqs. 3, 4, 6), numpy."""
    return np.linalg.norm((rotation(theta, psi) @ (r_k1 * U).T).T + [0.0, 0.0, Z] - r_k * U, axis=1)


def reference_chain(q: np.ndarray) -> list[np.ndarray]:
    """4x4 poses of vertebrae 1..17 as products of the eq. (5) transforms."""
    T = [np.eye(4)]
    for Z, theta, psi in q.reshape(-1, 3):
        T.append(T[-1] @ transform_from(rotation(theta, psi), [0.0, 0.0, Z]))
    return T


@pytest.fixture(scope="module")
def arm() -> CBHAArm:
    return CBHAArm()


@pytest.fixture(scope="module")
def random_q(arm: CBHAArm) -> np.ndarray:
    return arm.sample_configurations(6, np.random.default_rng(4))


def _random_platform_inputs(rng: np.random.Generator, n: int) -> np.ndarray:
    Z = rng.uniform(-0.03, 0.03, n)
    theta, psi = rng.uniform(-np.pi, np.pi, (2, n))
    r_k, r_k1 = rng.uniform(0.01, 0.06, (2, n))
    return np.vstack([Z, theta, psi, r_k, r_k1])


# ------------------------------------------------------------------ eqs. (7)-(9)
def test_derived_leg_lengths_equal_printed_eqs_7_to_9():
    """Eqs. (7)-(9) as printed are right: they equal |Q_{m,k}| of eqs. (3)-(6) for any pose and radii."""
    X = _random_platform_inputs(np.random.default_rng(0), 500)
    derived = np.asarray(PLATFORM_LEG_LENGTHS.map(X.shape[1])(*X[:, None, :]))
    printed = np.array(printed_leg_lengths(*X))
    reference = np.array([reference_legs(*x) for x in X.T]).T
    np.testing.assert_allclose(derived, reference, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(printed, derived, rtol=1e-10, atol=1e-15)


@pytest.mark.parametrize("term, zero", [("Z r_{k+1} (tilt of the leg ends)", 3), ("r_k r_{k+1} (alignment)", 0)])
def test_printed_eqs_term_by_term(term: str, zero: int):
    """Each term of eqs. (7)-(9) on its own: ``r_k = 0`` leaves only the ``Z r_{k+1}`` term,
    ``Z = 0`` only the ``r_k r_{k+1}`` one; both agree with the derivation, so no term is misprinted."""
    X = _random_platform_inputs(np.random.default_rng(1), 200)
    X[zero] = 0.0
    derived = np.asarray(PLATFORM_LEG_LENGTHS.map(X.shape[1])(*X[:, None, :])) ** 2
    printed = np.array(printed_leg_lengths(*X)) ** 2
    np.testing.assert_allclose(printed, derived, rtol=1e-10, atol=1e-16, err_msg=term)


def test_printed_eqs_fix_which_radius_is_the_upper_one():
    """The ``Z r_{k+1}`` terms make eqs. (7)-(9) asymmetric in the radii: swapping r_k and r_{k+1}
    changes them, so their agreement with the derivation confirms r_{k+1} is the upper vertebra's."""
    X = _random_platform_inputs(np.random.default_rng(2), 200)
    swapped = np.array(printed_leg_lengths(X[0], X[1], X[2], X[4], X[3]))
    derived = np.asarray(PLATFORM_LEG_LENGTHS.map(X.shape[1])(*X[:, None, :]))
    assert np.max(np.abs(swapped - derived)) > 1e-3


# ------------------------------------------------------------------ geometry
def test_radii_taper_per_eq_2(arm: CBHAArm):
    g = arm.geometry
    r = np.array([g.vertebra_radius(n) for n in range(1, 18)])
    assert r[0] == pytest.approx(g.r_max) and r[-1] == pytest.approx(g.r_min)
    np.testing.assert_allclose(np.diff(r), (g.r_min - g.r_max) / 16, rtol=1e-12)
    np.testing.assert_allclose(g.radii, r, rtol=0, atol=0)
    # Printed eq. (2) with k = n: r_1 = r_max - (r_max - r_min)/17, i.e. the base vertebra would miss r_max.
    assert 1 / 17 * (g.r_min - g.r_max) + g.r_max < r[0] - 1e-4
    with pytest.raises(ValueError, match="vertebra index"):
        g.vertebra_radius(18)


def test_table_i_in_metres(arm: CBHAArm):
    lo, hi = arm.leg_limits()
    np.testing.assert_allclose(lo, np.repeat(Q_MIN_MM, 3) / 1000, rtol=1e-15)
    np.testing.assert_allclose(hi, np.repeat(Q_MAX_MM, 3) / 1000, rtol=1e-15)


def test_geometry_rejects_inconsistent_values():
    with pytest.raises(ValueError, match="r_min <= r_max"):
        CBHAGeometry(r_min=0.05, r_max=0.04)
    with pytest.raises(ValueError, match="one value per platform"):
        CBHAGeometry(leg_min=(0.01,) * 15)
    with pytest.raises(ValueError, match="add up to 16"):
        CBHAGeometry(platforms_per_section=(8, 7))
    assert CBHAArm({"r_max": 0.05}).geometry.r_max == 0.05  # a problem file's mapping


# ------------------------------------------------------------------ legs and kinematics
def test_leg_lengths_match_numpy(arm: CBHAArm):
    r = radii(arm.geometry)
    Q = arm.sample_configurations(20, np.random.default_rng(5))
    Q[:10] = np.random.default_rng(6).uniform(arm.lower, arm.upper, (10, 48))  # also outside Table I
    expected = np.array(
        [
            np.concatenate([reference_legs(Z, t, p, r[k], r[k + 1]) for k, (Z, t, p) in enumerate(q.reshape(-1, 3))])
            for q in Q
        ]
    )
    np.testing.assert_allclose(arm.evaluate("leg_lengths", Q), expected, rtol=1e-12)


@pytest.mark.parametrize("fraction", [0.0, 0.5, 1.0])
def test_straight_configuration(arm: CBHAArm, fraction: float):
    q = arm.straight_configuration(fraction)
    legs_mm = np.array(Q_MIN_MM) + fraction * (np.array(Q_MAX_MM) - np.array(Q_MIN_MM))
    np.testing.assert_allclose(
        arm.leg_lengths(q).full().reshape(16, 3), np.repeat(legs_mm[:, None], 3, 1) / 1000, rtol=1e-12
    )
    P = arm.backbone(q).full()
    np.testing.assert_allclose(P[:2], 0.0, atol=1e-15)
    assert np.all(np.diff(P[2]) > 0)
    height = np.sum(np.sqrt((legs_mm / 1000) ** 2 - np.diff(radii(arm.geometry)) ** 2))
    np.testing.assert_allclose(arm.transform_of(q), transform_from(np.eye(3), [0, 0, height]), atol=1e-14)
    arm.validate(q)


def test_fk_equals_product_of_platform_transforms(random_q: np.ndarray):
    tool = 0.07
    arm = CBHAArm(CBHAGeometry(tool_offset=tool))
    for q in random_q:
        T = reference_chain(q)
        np.testing.assert_allclose(arm.transform_of(q), T[-1] @ transform_from(np.eye(3), [0, 0, tool]), atol=1e-14)
        section = arm.section_dq(q).full()
        np.testing.assert_allclose(transform_from_dual_quaternion(section[:, 0]), T[8], atol=1e-14)
        frames = arm.vertebra_frames(q).full()
        for n in range(17):
            np.testing.assert_allclose(transform_from_dual_quaternion(frames[:, n]), T[n], atol=1e-14)
        np.testing.assert_allclose(arm.vertebra_positions(q).full(), np.array([t[:3, 3] for t in T]).T, atol=1e-15)


def test_numpy_paths_match_the_reference(arm: CBHAArm, random_q: np.ndarray):
    """``platform_transform`` and ``vertebra_chain`` evaluated on numpy arrays (a batch)."""
    Z, theta, psi = random_q[:, :3].T
    expected = [transform_from(rotation(t, p), [0.0, 0.0, z]) for z, t, p in zip(Z, theta, psi)]
    np.testing.assert_allclose(platform_transform(Z, theta, psi), expected, atol=1e-15)
    positions = np.array([pos for _, pos in arm.vertebra_chain(random_q)])  # vertebra, sample, xyz
    expected = np.array([[t[:3, 3] for t in reference_chain(q)] for q in random_q])
    np.testing.assert_allclose(positions.transpose(1, 0, 2), expected, atol=1e-15)


def test_jac_position_matches_central_differences(arm: CBHAArm, random_q: np.ndarray):
    h = 1e-6
    for q in [arm.straight_configuration(0.3), *random_q[:3]]:
        steps = h * np.eye(48)
        p_plus = arm.evaluate("fk_position", q + steps)
        p_minus = arm.evaluate("fk_position", q - steps)
        J_fd = ((p_plus - p_minus) / (2 * h)).T
        J = arm.jac_position(q).full()
        assert np.linalg.norm(J - J_fd) / np.linalg.norm(J) < 1e-6


def test_tube_points_and_lengths(arm: CBHAArm, random_q: np.ndarray):
    r = radii(arm.geometry)
    for q in random_q[:3]:
        T = reference_chain(q)
        A = arm.tube_points(q).full().reshape(3, 3, 17)  # xyz, tube, vertebra
        expected = np.array([[T[n][:3, :3] @ (r[n] * U[m]) + T[n][:3, 3] for n in range(17)] for m in range(3)])
        np.testing.assert_allclose(A.transpose(1, 2, 0), expected, atol=1e-15)
        legs = np.array([reference_legs(Z, t, p, r[k], r[k + 1]) for k, (Z, t, p) in enumerate(q.reshape(-1, 3))])
        np.testing.assert_allclose(np.linalg.norm(np.diff(A, axis=2), axis=0).T, legs, rtol=1e-12)
        np.testing.assert_allclose(arm.tube_lengths(q).full(), [legs[:8].sum(0), legs[8:].sum(0)], rtol=1e-12)


def test_backbone_interpolates_between_vertebrae(random_q: np.ndarray):
    q = random_q[0]
    centres = np.array([t[:3, 3] for t in reference_chain(q)]).T
    fine = CBHAArm(backbone_points_per_section=16).backbone(q).full()
    np.testing.assert_allclose(fine[:, ::2], centres, atol=1e-15)
    np.testing.assert_allclose(fine[:, 1::2], 0.5 * (centres[:, :-1] + centres[:, 1:]), atol=1e-15)
    coarse = CBHAArm(backbone_points_per_section=3).backbone(q).full()  # section 1 at t = 8/3, 16/3, 8
    assert coarse.shape == (3, 7)
    np.testing.assert_allclose(coarse[:, 1], centres[:, 2] + 2 / 3 * (centres[:, 3] - centres[:, 2]), atol=1e-15)
    np.testing.assert_allclose(coarse[:, 3], centres[:, 8], atol=1e-15)


# ------------------------------------------------------------------ bounds and limits
def _leg_vectors(X: np.ndarray, r_k: float, r_k1: float) -> np.ndarray:
    """Q_{m,k} of eq. (4) for poses ``X = (N, 3)``: shape (N, leg, xyz).

    ``Ry(theta) Rx(psi) (u_x, u_y, 0) = (u_x ct + u_y sp st, u_y cp, -u_x st + u_y sp ct)``, multiplied out by hand.
    """
    Z, theta, psi = (c[:, None] for c in np.asarray(X).T)
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    ux, uy = U[:, 0], U[:, 1]
    return np.stack(
        [r_k1 * (ux * ct + uy * sp * st) - r_k * ux, r_k1 * uy * cp - r_k * uy, Z + r_k1 * (-ux * st + uy * sp * ct)],
        axis=-1,
    )


def test_legs_alone_do_not_bound_z_from_below():
    """Z -> -Z at theta = psi = 0 mirrors the upper vertebra and keeps every leg: hence the
    assumption, in the bounds, that the legs' upper ends lie above the lower vertebra."""
    X = _random_platform_inputs(np.random.default_rng(3), 50)
    X[1:3] = 0.0
    up = np.asarray(PLATFORM_LEG_LENGTHS.map(50)(*X[:, None, :]))
    X[0] = -X[0]
    np.testing.assert_allclose(np.asarray(PLATFORM_LEG_LENGTHS.map(50)(*X[:, None, :])), up, rtol=1e-14)


def test_bounds_contain_every_pose_within_table_i(arm: CBHAArm):
    """Random poses of every platform in {legs within Table I, upper leg ends above the lower
    vertebra} lie within the bounds. Z's upper bound and the angle bounds are closed-form
    inequalities; Z's lower bound is not, so it is also probed by minimising Z (SLSQP)."""
    rng = np.random.default_rng(7)
    r = radii(arm.geometry)
    lower, upper = arm.lower.reshape(16, 3), arm.upper.reshape(16, 3)
    for k in range(16):
        lo_q, hi_q = Q_MIN_MM[k] / 1000, Q_MAX_MM[k] / 1000

        def constraints(x, k=k, lo_q=lo_q, hi_q=hi_q):
            Q = _leg_vectors(np.atleast_2d(x), r[k], r[k + 1])
            q = np.linalg.norm(Q, axis=-1)
            return np.concatenate([q - lo_q, hi_q - q, Q[..., 2]], axis=-1).squeeze()

        # Summing |Q_m|^2 over the legs: 1 - cos(theta) <= q_max^2 / (r_k r_{k+1}), so |theta|, |psi| < 1 rad here.
        assert np.arccos(1 - hi_q**2 / (r[k] * r[k + 1])) < 1.0
        X = np.column_stack([rng.uniform(-hi_q, 1.5 * hi_q, 40000), rng.uniform(-1.0, 1.0, (40000, 2))])
        feasible = X[np.all(constraints(X) >= 0, axis=1)]
        assert len(feasible) > 20
        assert np.all(feasible >= lower[k]) and np.all(feasible <= upper[k]), k + 1
        res = minimize(
            lambda x: x[0],
            feasible[np.argmin(feasible[:, 0])],
            method="SLSQP",
            constraints={"type": "ineq", "fun": constraints},
            options={"ftol": 1e-12},
        )
        assert res.success and np.all(constraints(res.x) >= -1e-12)
        assert res.x[0] == pytest.approx(lower[k, 0], abs=1e-9), k + 1


def test_sample_configurations_respect_table_i(arm: CBHAArm):
    Q = arm.sample_configurations(200, np.random.default_rng(8))
    np.testing.assert_array_equal(Q, arm.sample_configurations(200, np.random.default_rng(8)))
    arm.validate(Q)
    r = radii(arm.geometry)
    for q in Q[:20]:
        for k, x in enumerate(q.reshape(-1, 3)):
            legs = reference_legs(*x, r[k], r[k + 1])
            assert np.all(legs >= Q_MIN_MM[k] / 1000) and np.all(legs <= Q_MAX_MM[k] / 1000)


def test_check_leg_lengths_names_sample_and_leg(arm: CBHAArm):
    L = np.tile(np.repeat(np.array(Q_MIN_MM) + 1.0, 3) / 1000, (3, 1))
    np.testing.assert_array_equal(arm.check_leg_lengths(L), L)
    L[1, 3 * 4 + 1] = 0.030  # sample 1, tube 2 of platform 5
    with pytest.raises(InputDataError, match=r"data\.csv: sample 1: q2_5: 30\.000 mm outside .*platform 5, tube 2"):
        arm.check_leg_lengths(L, source="data.csv")
    L[1, 3 * 4 + 1] = np.nan
    with pytest.raises(InputDataError, match="sample 1: q2_5"):
        arm.check_leg_lengths(L)
    with pytest.raises(InputDataError, match=r"shape \(N, 48\)"):
        arm.check_leg_lengths(L[:, :47])
