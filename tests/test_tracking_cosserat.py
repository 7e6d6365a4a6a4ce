"""Tracking on a pneumatic Cosserat rod plant: the nominal map is exact without gravity, gravity bends the rod as
beam theory says, the closed loop runs warm-started, and bad plant options name their field."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from optikin.algebra import dq_rotation, dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.qp import QPController
from optikin.control.reference import minimum_jerk_path, reference_from_configurations
from optikin.control.rod_plant import PneumaticRod, RodPlantSimulator, nominal_pressures
from optikin.control.simulate import Plant, simulate
from optikin.errors import SpecError
from optikin.runner import solve
from optikin.solvers.qp import step_solver
from tests.test_tracking_problem import short

ARM = ConstantCurvatureArm()
CBHA = PneumaticRod(
    youngs_modulus=40e3,
    poisson_ratio=0.5,
    density=150.0,
    radius=(0.045, 0.040),
    chamber_offset=(0.03725, 0.03175),
    chamber_area=3.1416e-4,
    rest_length=(0.162, 0.162),
    steps_per_segment=20,
    compiled=False,
)
WEIGHTLESS = replace(CBHA, gravity=(0.0, 0.0, 0.0))
COMPILED = replace(CBHA, compiled=True)  # closed loops: about 0.1 ms per warm-started equilibrium
CONFIGURATIONS = np.array(
    [
        [0.180, 0.6, 0.3, 0.180, 0.5, -1.0],
        [0.170, 1.0, 0.8, 0.190, -0.4, -0.5],
        [0.198, 2.0, -2.5, 0.162, -2.09, 3.0],
        [0.175, 0.0, 0.0, 0.185, 1e-9, 0.4],
    ]
)


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return float(quat_angle(quat_multiply(quat_conjugate(dq_rotation(a)), dq_rotation(b))))


@pytest.mark.parametrize("q", CONFIGURATIONS)
def test_without_gravity_the_rod_tip_is_the_cc_tip_to_the_discretisation_error(q):
    """The nominal map makes the weightless rod two CC sections (module docstring of optikin.control.rod_plant)."""
    cc = ARM.evaluate("fk_dq", q[None])[0]
    errors, angles = [], []
    for steps in (10, 20):
        tip = RodPlantSimulator(ARM, replace(WEIGHTLESS, steps_per_segment=steps)).tip(q, "pose")
        errors.append(np.linalg.norm(dq_translation(tip) - dq_translation(cc)))
        angles.append(angle_between(tip, cc))
    assert errors[1] < 1e-6 and angles[1] < 1e-5  # 0.36 m arm, RK4 with 20 steps per section
    if errors[0] > 1e-10:  # fourth order: halving the step divides the error by about 16
        assert 8.0 < errors[0] / errors[1] < 32.0


def test_a_straight_rod_under_a_small_sideways_gravity_bends_as_a_shear_deformable_cantilever():
    """Tip deflection ``v3^2 q L^4 / (8 E I) + q L^2 / (2 G A)`` (Euler-Bernoulli plus shear), ``q = rho A g``.

    Both sections alike and stretched by ``v3 = S / L0``; the chambers' axial forces are internal to each
    section (the section wrench is only the weight's), so they neither stiffen nor load the bending.
    """
    g = 0.05
    rod = replace(CBHA, radius=(0.04, 0.04), chamber_offset=(0.03, 0.03), gravity=(g, 0.0, 0.0))
    S, L0 = 0.18, 0.162
    tip = RodPlantSimulator(ARM, replace(rod, steps_per_segment=50)).tip(np.array([S, 0, 0, S, 0, 0]), "position")
    area, second = np.pi * 0.04**2, np.pi * 0.04**4 / 4
    q, L, v3 = rod.density * area * g, 2 * L0, S / L0
    expected = v3**2 * q * L**4 / (8 * rod.youngs_modulus * second) + q * L**2 / (2 * rod.youngs_modulus / 3 * area)
    assert tip[0] == pytest.approx(expected, rel=0.01)
    assert tip[2] == pytest.approx(2 * S, abs=1e-4)


def test_the_nominal_pressures_of_a_straight_section_are_equal_and_stretch_it_by_their_sum():
    """Equal pressures in three chambers at 120 degrees: pure extension ``3 p a / (E A)`` (physics.pneumatic)."""
    p = nominal_pressures(np.array([0.18, 0.0, 0.7, 0.17, 0.0, -0.2]), CBHA)
    for k, (S, R) in enumerate(((0.18, 0.045), (0.17, 0.040))):
        assert np.ptp(p[3 * k : 3 * k + 3]) == pytest.approx(0.0, abs=1e-9)
        strain = 3 * p[3 * k] * CBHA.chamber_area / (CBHA.youngs_modulus * np.pi * R**2)
        assert 0.162 * (1 + strain) == pytest.approx(S, rel=1e-12)


def test_weightless_rod_plant_gives_the_run_of_the_kinematic_plant_and_gravity_a_different_one():
    rate = 100.0
    t, Q, Qdot = minimum_jerk_path(CONFIGURATIONS[:2], 0.8, rate, hold=0.4)
    reference = reference_from_configurations(ARM, t, Q, Qdot, "pose")
    start = CONFIGURATIONS[0] + 0.01

    def run(plant):
        qp = QPController(ARM, 1.0 / rate, "pose", solver=step_solver("qp_osqp", ARM.n_config, 8))
        return simulate(qp, reference, start, plant)

    kinematic = run(Plant())
    weightless = run(Plant(rod=RodPlantSimulator(ARM, replace(COMPILED, gravity=(0.0, 0.0, 0.0)))))
    np.testing.assert_allclose(weightless.q, kinematic.q, atol=1e-5)
    assert weightless.plant_failures == 0 and kinematic.plant_failures is None
    assert weightless.metrics()["plant equilibrium failures"] == 0
    heavy = run(Plant(rod=RodPlantSimulator(ARM, COMPILED)))
    assert np.abs(heavy.q - kinematic.q).max() > 1e-2  # the controller compensates the sag
    assert "Newton iterations per step" in heavy.notes[0]


def test_the_qp_tracks_the_tip_position_of_the_heavy_rod_within_the_limits():
    """Position tracking is reachable under gravity: the QP converges with its CC Jacobian alone."""
    rate = 100.0
    t, Q, Qdot = minimum_jerk_path(CONFIGURATIONS[:2], 0.8, rate, hold=1.2)
    reference = reference_from_configurations(ARM, t, Q, Qdot, "position")
    qp = QPController(ARM, 1.0 / rate, "position", solver=step_solver("qp_osqp", ARM.n_config, 3))
    run = simulate(qp, reference, CONFIGURATIONS[0], Plant(rod=RodPlantSimulator(ARM, COMPILED)))
    metrics = run.metrics()
    assert metrics["position error max [mm]"] > 30.0  # the start: the CC tip is 64 mm off the rod's
    assert metrics["position error final [mm]"] < 0.05
    assert metrics["steps the controller kept or took outside"] == 0 and run.plant_failures == 0


@pytest.mark.parametrize(
    "key,value,field",
    [
        ("options.plant.physics.radius", [0.04], "options.plant.physics.radius"),
        ("options.plant.physics.chamber_offset", [0.05, 0.03], "options.plant.physics.chamber_offset"),
        ("options.plant.physics.rest_length", [0.16, 0.16, 0.16], "options.plant.physics.rest_length"),
        ("options.plant.physics.type", "elastica", "options.plant.physics.type"),
        ("options.plant.physics.payload", -1.0, "options.plant.physics.payload"),
        ("options.plant.physics.stiffness", 1.0, "options.plant.physics.stiffness"),
        ("options.plant.length_scale", 1.05, "options.plant.length_scale"),
    ],
)
def test_bad_rod_plant_options_name_the_field(key, value, field):
    with pytest.raises(SpecError) as error:
        solve("track-nominal-cosserat", overrides=short("track-nominal-cosserat", **{key: value}))
    assert error.value.field == field


def test_a_rod_plant_needs_a_constant_curvature_model_with_one_rod_section_per_cc_section():
    from optikin.arms.cbha import CBHAArm

    with pytest.raises(ValueError, match="constant_curvature"):
        RodPlantSimulator(CBHAArm(), CBHA)
    with pytest.raises(ValueError, match="radius needs 3 values"):
        RodPlantSimulator(ConstantCurvatureArm((0.18, 0.18, 0.18)), CBHA)
