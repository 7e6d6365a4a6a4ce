"""Tests of the DMPs of `optikin.dmp` (seed 000 eqs. 11-28).

Expected values come from outside the code under test: movement_primitives
(basis, phase, DMP and CartesianDMP roll-outs on the same demonstration),
pytransform3d (slerp for the goal filter), the closed-form response of a
critically damped spring, the discrete recursion of a linear system written
out with numpy matrix powers, and exact invariances (time scaling, norms).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import pytransform3d.rotations as pr
from hypothesis import given, settings
from hypothesis import strategies as st
from movement_primitives.dmp import DMP as MPDMP
from movement_primitives.dmp import CartesianDMP
from movement_primitives.dmp._forcing_term import ForcingTerm

from optikin.algebra import (
    dq_norm_residual,
    dq_rotation,
    dq_translation,
    quat_angle,
    quat_conjugate,
    quat_exp,
    quat_from_axis_angle,
    quat_log,
    quat_multiply,
)
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.data.demonstrations import imu_interface_recording, smooth_pose_demonstration
from optikin.dmp import DMP, Euclidean, Gains, UnitQuaternion
from optikin.dmp import basis
from optikin.dmp.canonical import stopped_log_phase
from optikin.dmp.imitation import demonstration_log_phase, prepare
from optikin.dmp.pose import (
    cartesian_dmp,
    dual_quaternion_dmp,
    from_variant,
    pose_dmp,
    seed_dual_quaternion_dmp,
    to_variant,
)
from optikin.dmp.smoothing import smooth_demonstration, smoothing_weight, whittaker
from optikin.errors import InputDataError

ZETA = -math.log(0.01)


def rotation_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return quat_angle(quat_multiply(a, quat_conjugate(b)))


@pytest.fixture(scope="module")
def demo():
    return smooth_pose_demonstration(samples=500, duration=5.0, seed=3)


@pytest.fixture(scope="module")
def quaternion_dmp(demo):
    dmp = DMP(UnitQuaternion(), n_basis=30)
    dmp.imitate(demo.t, demo.quaternion)
    return dmp


def random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# ----------------------------------------------------------------------------- phase and basis


def test_basis_matches_movement_primitives_forcing_term(demo):
    """Centres, widths and forcing values equal movement_primitives' ForcingTerm on the same demonstration."""
    prepared = prepare(Euclidean(3), demo.t, demo.position)
    log_s = demonstration_log_phase(prepared, ZETA)
    c = basis.centres_along(log_s, 20)
    h = basis.widths(c)
    reference = ForcingTerm(3, 20, demo.t[-1], 0.0, 0.8, ZETA)
    np.testing.assert_allclose(c, reference.centers, rtol=1e-12)
    np.testing.assert_allclose(h, reference.widths, rtol=1e-9)
    reference.weights_ = np.random.default_rng(0).normal(size=(3, 20))
    s = np.exp(log_s)
    np.testing.assert_allclose(
        basis.features(s, c, h) @ reference.weights_.T, reference.forcing_term(s).T, rtol=1e-10, atol=1e-12
    )


def test_phase_is_the_solution_of_the_canonical_system():
    """alpha = 0: exp(-zeta t / tau) (eq. 15); a constant error e slows the rate to zeta / (1 + alpha e) (eq. 25)."""
    dt, tau, k = 0.01, 2.0, np.arange(301)
    np.testing.assert_allclose(
        np.exp(stopped_log_phase(dt, tau, 3.0, 0.0, np.zeros(300))), np.exp(-3.0 * k * dt / tau), rtol=1e-13
    )
    np.testing.assert_allclose(
        np.exp(stopped_log_phase(dt, tau, 3.0, 4.0, np.full(300, 0.5))), np.exp(-3.0 / 3.0 * k * dt / tau), rtol=1e-13
    )


# ----------------------------------------------------------------------------- dynamics against closed forms


def _spring_rollout(space_dmp: DMP, dt: float, start, goal) -> tuple[np.ndarray, np.ndarray]:
    """Roll out with zero weights: the transformation system alone, a critically damped spring."""
    out = space_dmp.rollout(
        duration=space_dmp.tau, dt=dt, start=start, goal=goal, weights=np.zeros_like(space_dmp.weights)
    )
    return out.t, out.y


def test_zero_weight_dmp_is_the_discrete_critically_damped_spring(demo):
    """Per angle (eqs. 11-12) with f = 0: the roll-out equals the linear recursion written as matrix powers,
    and converges at first order in dt to y(t) = g + (y0 - g)(1 + w t) exp(-w t), w = beta / (2 tau)."""
    dmp = DMP(Euclidean(1), n_basis=5, gains=Gains(beta=20.0, gamma=5.0))
    dmp.imitate(demo.t, demo.position[:, :1])
    tau, y0, g = dmp.tau, np.array([0.3]), np.array([-0.2])

    dt = 0.01
    t, y = _spring_rollout(dmp, dt, y0, g)
    k1, k2 = 20.0 * dt / tau, 100.0 * (dt / tau) ** 2
    A = np.array([[1 - k1, -k2], [1 - k1, 1 - k2]])  # (u = dt/tau eta, e = y - g)
    states = [np.linalg.matrix_power(A, n) @ np.array([0.0, y0[0] - g[0]]) for n in range(t.size)]
    np.testing.assert_allclose(y[:, 0], g[0] + np.array(states)[:, 1], atol=1e-12)

    w = 20.0 / (2 * tau)
    errors = []
    for dt in (0.01, 0.005):
        t, y = _spring_rollout(dmp, dt, y0, g)
        exact = g[0] + (y0[0] - g[0]) * (1 + w * t) * np.exp(-w * t)
        errors.append(np.abs(y[:, 0] - exact).max())
    assert errors[0] < 5e-3 and 1.8 < errors[0] / errors[1] < 2.2


def test_single_axis_quaternion_dmp_follows_the_scalar_spring(quaternion_dmp):
    """A rotation about one fixed axis reduces eqs. 17-18 to the scalar spring of eqs. 11-12 on the angle."""
    dmp = quaternion_dmp
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    angle = 2.5
    out = dmp.rollout(
        start=np.array([1.0, 0, 0, 0]),
        goal=quat_from_axis_angle(axis, angle),
        dt=0.001,
        weights=np.zeros_like(dmp.weights),
    )
    w = dmp.gains.beta / (2 * dmp.tau)
    expected_angle = angle * (1 - (1 + w * out.t) * np.exp(-w * out.t))
    rotation_vector = 2 * quat_log(out.y)
    np.testing.assert_allclose(np.cross(rotation_vector, axis), 0.0, atol=1e-12)
    assert np.abs(rotation_vector @ axis - expected_angle).max() < 2e-3


# ----------------------------------------------------------------------------- unit norm and convergence


@pytest.mark.parametrize("beta_g0", [math.inf, 8.0])
def test_quaternion_rollouts_stay_unit_and_reach_random_goals(quaternion_dmp, beta_g0):
    """|q| - 1 < 1e-12 along every roll-out and final error < 1e-6 rad, for random goals and mid-motion switches."""
    rng = np.random.default_rng(11)
    gains = quaternion_dmp.gains.with_values(beta_g0=beta_g0)
    goals = random_quaternions(rng, 6)
    for first, second in zip(goals[:3], goals[3:]):
        out = quaternion_dmp.rollout(
            duration=6 * quaternion_dmp.tau, goal=first, gains=gains, goal_switches=[(0.4 * quaternion_dmp.tau, second)]
        )
        assert np.abs(np.linalg.norm(out.y, axis=1) - 1).max() < 1e-12
        assert np.abs(np.linalg.norm(out.goal, axis=1) - 1).max() < 1e-12
        assert rotation_error(out.y[-1], second) < 1e-6


unit_quaternions = (
    st.lists(st.floats(-1, 1), min_size=4, max_size=4)
    .map(np.array)
    .filter(lambda q: np.linalg.norm(q) > 0.1)
    .map(lambda q: q / np.linalg.norm(q))
)


@settings(max_examples=25, deadline=None)
@given(first=unit_quaternions, second=unit_quaternions, switch=st.floats(0.0, 1.5), beta_g0=st.floats(5.0, 50.0))
def test_any_goal_and_any_switch_keep_unit_norm_and_converge(quaternion_dmp, first, second, switch, beta_g0):
    """beta_g0 >= 5: the filter's own gap, pi exp(-beta_g0 (6 - 1.5)), is below 1e-9 rad by the end."""
    dmp = quaternion_dmp
    out = dmp.rollout(
        duration=6 * dmp.tau,
        goal=first,
        goal_switches=[(switch * dmp.tau, second)],
        gains=dmp.gains.with_values(beta_g0=beta_g0),
    )
    assert np.abs(np.linalg.norm(out.y, axis=1) - 1).max() < 1e-12
    assert rotation_error(out.y[-1], second) < 1e-6


def test_dual_quaternion_rollouts_stay_unit_and_reach_random_poses(demo):
    """The sound pose DMP stays a unit dual quaternion (|Q_r| = 1, Q_r . Q_d = 0) and reaches every goal pose."""
    dmp = dual_quaternion_dmp(n_basis=30)
    dmp.imitate(demo.t, demo.dual_quaternion)
    rng = np.random.default_rng(5)
    for q, p in zip(random_quaternions(rng, 3), rng.uniform(-0.2, 0.2, (3, 3))):
        goal = np.concatenate([q, 0.5 * quat_multiply(np.concatenate([[0.0], p]), q)])
        out = dmp.rollout(duration=6 * dmp.tau, goal=goal)
        norm_error, orthogonality = dq_norm_residual(out.y)
        assert np.abs(norm_error).max() < 1e-12 and np.abs(orthogonality).max() < 1e-12
        assert rotation_error(dq_rotation(out.y[-1]), q) < 1e-6
        assert np.linalg.norm(dq_translation(out.y[-1]) - p) < 1e-6


def test_seed_variant_cannot_change_the_norm_of_q_d(demo):
    """The seed's quaternion DMP on Q_d keeps |Q_d| = |p0|/2 (eq. 23 preserves norms), so it misses a goal at
    another distance from the origin, where the sound variants reach it."""
    dq = demo.dual_quaternion
    assert abs(np.linalg.norm(dq[-1, 4:]) - np.linalg.norm(dq[0, 4:])) > 0.01  # the demonstration changes |p|
    seed = seed_dual_quaternion_dmp(n_basis=30)
    seed.imitate(demo.t, dq)
    out = seed.rollout(duration=6 * seed.tau)
    np.testing.assert_allclose(np.linalg.norm(out.y[:, 4:], axis=1), np.linalg.norm(dq[0, 4:]), rtol=1e-12)
    assert np.linalg.norm(dq_translation(out.y[-1]) - demo.position[-1]) > 0.01
    for sound in (dual_quaternion_dmp(n_basis=30), cartesian_dmp(n_basis=30)):
        data = dq if sound.space.size == 8 else demo.pose
        sound.imitate(demo.t, data)
        final = sound.rollout(duration=6 * sound.tau).y[-1]
        position = dq_translation(final) if sound.space.size == 8 else final[:3]
        assert np.linalg.norm(position - demo.position[-1]) < 1e-6


# ----------------------------------------------------------------------------- learning and generalisation


@pytest.mark.parametrize("space,column", [(Euclidean(3), "rpy"), (UnitQuaternion(), "quaternion")])
def test_reproduction_error_falls_as_the_basis_grows(demo, space, column):
    data = demo.quaternion if column == "quaternion" else 2 * quat_log(demo.quaternion)
    errors = []
    for n in (4, 8, 16, 32):
        dmp = DMP(space, n_basis=n)
        dmp.imitate(demo.t, data)
        y = dmp.rollout().y
        errors.append((rotation_error(y, data) if column == "quaternion" else np.abs(y - data)).max())
    assert all(a > 1.5 * b for a, b in zip(errors, errors[1:])), errors
    assert errors[-1] < 1e-3


def test_time_scaling_replays_the_same_motion_slower(quaternion_dmp):
    """tau -> 2 tau with dt -> 2 dt gives the same samples: the roll-out depends on dt / tau only."""
    original = quaternion_dmp.rollout()
    slow = quaternion_dmp.rollout(tau=2 * quaternion_dmp.tau, dt=2 * quaternion_dmp.dt)
    np.testing.assert_allclose(slow.t, 2 * original.t)
    np.testing.assert_allclose(slow.y, original.y, atol=1e-13)


def test_goal_filter_with_one_rate_per_component(demo):
    """A diagonal beta_g0 (eq. 24 with beta_g0 a diagonal matrix): per angle the goal of each component
    follows its own exponential, g_i(t) = new_i + (old_i - new_i) exp(-beta_i (t - t_s) / tau)."""
    rates = (2.0, 7.0, 40.0)
    dmp = DMP(Euclidean(3), n_basis=10, gains=Gains(beta_g0=rates))
    dmp.imitate(demo.t, demo.position)
    old, new = demo.position[-1], demo.position[-1] + np.array([0.02, -0.03, 0.01])
    switch = 1.0 + 0.5 * dmp.dt
    out = dmp.rollout(goal_switches=[(switch, new)])
    k = int(np.flatnonzero(out.t >= switch)[0])
    elapsed = (out.t[k + 1 :] - out.t[k])[:, None]
    expected = new + (old - new) * np.exp(-np.array(rates) * elapsed / dmp.tau)
    np.testing.assert_allclose(out.goal[k + 1 :], expected, atol=1e-13)
    assert Gains(beta_g0=5.0).goal_rates(3).tolist() == [5.0, 5.0, 5.0]
    with pytest.raises(ValueError):
        Gains(beta_g0=(1.0, -2.0, 3.0))
    with pytest.raises(ValueError):
        DMP(Euclidean(3), gains=Gains(beta_g0=(1.0, 2.0))).gains.goal_rates(3)


def test_goal_filter_moves_the_goal_along_the_geodesic(quaternion_dmp):
    """Eq. (24) integrated exactly: after a switch at t_s the goal is slerp(new, old, exp(-beta_g0 (t - t_s)/tau))."""
    dmp, rng = quaternion_dmp, np.random.default_rng(2)
    old, new = rng.normal(size=(2, 4))
    old, new = old / np.linalg.norm(old), new / np.linalg.norm(new)
    new = new if old @ new >= 0 else -new
    switch, beta_g0 = 1.0 + 0.5 * dmp.dt, 6.0  # mid-step: the step from t_k = 1 + dt is the first to see it
    out = dmp.rollout(goal=old, goal_switches=[(switch, new)], gains=dmp.gains.with_values(beta_g0=beta_g0))
    k = int(np.flatnonzero(out.t >= switch)[0])
    elapsed = out.t[k + 1 :] - out.t[k]
    expected = np.array([pr.quaternion_slerp(new, old, math.exp(-beta_g0 * e / dmp.tau)) for e in elapsed])
    np.testing.assert_allclose(out.goal[k + 1 :], expected, atol=1e-12)
    np.testing.assert_allclose(out.goal[: k + 1], np.broadcast_to(old, (k + 1, 4)), atol=1e-15)
    # The spring term gamma gap(g, y) of eq. (17) changes smoothly across the switch (no kink in eta);
    # without the filter it jumps.
    jump = dmp.rollout(goal=old, goal_switches=[(switch, new)])
    window = slice(k - 2, k + 4)
    kink = np.abs(np.diff(out.eta, 2, axis=0)[window]).max()
    assert kink < 0.2 * np.abs(np.diff(jump.eta, 2, axis=0)[window]).max()


def test_perturbation_recovery_by_coupling_to_the_reference(demo):
    """A step disturbance (amplitude 1 from 40% to 56% of the motion, as seed Figs. 20-21 at 5-7 s of 12.5 s).

    Per angle the deviation from the undisturbed roll-out obeys the linear recursion of the spring plus the
    coupling of eq. (27), whatever the forcing term: written out with numpy, it must match the roll-outs to
    rounding, plain and coupled. On the quaternion DMP the coupling halves the peak, and both converge to
    the goal. The seed's phase stopping (eq. 28) keeps its labelled behaviour: the phase is slowed by the
    goal gap, so the coupled DMP ends on the reference."""
    tau, dt = demo.t[-1], demo.t[1]

    def step(t, dim=3):
        d = np.zeros((t.size, dim))
        d[(t >= 0.4 * tau) & (t < 0.56 * tau), 0] = 1.0
        return d

    for alpha_s in (0.0, 5.0):
        dmp = DMP(Euclidean(3), n_basis=30, gains=Gains(alpha_s=alpha_s))
        dmp.imitate(demo.t, demo.position)
        reference = demo.position if alpha_s else None
        deviation = (dmp.rollout(disturbance=step, reference=reference).y - dmp.rollout(reference=reference).y)[:, 0]
        # (u = dt/tau delta eta, d = delta y): u' = (1 - k1) u - k2 d + dt^2/tau^2 force, d' = d + u' - ks d
        k1, k2, ks = 25.0 * dt / tau, 25.0 * 6.25 * (dt / tau) ** 2, 2 * alpha_s * dt / tau
        A = np.array([[1 - k1, -k2], [1 - k1, 1 - k2 - ks]])
        b = np.array([1.0, 1.0]) * (dt / tau) ** 2
        state, expected = np.zeros(2), [0.0]
        for force in step(demo.t[:-1])[:, 0]:
            state = A @ state + b * force
            expected.append(state[1])
        np.testing.assert_allclose(deviation, expected, atol=1e-12)

    peaks = {}
    for label, gains in (("plain", Gains()), ("coupled", Gains(alpha_s=5.0))):
        dmp = DMP(UnitQuaternion(), n_basis=30, gains=gains)
        dmp.imitate(demo.t, demo.quaternion)
        out = dmp.rollout(disturbance=step, reference=demo.quaternion if label == "coupled" else None)
        peaks[label] = rotation_error(out.y, demo.quaternion).max()
        assert peaks[label] > 1e-3  # the disturbance did push the motion off
        final = dmp.rollout(duration=6 * tau, disturbance=step).y[-1]
        assert rotation_error(final, demo.quaternion[-1]) < 1e-6
    assert peaks["coupled"] < 0.6 * peaks["plain"]

    seed = DMP(UnitQuaternion(), n_basis=30, gains=Gains(alpha_s=5.0, alpha=5.0), phase_stopping="seed")
    seed.imitate(demo.t, demo.quaternion)
    out = seed.rollout(disturbance=step, reference=demo.quaternion)
    error = rotation_error(out.y, demo.quaternion)
    assert error[-1] < 0.02 * error.max() and out.phase[-1] > 0.2


def test_output_disturbance_displaces_the_pose_and_the_dmp_integrates_on_from_it(demo):
    """An output step (seed 000's "output step disturbance", Figs. 20-21): the pose is displaced by 1 and held
    from 40% to 56% of the motion. Per angle the deviation from the undisturbed roll-out obeys the linear
    recursion of the spring and the coupling with the displacement's jumps added to the pose, written out
    with numpy; on the quaternion DMP the pose is turned by exactly 1 rad at the first displaced sample."""
    tau, dt = demo.t[-1], demo.t[1]

    def step(t, dim=3):
        d = np.zeros((t.size, dim))
        d[(t >= 0.4 * tau) & (t < 0.56 * tau), 0] = 1.0
        return d

    for alpha_s in (0.0, 5.0):
        dmp = DMP(Euclidean(3), n_basis=30, gains=Gains(alpha_s=alpha_s))
        dmp.imitate(demo.t, demo.position)
        reference = demo.position if alpha_s else None
        deviation = (dmp.rollout(offset=step, reference=reference).y - dmp.rollout(reference=reference).y)[:, 0]
        k1, k2, ks = 25.0 * dt / tau, 25.0 * 6.25 * (dt / tau) ** 2, 2 * alpha_s * dt / tau
        A = np.array([[1 - k1, -k2], [1 - k1, 1 - k2 - ks]])
        jumps = np.diff(step(demo.t[1:])[:, 0], prepend=0.0)
        state, expected = np.zeros(2), [0.0]
        for jump in jumps:
            state = A @ state + np.array([0.0, jump])
            expected.append(state[1])
        np.testing.assert_allclose(deviation, expected, atol=1e-12)
    dmp = DMP(UnitQuaternion(), n_basis=30)
    dmp.imitate(demo.t, demo.quaternion)
    pushed, calm = dmp.rollout(offset=step).y, dmp.rollout().y
    first = int(np.flatnonzero(demo.t >= 0.4 * tau)[0])
    assert rotation_error(pushed[first], calm[first]) == pytest.approx(1.0, abs=1e-9)
    assert rotation_error(pushed[first - 1], calm[first - 1]) < 1e-12


def test_phase_stopping_changes_nothing_without_a_tracking_error(quaternion_dmp, demo):
    """Phase stopping on the tracking error (Ijspeert et al. 2013, Ude et al. 2014): with no reference, or a
    reference the DMP follows exactly (its own roll-out), the phase is eq. (15)'s exp(-zeta t / tau) and the
    roll-out is the one without phase stopping. The seed's eq. (28) also counts the goal gap: its phase lags."""
    free = DMP(UnitQuaternion(), n_basis=30, gains=Gains(alpha_s=2.0))
    free.imitate(demo.t, demo.quaternion)
    base = free.rollout()
    stopping = DMP(UnitQuaternion(), n_basis=30, gains=Gains(alpha_s=2.0, alpha=50.0))
    stopping.imitate(demo.t, demo.quaternion)
    np.testing.assert_allclose(stopping.weights, free.weights, rtol=1e-12)
    for reference in (None, base.y[:-1]):
        out = stopping.rollout(reference=reference)
        np.testing.assert_allclose(out.phase, np.exp(-ZETA * out.t / stopping.tau), rtol=1e-9)
        np.testing.assert_allclose(out.y, base.y, atol=1e-9)
    seed = DMP(UnitQuaternion(), n_basis=30, gains=Gains(alpha_s=2.0, alpha=50.0), phase_stopping="seed")
    seed.imitate(demo.t, demo.quaternion)
    assert seed.rollout().phase[-1] > 0.3
    with pytest.raises(ValueError, match="phase stopping"):
        DMP(UnitQuaternion(), phase_stopping="goal")


def test_phase_stopping_holds_the_motion_while_the_robot_is_blocked(quaternion_dmp, demo):
    """With the reference held at the start pose (a blocked robot) the tracking error stops the phase and the
    DMP waits near the start; once the robot follows again (reference = the DMP's own free roll-out from the
    release on) the phase runs at eq. (15)'s rate again."""
    dmp = quaternion_dmp
    held = np.broadcast_to(demo.quaternion[0], demo.quaternion.shape)
    free = dmp.rollout(reference=held, gains=dmp.gains.with_values(alpha_s=2.0))
    stopped = dmp.rollout(reference=held, gains=dmp.gains.with_values(alpha_s=2.0, alpha=50.0))
    assert free.phase[-1] < 0.02 and stopped.phase[-1] > 0.5
    progress = rotation_error(demo.quaternion[-1], demo.quaternion[0])
    assert rotation_error(stopped.y[-1], demo.quaternion[0]) < 0.5 * rotation_error(free.y[-1], demo.quaternion[0])
    assert progress > 0.1
    rate = np.diff(np.log(stopped.phase)) / np.diff(stopped.t)
    assert np.all(rate <= 0) and rate[-1] > -0.2 * ZETA / dmp.tau  # held: well below the free rate


# ----------------------------------------------------------------------------- after the demonstration


def test_forcing_term_is_off_past_the_demonstrations_phase():
    """Past the demonstration's final phase the DMP is the critically damped spring (eq. 11 with f = 0): on
    the noisy IMU positions the roll-out after tau must equal that linear recursion written out with numpy
    matrix powers from the state at tau (without the gate the forcing term, s times weights of ~1e5, went on
    pushing for seconds), and the last forced step is the last step of the demonstration."""
    recording = imu_interface_recording(samples=500, rate=50.0, seed=2020)
    dmp = DMP(Euclidean(3), n_basis=50)
    dmp.imitate(recording.t, recording.demonstration.position)
    assert np.abs(dmp.weights).max() > 1e4  # noisy targets divided by s ~ 0.01
    out = dmp.rollout(duration=3 * dmp.tau)
    k = int(round(dmp.tau / dmp.dt))  # the sample at tau
    assert out.phase[k - 1] > dmp.forcing_end > out.phase[k]
    dt, tau = dmp.dt, dmp.tau
    k1, k2 = 25.0 * dt / tau, 25.0 * 6.25 * (dt / tau) ** 2
    A = np.array([[1 - k1, -k2], [1 - k1, 1 - k2]])
    goal = dmp.demo.goal
    for i in range(3):
        state = np.array([dt / tau * out.eta[k, i], out.y[k, i] - goal[i]])
        expected = [goal[i] + (np.linalg.matrix_power(A, n) @ state)[1] for n in range(out.t.size - k)]
        np.testing.assert_allclose(out.y[k:, i], expected, atol=1e-12)
    assert np.abs(out.y[-1] - goal).max() < 1e-9


@pytest.fixture(scope="module")
def imu_recordings():
    return {seed: imu_interface_recording(samples=1000, seed=seed) for seed in (2020, 2)}


@pytest.mark.parametrize("variant", ["dual-quaternion", "cartesian"])
def test_imu_pose_dmps_settle_on_the_goal_after_tau(imu_recordings, variant):
    """IMU-learned pose DMPs (2.5 Hz smoothing) rolled out for 5 tau: after tau the tip stays within 2 mm of
    the box of the demonstrated positions and within 3 mm / 25 mrad of the goal, and converges to it. The
    goal is the recording's final pose to within the sensor noise, and within tau the roll-out follows the
    true (noise-free) motion to 1.5 mm (both checked against the interface's true configurations). With
    the gate alone the same roll-outs still swing 8-33 mm and up to 0.2 rad off the goal after tau (the
    noise-made final velocity); before the gate seed 2020's went from 0.32 to 0.45 m from the base within a
    second after tau and ended metres away after 5 tau."""
    arm = ConstantCurvatureArm()
    for recording in imu_recordings.values():
        demo = recording.demonstration
        q_true, p_true = arm.section_frames(recording.configuration)[-1]
        dmp = pose_dmp(variant, n_basis=50, smoothing=2.5)
        dmp.imitate(recording.t, to_variant(variant, demo.dual_quaternion))
        out = dmp.rollout(duration=5 * dmp.tau)
        p, q = from_variant(variant, out.y)
        p_goal, q_goal = from_variant(variant, dmp.demo.goal)
        k = demo.t.size - 1  # the sample at tau
        after = slice(k, None)
        outside = np.maximum(p[after] - demo.position.max(axis=0), demo.position.min(axis=0) - p[after])
        assert outside.max() < 2e-3
        assert np.linalg.norm(p[after] - p_goal, axis=1).max() < 3e-3
        assert rotation_error(q[after], q_goal).max() < 25e-3
        assert np.linalg.norm(p[-1] - p_goal) < 1e-9 and rotation_error(q[-1], q_goal) < 1e-9
        assert np.linalg.norm(p_goal - p_true[-1]) < 1.5e-3 and rotation_error(q_goal, q_true[-1]) < 10e-3
        assert np.linalg.norm(p[: k + 1] - p_true, axis=1).max() < 1.5e-3


# ----------------------------------------------------------------------------- smoothing


def test_whittaker_smoother_solves_its_normal_equations_and_has_its_transfer_function():
    """The banded solve equals (I + lam D'D)^-1 x with D from numpy's third differences; in the middle of a
    long record a sinusoid of frequency f is scaled by 1 / (1 + lam (2 sin(pi f dt))^6), which is 1/2 at the
    cutoff."""
    rng = np.random.default_rng(4)
    x = rng.normal(size=(40, 2))
    D = np.diff(np.eye(40), 3, axis=0)
    np.testing.assert_allclose(whittaker(x, 7.0), np.linalg.solve(np.eye(40) + 7.0 * D.T @ D, x), atol=1e-12)
    dt, cutoff = 0.01, 2.5
    lam = smoothing_weight(cutoff, dt)
    t = np.arange(6000) * dt
    middle = slice(2000, 4000)
    for f in (0.5, cutoff, 6.0):
        wave = np.sin(2 * np.pi * f * t)
        gain = 1.0 / (1.0 + lam * (2 * np.sin(np.pi * f * dt)) ** 6)
        np.testing.assert_allclose(whittaker(wave[:, None], lam)[middle, 0], gain * wave[middle], atol=1e-9)
    assert 1.0 / (1.0 + lam * (2 * np.sin(np.pi * cutoff * dt)) ** 6) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="Nyquist"):
        smoothing_weight(60.0, dt)


def test_smoothing_keeps_quaternions_unit_and_dual_quaternions_rigid(imu_recordings):
    """Smoothed in the goal's tangent space and mapped back by exp: unit quaternions and rigid poses to
    rounding; the smoothed positions are closer to the true motion than the recorded ones."""
    recording = imu_recordings[2020]
    demo = recording.demonstration
    _, p_true = ConstantCurvatureArm().section_frames(recording.configuration)[-1]
    q = smooth_demonstration(UnitQuaternion(), demo.quaternion, 0.01, 2.5)
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-12
    dq = smooth_demonstration(dual_quaternion_dmp().space, demo.dual_quaternion, 0.01, 2.5)
    norm_error, orthogonality = dq_norm_residual(dq)
    assert np.abs(norm_error).max() < 1e-12 and np.abs(orthogonality).max() < 1e-12
    rms = lambda p: np.sqrt(np.mean(np.sum((p - p_true) ** 2, axis=1)))  # noqa: E731
    assert rms(dq_translation(dq)) < 0.5 * rms(demo.position)


# ----------------------------------------------------------------------------- cross-checks with movement_primitives


def test_per_dof_dmp_agrees_with_movement_primitives(demo):
    """Same demonstration, gains, basis: reproduction, a new goal and a doubled duration agree with
    movement_primitives' DMP to within 1% of the change a generalisation makes."""
    ours = DMP(Euclidean(3), n_basis=30)
    ours.imitate(demo.t, demo.position)
    theirs = MPDMP(n_dims=3, execution_time=demo.t[-1], dt=demo.t[1], n_weights_per_dim=30)
    theirs.imitate(demo.t, demo.position)
    n = demo.t.size  # open_loop() may add a sample past the end
    base_ours, base_theirs = ours.rollout().y, theirs.open_loop()[1][:n]
    assert np.abs(base_ours - demo.position).max() < 1e-5
    assert np.abs(base_theirs - demo.position).max() < 2e-3

    goal = demo.position[-1] + np.array([0.04, -0.03, 0.05])
    theirs.configure(goal_y=goal)
    shift_ours = ours.rollout(goal=goal).y - base_ours
    shift_theirs = theirs.open_loop()[1][:n] - base_theirs
    assert np.abs(shift_ours - shift_theirs).max() < 0.01 * np.abs(shift_theirs).max()

    theirs.configure(goal_y=demo.position[-1])
    theirs.execution_time_ = 2 * demo.t[-1]
    slow_theirs = theirs.open_loop()[1]
    slow_ours = ours.rollout(tau=2 * ours.tau).y
    n = min(len(slow_ours), len(slow_theirs))
    assert np.abs(slow_ours[:n] - slow_theirs[:n]).max() < 0.01 * np.ptp(demo.position, axis=0).max()


def test_quaternion_dmp_agrees_with_movement_primitives_cartesian_dmp(demo):
    """CartesianDMP (Ude et al. 2014 on the orientation) on the same pose demonstration: new goal pose and
    new orientation move both by the same amount to within 1%."""
    ours = cartesian_dmp(n_basis=30)
    ours.imitate(demo.t, demo.pose)
    theirs = CartesianDMP(execution_time=demo.t[-1], dt=demo.t[1], n_weights_per_dim=30)
    theirs.imitate(demo.t, demo.pose)
    n = demo.t.size  # open_loop() may add a sample past the end
    base_ours, base_theirs = ours.rollout().y, theirs.open_loop()[1][:n]
    assert rotation_error(base_ours[:, 3:], demo.quaternion).max() < 2e-4
    assert rotation_error(base_theirs[:, 3:], demo.quaternion).max() < 2e-3

    goal = np.concatenate(
        [demo.position[-1] + 0.05, quat_multiply(quat_exp(np.array([0.2, -0.1, 0.25])), demo.quaternion[-1])]
    )
    theirs.configure(goal_y=goal)
    moved_ours, moved_theirs = ours.rollout(goal=goal).y, theirs.open_loop()[1][:n]
    turn_ours = 2 * quat_log(quat_multiply(moved_ours[:, 3:], quat_conjugate(base_ours[:, 3:])))
    turn_theirs = 2 * quat_log(quat_multiply(moved_theirs[:, 3:], quat_conjugate(base_theirs[:, 3:])))
    assert np.abs(turn_ours - turn_theirs).max() < 0.01 * np.abs(turn_theirs).max()
    shift_ours, shift_theirs = moved_ours[:, :3] - base_ours[:, :3], moved_theirs[:, :3] - base_theirs[:, :3]
    assert np.abs(shift_ours - shift_theirs).max() < 0.01 * np.abs(shift_theirs).max()


# ----------------------------------------------------------------------------- bad input


def test_bad_demonstrations_name_the_sample_and_field(demo):
    dmp = DMP(UnitQuaternion(), n_basis=10)
    t = demo.t.copy()
    t[7] += 1e-3
    with pytest.raises(InputDataError, match="sample 7.*t.*equally spaced"):
        dmp.imitate(t, demo.quaternion)
    Q = demo.quaternion.copy()
    Q[12, 2] = np.nan
    with pytest.raises(InputDataError, match="sample 12.*y"):
        dmp.imitate(demo.t, Q)
    with pytest.raises(InputDataError, match=r"shape \(N, 4\)"):
        dmp.imitate(demo.t, demo.pose)
    scaled = DMP(Euclidean(3), n_basis=10, scale_by_amplitude=True)
    flat = demo.position.copy()
    flat[:, 1] = 0.1
    with pytest.raises(InputDataError, match=r"gap\[1\]"):
        scaled.imitate(demo.t, flat)
