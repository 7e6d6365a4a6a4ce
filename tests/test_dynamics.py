"""Implicit Cosserat-rod dynamics (optikin.physics.dynamics), each check against something independent.

* free vibration of a clamped steel rod: bending frequencies against Euler-Bernoulli's closed form;
* Kelvin-Voigt damping: the decay rate against the modal closed form ``eta omega^2 / (2 E)``;
* the static limit: a held step load, damped, settles to the static shooting solver's equilibrium
  (:class:`optikin.physics.ShootingSolver`, an independent implementation of the statics);
* energy: without damping, bounded drift over 1,000 steps at the least dissipative stable alpha;
* derivatives of a step against finite differences of the step itself.

Frequencies and decay rates are read from the tip trace by the matrix-pencil method (a sum of
damped exponentials fitted exactly, Hua and Sarkar, IEEE T-ASSP 38(5), 1990).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pydantic import ValidationError

from optikin.errors import InputDataError
from optikin.physics import Loads, Rod, RodArm, ShootingOptions, ShootingSolver, Tendon
from optikin.physics.dynamics import Damping, DynamicsOptions, RodDynamics

BETA = (1.8751040687, 4.6940911330)
"""``beta_n L`` of the first two bending modes of a clamped-free Euler-Bernoulli beam."""


def steel_rod() -> Rod:
    """A slender steel rod (L / r = 200): Timoshenko corrections below 1e-3 on the first two modes."""
    return Rod(
        length=1.0, radius=0.005, youngs_modulus=200e9, poisson_ratio=0.3, density=8000.0, gravity=(0.0, 0.0, 0.0)
    )


def soft_rod() -> Rod:
    """The soft rod of the PyElastica comparisons: 0.3 m, r = 10 mm, E = 1 MPa, G = E / 3, 1000 kg/m^3, weight."""
    return Rod(
        length=0.3,
        radius=0.01,
        youngs_modulus=1e6,
        shear_modulus=1e6 / 3,
        density=1000.0,
        gravity=(0.0, 0.0, -9.81),
    )


HORIZONTAL = (np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0)
"""Base orientation pointing the rod along +x (gravity bends it)."""


def euler_bernoulli(rod: Rod) -> np.ndarray:
    """First two bending frequencies of the clamped-free beam [Hz]."""
    scale = np.sqrt(rod.EI / (rod.density * rod.A * rod.length**4)) / (2 * np.pi)
    return np.array(BETA) ** 2 * scale


def pencil(y: np.ndarray, dt: float, order: int) -> np.ndarray:
    """Continuous-time exponents ``s = sigma + i omega`` of ``y`` (mean removed) by the matrix-pencil method."""
    y = np.asarray(y, dtype=float) - np.mean(y)
    n = y.size
    window = n // 3
    Y = np.array([y[i : i + window + 1] for i in range(n - window)])
    V = np.linalg.svd(Y, full_matrices=False)[2][:order].T
    z = np.linalg.eigvals(np.linalg.pinv(V[:-1]) @ V[1:])
    return np.log(z.astype(complex)) / dt


def mode(exponents: np.ndarray, frequency: float) -> complex:
    """The exponent whose frequency is nearest ``frequency`` [Hz]."""
    f = np.abs(exponents.imag) / (2 * np.pi)
    return complex(exponents[np.argmin(np.abs(f - frequency))])


def release(rod: Rod, n_points: int, dt: float, alpha: float, duration: float, viscosity: float = 0.0):
    """Tip trace (x) of the clamped rod released from rest under a tip force bending its tip by 1 mm."""
    arm = RodArm.single(rod)
    dyn = RodDynamics(
        arm,
        DynamicsOptions(dt=dt, alpha=alpha, steps_per_segment=n_points - 1),
        (Damping.kelvin_voigt(rod, viscosity),),
    )
    force = 3 * rod.EI * 1e-3 / rod.length**3
    start = dyn.rest(Loads(tip_force=(force, 0.0, 0.0), gravity=(0.0, 0.0, 0.0)))
    trajectory = dyn.simulate(start, np.zeros((int(round(duration / dt)), dyn.n_loads)), keep_shapes=False)
    assert trajectory.complete, trajectory.failure
    return trajectory


# --------------------------------------------------------------------------------------- rest and statics


def test_rest_is_the_static_shooting_equilibrium():
    rod = soft_rod()
    arm = RodArm.single(rod, base_orientation=HORIZONTAL)
    dyn = RodDynamics(arm, DynamicsOptions(dt=0.01, steps_per_segment=10))
    loads = Loads(tip_force=(0.0, 0.01, -0.02))
    start = dyn.rest(loads)
    statics = ShootingSolver(arm, ShootingOptions(steps_per_segment=10)).solve(loads)
    assert statics.ok
    # the same discrete equations on the same grid: equal to rounding
    np.testing.assert_allclose(start.positions, statics.positions, rtol=0, atol=1e-12)
    assert start.energy[0] == 0.0


def test_held_step_load_settles_to_the_static_equilibrium():
    """Release a horizontal soft rod from its weight-only equilibrium into a tip-force step, damped (zeta_1 = 1/2)."""
    rod = soft_rod()
    arm = RodArm.single(rod, base_orientation=HORIZONTAL)
    omega1 = BETA[0] ** 2 * np.sqrt(rod.EI / (rod.density * rod.A * rod.length**4))
    dyn = RodDynamics(
        arm,
        DynamicsOptions(dt=0.01, steps_per_segment=10),
        (Damping.kelvin_voigt(rod, rod.youngs_modulus / omega1),),
    )
    start = dyn.rest(Loads())
    loads = dyn.load_vector(Loads(tip_force=(0.0, 0.0, -0.02)))
    trajectory = dyn.simulate(start, np.tile(loads, (600, 1)))
    assert trajectory.complete
    statics = ShootingSolver(arm, ShootingOptions(steps_per_segment=10)).solve(loads)
    error = np.abs(trajectory.positions - statics.positions[None]).max(axis=(1, 2))
    assert error[0] > 1e-3  # it moved
    assert error[-1] < 1e-8  # 6 s later: 1.7e-12 m when written
    assert abs(trajectory.energy[-1, 0]) < 1e-12  # at rest


def test_tendon_step_settles_to_the_static_equilibrium():
    """A tendon tension step (0 -> 0.5 N) with a tip force, damped: the statics' tendon model to 1e-7 m."""
    rod = soft_rod()
    arm = RodArm.single(rod, base_orientation=HORIZONTAL, tendons=(Tendon(offset=0.008),))
    omega1 = BETA[0] ** 2 * np.sqrt(rod.EI / (rod.density * rod.A * rod.length**4))
    dyn = RodDynamics(
        arm,
        DynamicsOptions(dt=0.01, steps_per_segment=40),
        (Damping.kelvin_voigt(rod, rod.youngs_modulus / omega1),),
    )
    start = dyn.rest(Loads(actuation=(0.0,)))
    loads = dyn.load_vector(Loads(tip_force=(0.0, 0.0, -0.02), actuation=(0.5,)))
    trajectory = dyn.simulate(start, np.tile(loads, (600, 1)), keep_shapes=False)
    assert trajectory.complete
    statics = ShootingSolver(arm, ShootingOptions(steps_per_segment=40)).solve(loads)
    moved = np.linalg.norm(trajectory.tip[-1] - start.tip_position)
    assert moved > 0.01
    # 4.4e-8 m when written: the rods' RK4 errors differ (the statics' own grid error here is 7.6e-8 m)
    assert np.abs(trajectory.final.positions - statics.positions).max() < 1e-7


# --------------------------------------------------------------------------------------- vibration


def test_first_bending_frequency_coarse():
    """20 points, dt = 1 ms, alpha = -0.45, 0.4 s: the first frequency within 1 % of Euler-Bernoulli."""
    rod = steel_rod()
    dt = 1e-3
    trajectory = release(rod, 20, dt, -0.45, 0.4)
    f_eb = euler_bernoulli(rod)
    s1 = mode(pencil(trajectory.tip[::2, 0], 2 * dt, 8), f_eb[0])
    assert abs(abs(s1.imag) / (2 * np.pi) / f_eb[0] - 1) < 0.01


@pytest.mark.slow
def test_first_two_bending_frequencies():
    """40 points, dt = 0.5 ms, alpha = -0.4, 0.5 s: both frequencies within 1 % (-1e-4 and -3e-3 when written)."""
    rod = steel_rod()
    dt = 5e-4
    trajectory = release(rod, 40, dt, -0.4, 0.5)
    f_eb = euler_bernoulli(rod)
    exponents = pencil(trajectory.tip[::2, 0], 2 * dt, 8)
    for f in f_eb:
        assert abs(abs(mode(exponents, f).imag) / (2 * np.pi) / f - 1) < 0.01


def test_kelvin_voigt_decay_rate():
    """A viscosity giving sigma_1 = 2 / s: the first mode's decay rate eta omega_1^2 / (2 E) within 2 %."""
    rod = steel_rod()
    dt = 1e-3
    omega_eb = 2 * np.pi * euler_bernoulli(rod)[0]
    viscosity = 2 * 2.0 * rod.youngs_modulus / omega_eb**2
    trajectory = release(rod, 20, dt, -0.45, 0.4, viscosity)
    s1 = mode(pencil(trajectory.tip[::2, 0], 2 * dt, 8), omega_eb / (2 * np.pi))
    omega = np.hypot(s1.real, s1.imag)  # the undamped frequency of the measured mode
    expected = viscosity * omega**2 / (2 * rod.youngs_modulus)
    assert abs(-s1.real / expected - 1) < 0.02


def test_energy_drift_without_damping():
    """1,000 steps, no damping, alpha = -0.48: the energy falls by 2.2 % (numerical damping), never rises."""
    rod = steel_rod()
    trajectory = release(rod, 20, 2e-3, -0.48, 2.0)
    energy = trajectory.energy.sum(axis=1)
    assert trajectory.t.size == 1001
    drift = (energy[0] - energy[-1]) / energy[0]
    assert 0 <= drift < 0.03
    assert energy.max() <= energy[0] * (1 + 1e-6)


# --------------------------------------------------------------------------------------- derivatives


def test_step_derivatives_match_finite_differences():
    rod = soft_rod()
    arm = RodArm.single(rod, base_orientation=HORIZONTAL)
    dyn = RodDynamics(arm, DynamicsOptions(dt=0.01, steps_per_segment=6, tolerance=1e-12))
    state = dyn.step(dyn.rest(Loads()), dyn.load_vector(Loads(tip_force=(0.0, 0.0, -0.01))))
    P = dyn.load_vector(Loads(tip_force=(0.0, 0.0, -0.01)))
    d = dyn.derivatives(state, P)
    h = 1e-6
    for j in (1, 2):  # tip force y and z
        dP = np.zeros_like(P)
        dP[j] = h
        plus, minus = dyn.step(state, P + dP), dyn.step(state, P - dP)
        fd_tip = (plus.tip_position - minus.tip_position) / (2 * h)
        np.testing.assert_allclose(d.tip_wrt_loads[:, j], fd_tip, rtol=1e-5, atol=1e-9)
        fd_state = (plus.vector - minus.vector) / (2 * h)
        np.testing.assert_allclose(d.wrt_loads[:, j], fd_state, rtol=1e-4, atol=1e-6 * np.abs(fd_state).max())
    # along a perturbation of the state: the history (velocities) of every stage
    rng = np.random.default_rng(0)
    direction = np.zeros_like(state.vector)
    direction[: state.history.size] = rng.standard_normal(state.history.size) * 1e-3
    shape = state.history.shape

    def shifted(e: float) -> np.ndarray:
        history = (state.vector + e * direction)[: state.history.size].reshape(shape, order="F")
        return dyn.step(replace(state, history=history), P).tip_position

    fd = (shifted(h) - shifted(-h)) / (2 * h)
    np.testing.assert_allclose(d.tip_wrt_state @ direction, fd, rtol=1e-4, atol=1e-10)


# --------------------------------------------------------------------------------------- bad input


def test_bad_input_names_the_field():
    rod = soft_rod()
    arm = RodArm.single(rod)
    with pytest.raises(ValidationError, match="B_bt"):
        Damping(B_bt=(-1.0, 0.0, 0.0))
    with pytest.raises(ValidationError, match="alpha"):
        DynamicsOptions(dt=0.01, alpha=-0.7)
    with pytest.raises(InputDataError, match="dt: .* first bending period"):
        RodDynamics(arm, DynamicsOptions(dt=0.5, steps_per_segment=4, compiled=False))
    with pytest.raises(InputDataError, match="dt: .* too short for shooting"):
        RodDynamics(arm, DynamicsOptions(dt=1e-7, steps_per_segment=4, compiled=False))
    massless = RodArm.single(rod.model_copy(update={"density": 0.0}))
    with pytest.raises(InputDataError, match="segments.0.rod.density"):
        RodDynamics(massless, DynamicsOptions(dt=0.01, steps_per_segment=4, compiled=False))
    kirchhoff = RodArm.single(rod.model_copy(update={"model": "kirchhoff"}))
    with pytest.raises(InputDataError, match="segments.0.rod.model"):
        RodDynamics(kirchhoff, DynamicsOptions(dt=0.01, steps_per_segment=4, compiled=False))
    with pytest.raises(InputDataError, match="damping"):
        RodDynamics(arm, DynamicsOptions(dt=0.01, steps_per_segment=4, compiled=False), (Damping(), Damping()))


def test_a_step_that_does_not_converge_stops_the_trajectory():
    rod = soft_rod()
    arm = RodArm.single(rod, base_orientation=HORIZONTAL)
    start = RodDynamics(arm, DynamicsOptions(dt=0.01, steps_per_segment=6)).rest(Loads())
    dyn = RodDynamics(arm, DynamicsOptions(dt=0.01, steps_per_segment=6, max_iterations=1, tolerance=1e-14))
    loads = np.tile(dyn.load_vector(Loads(tip_force=(0.0, 0.0, -0.5))), (5, 1))
    trajectory = dyn.simulate(start, loads)
    assert not trajectory.complete
    assert trajectory.failure.step == 1 and trajectory.t.size == 1
    assert "time step 1 (t = 0.01 s)" in str(trajectory.failure)
    assert trajectory.failure.residual > 1e-14


@pytest.mark.slow
def test_linearised_bdf2_step_does_not_amplify():
    """The soft rod at 7 points, dt = 2 ms: BDF2's step map has spectral radius 1 (the rigid modes), alpha = -0.4's
    a growing mode (1.69 when written): the reason BDF2 is the default (docs/guide/dynamics.md)."""
    rod = soft_rod().model_copy(update={"gravity": (0.0, 0.0, 0.0)})
    radii = {}
    for alpha in (0.0, -0.4):
        dyn = RodDynamics(
            RodArm.single(rod), DynamicsOptions(dt=0.002, alpha=alpha, steps_per_segment=6, compiled=False)
        )
        loads = Loads(tip_force=(0.005, 0.0, 0.0))
        d = dyn.derivatives(dyn.rest(loads), loads, wrt_state=True)
        radii[alpha] = float(np.abs(np.linalg.eigvals(d.wrt_state)).max())
    assert radii[0.0] < 1 + 1e-6
    assert radii[-0.4] > 1.1


def test_tip_mass_lowers_the_first_frequency_to_the_closed_form():
    """A payload of the rod's own mass at the tip: the first root of
    ``1 + cos b cosh b + mu b (cos b sinh b - sin b cosh b) = 0`` (Euler-Bernoulli, mu = 1: b = 1.2479),
    within 1 % (-2e-4 when written, 20 points, dt = 2 ms)."""
    from scipy.optimize import brentq

    rod = steel_rod()
    mass = rod.density * rod.A * rod.length
    dt = 2e-3
    dyn = RodDynamics(RodArm.single(rod), DynamicsOptions(dt=dt, alpha=-0.45, steps_per_segment=19, tip_mass=mass))
    force = 3 * rod.EI * 1e-3 / rod.length**3
    start = dyn.rest(Loads(tip_force=(force, 0.0, 0.0)))
    trajectory = dyn.simulate(start, np.zeros((500, dyn.n_loads)), keep_shapes=False)
    assert trajectory.complete

    def characteristic(b: float) -> float:
        return 1 + np.cos(b) * np.cosh(b) + (np.cos(b) * np.sinh(b) - np.sin(b) * np.cosh(b)) * b

    beta = brentq(characteristic, 0.5, BETA[0])
    expected = beta**2 * np.sqrt(rod.EI / (rod.density * rod.A * rod.length**4)) / (2 * np.pi)
    s1 = mode(pencil(trajectory.tip[::2, 0], 2 * dt, 6), expected)
    assert abs(abs(s1.imag) / (2 * np.pi) / expected - 1) < 0.01
    # the payload's kinetic energy is counted: the total is conserved to the scheme's dissipation
    energy = trajectory.energy.sum(axis=1)
    assert energy.max() <= energy[0] * (1 + 1e-6) and energy[-1] > 0.9 * energy[0]
