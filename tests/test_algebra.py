"""Independent tests of the quaternion and dual-quaternion algebra (`optikin.algebra`).

Every expected value comes from a source other than the code under test:
pytransform3d, scipy's ``Rotation``, closed forms evaluated in extended
precision (``np.longdouble``), or the power series of the exponential in the
dual-quaternion algebra (summed in extended precision). Conventions (docs/conventions.md):
quaternions ``(w, x, y, z)`` Hamilton; ``Q = Q_r + eps Q_d`` with
``Q_d = 0.5 (0, p) Q_r``; ``quat_log`` returns half the rotation vector.
"""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np
import pytest
import pytransform3d.rotations as pr
import pytransform3d.transformations as pt
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from optikin.algebra import (
    dq_combined_conjugate,
    dq_conjugate,
    dq_dual_number_conjugate,
    dq_exp,
    dq_from_parts,
    dq_from_rotation_translation,
    dq_from_transform,
    dq_log,
    dq_multiply,
    dq_norm_residual,
    dq_parts,
    dq_pose_error,
    dq_power,
    dq_rotation,
    dq_sclerp,
    dq_transform_point,
    dq_translation,
    matrix_from_quat,
    quat_angle,
    quat_conjugate,
    quat_exp,
    quat_from_axis_angle,
    quat_from_matrix,
    quat_from_pure,
    quat_from_rpy,
    quat_hemisphere_continuous,
    quat_inverse,
    quat_log,
    quat_multiply,
    quat_norm,
    quat_normalize,
    quat_power,
    quat_rotate,
    quat_slerp,
    quat_vector,
    rpy_from_quat,
    transform_from_dq,
)
from optikin.algebra.backend import SERIES_BAND

HYP = settings(max_examples=50, deadline=None, derandomize=True)
LD = np.longdouble
EPS = np.finfo(float).eps

# Half angles a (q = (cos a, sin a n)) at and around the series switches:
# quat_log switches on |vec(q)| = sin(a) = 1e-3, the dual-quaternion
# coefficients on |u| = a = 1e-3.
A_BAND = SERIES_BAND
A_SIN_BAND = float(np.arcsin(SERIES_BAND))
HALF_ANGLES_NEAR_IDENTITY = [
    1e-12,
    1e-8,
    1e-4,
    A_BAND * (1 - 1e-9),
    A_BAND,
    A_BAND * (1 + 1e-9),
    A_SIN_BAND * (1 - 1e-12),
    A_SIN_BAND,
    A_SIN_BAND * (1 + 1e-12),
    A_BAND * (1 + 1e-4),
    1e-2,
]


# ---------------------------------------------------------------------------
# Independent references (extended precision where it matters)
# ---------------------------------------------------------------------------


def ref_qmul(p, q):
    """Hamilton product in scalar/vector form: (p0 q0 - p.q, p0 q + q0 p + p x q)."""
    p, q = np.asarray(p, LD), np.asarray(q, LD)
    w = p[0] * q[0] - np.dot(p[1:], q[1:])
    v = p[0] * q[1:] + q[0] * p[1:] + np.cross(p[1:], q[1:])
    return np.concatenate([[w], v])


def ref_dqmul(a, b):
    a, b = np.asarray(a, LD), np.asarray(b, LD)
    return np.concatenate([ref_qmul(a[:4], b[:4]), ref_qmul(a[:4], b[4:]) + ref_qmul(a[4:], b[:4])])


def ref_quat_exp(v):
    """exp(0, v) = (cos|v|, sin|v| v/|v|)."""
    v = np.asarray(v, LD)
    a = np.sqrt(np.dot(v, v))
    s = np.sin(a) / a if a > 0 else LD(1)
    return np.concatenate([[np.cos(a)], s * v])


def ref_quat_log(q):
    """Half rotation vector of q: atan2(|vec|, w) vec/|vec| (the limit 1/w at vec = 0)."""
    q = np.asarray(q, LD)
    s = np.sqrt(np.dot(q[1:], q[1:]))
    ratio = np.arctan2(s, q[0]) / s if s > 0 else 1 / q[0]
    return ratio * q[1:]


def ref_left_matrix(dq):
    """8x8 matrix of left multiplication by a dual quaternion, columns from ref_qmul on the basis."""
    r, d = np.asarray(dq, LD)[:4], np.asarray(dq, LD)[4:]
    Lr = np.stack([ref_qmul(r, e) for e in np.eye(4, dtype=LD)], axis=1)
    Ld = np.stack([ref_qmul(d, e) for e in np.eye(4, dtype=LD)], axis=1)
    return np.block([[Lr, np.zeros((4, 4), LD)], [Ld, Lr]])


def ref_dq_exp(xi, terms=36):
    """exp of the pure dual quaternion (0, u) + eps (0, v) by its power series, in long double.

    The dual part of the k-th term is at most |u|^(k-1) |v| / (k-1)!, so 36 terms reach
    long-double precision for |u| <= pi.
    """
    xi = np.asarray(xi, LD)
    L = ref_left_matrix(np.concatenate([[0], xi[:3], [0], xi[3:]]))
    term = np.zeros(8, LD)
    term[0] = 1
    total = term.copy()
    for k in range(1, terms):
        term = L @ term / k
        total = total + term
    return total


def _solve3(A, b):
    """3x3 linear solve by the adjugate (works in long double)."""
    cof = np.array([np.cross(A[:, 1], A[:, 2]), np.cross(A[:, 2], A[:, 0]), np.cross(A[:, 0], A[:, 1])])
    return cof @ b / np.dot(A[:, 0], cof[0])


def ref_dq_log(Q):
    """Inverse of ref_dq_exp: u = log Q_r (closed form); v solves the linear dual part of the series."""
    Q = np.asarray(Q, LD)
    u = ref_quat_log(Q[:4])
    # The dual part of exp(u + eps v) is linear in v: its columns from the series.
    D = np.stack([ref_dq_exp(np.concatenate([u, e]))[4:] for e in np.eye(3, dtype=LD)], axis=1)
    v = _solve3(D.T @ D, D.T @ Q[4:])
    return np.concatenate([u, v])


def screw(n, c, theta, d):
    """Dual quaternion and its log for a screw: rotation theta about the axis n through c, slide d along n.

    With Plücker line L = n + eps (c x n) and dual angle Theta = theta + eps d,
    Q = cos(Theta/2) + sin(Theta/2) L and log Q = Theta/2 L, i.e.
    u = theta/2 n and v = d/2 n + theta/2 (c x n). Returns (dq in long double, log, p).
    """
    n = np.asarray(n, LD) / np.sqrt(np.dot(np.asarray(n, LD), np.asarray(n, LD)))
    c = np.asarray(c, LD)
    c = c - np.dot(c, n) * n
    theta, d = LD(theta), LD(d)
    qr = np.concatenate([[np.cos(theta / 2)], np.sin(theta / 2) * n])
    # p = (I - R) c + d n with R c by Rodrigues (c is perpendicular to n).
    p = c * (1 - np.cos(theta)) - np.cross(n, c) * np.sin(theta) + d * n
    qd = ref_qmul(np.concatenate([[0], p]), qr) / 2
    log = np.concatenate([theta / 2 * n, d / 2 * n + theta / 2 * np.cross(c, n)])
    return np.concatenate([qr, qd]), log, p


def rot_x(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def rot_y(a):
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def rot_z(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def close_up_to_sign(a, b, atol):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return min(np.max(np.abs(a - b)), np.max(np.abs(a + b))) <= atol


def rel_err(got, ref):
    got, ref = np.asarray(got, float), np.asarray(ref, float)
    return np.linalg.norm(got - ref) / max(np.linalg.norm(ref), 1e-300)


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# ---------------------------------------------------------------------------
# Hypothesis strategies
# ---------------------------------------------------------------------------

_f = lambda lo, hi: st.floats(lo, hi, allow_nan=False, allow_infinity=False)  # noqa: E731
axes = st.tuples(_f(-1, 1), _f(-1, 1), _f(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.2).map(unit)
rotation_angles = st.one_of(
    _f(0.0, np.pi),
    st.sampled_from([0.0, 1e-12, 1e-7, 2e-3, np.pi - 1e-7, np.pi]),
)
vectors3 = st.tuples(_f(-2, 2), _f(-2, 2), _f(-2, 2)).map(np.array)


@st.composite
def quaternions(draw, angles=rotation_angles, signed=True):
    n, angle = draw(axes), draw(angles)
    q = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * n])
    return -q if signed and draw(st.booleans()) else q


@st.composite
def general_quaternions(draw):
    """Non-unit quaternions (norm in about [0.2, 2])."""
    q = np.array(draw(st.tuples(_f(-1, 1), _f(-1, 1), _f(-1, 1), _f(-1, 1))))
    if np.linalg.norm(q) < 0.2:
        q = q + np.array([0.5, 0, 0, 0])
    return q


poses = st.tuples(quaternions(), vectors3)


# ---------------------------------------------------------------------------
# Quaternion: product, conjugate, inverse, norm, rotation
# ---------------------------------------------------------------------------


@HYP
@given(quaternions(), quaternions())
def test_product_matches_pytransform3d_and_matrix_product(p, q):
    pq = quat_multiply(p, q)
    np.testing.assert_allclose(pq, pr.concatenate_quaternions(p, q), atol=1e-15)
    np.testing.assert_allclose(
        matrix_from_quat(pq), pr.matrix_from_quaternion(p) @ pr.matrix_from_quaternion(q), atol=1e-14
    )


@HYP
@given(general_quaternions(), general_quaternions())
def test_conjugate_inverse_norm_of_general_quaternions(p, q):
    w, x, y, z = q
    np.testing.assert_array_equal(quat_conjugate(q), [w, -x, -y, -z])
    assert quat_norm(q) == pytest.approx(np.linalg.norm(q), rel=1e-15)
    # |p q| = |p| |q|
    assert quat_norm(quat_multiply(p, q)) == pytest.approx(np.linalg.norm(p) * np.linalg.norm(q), rel=1e-14)
    np.testing.assert_allclose(quat_multiply(q, quat_inverse(q)), [1, 0, 0, 0], atol=1e-14)
    np.testing.assert_allclose(quat_multiply(quat_inverse(q), q), [1, 0, 0, 0], atol=1e-14)
    np.testing.assert_allclose(quat_inverse(q), np.array([w, -x, -y, -z]) / np.dot(q, q), rtol=1e-14)
    np.testing.assert_allclose(quat_normalize(q), q / np.linalg.norm(q), rtol=1e-15, atol=1e-16)
    # (p q)* = q* p*
    np.testing.assert_allclose(
        quat_conjugate(quat_multiply(p, q)), pr.concatenate_quaternions(pr.q_conj(q), pr.q_conj(p)), atol=1e-14
    )


@HYP
@given(quaternions(), vectors3)
def test_rotate_vector_matches_rotation_matrix(q, v):
    R = pr.matrix_from_quaternion(q)
    np.testing.assert_allclose(quat_rotate(q, v), R @ v, atol=1e-14)
    np.testing.assert_allclose(quat_rotate(q, v), pr.q_prod_vector(q, v), atol=1e-14)
    np.testing.assert_allclose(quat_rotate(q, v), Rotation.from_quat(q, scalar_first=True).apply(v), atol=1e-14)


def test_batched_product_and_rotation_broadcast():
    rng = np.random.default_rng(0)
    P = Rotation.random(6, random_state=1).as_quat(scalar_first=True).reshape(2, 3, 4)
    Q = Rotation.random(6, random_state=2).as_quat(scalar_first=True).reshape(2, 3, 4)
    V = rng.normal(size=(2, 3, 3))
    PQ = quat_multiply(P, Q)
    PQ0 = quat_multiply(P, Q[0, 0])  # broadcast one quaternion against a batch
    PV = quat_rotate(P, V)
    assert PQ.shape == (2, 3, 4) and PQ0.shape == (2, 3, 4) and PV.shape == (2, 3, 3)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(PQ[i, j], pr.concatenate_quaternions(P[i, j], Q[i, j]), atol=1e-15)
            np.testing.assert_allclose(PQ0[i, j], pr.concatenate_quaternions(P[i, j], Q[0, 0]), atol=1e-15)
            np.testing.assert_allclose(PV[i, j], pr.matrix_from_quaternion(P[i, j]) @ V[i, j], atol=1e-14)
    assert quat_norm(P).shape == (2, 3)
    np.testing.assert_allclose(quat_norm(P), 1.0, atol=1e-15)


def test_pure_and_vector_parts():
    v = np.array([0.3, -1.2, 2.5])
    np.testing.assert_array_equal(quat_from_pure(v), [0.0, 0.3, -1.2, 2.5])
    np.testing.assert_array_equal(quat_vector(np.array([9.0, 0.3, -1.2, 2.5])), v)


@pytest.mark.parametrize(
    "bad, fn",
    [(np.zeros(3), quat_multiply), (np.zeros((2, 5)), quat_conjugate), (ca.SX.sym("q", 3, 1), quat_conjugate)],
)
def test_wrong_component_count_is_a_clear_error(bad, fn):
    args = (bad, bad) if fn is quat_multiply else (bad,)
    with pytest.raises(ValueError, match="expected"):
        fn(*args)


# ---------------------------------------------------------------------------
# Matrix <-> quaternion (Shepperd branches, near 180 degrees, batches)
# ---------------------------------------------------------------------------


@HYP
@given(quaternions())
def test_matrix_from_quat_matches_pytransform3d_and_scipy(q):
    R = matrix_from_quat(q)
    np.testing.assert_allclose(R, pr.matrix_from_quaternion(q), atol=1e-15)
    np.testing.assert_allclose(R, Rotation.from_quat(q, scalar_first=True).as_matrix(), atol=1e-15)


@HYP
@given(quaternions())
def test_quat_from_matrix_round_trip_and_reference(q):
    R = pr.matrix_from_quaternion(q)
    got = quat_from_matrix(R)
    assert got[0] >= 0
    assert close_up_to_sign(got, q, 2e-15)
    assert close_up_to_sign(got, pr.quaternion_from_matrix(R), 2e-15)
    np.testing.assert_allclose(pr.matrix_from_quaternion(got), R, atol=2e-15)


# One case per Shepperd branch (largest of 1 + trace, 1 + 2 R_ii - trace) and
# rotations just short of, and exactly at, 180 degrees about various axes.
NEAR_HALF_TURN = [0.0, 1e-12, 1e-8, 1e-5, 1e-3]
SHEPPERD_AXES = [
    np.array([1.0, 0, 0]),
    np.array([0, 1.0, 0]),
    np.array([0, 0, 1.0]),
    unit([1.0, 1.0, 0]),
    unit([0.3, -0.5, 0.8]),
    unit([-0.9, 0.1, 0.2]),
    unit([0.1, 0.2, -0.97]),
]


@pytest.mark.parametrize("delta", NEAR_HALF_TURN)
@pytest.mark.parametrize("axis", SHEPPERD_AXES, ids=lambda a: np.array2string(a, precision=2))
def test_quat_from_matrix_near_half_turn(axis, delta):
    angle = np.pi - delta
    R = pr.matrix_from_axis_angle(np.r_[axis, angle])
    expected = np.r_[np.cos(angle / 2), np.sin(angle / 2) * axis]  # w = sin(delta/2) >= 0
    got = quat_from_matrix(R)
    assert got[0] >= 0
    assert close_up_to_sign(got, expected, 3e-15)  # at delta = 0 the sign is free
    np.testing.assert_allclose(matrix_from_quat(got), R, atol=3e-15)


def test_quat_from_matrix_each_shepperd_branch_and_identity():
    cases = {
        "trace": (np.eye(3), [1.0, 0, 0, 0]),
        "x": (rot_x(np.pi), [0.0, 1, 0, 0]),
        "y": (rot_y(np.pi), [0.0, 0, 1, 0]),
        "z": (rot_z(np.pi), [0.0, 0, 0, 1]),
        "small": (rot_z(1e-9) @ rot_x(2e-9), None),
    }
    for name, (R, expected) in cases.items():
        got = quat_from_matrix(R)
        if expected is not None:
            assert close_up_to_sign(got, expected, 2e-16), name
        np.testing.assert_allclose(matrix_from_quat(got), R, atol=2e-16, err_msg=name)
        assert abs(np.linalg.norm(got) - 1) < 4e-16, name


def test_matrix_quat_batched_shapes():
    axes_ = np.array(SHEPPERD_AXES[:6])
    angles = np.array([0.1, np.pi, np.pi - 1e-9, 2.0, 1e-10, np.pi - 1e-4])
    Q = np.array([np.r_[np.cos(a / 2), np.sin(a / 2) * n] for n, a in zip(axes_, angles)]).reshape(2, 3, 4)
    R = matrix_from_quat(Q)
    assert R.shape == (2, 3, 3, 3)
    Qb = quat_from_matrix(R)
    assert Qb.shape == (2, 3, 4)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(R[i, j], pr.matrix_from_quaternion(Q[i, j]), atol=1e-15)
            assert close_up_to_sign(Qb[i, j], Q[i, j], 2e-15)
            # each element of the batch takes its own Shepperd branch
            np.testing.assert_array_equal(Qb[i, j], quat_from_matrix(R[i, j]))


# ---------------------------------------------------------------------------
# Roll-pitch-yaw (R = Rz(yaw) Ry(pitch) Rx(roll), seed 000 eq. 30)
# ---------------------------------------------------------------------------

rolls = _f(-np.pi, np.pi)
pitches = _f(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3)


@HYP
@given(rolls, pitches, rolls)
def test_rpy_to_quat_matches_scipy_and_matrix_product(roll, pitch, yaw):
    q = quat_from_rpy(roll, pitch, yaw)
    ref = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat(scalar_first=True)
    assert close_up_to_sign(q, ref, 1e-15)
    R = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
    np.testing.assert_allclose(pr.matrix_from_quaternion(q), R, atol=1e-15)
    # pytransform3d: intrinsic z-y'-x'' with angles (yaw, pitch, roll)
    np.testing.assert_allclose(pr.matrix_from_euler([yaw, pitch, roll], 2, 1, 0, False), R, atol=1e-15)


@HYP
@given(rolls, pitches, rolls, st.booleans())
def test_quat_to_rpy_matches_scipy_and_round_trips(roll, pitch, yaw, flip):
    q = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat(scalar_first=True)
    q = -q if flip else q
    rpy = rpy_from_quat(q)
    yaw_s, pitch_s, roll_s = Rotation.from_quat(q, scalar_first=True).as_euler("ZYX")
    # angles modulo 2 pi (roll, yaw = +-pi are the same angle)
    wrap = lambda a: np.angle(np.exp(1j * a))  # noqa: E731
    np.testing.assert_allclose(wrap(rpy - [roll_s, pitch_s, yaw_s]), 0, atol=1e-9)
    np.testing.assert_allclose(wrap(rpy - [roll, pitch, yaw]), 0, atol=1e-9)
    # asin is ill-conditioned near pitch = +-90 deg (scipy shows the same): scale by 1/cos(pitch)
    assert close_up_to_sign(quat_from_rpy(*rpy), q, 4e-15 / np.cos(pitch))


def test_rpy_batched():
    rng = np.random.default_rng(3)
    roll, yaw = rng.uniform(-3, 3, size=(2, 2, 3))
    pitch = rng.uniform(-1.5, 1.5, size=(2, 3))
    Q = quat_from_rpy(roll, pitch, yaw)
    assert Q.shape == (2, 3, 4)
    rpy = rpy_from_quat(Q)
    assert rpy.shape == (2, 3, 3)
    np.testing.assert_allclose(rpy, np.stack([roll, pitch, yaw], axis=-1), atol=1e-12)
    ref = Rotation.from_euler("ZYX", np.stack([yaw, pitch, roll], -1).reshape(-1, 3)).as_matrix()
    np.testing.assert_allclose(matrix_from_quat(Q).reshape(-1, 3, 3), ref, atol=1e-15)


# ---------------------------------------------------------------------------
# exp / log / power / slerp / angle
# ---------------------------------------------------------------------------


@HYP
@given(axes, _f(0, np.pi - 1e-6))
def test_exp_matches_closed_form_and_pytransform3d(n, a):
    v = a * n  # half rotation vector
    q = quat_exp(v)
    np.testing.assert_allclose(q, ref_quat_exp(v).astype(float), atol=2e-16)
    assert close_up_to_sign(q, pr.quaternion_from_compact_axis_angle(2 * v), 1e-15)  # pytransform3d: w >= 0
    np.testing.assert_allclose(quat_log(q), v, atol=2e-15 * max(1.0, 1 / np.sin(a) if a > 1 else 1.0))


@HYP
@given(quaternions())
def test_log_matches_pytransform3d_and_round_trips(q):
    assume(np.any(q != [-1, 0, 0, 0]))  # log(-1) has no unique axis: see test_log_of_minus_one_is_not_nan
    u = quat_log(q)
    np.testing.assert_allclose(u, ref_quat_log(q).astype(float), atol=1e-15)
    if q[0] >= 0:
        np.testing.assert_allclose(2 * u, pr.compact_axis_angle_from_quaternion(q), atol=1e-14)
    if np.linalg.norm(q + [1, 0, 0, 0]) > 1e-6:  # exp(log q) = q for every q except -1
        np.testing.assert_allclose(quat_exp(u), q, atol=1e-15 / max(np.linalg.norm(q + [1, 0, 0, 0]), 1e-3))


@pytest.mark.parametrize("a", HALF_ANGLES_NEAR_IDENTITY)
@pytest.mark.parametrize("n", [np.array([1.0, 0, 0]), unit([0.3, -0.5, 0.8])], ids=["x", "oblique"])
def test_log_and_exp_near_identity_to_machine_precision(a, n):
    q = np.r_[np.cos(a), np.sin(a) * n]
    u = quat_log(q)
    assert rel_err(u, ref_quat_log(q)) < 4 * EPS
    assert rel_err(u, a * n) < 4 * EPS  # (the input itself is rounded to 1 ulp)
    v = a * n
    assert rel_err(quat_exp(v)[1:], ref_quat_exp(v)[1:]) < 4 * EPS
    assert abs(quat_exp(v)[0] - float(np.cos(LD(a)))) <= EPS
    assert rel_err(quat_log(quat_exp(v)), v) < 4 * EPS


def test_log_and_exp_at_identity_exact():
    np.testing.assert_array_equal(quat_log(np.array([1.0, 0, 0, 0])), [0, 0, 0])
    np.testing.assert_array_equal(quat_exp(np.zeros(3)), [1, 0, 0, 0])


@HYP
@given(quaternions(angles=_f(0, np.pi - 1e-6), signed=False), _f(-2, 2))
def test_power_matches_axis_angle_scaling(q, t):
    axis_angle = pr.axis_angle_from_quaternion(q)  # angle in [0, pi]
    ref = pr.quaternion_from_axis_angle(np.r_[axis_angle[:3], t * axis_angle[3]])  # (w >= 0)
    assert close_up_to_sign(quat_power(q, t), ref, 1e-14)
    np.testing.assert_allclose(quat_power(q, 2.0), pr.concatenate_quaternions(q, q), atol=1e-14)
    half = quat_power(q, 0.5)
    np.testing.assert_allclose(pr.concatenate_quaternions(half, half), q, atol=1e-14)


@HYP
@given(quaternions(), quaternions(), _f(0, 1))
def test_slerp_matches_pytransform3d(q0, q1, t):
    assume(abs(np.dot(q0, q1)) > 1e-6)  # otherwise the two arcs are equally short: no unique answer
    got = quat_slerp(q0, q1, t)
    ref = pr.quaternion_slerp(q0, q1, t, shortest_path=True)
    assert close_up_to_sign(got, ref, 1e-12)
    # end points, and invariance under the sign of the target
    assert close_up_to_sign(quat_slerp(q0, q1, 0.0), q0, 1e-15)
    assert close_up_to_sign(quat_slerp(q0, q1, 1.0), q1, 1e-14)
    assert close_up_to_sign(quat_slerp(q0, -q1, t), got, 1e-14)
    assert abs(np.linalg.norm(got) - 1) < 1e-14


@HYP
@given(quaternions())
def test_angle_matches_pytransform3d(q):
    angle = pr.axis_angle_from_quaternion(q)[3]
    assert quat_angle(q) == pytest.approx(angle, abs=1e-14)
    assert quat_angle(-q) == pytest.approx(angle, abs=1e-14)


@HYP
@given(axes, _f(-2 * np.pi, 2 * np.pi))
def test_axis_angle_matches_pytransform3d(n, angle):
    q = quat_from_axis_angle(n, angle)
    np.testing.assert_allclose(q, np.r_[np.cos(angle / 2), np.sin(angle / 2) * n], atol=1e-16)
    assert close_up_to_sign(q, pr.quaternion_from_axis_angle(np.r_[n, angle]), 1e-15)  # pytransform3d: w >= 0


def test_batched_exp_log_power():
    Q = Rotation.random(6, random_state=4).as_quat(scalar_first=True).reshape(2, 3, 4)
    Q = Q * np.sign(Q[..., :1])
    U = quat_log(Q)
    assert U.shape == (2, 3, 3)
    np.testing.assert_allclose(quat_exp(U), Q, atol=1e-15)
    t = np.array([[0.0, 0.5, 1.0], [2.0, -1.0, 0.25]])
    P = quat_power(Q, t)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(U[i, j], ref_quat_log(Q[i, j]).astype(float), atol=1e-15)
            np.testing.assert_allclose(P[i, j], quat_power(Q[i, j], t[i, j]), atol=1e-15)


def test_batched_exponent_with_batch_shape_is_not_silently_misapplied():
    """t of the batch shape (like the angle of quat_from_axis_angle) must act per element, or be refused.

    With three quaternions and t of shape (3,), t * log(q) broadcasts t along
    the *component* axis and silently returns a wrong answer.
    """
    n = np.array([1.0, 0, 0])
    qs = np.stack([quat_from_axis_angle(n, 0.6)] * 3)
    t = np.array([0.0, 0.5, 1.0])
    expected = np.stack([pr.quaternion_from_axis_angle(np.r_[n, 0.6 * ti]) for ti in t])
    try:
        got = quat_power(qs, t)
    except ValueError:
        return  # an explicit error is acceptable
    np.testing.assert_allclose(got, expected, atol=1e-15)


# ---------------------------------------------------------------------------
# Hemisphere continuity
# ---------------------------------------------------------------------------


def test_hemisphere_continuity_along_sequence():
    # A smooth rotation through several full turns, then signs scrambled (as from a sensor).
    angles = np.linspace(0, 5 * np.pi, 200)
    n = unit([0.2, -0.4, 0.9])
    smooth = np.array([np.r_[np.cos(a / 2), np.sin(a / 2) * n] for a in angles])
    signs = np.where(np.random.default_rng(5).random(len(angles)) < 0.5, -1.0, 1.0)
    scrambled = smooth * signs[:, None]
    signs[0] = 1.0
    scrambled[0] = smooth[0]
    out = quat_hemisphere_continuous(scrambled)
    assert out.shape == scrambled.shape
    np.testing.assert_array_equal(out[0], scrambled[0])  # first sample is kept
    np.testing.assert_allclose(out, smooth, atol=0)  # recovers the continuous sequence exactly
    assert np.all(np.einsum("ij,ij->i", out[1:], out[:-1]) > 0)
    # from quat_from_matrix (w >= 0, a jump at each half turn)
    from_matrices = quat_from_matrix(matrix_from_quat(smooth))
    assert np.any(np.einsum("ij,ij->i", from_matrices[1:], from_matrices[:-1]) < 0)
    fixed = quat_hemisphere_continuous(from_matrices)
    np.testing.assert_allclose(fixed, smooth * np.sign(np.dot(from_matrices[0], smooth[0])), atol=1e-14)


def test_hemisphere_continuity_rejects_wrong_shape():
    with pytest.raises(ValueError):
        quat_hemisphere_continuous(np.zeros((2, 3, 4)))


# ---------------------------------------------------------------------------
# Dual quaternions: construction, transforms, product, conjugates, points
# ---------------------------------------------------------------------------


def _transform(q, p):
    return pt.transform_from(pr.matrix_from_quaternion(q), p)


@HYP
@given(poses)
def test_dq_from_rotation_translation_and_transform_match_pytransform3d(pose):
    q, p = pose
    T = _transform(q, p)
    dq = dq_from_rotation_translation(q, p)
    ref = pt.dual_quaternion_from_transform(T)
    assert close_up_to_sign(dq, ref, 1e-14)
    # Q_d = 0.5 (0, p) Q_r
    np.testing.assert_allclose(dq_parts(dq)[1], 0.5 * pr.concatenate_quaternions(np.r_[0, p], q), atol=1e-15)
    assert close_up_to_sign(dq_from_transform(T), ref, 1e-14)
    np.testing.assert_allclose(transform_from_dq(dq), T, atol=1e-14)
    np.testing.assert_allclose(transform_from_dq(dq), pt.transform_from_dual_quaternion(dq), atol=1e-14)
    np.testing.assert_allclose(dq_translation(dq), p, atol=1e-14)
    np.testing.assert_array_equal(dq_rotation(dq), q)
    np.testing.assert_allclose(dq_norm_residual(dq), [0, 0], atol=1e-15)
    np.testing.assert_array_equal(dq_from_parts(*dq_parts(dq)), dq)


def test_dq_transform_batched_shapes():
    R = Rotation.random(6, random_state=6).as_matrix()
    p = np.random.default_rng(6).normal(size=(6, 3))
    T = np.array([pt.transform_from(Ri, pi) for Ri, pi in zip(R, p)]).reshape(2, 3, 4, 4)
    DQ = dq_from_transform(T)
    assert DQ.shape == (2, 3, 8)
    Tb = transform_from_dq(DQ)
    assert Tb.shape == (2, 3, 4, 4)
    np.testing.assert_allclose(Tb, T, atol=1e-14)
    for i in range(2):
        for j in range(3):
            assert close_up_to_sign(DQ[i, j], pt.dual_quaternion_from_transform(T[i, j]), 1e-14)
    # a batch of rotations with one shared translation broadcasts
    Q = quat_from_matrix(R).reshape(2, 3, 4)
    DQ1 = dq_from_rotation_translation(Q, p[0])
    np.testing.assert_allclose(dq_translation(DQ1), np.broadcast_to(p[0], (2, 3, 3)), atol=1e-14)


@HYP
@given(poses, poses)
def test_dq_product_matches_pytransform3d(a, b):
    A, B_ = dq_from_rotation_translation(*a), dq_from_rotation_translation(*b)
    AB = dq_multiply(A, B_)
    np.testing.assert_allclose(AB, pt.concatenate_dual_quaternions(A, B_), atol=1e-14)
    np.testing.assert_allclose(transform_from_dq(AB), _transform(*a) @ _transform(*b), atol=1e-13)


@HYP
@given(poses)
def test_dq_conjugates(pose):
    dq = dq_from_rotation_translation(*pose)
    np.testing.assert_allclose(dq_conjugate(dq), pt.dq_q_conj(dq), atol=1e-15)
    np.testing.assert_allclose(dq_combined_conjugate(dq), pt.dq_conj(dq), atol=1e-15)
    np.testing.assert_array_equal(dq_dual_number_conjugate(dq), np.r_[dq[:4], -dq[4:]])
    # the quaternion conjugate is the inverse transform
    np.testing.assert_allclose(dq_multiply(dq, dq_conjugate(dq)), [1, 0, 0, 0, 0, 0, 0, 0], atol=1e-14)
    np.testing.assert_allclose(transform_from_dq(dq_conjugate(dq)), np.linalg.inv(_transform(*pose)), atol=1e-13)


@HYP
@given(poses, vectors3)
def test_dq_transform_point(pose, x):
    dq = dq_from_rotation_translation(*pose)
    ref = (_transform(*pose) @ np.r_[x, 1])[:3]
    np.testing.assert_allclose(dq_transform_point(dq, x), ref, atol=1e-14)
    np.testing.assert_allclose(dq_transform_point(dq, x), pt.dq_prod_vector(dq, x), atol=1e-14)
    # the same through the combined conjugate: Q (1 + eps (0, x)) Q^#
    point = np.r_[1, 0, 0, 0, 0, x]
    moved = dq_multiply(dq_multiply(dq, point), dq_combined_conjugate(dq))
    np.testing.assert_allclose(moved[5:], ref, atol=1e-14)


def test_dq_transform_point_batched():
    rng = np.random.default_rng(7)
    Q = Rotation.random(6, random_state=7).as_quat(scalar_first=True).reshape(2, 3, 4)
    p = rng.normal(size=(2, 3, 3))
    x = rng.normal(size=(2, 3, 3))
    out = dq_transform_point(dq_from_rotation_translation(Q, p), x)
    assert out.shape == (2, 3, 3)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(out[i, j], pr.q_prod_vector(Q[i, j], x[i, j]) + p[i, j], atol=1e-14)


def test_dq_norm_residual_detects_non_unit():
    dq = dq_from_rotation_translation(quat_from_axis_angle(np.array([0, 0, 1.0]), 0.4), np.array([1.0, 2, 3]))
    r, d = dq_norm_residual(2.0 * dq)
    assert r == pytest.approx(1.0) and d == pytest.approx(0.0, abs=1e-14)
    bad = dq + np.r_[np.zeros(4), dq[:4]]  # adds Q_r . Q_d = 1
    assert dq_norm_residual(bad)[1] == pytest.approx(1.0)


# ---------------------------------------------------------------------------
# Dual-quaternion exp / log / power / ScLERP / pose error
# ---------------------------------------------------------------------------

screws = st.tuples(
    axes,
    vectors3,
    st.one_of(_f(-np.pi + 1e-3, np.pi - 1e-3), st.sampled_from([0.0, 1e-12, -1e-8, 2e-3, 1.999e-3, 2.001e-3])),
    _f(-2, 2),
)


@HYP
@given(screws)
def test_dq_log_matches_screw_closed_form(s):
    dq_ld, log_ref, p = screw(*s)
    dq = dq_ld.astype(float)
    got = dq_log(dq)
    scale = max(1.0, float(np.linalg.norm(log_ref.astype(float))))
    np.testing.assert_allclose(got, log_ref.astype(float), atol=4e-15 * scale)
    np.testing.assert_allclose(got, ref_dq_log(dq).astype(float), atol=4e-15 * scale)
    np.testing.assert_allclose(dq_exp(got), dq, atol=4e-15 * scale)


@HYP
@given(screws)
def test_dq_exp_matches_power_series(s):
    _, xi, _ = screw(*s)
    xi = xi.astype(float)
    got = dq_exp(xi)
    np.testing.assert_allclose(got, ref_dq_exp(xi).astype(float), atol=2e-15 * max(1.0, np.linalg.norm(xi)))
    np.testing.assert_allclose(dq_norm_residual(got), [0, 0], atol=1e-15)
    np.testing.assert_allclose(dq_log(got), xi, atol=4e-15 * max(1.0, np.linalg.norm(xi)))


@HYP
@given(poses)
def test_dq_log_is_half_the_exponential_coordinates_of_pytransform3d(pose):
    q, p = pose
    # pytransform3d's closed form loses accuracy near 0 and pi (covered there by the screw reference)
    assume(np.linalg.norm(q[1:]) > 1e-6 and abs(q[0]) > 1e-3)
    q = q * np.sign(q[0])
    T = _transform(q, p)
    xi = dq_log(dq_from_transform(T))
    np.testing.assert_allclose(2 * xi, pt.exponential_coordinates_from_transform(T), atol=1e-11)
    np.testing.assert_allclose(
        transform_from_dq(dq_exp(xi)), pt.transform_from_exponential_coordinates(2 * xi), atol=1e-12
    )


@pytest.mark.parametrize("a", HALF_ANGLES_NEAR_IDENTITY)
def test_dq_log_exp_near_identity_to_machine_precision(a):
    n, c, d = unit([0.3, -0.5, 0.8]), np.array([0.4, 1.1, -0.7]), 0.35
    dq_ld, log_ref, _ = screw(n, c, 2 * a, d)
    dq = dq_ld.astype(float)
    assert rel_err(dq_log(dq), log_ref) < 1e-15
    assert rel_err(dq_log(dq), ref_dq_log(dq)) < 1e-15
    xi = log_ref.astype(float)
    assert rel_err(dq_exp(xi), ref_dq_exp(xi)) < 1e-15
    assert rel_err(dq_log(dq_exp(xi)), xi) < 1e-15


def test_dq_log_exp_pure_translation_and_identity():
    for p in [np.array([0.3, -1.0, 2.0]), np.array([1e-12, 0, 0]), np.zeros(3)]:
        dq = dq_from_rotation_translation(np.array([1.0, 0, 0, 0]), p)
        np.testing.assert_array_equal(dq_log(dq), np.r_[0, 0, 0, p / 2])
        np.testing.assert_array_equal(dq_exp(np.r_[0, 0, 0, p / 2]), dq)
        np.testing.assert_allclose(
            dq_power(dq, 0.3), dq_from_rotation_translation(np.array([1.0, 0, 0, 0]), 0.3 * p), atol=1e-16
        )


@HYP
@given(screws, _f(-2, 2))
def test_dq_power_matches_screw_and_pytransform3d(s, t):
    n, c, theta, d = s
    dq = screw(n, c, theta, d)[0].astype(float)
    ref = screw(n, c, t * theta, t * d)[0].astype(float)
    got = dq_power(dq, t)
    np.testing.assert_allclose(got, ref, atol=1e-14)
    if abs(theta) > 1e-2:  # pytransform3d divides by tan(theta/2)
        np.testing.assert_allclose(got, pt.dual_quaternion_power(dq, t), atol=1e-12)
    np.testing.assert_allclose(dq_power(dq, 2.0), pt.concatenate_dual_quaternions(dq, dq), atol=1e-13)


@HYP
@given(poses, poses, _f(0, 1))
def test_dq_sclerp_matches_pytransform3d(a, b, t):
    A, B_ = dq_from_rotation_translation(*a), dq_from_rotation_translation(*b)
    rel = pt.concatenate_dual_quaternions(pt.dq_q_conj(A), B_)
    assume(abs(rel[0]) > 1e-2)  # otherwise the relative rotation is near a half turn: two screws equally short
    got = dq_sclerp(A, B_, t)
    assert close_up_to_sign(got, pt.dual_quaternion_sclerp(A, B_, t), 1e-11)
    assert close_up_to_sign(dq_sclerp(A, B_, 0.0), A, 1e-14)
    assert close_up_to_sign(dq_sclerp(A, B_, 1.0), B_, 1e-12)
    assert close_up_to_sign(dq_sclerp(A, -B_, t), got, 1e-12)  # -B is the same pose


@HYP
@given(poses, screws)
def test_dq_pose_error_recovers_the_relative_screw(pose, s):
    A = dq_from_rotation_translation(*pose)
    xi = screw(*s)[1].astype(float)
    B_ = dq_multiply(A, dq_exp(xi))
    np.testing.assert_allclose(dq_pose_error(A, B_), xi, atol=1e-12 * max(1.0, np.linalg.norm(xi)))
    np.testing.assert_allclose(dq_pose_error(A, A), np.zeros(6), atol=1e-15)
    if np.linalg.norm(xi) > 1e-9:
        assert np.linalg.norm(dq_pose_error(A, B_)) > 0


@pytest.mark.parametrize("offset", [0.0, 1e-3], ids=["same", "nearby"])
def test_dq_pose_error_does_not_depend_on_the_sign_of_the_dual_quaternion(offset):
    """Q and -Q are the same rigid pose: the pose error is zero iff the poses agree, either sign."""
    A = dq_from_rotation_translation(quat_from_axis_angle(unit([0.3, -0.5, 0.8]), 0.9), np.array([0.1, 0.2, 0.3]))
    B_ = dq_multiply(A, dq_exp(np.r_[0, 0, offset, offset, 0, 0]))  # B = A exp(xi)
    expected = np.r_[0, 0, offset, offset, 0, 0]
    np.testing.assert_allclose(dq_pose_error(A, B_), expected, atol=1e-15)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        flipped = dq_pose_error(A, -B_)
    np.testing.assert_allclose(flipped, expected, atol=1e-14)


def test_log_of_minus_one_is_not_nan():
    """q = -1 is a full turn: log q has norm pi about any axis; a NaN is the one wrong answer."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        u = quat_log(np.array([-1.0, 0, 0, 0]))
    assert np.all(np.isfinite(u)), u
    assert np.linalg.norm(u) == pytest.approx(np.pi)


# ---------------------------------------------------------------------------
# numpy path: no warnings (silent NaN sources) at the identity and on the band
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("a", [0.0] + HALF_ANGLES_NEAR_IDENTITY)
def test_no_floating_point_warnings_near_identity(a):
    n = unit([0.3, -0.5, 0.8])
    q = np.r_[np.cos(a), np.sin(a) * n]
    dq = dq_from_rotation_translation(q, np.array([0.1, 0.2, 0.3]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        outs = [
            quat_log(q),
            quat_exp(a * n),
            quat_power(q, 0.3),
            quat_slerp(np.r_[1.0, 0, 0, 0], q, 0.5),
            dq_log(dq),
            dq_exp(dq_log(dq)),
            dq_power(dq, 0.3),
            dq_pose_error(dq, dq),
            quat_from_matrix(matrix_from_quat(q)),
        ]
    assert all(np.all(np.isfinite(o)) for o in outs)


# ---------------------------------------------------------------------------
# CasADi: SX / MX / DM give the numpy values
# ---------------------------------------------------------------------------


def _sample_inputs():
    """Unit quaternions and poses at the identity, on the series bands, generic and near a half turn."""
    n = unit([0.3, -0.5, 0.8])
    qs = [np.r_[np.cos(a), np.sin(a) * n] for a in [0.0, 1e-9, A_BAND, A_SIN_BAND, 0.4, 1.2, np.pi / 2 - 1e-7]]
    qs += [quat_from_matrix(pr.matrix_from_axis_angle(np.r_[ax, np.pi - 1e-9])) for ax in SHEPPERD_AXES[:3]]
    ps = [np.array([0.1, -0.2, 0.3]), np.zeros(3), np.array([1.5, 0.0, -2.0])]
    return qs, ps


QS, PS = _sample_inputs()
_Q2 = quat_from_axis_angle(unit([-0.2, 0.9, 0.1]), 0.8)
_DQ2 = dq_from_rotation_translation(_Q2, np.array([0.5, 0.4, -0.1]))

CASADI_CASES = [
    ("quat_multiply", lambda q, p: quat_multiply(q, _Q2), None),
    ("quat_multiply_left", lambda q, p: quat_multiply(_Q2, q), None),
    ("quat_conjugate", lambda q, p: quat_conjugate(q), None),
    ("quat_inverse", lambda q, p: quat_inverse(2.0 * q), None),
    ("quat_norm", lambda q, p: quat_norm(2.0 * q), None),
    ("quat_normalize", lambda q, p: quat_normalize(3.0 * q), None),
    ("quat_rotate", lambda q, p: quat_rotate(q, p), None),
    ("matrix_from_quat", lambda q, p: matrix_from_quat(q), None),
    ("quat_from_matrix", lambda R, p: quat_from_matrix(R), "matrix"),
    ("rpy_from_quat", lambda q, p: rpy_from_quat(q), None),
    ("quat_from_rpy", lambda q, p: quat_from_rpy(p[0], p[1], p[2]), None),
    ("quat_exp", lambda q, p: quat_exp(p), None),
    ("quat_log", lambda q, p: quat_log(q), None),
    ("quat_angle", lambda q, p: quat_angle(q), None),
    ("quat_power", lambda q, p: quat_power(q, 0.37), None),
    ("quat_slerp", lambda q, p: quat_slerp(_Q2, q, 0.3), None),
    ("quat_from_axis_angle", lambda q, p: quat_from_axis_angle(np.array([0, 0.6, 0.8]), p[0]), None),
    ("dq_from_rotation_translation", lambda q, p: dq_from_rotation_translation(q, p), None),
    ("dq_translation", lambda q, p: dq_translation(dq_from_rotation_translation(q, p)), None),
    ("transform_from_dq", lambda q, p: transform_from_dq(dq_from_rotation_translation(q, p)), None),
    ("dq_from_transform", lambda T, p: dq_from_transform(T), "transform"),
    ("dq_multiply", lambda q, p: dq_multiply(_DQ2, dq_from_rotation_translation(q, p)), None),
    ("dq_conjugate", lambda q, p: dq_conjugate(dq_from_rotation_translation(q, p)), None),
    ("dq_combined_conjugate", lambda q, p: dq_combined_conjugate(dq_from_rotation_translation(q, p)), None),
    ("dq_transform_point", lambda q, p: dq_transform_point(dq_from_rotation_translation(q, p), _Q2[1:]), None),
    ("dq_log", lambda q, p: dq_log(dq_from_rotation_translation(q, p)), None),
    ("dq_exp", lambda q, p: dq_exp(dq_log(dq_from_rotation_translation(q, p))), None),
    ("dq_power", lambda q, p: dq_power(dq_from_rotation_translation(q, p), -0.6), None),
    ("dq_sclerp", lambda q, p: dq_sclerp(_DQ2, dq_from_rotation_translation(q, p), 0.4), None),
    ("dq_pose_error", lambda q, p: dq_pose_error(dq_from_rotation_translation(q, p), _DQ2), None),
    ("dq_norm_residual", lambda q, p: dq_norm_residual(1.5 * dq_from_rotation_translation(q, p))[0], None),
]


def _as_casadi_arg(kind, q, p):
    if kind == "matrix":
        return pr.matrix_from_quaternion(q)
    if kind == "transform":
        return _transform(q, p)
    return q


def _np_out(x):
    return np.atleast_1d(np.asarray(x, float))


@pytest.mark.parametrize("sym", [ca.SX, ca.MX], ids=["SX", "MX"])
@pytest.mark.parametrize("name, fn, kind", CASADI_CASES, ids=[c[0] for c in CASADI_CASES])
def test_casadi_function_values_equal_numpy(name, fn, kind, sym):
    first = _as_casadi_arg(kind, QS[0], PS[0])
    x = sym.sym("x", *(first.shape if first.ndim == 2 else (first.size, 1)))
    y = sym.sym("y", 3, 1)
    out = fn(x, y)
    assert isinstance(out, sym), f"{name} did not stay symbolic"
    f = ca.Function(name, [x, y], [out])
    for k, q in enumerate(QS):
        p = PS[k % len(PS)]
        arg = _as_casadi_arg(kind, q, p)
        expected = _np_out(fn(arg, p))
        got = np.asarray(f(arg if arg.ndim == 2 else arg[:, None], p[:, None]), float)
        got = got.reshape(expected.shape) if expected.ndim == 1 else got
        np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-14, err_msg=f"{name} q={q} p={p}")
        if sym is ca.SX and k % 3 == 0:  # DM in, DM out
            dm = np.asarray(fn(ca.DM(arg if arg.ndim == 2 else arg[:, None]), ca.DM(p)), float)
            dm = dm.reshape(expected.shape) if expected.ndim == 1 else dm
            np.testing.assert_allclose(dm, expected, rtol=1e-14, atol=1e-14, err_msg=f"{name} DM q={q}")


def test_casadi_columns_are_a_batch():
    N = 5
    Q = Rotation.random(N, random_state=8).as_quat(scalar_first=True)
    P = Rotation.random(N, random_state=9).as_quat(scalar_first=True)
    x, y = ca.SX.sym("x", 4, N), ca.SX.sym("y", 4, N)
    f = ca.Function("f", [x, y], [quat_multiply(x, y), quat_log(x), dq_log(dq_from_parts(x, 0.5 * y))])
    pq, lq, ldq = (np.asarray(o) for o in f(Q.T, P.T))
    assert pq.shape == (4, N) and lq.shape == (3, N) and ldq.shape == (6, N)
    np.testing.assert_allclose(pq.T, quat_multiply(Q, P), atol=1e-15)
    np.testing.assert_allclose(lq.T, quat_log(Q), atol=1e-15)
    np.testing.assert_allclose(ldq.T, dq_log(dq_from_parts(Q, 0.5 * P), check=False), atol=1e-14)


def test_casadi_matrix_from_quat_rejects_several_columns():
    with pytest.raises(ValueError):
        matrix_from_quat(ca.SX.sym("q", 4, 2))


# ---------------------------------------------------------------------------
# CasADi Jacobians: finite, and equal to central differences, at the identity and on/around the bands
# ---------------------------------------------------------------------------

_N = unit([0.3, -0.5, 0.8])
JAC_HALF_ANGLES = [
    0.0,
    1e-8,
    1e-4,
    A_BAND * (1 - 1e-6),
    A_BAND,
    A_BAND * (1 + 1e-6),
    A_SIN_BAND * (1 - 1e-6),
    A_SIN_BAND,
    A_SIN_BAND * (1 + 1e-6),
    0.7,
]
_JAC_POINTS = [(a, ax) for a in JAC_HALF_ANGLES for ax in (np.array([1.0, 0, 0]), _N)]
_JAC_IDS = [f"a={a:.9g}-{'x' if ax[0] == 1 else 'oblique'}" for a, ax in _JAC_POINTS]


def central_fd(f, x, h, dtype=float):
    x = np.asarray(x, dtype)
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((np.asarray(f(x + e), dtype) - np.asarray(f(x - e), dtype)) / (2 * h))
    return np.stack(cols, axis=1)


def _jacobian_function(fn, n_in):
    x = ca.SX.sym("x", n_in, 1)
    y = fn(x)
    return ca.Function("J", [x], [ca.jacobian(y, x)])


def _check_jacobian(J, J_ref, what):
    J = np.asarray(J, float)
    assert np.all(np.isfinite(J)), f"{what}: non-finite Jacobian"
    err = np.linalg.norm(J - np.asarray(J_ref, float)) / max(np.linalg.norm(np.asarray(J_ref, float)), 1e-12)
    assert err < 1e-6, f"{what}: relative error {err:.3g}"


J_QUAT_LOG = _jacobian_function(quat_log, 4)
J_QUAT_EXP = _jacobian_function(quat_exp, 3)
J_DQ_LOG = _jacobian_function(dq_log, 8)
J_DQ_EXP = _jacobian_function(dq_exp, 6)


@pytest.mark.parametrize("a, n", _JAC_POINTS, ids=_JAC_IDS)
def test_jacobian_quat_log(a, n):
    q = np.r_[np.cos(a), np.sin(a) * n]
    J = J_QUAT_LOG(q)
    _check_jacobian(J, central_fd(ref_quat_log, q, LD(1e-7), LD), "quat_log vs closed form")
    _check_jacobian(J, central_fd(lambda x: quat_log(x, check=False), q, 1e-6), "quat_log vs its own numpy path")


@pytest.mark.parametrize("a, n", _JAC_POINTS, ids=_JAC_IDS)
def test_jacobian_quat_exp(a, n):
    v = a * n
    J = J_QUAT_EXP(v)
    _check_jacobian(J, central_fd(ref_quat_exp, v, LD(1e-7), LD), "quat_exp vs closed form")
    _check_jacobian(J, central_fd(quat_exp, v, 1e-6), "quat_exp vs its own numpy path")


@pytest.mark.parametrize("a, n", _JAC_POINTS, ids=_JAC_IDS)
@pytest.mark.parametrize("pitch", [0.0, 0.35], ids=["no-slide", "slide"])
def test_jacobian_dq_exp(a, n, pitch):
    xi = np.r_[a * n, pitch * n + np.cross(np.array([0.4, 1.1, -0.7]), n) * a]
    J = J_DQ_EXP(xi)
    _check_jacobian(J, central_fd(lambda z: ref_dq_exp(z, terms=30), xi, LD(1e-7), LD), "dq_exp vs series")
    _check_jacobian(J, central_fd(dq_exp, xi, 1e-6), "dq_exp vs its own numpy path")


@pytest.mark.parametrize("a, n", _JAC_POINTS, ids=_JAC_IDS)
def test_jacobian_dq_log(a, n):
    dq = screw(n, np.array([0.4, 1.1, -0.7]), 2 * a, 0.35)[0].astype(float)
    J = np.asarray(J_DQ_LOG(dq), float)  # 6 x 8, in the ambient space
    _check_jacobian(J, central_fd(lambda z: dq_log(z, check=False), dq, 1e-6), "dq_log vs its own numpy path")
    # Along the manifold (dq exp(s)), against the independent long-double log of the series exp.
    tangent = np.stack(
        [ref_dqmul(dq, np.r_[0, e[:3], 0, e[3:]]).astype(float) for e in np.eye(6)], axis=1
    )  # d/ds dq exp(s) at s = 0
    ref = central_fd(lambda s: ref_dq_log(ref_dqmul(dq, ref_dq_exp(s, terms=30))), np.zeros(6), LD(1e-7), LD)
    _check_jacobian(J @ tangent, ref, "dq_log along the manifold vs series reference")


@pytest.mark.parametrize(
    "name, fn, x0",
    [
        ("quat_log", quat_log, np.array([1.0, 0, 0, 0])),
        ("quat_exp", quat_exp, np.zeros(3)),
        ("dq_log", dq_log, np.r_[1.0, 0, 0, 0, 0, 0.1, -0.2, 0.05]),
        ("dq_exp", dq_exp, np.r_[0, 0, 0, 0.1, -0.2, 0.05]),
    ],
)
def test_second_derivatives_finite_and_consistent_at_identity(name, fn, x0):
    x = ca.SX.sym("x", x0.size, 1)
    y = fn(x)
    weights = np.linspace(0.3, 1.1, y.shape[0])
    scalar = ca.dot(ca.DM(weights), y)
    H = np.asarray(ca.Function("H", [x], [ca.hessian(scalar, x)[0]])(x0), float)
    g = ca.Function("g", [x], [ca.gradient(scalar, x)])
    assert np.all(np.isfinite(H)), name
    H_fd = central_fd(lambda z: np.asarray(g(z), float).ravel(), x0, 1e-6)
    assert np.linalg.norm(H - H_fd) <= 1e-6 * max(1.0, np.linalg.norm(H_fd)), name


@pytest.mark.parametrize(
    "name, fn, n_in",
    [("quat_log", quat_log, 4), ("quat_exp", quat_exp, 3), ("dq_log", dq_log, 8), ("dq_exp", dq_exp, 6)],
)
def test_mx_jacobians_equal_sx_jacobians(name, fn, n_in):
    sx = {"quat_log": J_QUAT_LOG, "quat_exp": J_QUAT_EXP, "dq_log": J_DQ_LOG, "dq_exp": J_DQ_EXP}[name]
    x = ca.MX.sym("x", n_in, 1)
    mx = ca.Function("J", [x], [ca.jacobian(fn(x), x)])
    for a in [0.0, A_BAND, A_SIN_BAND, 0.7]:
        q = np.r_[np.cos(a), np.sin(a) * _N]
        point = {
            "quat_log": q,
            "quat_exp": a * _N,
            "dq_log": np.r_[q, 0.5 * ref_qmul(np.r_[0, 0.1, 0.2, 0.3], q)],
            "dq_exp": np.r_[a * _N, 0.1, 0.2, 0.3],
        }[name].astype(float)
        J = np.asarray(mx(point), float)
        assert np.all(np.isfinite(J)), (name, a)
        np.testing.assert_allclose(J, np.asarray(sx(point), float), rtol=1e-12, atol=1e-12, err_msg=f"{name} a={a}")


# ---------------------------------------------------------------------------
# Mixed numpy constants and CasADi symbols
# ---------------------------------------------------------------------------


def test_mixed_numpy_constant_and_casadi_symbol():
    q = ca.SX.sym("q", 4, 1)
    p = ca.SX.sym("p", 3, 1)
    target = _DQ2
    err = dq_pose_error(dq_from_rotation_translation(q, p), target)
    assert isinstance(err, ca.SX) and err.shape == (6, 1)
    f = ca.Function("err", [q, p], [err, quat_multiply(_Q2, q), quat_multiply(q, _Q2)])
    q0, p0 = QS[4], PS[0]
    e, a, b = (np.asarray(o, float).ravel() for o in f(q0, p0))
    np.testing.assert_allclose(e, dq_pose_error(dq_from_rotation_translation(q0, p0), target), atol=1e-14)
    np.testing.assert_allclose(a, pr.concatenate_quaternions(_Q2, q0), atol=1e-15)
    np.testing.assert_allclose(b, pr.concatenate_quaternions(q0, _Q2), atol=1e-15)
