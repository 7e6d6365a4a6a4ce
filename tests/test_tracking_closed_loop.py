"""Closed-loop tracking: limits held by the QP and crossed by the classical controllers, convergence,
the Lyapunov function of seed 000 section VI, MRAC gain saturation, model mismatch, disturbances.

References are made by forward kinematics of minimum-jerk configuration paths,
so "reachable" and "drives into a limit" are known by construction. Limits are
checked on the plant's configuration directly against the arm's bounds.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.baselines.mrac import MRACController, SecondOrderReferenceModel
from optikin.baselines.pseudo_inverse import DampedLeastSquaresController, PseudoInverseController
from optikin.control.qp import QPController
from optikin.control.reference import minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import Plant, simulate
from optikin.solvers.qp import step_solver

ARM = ConstantCurvatureArm()
RATE = 200.0
DT = 1.0 / RATE
START = np.array([0.18, 0.6, 0.3, 0.18, 0.5, -1.0])
INSIDE = np.array([0.17, 1.0, 0.8, 0.19, -0.4, -0.5])


def OSQPController(arm, dt, task="pose"):
    """The QP controller with OSQP updated in place (preset ``qp-osqp``'s backend at its defaults)."""
    return QPController(arm, dt, task, solver=step_solver("qp_osqp", arm.n_config, 8 if task == "pose" else 3))


QP_CONTROLLERS = (QPController, OSQPController)
"""The QP by its default step solver (the warm-started active set) and by OSQP."""
CONTROLLERS = (*QP_CONTROLLERS, PseudoInverseController, DampedLeastSquaresController, MRACController)
CLASSICAL = CONTROLLERS[len(QP_CONTROLLERS) :]
PHI = [2, 5]


def reference(waypoints, task="pose", duration=1.5, hold=1.5):
    t, Q, Qdot = minimum_jerk_path(np.asarray(waypoints), duration, RATE, hold=hold)
    return reference_from_configurations(ARM, t, Q, Qdot, task)


def outside_by(Q):
    """Distance of every sample's variables outside the arm's bounds (phi periodic: never)."""
    excess = np.maximum(Q - ARM.upper, 0.0) + np.maximum(ARM.lower - Q, 0.0)
    excess[:, PHI] = 0.0
    return excess


def test_minimum_jerk_path_hits_its_waypoints_at_rest_and_its_rate_is_the_derivative():
    t, Q, Qdot = minimum_jerk_path(np.array([START, INSIDE, START]), [1.0, 2.0], 1000.0, hold=0.5)
    for time, q in ((0.0, START), (1.0, INSIDE), (3.0, START), (3.5, START)):
        k = int(round(time * 1000))
        np.testing.assert_allclose(Q[k], q, atol=1e-12)
        np.testing.assert_allclose(Qdot[k], 0.0, atol=1e-9)
    np.testing.assert_allclose(Qdot[1:-1], (Q[2:] - Q[:-2]) / 2e-3, atol=2e-5 * np.abs(Qdot).max())
    # peak speed of a minimum-jerk segment: 15/8 of the mean speed (Flash & Hogan 1985)
    np.testing.assert_allclose(np.abs(Qdot[:1000]).max(axis=0), 1.875 * np.abs(INSIDE - START), rtol=1e-4)


@pytest.mark.parametrize("task", ["pose", "position"])
def test_reference_rate_is_the_time_derivative_of_the_reference(task):
    ref = reference([START, INSIDE], task, duration=1.0, hold=0.0)
    centred = (ref.value[2:] - ref.value[:-2]) / (2 * ref.dt)
    np.testing.assert_allclose(ref.rate[1:-1], centred, atol=2e-3 * np.abs(ref.rate).max())


def test_second_order_reference_model_follows_the_critically_damped_step_response():
    wn, dt = 10.0, 1e-3
    model = SecondOrderReferenceModel(dt, natural_frequency=wn, damping_ratio=1.0)
    model.reset(np.zeros(1))
    response = []
    for _ in range(1000):
        response.append(model.value[0])
        model.step(np.ones(1))
    t = np.arange(1000) * dt
    np.testing.assert_allclose(response, 1.0 - (1.0 + wn * t) * np.exp(-wn * t), atol=1e-12)


@pytest.mark.parametrize("Controller", CONTROLLERS)
def test_every_controller_converges_on_a_reachable_reference(Controller):
    """Start 3 mm / 3 deg-ish off a reachable pose path; tolerance: 0.05 mm and 0.05 deg over the last 10 %."""
    q0 = START + np.array([0.003, 0.05, -0.05, -0.003, 0.05, 0.05])
    run = simulate(Controller(ARM, DT, "pose"), reference([START, INSIDE]), q0)
    metrics = run.metrics()
    assert metrics["position error final [mm]"] < 0.05
    assert metrics["orientation error final [deg]"] < 0.05
    assert metrics["fallback steps"] == 0
    assert metrics["position error max [mm]"] > 3.0  # it did start off the reference


@pytest.mark.parametrize("QP", QP_CONTROLLERS)
@pytest.mark.parametrize("task", ["pose", "position"])
def test_qp_never_leaves_the_limits_while_the_classical_controllers_do(task, QP):
    """A reference driving theta_1 to 1.3 theta_max and S_2 beyond its range (outside the workspace)."""
    beyond = START.copy()
    beyond[1], beyond[3] = 1.3 * ARM.theta_max, 1.2 * ARM.upper[3]
    ref = reference([START, beyond], task)
    qp = simulate(QP(ARM, DT, task), ref, START)
    assert np.all(qp.q >= ARM.lower) and np.all(qp.q[:, [0, 1, 3, 4]] <= ARM.upper[[0, 1, 3, 4]])
    assert qp.metrics()["fallback steps"] == 0
    qp_rate = np.abs(qp.qdot).max(axis=0)
    assert np.all(qp_rate <= np.array([0.1, np.pi, 2 * np.pi] * 2) + 1e-12)
    for Controller in CLASSICAL:
        run = simulate(Controller(ARM, DT, task), ref, START)
        excess = outside_by(run.q)
        # they reach the unreachable pose by stretching the sections far past their length range
        assert excess[:, [0, 3]].max() > 0.05, Controller.name
        assert run.metrics()["max limit excess S [mm]"] == pytest.approx(1e3 * excess[:, [0, 3]].max())
        assert run.metrics()["samples outside limits"] == int(np.any(excess > 0, axis=1).sum())


@pytest.mark.parametrize("QP", QP_CONTROLLERS)
def test_qp_steers_back_from_outside_the_limits_at_the_rate_limit_and_never_farther(QP):
    q0 = START.copy()
    q0[1] = ARM.theta_max + 0.3  # theta_1 17 deg past its limit
    q0[3] = ARM.lower[3] - 0.004  # S_2 4 mm short of its range
    run = simulate(QP(ARM, DT, "pose"), reference([START, INSIDE]), q0)
    excess = outside_by(run.q)
    assert np.all(np.diff(excess, axis=0) <= 1e-15)  # never farther out
    rate = np.array([0.1, np.pi, 2 * np.pi] * 2)
    steps_back = np.ceil(excess[0] / (rate * DT) - 1e-9).astype(int)
    assert steps_back[1] == 20 and steps_back[3] == 8
    for i in (1, 3):
        assert np.all(excess[steps_back[i] :, i] == 0.0)
        np.testing.assert_allclose(np.diff(excess[: steps_back[i], i]), -rate[i] * DT, rtol=1e-9)
    assert run.metrics()["steps the controller kept or took outside"] == 0
    assert run.metrics()["position error final [mm]"] < 0.05


@pytest.mark.parametrize("task", ["pose", "position"])
@pytest.mark.parametrize("Controller", CONTROLLERS)
def test_lyapunov_function_decreases_on_a_static_reachable_reference(task, Controller):
    """Seed 000 eq. (39): Vdot = -e'Ke < 0 for an exact model and a reference at rest (here with J J^+ e = e)."""
    q0 = START + np.array([0.003, 0.05, -0.05, -0.003, 0.05, 0.05])
    run = simulate(Controller(ARM, DT, task), reference([START, START], task, duration=2.0, hold=0.0), q0)
    V = run.lyapunov
    assert np.all(np.diff(V) <= 1e-12 * V[0])
    assert V[-1] < 2e-2 * V[0]


def test_mrac_gains_only_grow_and_saturate_at_the_limit_and_this_is_reported():
    """Seed 000 eq. (35) integrates |e_1 x|: gains never decrease; Fig. 12's saturation caps them."""
    gain = np.array([7.45, 3.43, 3.70, 3.02, 9.62, 5.06, 4.69, 8.15])
    limit = 1.2 * gain
    controller = MRACController(ARM, DT, "pose", adaptation=2000.0, gain_limit=limit)
    plant = Plant(disturbance=(0.0, 0.3, 0.0, 0.0, -0.3, 0.0), disturbance_window=(1.0, 1.5))
    run = simulate(controller, reference([START, INSIDE]), START, plant)
    assert np.all(np.diff(run.gains, axis=0) >= 0.0)
    assert np.all(run.gains <= limit)
    metrics = run.metrics()
    assert metrics["gain saturation steps"] == int(np.any(run.gains >= limit, axis=1).sum()) > 0
    assert metrics["first gain saturation [s]"] >= 0.0
    assert metrics["position error final [mm]"] < 0.5


def test_model_mismatch_is_rejected_with_tip_feedback_and_not_with_model_feedback():
    """True arc lengths 5 % longer than modelled: a tip sensor closes the loop on the truth, the model cannot."""
    ref = reference([START, INSIDE])
    with_tip = simulate(OSQPController(ARM, DT, "pose"), ref, START, Plant(length_scale=1.05))
    with_model = simulate(OSQPController(ARM, DT, "pose"), ref, START, Plant(length_scale=1.05, feedback="model"))
    assert with_tip.metrics()["position error final [mm]"] < 0.05
    # converged in the model, so the true tip is off by roughly 5 % of its distance from the base
    reach = np.linalg.norm(ref.position[-1]) * 1e3
    assert 0.02 * reach < with_model.metrics()["position error final [mm]"] < 0.08 * reach


def test_qp_rejects_a_step_disturbance_without_leaving_the_limits():
    plant = Plant(disturbance=(0.0, 0.3, 0.0, 0.0, -0.3, 0.0), disturbance_window=(1.0, 2.0))
    run = simulate(OSQPController(ARM, DT, "pose"), reference([START, INSIDE]), START, plant)
    metrics = run.metrics()
    assert metrics["position error max [mm]"] > 20.0  # the disturbance was felt
    assert metrics["position error final [mm]"] < 0.1
    assert metrics["steps the controller kept or took outside"] == 0


def test_settling_time_of_a_first_order_decay_is_the_logarithm_of_the_error_ratio_over_the_gain():
    """Position task, exact model, static reference: ``e_k = (1 - K dt)^k e_0`` to first order in ``e_0``,
    so the error enters the band ``tol`` after ``ln(tol / e_0) / ln(1 - K dt)`` steps."""
    ref = reference([INSIDE, INSIDE], "position", duration=0.5, hold=1.5)
    run = simulate(PseudoInverseController(ARM, DT, "position", gain=10.0), ref, INSIDE + [1e-4, 1e-3, 0, 0, 0, 0])
    e0 = run.position_error[0]
    tolerance = 1e-3 * e0
    expected = np.log(tolerance / e0) / np.log(1 - 10.0 * DT) * DT
    assert run.settling_time(0.0, tolerance) == pytest.approx(expected, abs=1.5 * DT)
    assert run.settling_time(0.0, 1e-30) is None  # not settled by the end: the time-out
    assert run.settling_time(1.0, tolerance) == 0.0  # inside from about 0.68 s on
    assert run.settling_time(0.5, tolerance) == pytest.approx(expected - 0.5, abs=1.5 * DT)
