"""Energies of PH quintics and the minimum-energy choice (`optikin.curves.energy`, `optikin.curves.min_energy`).

Independent references: adaptive quadrature (``scipy.integrate.quad``) of
``kappa^2 sigma`` built from the generic curvature formula; the closed-form
energy ``theta^2 / L`` and geometry of circular arcs; straight segments (energy 0);
a dense grid over the free parameters; IPOPT against the Newton fast path.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from optikin.curves import ph_quintic_hermite
from optikin.curves.energy import DEFAULT_NODES, bending_energy, twist_energy
from optikin.curves import EnergySettings, ShapeData, ShapeEnergyModel
from optikin.algebra import wrap_periodic
from optikin.errors import InputDataError
from optikin.solvers import preset_of
from optikin.spec import SolverSpec

LENGTH = 0.36  # two 18 cm sections, the default constant-curvature arm


def arc_data(theta: float, azimuth: float = 0.3, length: float = LENGTH, **kw) -> ShapeData:
    """End poses of a circular arc leaving the origin along +z, bending by ``theta`` towards ``azimuth``."""
    kappa = theta / length
    u = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    p1 = (1 - np.cos(theta)) / kappa * u + np.sin(theta) / kappa * np.array([0, 0, 1.0])
    t1 = np.sin(theta) * u + np.cos(theta) * np.array([0, 0, 1.0])
    return ShapeData.checked(np.zeros(3), [0, 0, 1], p1, t1, length=length, **kw)


def distance_to_arc(points: np.ndarray, theta: float, azimuth: float = 0.3, length: float = LENGTH) -> np.ndarray:
    """Distance of points to the circle carrying the arc of :func:`arc_data`."""
    radius = length / theta
    u = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    normal = np.cross([0, 0, 1.0], u)
    rel = points - radius * u
    in_plane = rel - np.outer(rel @ normal, normal)
    return np.hypot(np.linalg.norm(in_plane, axis=1) - radius, rel @ normal)


def cc_two_section_data(q: np.ndarray, section: float = 0.18) -> ShapeData:
    """Tip pose of two constant-curvature sections, R = Rz(phi) Ry(theta) Rz(-phi) (seed 000 convention)."""
    R, p = np.eye(3), np.zeros(3)
    for theta, phi in q.reshape(2, 2):
        c, s = np.cos(phi), np.sin(phi)
        Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        Ry = np.array([[np.cos(theta), 0, np.sin(theta)], [0, 1, 0], [-np.sin(theta), 0, np.cos(theta)]])
        bend = (1 - np.cos(theta)) / theta
        local = section * np.array([bend * c, bend * s, np.sin(theta) / theta])
        p = p + R @ local
        R = R @ Rz @ Ry @ Rz.T
    return ShapeData.checked(np.zeros(3), [0, 0, 1], p, R[:, 2], length=2 * section)


def random_backbones(n: int, seed: int = 5) -> list[ShapeData]:
    rng = np.random.default_rng(seed)
    q = np.column_stack(
        [
            rng.uniform(0.2, 2.0, n),
            rng.uniform(-np.pi, np.pi, n),
            rng.uniform(0.2, 2.0, n),
            rng.uniform(-np.pi, np.pi, n),
        ]
    )
    return [cc_two_section_data(qi) for qi in q]


def newton_adapter(**options):
    """The ``ph_newton`` backend (warm-started along the samples) with Newton's own defaults."""
    spec = SolverSpec(
        name="newton-test", backend="ph_newton", options=options, limits={"tolerance": 1e-10, "max_iterations": 50}
    )
    return preset_of(spec).build()


@pytest.fixture(scope="module")
def model():
    return ShapeEnergyModel()


@pytest.fixture(scope="module")
def free_model():
    return ShapeEnergyModel(free_speeds=True)


# -- energy and its quadrature -----------------------------------------------------


def test_bending_energy_equals_adaptive_quadrature_of_generic_curvature():
    rng = np.random.default_rng(3)
    for _ in range(5):
        p0, p1 = rng.normal(size=3), rng.normal(size=3)
        d0, d1 = rng.normal(size=3), rng.normal(size=3)
        curve = ph_quintic_hermite(p0, d0, p1, d1, *rng.uniform(-0.5, 0.5, 2))
        reference = quad(
            lambda t: curve.curvature(t) ** 2 * curve.parametric_speed(t), 0, 1, epsabs=0, epsrel=1e-12, limit=500
        )[0]
        assert abs(bending_energy(curve, 48) - reference) <= 1e-9 * reference


@pytest.mark.parametrize("theta", [0.05, 1.0, 2.0, np.pi, 4.2])
def test_default_quadrature_is_converged_on_minimum_energy_shapes(model, theta):
    """DEFAULT_NODES reproduces adaptive quadrature to 1e-10 on the optimum, for bends up to 240 degrees."""
    data = arc_data(theta)
    curve = model.curve(model.solve_nlp(data), data)
    reference = quad(
        lambda t: curve.curvature(t) ** 2 * curve.parametric_speed(t), 0, 1, epsabs=0, epsrel=1e-13, limit=500
    )[0]
    errors = {n: abs(bending_energy(curve, n) - reference) / reference for n in (4, 8, DEFAULT_NODES)}
    assert errors[DEFAULT_NODES] < 1e-10
    assert errors[DEFAULT_NODES] <= max(errors[8], 1e-15) and errors[8] <= max(errors[4], 1e-15)


def test_planar_optimum_of_planar_data_has_no_twist_energy(model):
    data = arc_data(1.0, azimuth=0.0)  # the x-z plane
    sol = model.solve_nlp(data)
    curve = model.curve(sol, data)
    assert np.max(np.abs(curve.point(np.linspace(0, 1, 11))[:, 1])) < 1e-12
    assert twist_energy(curve) < 1e-12 * sol.energy


# -- known minima ------------------------------------------------------------------


def test_straight_segment_has_zero_energy_and_stays_straight(model):
    direction = np.array([0.2, -0.3, 0.9]) / np.linalg.norm([0.2, -0.3, 0.9])
    data = ShapeData.checked(
        [0.1, 0.0, 0.0], direction, np.array([0.1, 0.0, 0.0]) + 0.3 * direction, direction, speeds=(0.36, 0.3)
    )
    sol = model.solve_nlp(data)
    assert sol.energy < 1e-12
    points = model.curve(sol, data).point(np.linspace(0, 1, 21)) - data.p0
    off_line = points - np.outer(points @ direction, direction)
    assert np.max(np.linalg.norm(off_line, axis=1)) < 1e-7


@pytest.mark.parametrize("theta", [0.3, 1.0, 2.0])
def test_minimum_energy_curve_is_close_to_the_circular_arc(model, free_model, theta):
    """End poses of an arc: the optimum is within 0.6% (given speeds) / 0.3% (free speeds, length held) of L.

    Measured (L = 0.36 m): max distance 0.006 / 0.21 / 1.8 mm with given speeds L,
    0.0004 / 0.05 / 0.8 mm with free speeds, for theta = 0.3 / 1 / 2 rad.
    """
    data = arc_data(theta)
    t = np.linspace(0, 1, 201)
    for m, bound in ((model, 6e-3), (free_model, 3e-3)):
        sol = m.solve_nlp(data)
        distance = distance_to_arc(m.curve(sol, data).point(t), theta)
        assert np.max(distance) < bound * LENGTH
        assert sol.energy == pytest.approx(theta**2 / LENGTH, rel=2e-2)
    assert free_model.solve_nlp(data).arc_length == pytest.approx(LENGTH, rel=1e-10)


# -- NLP, fast path and grid -----------------------------------------------------


def test_nlp_is_never_worse_than_the_grid_and_newton_agrees(model):
    cases = [arc_data(1.2), arc_data(np.pi, azimuth=-2.0)] + random_backbones(4)
    for data in cases:
        nlp, grid, newton = model.solve_nlp(data), model.solve_grid(data, n=48), model.solve_newton(data)
        assert nlp.status == "ok" and newton.status == "ok"
        assert nlp.energy <= grid.energy + 1e-12 * grid.energy
        assert newton.energy == pytest.approx(nlp.energy, rel=1e-10)
        np.testing.assert_allclose(wrap_periodic(newton.angles - nlp.angles), 0.0, atol=1e-6)
        assert nlp.quadrature_error < 1e-9 * nlp.energy


def test_free_speeds_with_length_held(free_model):
    for data in [arc_data(1.5)] + random_backbones(2, seed=8):
        nlp, newton = free_model.solve_nlp(data), free_model.solve_newton(data)
        grid = free_model.solve_grid(data, n=20, n_ratio=5)
        assert nlp.arc_length == pytest.approx(data.length, rel=1e-10)
        assert newton.arc_length == pytest.approx(data.length, rel=1e-10)
        assert grid.arc_length == pytest.approx(data.length, rel=1e-9)
        assert nlp.energy <= grid.energy + 1e-12 * grid.energy
        assert newton.energy == pytest.approx(nlp.energy, rel=1e-9)
        np.testing.assert_allclose(newton.x[2:], nlp.x[2:], rtol=1e-6)


def test_warm_started_trajectory_follows_the_reference(model):
    thetas = np.linspace(0.2, 2.5, 12)
    samples = [arc_data(th, azimuth=0.3 + 0.2 * k) for k, th in enumerate(thetas)]
    fast = newton_adapter().solve(model, samples)
    for data, sol in zip(samples, fast):
        reference = model.solve_nlp(data)
        assert sol.status == "ok" and not sol.notes
        assert sol.energy == pytest.approx(reference.energy, rel=1e-10)
        assert sol.iterations <= 6


def test_basin_check_leaves_the_worse_branch_a_warm_start_follows(free_model):
    """Free speeds along the first 12 postures of ``cbha-ph-shape``: warm-started, Newton stays on a
    worse minimum (measured over the 100 postures: 19 samples up to 4.1 above a cold three-start
    IPOPT); with the basin check every sample's energy is at most the warm one's, and here matches
    IPOPT's to 1e-3 (over 100 postures: 3 samples off, by at most 1e-3)."""
    from optikin.problems.ph_shared import backbone_lengths, end_data, recording_of

    recording = recording_of("cbha-ph-shape").with_fixed_base().take(slice(0, 12))
    samples = end_data(recording, backbone_lengths(recording, "model", "test"), "test")
    warm = newton_adapter().solve(free_model, samples)
    checked = newton_adapter(basin_check=True).solve(free_model, samples)
    reference = np.array([free_model.solve_nlp(d, starts=3).energy for d in samples])
    warm_energy, checked_energy = (np.array([s.energy for s in sols]) for sols in (warm, checked))
    assert all(s.status == "ok" for s in warm + checked)
    assert np.any(warm_energy > reference + 1e-3)  # the trap this option is for
    assert np.all(checked_energy <= warm_energy * (1 + 1e-9))
    np.testing.assert_allclose(checked_energy, reference, rtol=0, atol=1e-3)
    assert all(s.arc_length == pytest.approx(d.length, rel=1e-9) for s, d in zip(checked, samples))


def test_twist_weight_lowers_the_twist_of_the_optimum():
    data = random_backbones(1, seed=21)[0]
    plain, twisting = ShapeEnergyModel(), ShapeEnergyModel(EnergySettings(twist_weight=0.5))
    bending_only, weighted = plain.solve_nlp(data), twisting.solve_nlp(data)
    twist = [twist_energy(m.curve(s, data)) for m, s in ((plain, bending_only), (twisting, weighted))]
    assert twist[1] <= twist[0]
    assert bending_energy(twisting.curve(weighted, data)) >= bending_only.energy * (1 - 1e-12)


# -- bad input ---------------------------------------------------------------------


def test_bad_shape_data_is_rejected(model, free_model):
    with pytest.raises(InputDataError, match="t1"):
        ShapeData.checked(np.zeros(3), [0, 0, 1], [0, 0, 0.3], [0, 0, 0], length=0.36, source="poses.csv", sample=3)
    with pytest.raises(InputDataError, match="sample 3: length"):
        ShapeData.checked(np.zeros(3), [0, 0, 1], [0, 0, 0.5], [0, 0, 1], length=0.36, source="poses.csv", sample=3)
    with pytest.raises(InputDataError, match="speeds"):
        ShapeData.checked(np.zeros(3), [0, 0, 1], [0, 0, 0.3], [0, 0, 1], speeds=(0.3, -1.0))
    no_length = ShapeData.checked(np.zeros(3), [0, 0, 1], [0, 0.1, 0.3], [0, 0, 1], speeds=(0.3, 0.3))
    with pytest.raises(InputDataError, match="length"):
        free_model.solve_nlp(no_length)
    with pytest.raises(InputDataError, match="speeds"):
        model.solve_newton(ShapeData.checked(np.zeros(3), [0, 0, 1], [0, 0.1, 0.3], [0, 0, 1]))
