"""Orientation DMPs on motions that turn by more than half a turn from start to goal.

The quaternion gap ``2 log(g conj(y))`` (seed 000 eq. 19) has one branch per
whole turn; the imitation and the roll-out must take the same one
(:meth:`optikin.dmp.spaces.Space.lift`). The expected values are the
demonstrations themselves (a roll-out with the demonstration's start, goal and
duration replays it), rotations built with pytransform3d, and the exact
identity ``exp(lift(v) / 2) = +-exp(v / 2)`` (the branch changes the
representation, not the rotation or the pose).
"""

from __future__ import annotations

import numpy as np
import pytest
import pytransform3d.rotations as pr
from movement_primitives.dmp import CartesianDMP

from optikin.algebra import (
    dq_exp,
    dq_from_rotation_translation,
    dq_rotation,
    dq_translation,
    quat_angle,
    quat_conjugate,
    quat_exp,
    quat_multiply,
)
from optikin.data.demonstrations import imu_interface_recording
from optikin.dmp import DMP, Euclidean, Gains, GoalLogQuaternion, Product, UnitDualQuaternion, UnitQuaternion
from optikin.dmp.pose import cartesian_dmp, dual_quaternion_dmp, seed_dual_quaternion_dmp

AXIS = np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93])
SAMPLES, DURATION = 500, 5.0


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.rad2deg(quat_angle(quat_multiply(a, quat_conjugate(b))))


def minimum_jerk(samples: int = SAMPLES, duration: float = DURATION) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration, samples)
    s = t / duration
    return t, 10 * s**3 - 15 * s**4 + 6 * s**5


def turn(total_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """A rotation by ``total_deg`` about a fixed oblique axis, minimum-jerk in time: ``t (N,)``, ``q (N, 4)``
    (pytransform3d's quaternions, sign-continuous along the motion)."""
    t, s = minimum_jerk()
    q = np.array([pr.quaternion_from_axis_angle(np.r_[AXIS, a]) for a in np.deg2rad(total_deg) * s])
    return t, continuous(q)


def continuous(q: np.ndarray) -> np.ndarray:
    flips = np.concatenate([[1.0], np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))])
    return q * flips[:, None]


def translation(t: np.ndarray) -> np.ndarray:
    """A straight minimum-jerk translation by (10, -5, 10) cm over the motion [m]."""
    _, s = minimum_jerk(t.size, t[-1])
    return s[:, None] * np.array([0.1, -0.05, 0.1])


@pytest.mark.parametrize("total_deg", [90.0, 179.0, 181.0, 270.0, 350.0])
def test_quaternion_and_dual_quaternion_dmps_replay_a_turn_past_half_a_turn(total_deg):
    """Replay error below 0.01 degrees at every total turn (before the fix: 179.3 degrees past 180).

    The dual-quaternion DMP's translation is replayed within 0.01 mm up to 270 degrees; at 350 degrees the
    spatial screw that carries the translation has its axis far from the motion ((I - R) c = p with R ten
    degrees from the identity) and the replay is off by up to 1 cm, though the rotation is exact."""
    t, q = turn(total_deg)
    quaternion = DMP(UnitQuaternion(), n_basis=50)
    quaternion.imitate(t, q)
    assert rotation_error_deg(quaternion.rollout().y, q).max() < 0.01
    dual = dual_quaternion_dmp(n_basis=50)
    dual.imitate(t, dq_from_rotation_translation(q, translation(t)))
    y = dual.rollout().y
    assert rotation_error_deg(dq_rotation(y), q).max() < 0.01
    assert np.abs(dq_translation(y) - translation(t)).max() < (1e-5 if total_deg <= 270 else 0.02)


def test_a_turn_past_half_a_turn_with_either_sign_of_the_goal():
    """The goal given as -q (one rotation) is the same target: the roll-out is the one to +q."""
    t, q = turn(270.0)
    dmp = DMP(UnitQuaternion(), n_basis=50)
    dmp.imitate(t, q)
    plus, minus = dmp.rollout(goal=q[-1]).y, dmp.rollout(goal=-q[-1]).y
    assert rotation_error_deg(plus, minus).max() < 1e-9
    assert rotation_error_deg(minus, q).max() < 0.01


def test_a_heading_that_winds_past_a_full_turn():
    """Heading (yaw) from 0 to 450 degrees at a fixed pitch of 20 degrees: every orientation DMP replays it."""
    t, s = minimum_jerk()
    heading = np.deg2rad(450.0) * s
    pitch = np.deg2rad(20.0)
    q = continuous(np.array([pr.quaternion_from_euler([h, pitch, 0.0], 2, 1, 0, extrinsic=False) for h in heading]))
    p = translation(t) + np.array([0.05, 0.05, 0.2])  # away from the origin: Q_d = (0, p) Q_r / 2 is not zero
    quaternion = DMP(UnitQuaternion(), n_basis=50)
    quaternion.imitate(t, q)
    assert rotation_error_deg(quaternion.rollout().y, q).max() < 0.01
    seed = seed_dual_quaternion_dmp(n_basis=50)
    dq = dq_from_rotation_translation(q, p)
    seed.imitate(t, dq)
    assert rotation_error_deg(seed.rollout().y[:, :4], q).max() < 0.01
    dual = dual_quaternion_dmp(n_basis=50)
    dual.imitate(t, dq)
    y = dual.rollout().y
    assert rotation_error_deg(dq_rotation(y), q).max() < 0.01  # (its translation: see UnitDualQuaternion.lift)
    cartesian = cartesian_dmp(n_basis=50)
    cartesian.imitate(t, np.c_[p, q])
    y = cartesian.rollout().y
    assert rotation_error_deg(y[:, 3:], q).max() < 0.01
    assert np.abs(y[:, :3] - p).max() < 1e-5


def test_past_half_a_turn_within_movement_primitives_error():
    """At 190 degrees CartesianDMP (Ude et al.'s gap, shortest branch) replays within a few degrees; ours
    (one continuous branch) does at least as well."""
    t, q = turn(190.0)
    p = translation(t)
    theirs = CartesianDMP(execution_time=t[-1], dt=t[1], n_weights_per_dim=50)
    theirs.imitate(t, np.c_[p, q])
    their_error = rotation_error_deg(theirs.open_loop()[1][: t.size, 3:], q).max()
    ours = cartesian_dmp(n_basis=50)
    ours.imitate(t, np.c_[p, q])
    our_error = rotation_error_deg(ours.rollout().y[:, 3:], q).max()
    assert our_error < min(their_error, 0.01)


def test_lift_changes_the_branch_not_the_rotation_or_pose():
    """``exp(lift(v, previous) / 2) = +-exp(v / 2)`` and the lifted rotation part is nearest ``previous``."""
    rng = np.random.default_rng(4)
    v = rng.normal(size=(200, 3)) * 2.0
    previous = v * rng.uniform(-3.0, 3.0, size=(200, 1)) + 0.1 * rng.normal(size=(200, 3))
    lifted = np.array([UnitQuaternion().lift(a, b) for a, b in zip(v, previous)])
    same = np.abs(np.sum(quat_exp(0.5 * lifted) * quat_exp(0.5 * v), axis=1))
    np.testing.assert_allclose(same, 1.0, atol=1e-12)
    axis = v / np.linalg.norm(v, axis=1, keepdims=True)
    for k in (-1.0, 1.0):  # one more or one less whole turn is never nearer
        other = lifted + 2 * np.pi * k * axis
        assert np.all(np.linalg.norm(lifted - previous, axis=1) <= np.linalg.norm(other - previous, axis=1) + 1e-12)
    screw = np.c_[v, rng.normal(size=(200, 3))]
    lifted_screw = np.array([UnitDualQuaternion().lift(a, np.r_[b, 0, 0, 0]) for a, b in zip(screw, previous)])
    a, b = dq_exp(0.5 * lifted_screw), dq_exp(0.5 * screw)
    sign = np.sign(np.sum(a[:, :4] * b[:, :4], axis=1))[:, None]
    np.testing.assert_allclose(a, sign * b, atol=1e-10)
    product = Product(UnitQuaternion(), UnitQuaternion())
    np.testing.assert_allclose(product.lift(np.r_[v[0], v[1]], np.r_[previous[0], previous[1]]), lifted[:2].ravel())


def test_koutras_doulgeri_dmp_is_the_linear_dmp_on_the_log_of_the_rotation_to_the_goal():
    """Koutras & Doulgeri (CoRL 2020): the orientation DMP is the per-component DMP of eq. (11) on
    ``y_e = log(q conj(q_g))`` driven to 0, with ``q = exp(y_e) q_g``. A Euclidean DMP learned on ``y_e``
    (computed here with pytransform3d) and mapped back gives the roll-out of GoalLogQuaternion."""
    t, q = turn(150.0)
    wobble = np.array([pr.quaternion_from_axis_angle([1.0, 0.0, 0.0, a]) for a in 0.3 * np.sin(np.pi * t / t[-1])])
    q = continuous(np.array([pr.concatenate_quaternions(a, b) for a, b in zip(wobble, q)]))
    goal = q[-1]
    log_to_goal = (
        np.array([pr.compact_axis_angle_from_quaternion(pr.concatenate_quaternions(x, pr.q_conj(goal))) for x in q]) / 2
    )
    linear = DMP(Euclidean(3), n_basis=40)
    linear.imitate(t, log_to_goal)
    expected = quat_multiply(quat_exp(linear.rollout().y), goal)
    dmp = DMP(GoalLogQuaternion(), n_basis=40)
    dmp.imitate(t, q)
    assert rotation_error_deg(dmp.rollout().y, expected).max() < 1e-9


def test_seed_gains_diverge_in_udes_form_and_not_in_koutras_doulgeri():
    """Seed 000's Q_r gains (beta, gamma = 348.348, 977.24, Fig. 15) on its IMU demonstration (10 s at
    100 Hz, 150-180 degrees from the goal): Ude's form leaves the demonstration by more than 1 rad, where
    its gain across the gap, (theta/2) cot(theta/2), is near 0 or negative; the log-to-goal form replays it
    within 10 mrad."""
    d = imu_interface_recording(samples=1000, rate=100.0, seed=2020, via_points=2).demonstration
    gains = Gains(beta=348.348, gamma=977.24)
    errors = {}
    for space in (UnitQuaternion(), GoalLogQuaternion()):
        dmp = DMP(space, n_basis=50, gains=gains, smoothing=2.5)
        dmp.imitate(d.t, d.quaternion)
        errors[space.name] = np.deg2rad(rotation_error_deg(dmp.rollout().y, dmp.learned.Y)).max()
    assert errors["S3"] > 1.0
    assert errors["S3-log"] < 0.01
