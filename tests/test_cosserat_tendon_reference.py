"""The tendon-driven Cosserat arm against tdcr-modeling's Cosserat rod model (tests/data/tdcr/).

tdcr-modeling is the reference implementation of Rao, Peyron, Lilge and Burgner-Kahrs, "How to model
tendon-driven continuum robots and benchmark modelling performance", Frontiers in Robotics and AI 7:630245,
2021. Its C++ ``CosseratRodModel`` (commit 379d34a, run by ``tools/tdcr_reference.py``) is an independent
implementation of the model of Rucker & Webster (IEEE T-RO 27(6), 2011): a shear-extensible rod with
``G = E / 2.6`` and ``J = 2 I``, straight tendons (three per segment, at 90, -30 and 210 degrees) running from the
base to the end of their segment, where they load the rod with a point force and moment; GSL's RKF45 and
Levenberg-Marquardt. The shipped files hold its frames at the 21 disks (base, 10 per segment) for six cases of
its default robot (2 x 0.1 m, E = 60 GPa, backbone radius 0.5 mm, tendons at 8 and 6 mm), with and without a
tip force and moment, and two of the robot of its ``main.cpp`` (2 x 0.2 m, 54 GPa, 0.7 mm, 10 mm).

optikin's arm is built with the same parameters (``model="cosserat"``, the same ``G`` and ``J``, no gravity) and
solved by shooting with 50 RK4 steps per segment, so every disk is a node. Tolerances, and why:

* positions within 1 um at every disk (5e-6 of the 0.2 m arm). The reference's own error is below 0.25 um: the
  shipped build with its published ODE error control (abs 1e-6, rel 1e-3) and a build with it tightened to
  1e-12 differ by at most 0.20 um, through the residual at which Levenberg-Marquardt stops (up to 4e-8 N); our
  RK4 grid changes the disks by less than 0.02 um between 50 and 100 steps. Measured: at most 0.015 um.
* 1 um resolves the model: the same arm as an inextensible, unshearable (Kirchhoff) rod is 6 to 19 um away.
* orientations within 1e-5 per matrix entry, the base wrench within 1e-6 N and 1e-7 N m (the reference's from
  its base strains through its stiffnesses).

The repository's MATLAB implementation of the same model (``matlab/Models/VC/VC_solver.m``: ode45 and fsolve, a
tip force but no tip moment), run in Octave 7.3 on the robot of its ``matlab/Parameters/tdcr_2segments.m``
(2 x 0.2 m, E = 54 GPa, nu = 0.3, backbone radius 0.7 mm, tendons at 10 mm, no gravity) for four cases, is a second
reference (``matlab_vc_*.json``). Its positions are at the points where ode45 stopped; ours are interpolated there
by a cubic spline through the nodes of each segment (against a 200-step solution the spline is off by at most
0.012 um between nodes, no more than at the nodes themselves: the RK4 grid's error). Same 1 um tolerance;
measured: at most 0.057 um (the case bent by 90 degrees, where ode45's tolerance of 1e-6 shows: with 1e-10 its tip
moves by 0.068 um, to within 0.012 um of ours).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from optikin.algebra import matrix_from_quat
from optikin.physics import Loads, Rod, RodArm, Segment, ShootingOptions, ShootingSolver, Tendon
from optikin.physics.solution import RodSolution

DATA = Path(__file__).resolve().parent / "data" / "tdcr"
CASES = sorted(p.stem for p in DATA.glob("*.json") if not p.stem.startswith("matlab_")) if DATA.is_dir() else []
MATLAB_CASES = sorted(p.stem for p in DATA.glob("matlab_vc_*.json")) if DATA.is_dir() else []
STEPS = 50
POSITION_TOLERANCE = 1e-6  # m
ROTATION_TOLERANCE = 1e-5
FORCE_TOLERANCE = 1e-6  # N
MOMENT_TOLERANCE = 1e-7  # N m


def reference(case: str) -> dict[str, Any]:
    return json.loads((DATA / f"{case}.json").read_text())


def our_solution(data: dict[str, Any], model: Literal["cosserat", "kirchhoff"] = "cosserat") -> RodSolution:
    """Our equilibrium of the case's robot and loads."""
    robot, derived = data["robot"], data["derived"]
    segments = []
    for k in range(2):
        rod = Rod(
            length=robot["length"][k],
            area=derived["area"],
            second_moment=derived["second_moment"],
            polar_moment=derived["torsion_constant"],
            outer_radius=2 * max(robot["pitch_radius"]),
            youngs_modulus=robot["youngs_modulus"],
            shear_modulus=derived["shear_modulus"],
            gravity=(0.0, 0.0, 0.0),
            model=model,
        )
        tendons = tuple(
            Tendon(offset=robot["pitch_radius"][k], angle=math.radians(a)) for a in derived["tendon_angles_deg"]
        )
        segments.append(Segment(rod=rod, tendons=tendons))
    solver = ShootingSolver(RodArm(segments=tuple(segments)), ShootingOptions(steps_per_segment=STEPS))
    loads = Loads(
        tip_force=tuple(data["tip_force"]), tip_couple=tuple(data["tip_moment"]), actuation=tuple(data["tensions"])
    )
    solution = solver.solve(loads)
    assert solution.ok, solution.message
    return solution


def at_disks(data: dict[str, Any], solution: RodSolution) -> np.ndarray:
    """Indices of the nodes at the reference's disks."""
    s_disk = np.asarray(data["disk_arc_length"])
    index = np.array([int(np.argmin(np.abs(solution.s - s))) for s in s_disk])
    np.testing.assert_allclose(solution.s[index], s_disk, atol=1e-12)
    return index


@pytest.mark.skipif(not CASES, reason="no tdcr-modeling reference shapes in tests/data/tdcr")
@pytest.mark.parametrize("case", CASES)
def test_shooting_matches_tdcr_modeling(case):
    data = reference(case)
    ref = data["published"]
    assert ref["success"]
    solution = our_solution(data)
    index = at_disks(data, solution)

    error = np.linalg.norm(solution.positions[index] - np.asarray(ref["positions"]), axis=1)
    assert error.max() < POSITION_TOLERANCE, f"max disk error {error.max() * 1e6:.3f} um"

    rotations = np.array([matrix_from_quat(q) for q in solution.orientations[index]])
    assert np.abs(rotations - np.asarray(ref["rotations"])).max() < ROTATION_TOLERANCE

    derived, robot = data["derived"], data["robot"]
    G, E, A = derived["shear_modulus"], robot["youngs_modulus"], derived["area"]
    EI, GJ = E * derived["second_moment"], G * derived["torsion_constant"]
    n0 = np.array([G * A, G * A, E * A]) * (np.asarray(ref["base_v"]) - [0.0, 0.0, 1.0])
    m0 = np.array([EI, EI, GJ]) * np.asarray(ref["base_u"])
    np.testing.assert_allclose(solution.base_wrench[:3], n0, rtol=0, atol=FORCE_TOLERANCE)
    np.testing.assert_allclose(solution.base_wrench[3:], m0, rtol=0, atol=MOMENT_TOLERANCE)


@pytest.mark.skipif(not CASES, reason="no tdcr-modeling reference shapes in tests/data/tdcr")
@pytest.mark.parametrize("case", CASES)
def test_reference_is_converged(case):
    """The shipped reference is solved (small residual) and insensitive to its ODE tolerance (< 0.25 um)."""
    data = reference(case)
    published, tight = data["published"], data["tight_ode_tolerance"]
    assert published["success"] and tight["success"]
    assert np.abs(published["residual"]).max() < 1e-7
    spread = np.linalg.norm(np.asarray(published["positions"]) - np.asarray(tight["positions"]), axis=1)
    assert spread.max() < 0.25e-6


@pytest.mark.skipif("three_tendons" not in CASES, reason="no tdcr-modeling reference shapes in tests/data/tdcr")
def test_tolerance_resolves_extension_and_shear():
    """The same arm as a Kirchhoff rod misses the reference by far more than the tolerance."""
    data = reference("three_tendons")
    solution = our_solution(data, model="kirchhoff")
    index = at_disks(data, solution)
    error = np.linalg.norm(solution.positions[index] - np.asarray(data["published"]["positions"]), axis=1)
    assert error.max() > 10 * POSITION_TOLERANCE


def matlab_solution(ref: dict[str, Any], data: dict[str, Any]) -> RodSolution:
    """Our equilibrium of a MATLAB case: the robot of ``tdcr_2segments.m`` as ``VC_solver`` reports it (``ref``)."""
    robot = ref["robot"]
    E, radius = robot["youngs_modulus"], robot["backbone_radius"]
    second_moment = math.pi * radius**4 / 4
    segments = tuple(
        Segment(
            rod=Rod(
                length=robot[f"length_{k}"],
                area=math.pi * radius**2,
                second_moment=second_moment,
                polar_moment=2 * second_moment,
                outer_radius=2 * robot["pitch_radius"],
                youngs_modulus=E,
                poisson_ratio=robot["poisson_ratio"],
                gravity=(0.0, 0.0, 0.0),
            ),
            tendons=tuple(Tendon(offset=math.hypot(x, y), angle=math.atan2(y, x)) for x, y, _ in ref["routing"]),
        )
        for k in (1, 2)
    )
    solver = ShootingSolver(RodArm(segments=segments), ShootingOptions(steps_per_segment=STEPS))
    solution = solver.solve(Loads(tip_force=tuple(data["tip_force"]), actuation=tuple(data["tensions"])))
    assert solution.ok, solution.message
    return solution


@pytest.mark.skipif(not MATLAB_CASES, reason="no tdcr-modeling MATLAB reference shapes in tests/data/tdcr")
@pytest.mark.parametrize("case", MATLAB_CASES)
def test_shooting_matches_tdcr_modeling_matlab(case):
    """Against the MATLAB ``VC_solver`` at the points its ode45 returned, our nodes interpolated per segment."""
    data = reference(case)
    ref = data["published"]
    assert ref["exitflag"] > 0 and np.abs(ref["residual"]).max() < 1e-7
    assert ref["robot"]["gravity"] == 0.0
    solution = matlab_solution(ref, data)
    s, positions = np.asarray(ref["s"]), np.asarray(ref["positions"])
    s1 = ref["robot"]["length_1"]
    first = solution.s <= s1 + 1e-12
    second = solution.s >= s1 - 1e-12
    # One cubic spline per segment: the curvature jumps at the disk where segment 1's tendons end.
    ours = np.where(
        (s <= s1)[:, None],
        CubicSpline(solution.s[first], solution.positions[first])(np.minimum(s, s1)),
        CubicSpline(solution.s[second], solution.positions[second])(np.maximum(s, s1)),
    )
    error = np.linalg.norm(ours - positions, axis=1)
    assert error.max() < POSITION_TOLERANCE, f"max error {error.max() * 1e6:.3f} um"
    tip = matrix_from_quat(solution.orientations[-1])
    assert np.abs(tip - np.asarray(ref["rotations"][-1])).max() < ROTATION_TOLERANCE


@pytest.mark.skipif(not MATLAB_CASES, reason="no tdcr-modeling MATLAB reference shapes in tests/data/tdcr")
@pytest.mark.parametrize("case", MATLAB_CASES)
def test_matlab_reference_is_converged(case):
    """The MATLAB tip moves by less than 0.25 um when ode45's tolerances go from 1e-6 to 1e-10."""
    data = reference(case)
    published, tight = data["published"], data["tight_ode_tolerance"]
    assert tight["exitflag"] > 0 and np.abs(tight["residual"]).max() < 1e-7
    spread = np.linalg.norm(np.asarray(published["positions"][-1]) - np.asarray(tight["positions"][-1]))
    assert spread < 0.25e-6


@pytest.mark.skipif(
    not {"example_robot_main_m", "matlab_vc_two_tendons"} <= set(CASES + MATLAB_CASES),
    reason="no tdcr-modeling reference shapes in tests/data/tdcr",
)
def test_cpp_and_matlab_references_agree():
    """The two implementations of tdcr-modeling agree on the equilibrium of ``matlab/main.m`` (measured 0.015 um)."""
    cpp = reference("example_robot_main_m")["published"]
    matlab = reference("matlab_vc_two_tendons")["published"]
    assert np.linalg.norm(np.subtract(cpp["positions"][-1], matlab["positions"][-1])) < 0.1e-6
    assert np.abs(np.subtract(cpp["rotations"][-1], matlab["rotations"][-1])).max() < ROTATION_TOLERANCE
