"""Static Cosserat-rod model (optikin.physics): each check against a closed form or finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from optikin.errors import InputDataError
from optikin.physics import (
    Chamber,
    CollocationSolver,
    Loads,
    Rod,
    RodArm,
    Segment,
    ShootingOptions,
    ShootingSolver,
    Tendon,
    cbha_chambers,
)

NO_GRAVITY = (0.0, 0.0, 0.0)


def rod(**kw) -> Rod:
    """The 0.3 m, r = 10 mm, E = 1 MPa rod of the PyElastica cases."""
    base = dict(length=0.3, radius=0.01, youngs_modulus=1e6, shear_modulus=1e6 / 3, density=1000.0)
    return Rod(**{**base, **kw})


def arc(s: np.ndarray, radius: float, scale: float = 1.0) -> np.ndarray:
    """Circular arc in the x-z plane from the origin along +z, bending towards +x for radius > 0.

    ``scale`` is the stretch ``v3``: the arc of reference length ``s`` has spatial length ``scale * s``.
    """
    angle = s / radius
    return scale * np.stack([radius * (1 - np.cos(angle)), 0 * s, radius * np.sin(angle)], axis=1)


# --------------------------------------------------------------------------- parameters


@pytest.mark.parametrize(
    "field, value",
    [
        ("youngs_modulus", 0.0),
        ("youngs_modulus", -1.0),
        ("radius", 0.0),
        ("length", -0.3),
        ("density", -1.0),
        ("shear_modulus", 0.0),
    ],
)
def test_bad_physics_is_an_error_naming_the_field(field, value):
    with pytest.raises(ValidationError, match=field):
        rod(**{field: value})


def test_shear_modulus_is_required_or_from_poisson():
    with pytest.raises(ValidationError, match="shear_modulus"):
        Rod(length=0.3, radius=0.01, youngs_modulus=1e6)
    assert Rod(length=0.3, radius=0.01, youngs_modulus=1e6, poisson_ratio=0.3).G == pytest.approx(1e6 / 2.6)


def test_section_given_by_area_and_moments():
    r = Rod(
        length=0.3,
        area=2e-4,
        second_moment=3e-9,
        polar_moment=5e-9,
        outer_radius=0.01,
        youngs_modulus=1e6,
        poisson_ratio=0.5,
    )
    assert r.K_bt == pytest.approx([3e-3, 3e-3, 5e-9 * 1e6 / 3]) and r.K_se[2] == pytest.approx(200.0)
    with pytest.raises(ValidationError, match="radius"):
        Rod(length=0.3, area=2e-4, youngs_modulus=1e6, poisson_ratio=0.5)


def test_actuators_outside_the_section_and_negative_tension_are_errors_naming_the_field():
    with pytest.raises(ValidationError, match=r"segments\.0\.tendons\.0\.offset"):
        RodArm.single(rod(), tendons=(Tendon(offset=0.01),))
    with pytest.raises(ValidationError, match=r"chambers\.1\.offset"):
        Segment(rod=rod(), chambers=(Chamber(offset=0.002, area=1e-6), Chamber(offset=0.02, area=1e-6)))
    thin = rod(radius=0.004)
    with pytest.raises(ValidationError, match=r"segments\.1\.tendons\.0\.offset"):  # passes through segment 0
        RodArm(segments=(Segment(rod=thin), Segment(rod=rod(), tendons=(Tendon(offset=0.006),))))
    arm = RodArm.single(rod(), tendons=(Tendon(offset=0.005),))
    with pytest.raises(InputDataError, match="segments.0.tendons.0: tension"):
        ShootingSolver(arm).solve(Loads(actuation=(-1.0,)))


# --------------------------------------------------------------------------- closed forms


def test_follower_end_couple_bends_an_inextensible_rod_into_a_circle():
    r = rod(model="kirchhoff", density=0.0)
    M = r.EI * 1.0 / r.length  # a bend of 1 rad
    solver = ShootingSolver(RodArm.single(r, tip_couple_frame="follower"))
    sol = solver.solve(Loads(tip_couple=(0.0, M, 0.0)))
    radius = r.EI / M
    assert sol.ok
    assert np.abs(sol.positions - arc(sol.s, radius)).max() / radius < 1e-9
    # the same couple about y in the tip frame is +y in space too: n = 0, m = M e_y everywhere
    assert np.abs(sol.n).max() < 1e-12 and np.allclose(sol.m, [0, M, 0], atol=1e-12)


@pytest.mark.parametrize("model", ["kirchhoff", "cosserat"])
def test_small_tip_force_matches_linear_beam_theory(model):
    # Euler-Bernoulli: P L^3 / (3 E I); the shear-deformable rod adds Timoshenko's P L / (G A).
    # Bound: the geometric nonlinearity is O((w/L)^2); at w/L = 1e-3 the relative error must stay below 1e-5.
    r = rod(model=model, density=0.0)
    L = r.length
    P = 1e-3 * 3 * r.EI / L**2
    sol = ShootingSolver(RodArm.single(r)).solve(Loads(tip_force=(P, 0, 0)))
    expected = P * L**3 / (3 * r.EI) + (P * L / (r.G * r.A) if model == "cosserat" else 0.0)
    assert sol.ok and abs(sol.tip_position[0] / expected - 1) < 1e-5


@pytest.mark.parametrize("model", ["kirchhoff", "cosserat"])
def test_clamped_rod_under_gravity_matches_linear_beam_theory(model):
    # w L^4 / (8 E I) (+ w L^2 / (2 G A) for the shear-deformable rod), same bound as above
    r = rod(model=model, gravity=(-9.81, 0.0, 0.0))
    L, w = r.length, 1e-3 * 8 * r.EI / r.length**3
    r = r.model_copy(update={"density": w / (r.A * 9.81)})
    sol = ShootingSolver(RodArm.single(r)).solve(Loads())
    expected = w * L**4 / (8 * r.EI) + (w * L**2 / (2 * r.G * r.A) if model == "cosserat" else 0.0)
    assert sol.ok and abs(-sol.tip_position[0] / expected - 1) < 1e-5


@pytest.mark.parametrize("model", ["kirchhoff", "cosserat"])
def test_straight_tendon_bends_with_constant_curvature(model):
    # Tendon loads as external loads (Rucker & Webster 2011): the tendon's distributed force tau t' plus its point
    # load at the termination leave the rod with the axial compression tau along its tangent and the moment tau r,
    # so kappa = tau r / (E I) per unit reference length (not tau r / (E I + tau r^2): that r^2 term would need the
    # compression to act off the tangent). A Cosserat rod also shortens: v3 = 1 - tau / (E A).
    r = rod(model=model, density=0.0)
    tau, offset = 0.5, 0.008
    arm = RodArm.single(r, tendons=(Tendon(offset=offset),))
    sol = ShootingSolver(arm).solve(Loads(actuation=(tau,)))
    kappa = tau * offset / r.EI
    v3 = 1.0 if model == "kirchhoff" else 1 - tau / r.K_se[2]
    assert sol.ok
    assert np.abs(sol.positions - arc(sol.s, 1 / kappa, v3)).max() < 1e-9 * r.length
    assert np.allclose(sol.base_wrench, [0, 0, -tau, 0, tau * offset, 0], atol=1e-12)


@pytest.mark.parametrize("model", ["kirchhoff", "cosserat"])
def test_helical_tendon_matches_its_straight_limit_and_twists(model):
    r = rod(model=model, density=0.0)
    straight = ShootingSolver(RodArm.single(r, tendons=(Tendon(offset=0.008),))).solve(Loads(actuation=(0.5,)))
    barely = ShootingSolver(RodArm.single(r, tendons=(Tendon(offset=0.008, helix_rate=1e-6),)))
    assert np.abs(barely.solve(Loads(actuation=(0.5,))).positions - straight.positions).max() < 1e-8
    helix = ShootingSolver(RodArm.single(r, tendons=(Tendon(offset=0.008, helix_rate=2 * np.pi / 0.3),)))
    sol = helix.solve(Loads(actuation=(0.5,)))
    assert sol.ok and abs(sol.tip_position[1]) > 1e-3  # one turn of the routing: the tip leaves the x-z plane


def test_three_equal_chambers_give_pure_extension():
    r = rod(density=0.0)
    pressure, area = 5e3, 2e-5
    arm = RodArm.single(r, chambers=cbha_chambers(0.005, area))
    sol = ShootingSolver(arm).solve(Loads(actuation=(pressure,) * 3))
    stretch = 1 + 3 * pressure * area / r.K_se[2]
    assert sol.ok
    assert np.abs(sol.positions[:, :2]).max() < 1e-12
    assert np.allclose(sol.positions[:, 2], stretch * sol.s, rtol=0, atol=1e-12)


@pytest.mark.parametrize("model", ["kirchhoff", "cosserat"])
def test_one_chamber_bends_away_with_curvature_p_a_r_over_ei(model):
    # P a at offset r along d3: moment P a r, curvature P a r / (E I) away from the chamber; stretch 1 + P a / (E A)
    r = rod(model=model, density=0.0)
    pressure, area, offset = 5e3, 2e-5, 0.005
    arm = RodArm.single(r, chambers=(Chamber(offset=offset, area=area),))
    sol = ShootingSolver(arm).solve(Loads(actuation=(pressure,)))
    kappa = pressure * area * offset / r.EI
    v3 = 1.0 if model == "kirchhoff" else 1 + pressure * area / r.K_se[2]
    assert sol.ok
    assert np.abs(sol.positions - arc(sol.s, -1 / kappa, v3)).max() < 1e-9 * r.length


def test_two_segments_each_with_its_own_tendon():
    # Segment 1's tendon ends at the disk: the distal segment carries only its own tendon's moment tau2 r;
    # the proximal carries both (same side): curvatures (tau1 + tau2) r / EI and tau2 r / EI.
    r = rod(model="kirchhoff", density=0.0, length=0.15)
    tendon = Tendon(offset=0.006)
    arm = RodArm(segments=(Segment(rod=r, tendons=(tendon,)), Segment(rod=r, tendons=(tendon,))))
    tau1, tau2 = 0.3, 0.2
    sol = ShootingSolver(arm, ShootingOptions(steps_per_segment=60)).solve(Loads(actuation=(tau1, tau2)))
    k1, k2 = (tau1 + tau2) * 0.006 / r.EI, tau2 * 0.006 / r.EI
    first = sol.s <= 0.15 + 1e-12
    assert sol.ok and np.abs(sol.positions[first] - arc(sol.s[first], 1 / k1)).max() < 1e-10
    # the distal segment: an arc of curvature k2 continuing from the disk's pose
    a = k1 * 0.15
    t = sol.s[~first] - 0.15
    local = np.stack([(1 - np.cos(k2 * t)) / k2, np.sin(k2 * t) / k2], axis=1)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])  # rows: the disk frame's normal, tangent
    expected = sol.positions[first][-1][[0, 2]] + local @ rot
    assert np.abs(sol.positions[~first][:, [0, 2]] - expected).max() < 1e-10


# --------------------------------------------------------------------------- solvers


def test_shooting_and_collocation_agree():
    r = rod()
    arm = RodArm.single(r, tip_couple_frame="follower")
    loads = Loads(tip_force=(0.02, 0.01, 0.0), tip_couple=(0.0, 0.001, 0.0005))
    shot = ShootingSolver(arm, ShootingOptions(steps_per_segment=100)).solve(loads)
    colloc = CollocationSolver(arm).solve(loads)  # 25 intervals of 3 Gauss-Legendre points
    assert shot.ok and colloc.ok
    assert np.abs(shot.positions[::4] - colloc.positions).max() < 1e-8
    assert np.abs(np.linalg.norm(colloc.orientations, axis=1) - 1).max() < 1e-10


def test_load_derivatives_match_central_differences():
    r = rod()
    arm = RodArm.single(r, tendons=(Tendon(offset=0.006, angle=0.4),))
    solver = ShootingSolver(arm, ShootingOptions(steps_per_segment=40, tolerance=1e-13))
    P = solver.load_vector(Loads(tip_force=(0.01, -0.02, 0.0), tip_couple=(0.0, 0.0, 0.001), actuation=(0.3,)))
    sens = solver.jacobian_wrt_loads(P)
    base = sens.solution.base_wrench
    for j in range(len(P)):
        h = 1e-6 * max(1.0, abs(P[j]))
        plus, minus = P.copy(), P.copy()
        plus[j] += h
        minus[j] -= h
        a, b = solver.solve(plus, base), solver.solve(minus, base)
        fd = (a.positions - b.positions) / (2 * h)
        scale = max(1.0, np.abs(sens.positions[:, :, j]).max())
        assert np.abs(fd - sens.positions[:, :, j]).max() < 1e-6 * scale, sens.names[j]


def test_compiled_newton_matches_the_vm_rootfinder():
    r = rod()
    arm = RodArm.single(r)
    loads = [Loads(tip_force=(0.02 * t, 0.0, -0.01), tip_couple=(0.0, 0.001 * t, 0.0)) for t in np.linspace(0, 1, 5)]
    vm = ShootingSolver(arm, ShootingOptions(steps_per_segment=50)).solve_sequence(loads)
    try:
        compiled = ShootingSolver(arm, ShootingOptions(steps_per_segment=50, compiled=True)).solve_sequence(loads)
    except Exception as exc:  # no C compiler
        pytest.skip(str(exc))
    for a, b in zip(vm, compiled):
        assert a.ok and b.ok and np.abs(a.positions - b.positions).max() < 1e-10


def test_unreachable_equilibrium_is_reported_as_failed():
    r = rod(density=0.0)
    solver = ShootingSolver(RodArm.single(r), ShootingOptions(steps_per_segment=20, max_iterations=2, max_ramp_steps=1))
    sol = solver.solve(Loads(tip_force=(5.0, 0.0, -5.0)))
    assert sol.status == "failed" and sol.residual_norm > 1e-10 and "converge" in sol.message


def test_vm_newton_prints_no_nan_warnings(capfd):
    """A Newton trial step that integrates to NaN is rejected quietly (CasADi would print a warning per evaluation)."""
    solver = ShootingSolver(RodArm.single(rod(density=0.0)))
    solution = solver.solve(Loads(tip_force=(30.0, 0.0, 30.0), tip_couple=(0.0, 0.5, 0.3)))
    assert not solution.ok  # far beyond what the rod carries from a straight start: every trial diverges
    out, err = capfd.readouterr()
    assert "NaN detected" not in out + err


def test_weight_only_when_gravity_is_given_and_the_shear_coefficient():
    heavy = rod(density=1000.0, gravity=(-9.81, 0.0, 0.0))
    quiet = rod(density=1000.0)  # a density alone adds no weight
    assert quiet.gravity == NO_GRAVITY and np.all(quiet.weight_per_length == 0)
    straight = ShootingSolver(RodArm.single(quiet)).solve(Loads())
    bent = ShootingSolver(RodArm.single(heavy)).solve(Loads())
    assert straight.ok and np.abs(straight.tip_position - (0.0, 0.0, 0.3)).max() < 1e-12
    assert bent.ok and bent.tip_position[0] < -1e-3
    timoshenko = rod(shear_coefficient=27 / 28)
    np.testing.assert_allclose(timoshenko.K_se, [27 / 28 * quiet.G * quiet.A] * 2 + [quiet.youngs_modulus * quiet.A])
    with pytest.raises(ValueError, match="shear_coefficient"):
        rod(shear_coefficient=1.5)


def test_one_solver_serves_every_base_pose():
    """solve_at turns the global loads into the arm's frame and the shape back: the same equilibrium as a solver
    built for that base pose (gravity, a spatial tip force, a follower couple, tendon-free)."""
    from optikin.algebra import quat_from_matrix

    heavy = rod(density=1000.0, gravity=(0.0, 0.0, -9.81))
    loads = Loads(tip_force=(0.01, -0.02, 0.005), tip_couple=(0.0, 0.001, 0.0005))
    base = quat_from_matrix(np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]))  # clamped along -y
    base = base / np.linalg.norm(base)
    position = (0.1, 0.2, -0.3)
    mine = ShootingSolver(RodArm.single(heavy, tip_couple_frame="follower"))
    theirs = ShootingSolver(
        RodArm.single(heavy, tip_couple_frame="follower", base_position=position, base_orientation=tuple(base))
    )
    moved, direct = mine.solve_at(position, base, loads), theirs.solve(loads)
    assert moved.ok and direct.ok
    assert np.abs(moved.positions - direct.positions).max() < 1e-8  # measured 9e-10 m
    assert np.abs(np.abs(np.sum(moved.orientations * direct.orientations, axis=1)) - 1).max() < 1e-12
    np.testing.assert_allclose(moved.base_wrench, direct.base_wrench, atol=1e-8)
    # warm-started from the other's base wrench: converged at once
    again = mine.solve_at(position, base, loads, guess=direct.base_wrench)
    assert again.ok and again.iterations <= 2 < moved.iterations
    # the arm's own pose: solve_at is solve
    np.testing.assert_allclose(mine.solve_at((0, 0, 0), (1, 0, 0, 0), loads).positions, mine.solve(loads).positions)
