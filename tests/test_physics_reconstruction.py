"""Shapes rebuilt from end poses by fitting a tip wrench (optikin.physics.reconstruction).

The truth is independent of the fit: equilibria of the boundary-value problem under
known loads solved by :class:`optikin.physics.ShootingSolver` (its Newton on the tip
residual, not the fit's initial-value integration), and the continuum solutions
shipped with the PyElastica reference shapes (tests/data/pyelastica/, a scipy
``solve_bvp`` of the planar rod, see the README there).

* A tip-loaded rod's shape and tip wrench come back from its two end poses to the
  solver's precision (nodes within 1e-8 m, wrench within 1e-7 relative).
* A rod under an unmodelled uniform distributed force (0.05 N/m sideways, with a
  0.01 N tip force) is not exactly rebuilt: the fitted tip wrench reaches the tip
  pose exactly but the nodes in between are off by 0.14 mm (the test asserts
  between 0.1 and 0.2 mm); fitting the distributed force too (9 unknowns for 6
  residuals) reaches the tip pose exactly as well, not necessarily the true load.
* The PyElastica continuum shapes (linear Reissner law) of the four tip-load cases
  are rebuilt from their end poses within 0.5 mm at every node (in fact within 4, 17,
  1e-8 and 4 um: the tip frame is taken from the shape's end tangent, which differs
  from ``d3`` by the shear strain, about 1e-4 under the tip forces).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optikin.algebra import quat_from_matrix, quat_multiply
from optikin.physics import Loads, Rod, RodArm, ShootingOptions, ShootingSolver
from optikin.physics.reconstruction import ReconstructionOptions, ShapeReconstructor, reconstruct_shape

DATA = Path(__file__).resolve().parent / "data" / "pyelastica"
TIP_CASES = ("tip_force_small", "tip_force_large", "tip_couple_x", "tip_force_couple_y")
ROD = Rod(length=0.3, radius=0.01, youngs_modulus=1e6, poisson_ratio=0.5)


def truth(arm: RodArm, loads: Loads):
    solution = ShootingSolver(arm, ShootingOptions(steps_per_segment=100)).solve(loads)
    assert solution.ok, solution.message
    return solution


def ends(solution):
    return (solution.positions[0], solution.orientations[0]), (solution.positions[-1], solution.orientations[-1])


@pytest.mark.parametrize(
    "force, couple",
    [((0.03, -0.01, 0.0), (0.001, 0.002, 0.0005)), ((-0.02, 0.0, -0.05), (0.0, -0.003, 0.0))],
)
def test_tip_loaded_rod_is_rebuilt_exactly(force, couple):
    base = quat_from_matrix(np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]))  # clamped along -y
    arm = RodArm.single(ROD, base_position=(0.1, 0.2, -0.3), base_orientation=tuple(base))
    known = truth(arm, Loads(tip_force=force, tip_couple=couple))
    base_pose, tip_pose = ends(known)
    solution, wrench, residual, status = reconstruct_shape(RodArm.single(ROD), base_pose, tip_pose)
    assert status == "ok" and np.linalg.norm(residual) < 1e-10
    assert np.abs(solution.positions - known.positions).max() < 1e-8
    np.testing.assert_allclose(wrench, np.concatenate([force, couple]), rtol=0, atol=1e-7 * 0.05)


def test_sequence_warm_starts_and_follower_couple():
    arm = RodArm.single(ROD, tip_couple_frame="follower")
    couples = [(0.0, 0.004 * t, 0.001 * t) for t in np.linspace(0.2, 1.0, 5)]
    known = [truth(arm, Loads(tip_force=(0.01, 0.0, 0.0), tip_couple=c)) for c in couples]
    reconstructor = ShapeReconstructor(arm)
    results = reconstructor.reconstruct_sequence([ends(k)[0] for k in known], [ends(k)[1] for k in known])
    for result, k, c in zip(results, known, couples):
        assert result.status == "ok"
        assert np.abs(result.solution.positions - k.positions).max() < 1e-8
        np.testing.assert_allclose(result.wrench[3:], c, atol=1e-9)
    cold = reconstructor.reconstruct(*ends(known[-1]))[0]
    assert results[-1].iterations < cold.iterations  # the warm start pays


def test_unmodelled_distributed_load_is_not_exact():
    arm = RodArm.single(ROD)
    known = truth(arm, Loads(tip_force=(0.01, 0.0, 0.0), distributed_force=(0.0, 0.05, 0.0)))
    base_pose, tip_pose = ends(known)
    solution, _, residual, status = reconstruct_shape(arm, base_pose, tip_pose)
    error = np.abs(solution.positions - known.positions).max()
    assert status == "ok" and np.linalg.norm(residual) < 1e-10
    assert 1e-4 < error < 2e-4
    fitted = ShapeReconstructor(arm, ReconstructionOptions(distributed_force=True)).reconstruct(base_pose, tip_pose)[0]
    assert fitted.status == "ok" and fitted.wrench.shape == (9,)


def shipped(case: str) -> dict[str, np.ndarray]:
    path = DATA / f"{case}_n200.npz"
    if not path.exists():
        pytest.skip(f"{path.name} not shipped")
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def end_tangent(points: np.ndarray, h: float) -> np.ndarray:
    """Unit tangent at the last of equally spaced points (one-sided fourth-order difference)."""
    p = points[-5:]
    d = (25 * p[4] - 48 * p[3] + 36 * p[2] - 16 * p[1] + 3 * p[0]) / (12 * h)
    return d / np.linalg.norm(d)


@pytest.mark.parametrize("case", TIP_CASES)
def test_pyelastica_continuum_shapes_from_their_end_poses(case):
    data = shipped(case)
    d1, d3 = data["base_normal"], data["base_direction"]
    base = quat_from_matrix(np.stack([d1, np.cross(d3, d1), d3], axis=1))
    base = base / np.linalg.norm(base)
    shape = data["continuum_positions"]
    L = float(data["length"])
    t = end_tangent(shape, L / (len(shape) - 1))
    axis = np.cross(d3, t)  # planar bending: the tip frame is the base frame turned about the plane's normal
    angle = np.arctan2(np.linalg.norm(axis), d3 @ t)
    axis = axis / max(np.linalg.norm(axis), 1e-300)
    turn = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    rod = Rod(
        length=L,
        radius=float(data["radius"]),
        youngs_modulus=float(data["youngs_modulus"]),
        shear_modulus=float(data["shear_modulus"]),
    )
    solution, _, _, status = reconstruct_shape(
        RodArm.single(rod),
        (shape[0], base),
        (shape[-1], quat_multiply(turn, base)),
        options=ReconstructionOptions(steps_per_segment=len(shape) - 1),
    )
    assert status == "ok"
    assert np.linalg.norm(solution.positions - shape, axis=1).max() < 0.5e-3


def test_a_sequence_starts_each_fit_where_start_says():
    arm = RodArm.single(ROD)
    forces = [(0.01 * t, -0.005, 0.002 * t) for t in np.linspace(0.2, 1.0, 4)]
    known = [truth(arm, Loads(tip_force=f)) for f in forces]
    bases, tips = [ends(k)[0] for k in known], [ends(k)[1] for k in known]
    reconstructor = ShapeReconstructor(arm)
    seen = []

    def at_the_truth(i, previous):
        seen.append(None if previous is None else previous.copy())
        return known[i].base_wrench  # the shooting's root: the fit starts at its minimiser

    exact = reconstructor.reconstruct_sequence(bases, tips, start=at_the_truth)
    assert all(r.status == "ok" and r.iterations <= 1 for r in exact)
    assert seen[0] is None and all(np.abs(p - k.base_wrench).max() < 1e-9 for p, k in zip(seen[1:], known))
    cold = reconstructor.reconstruct_sequence(bases, tips, start=lambda i, previous: None)
    alone = [reconstructor.reconstruct(b, t)[0] for b, t in zip(bases, tips)]
    assert [r.iterations for r in cold] == [r.iterations for r in alone]
    for r, k in zip(cold, known):
        assert r.status == "ok" and np.abs(r.solution.positions - k.positions).max() < 1e-8
