"""The tendon-driven Cosserat arm against tdcr-modeling's Cosserat rod model (tests/data/tdcr/).

tdcr-modeling is the reference implementation of Rao, Peyron, Lilge and Burgner-Kahrs, "How to model
tendon-driven continuum robots and benchmark modelling performance", Frontiers in Robotics and AI 7:630245,
2021. Its C++ ``CosseratRodModel`` (commit 379d34a, run by ``tools/tdcr_reference.py``) is an independent
implementation of the model of Rucker & Webster (IEEE T-RO 27(6), 2011): a shear-extensible rod with
``G = E / 2.6`` and ``J = 2 I``, straight tendons (three per segment, at 90, -30 and 210 degrees) running from the
base to the end of their segment, where they load the rod with a point force and moment; GSL's RKF45 and
Levenberg-Marquardt. The shipped files hold its frames at the 21 disks (base, 10 per segment) for seven cases of
its default robot (2 x 0.1 m, E = 60 GPa, backbone radius 0.5 mm, tendons at 8 and 6 mm) and of the robot of
its ``main.cpp`` (2 x 0.2 m, 54 GPa, 0.7 mm, 10 mm), with and without a tip force and moment.

optikin's arm is built with the same parameters (``model="cosserat"``, the same ``G`` and ``J``, no gravity) and
solved by shooting with 50 RK4 steps per segment, so every disk is a node. Tolerances, and why:

* positions within 1 um at every disk (5e-6 of the 0.2 m arm). The reference's own error is below 0.25 um: the
  shipped build with its published ODE error control (abs 1e-6, rel 1e-3) and a build with it tightened to
  1e-12 differ by at most 0.20 um, through the residual at which Levenberg-Marquardt stops (up to 4e-8 N); our
  RK4 grid changes the disks by less than 0.02 um between 50 and 100 steps. Measured: at most 0.012 um.
* 1 um resolves the model: the same arm as an inextensible, unshearable (Kirchhoff) rod is 6 to 19 um away.
* orientations within 1e-5 per matrix entry, the base wrench within 1e-6 N and 1e-7 N m (the reference's from
  its base strains through its stiffnesses).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest

from optikin.algebra import matrix_from_quat
from optikin.physics import Loads, Rod, RodArm, Segment, ShootingOptions, ShootingSolver, Tendon
from optikin.physics.solution import RodSolution

DATA = Path(__file__).resolve().parent / "data" / "tdcr"
CASES = sorted(p.stem for p in DATA.glob("*.json")) if DATA.is_dir() else []
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
