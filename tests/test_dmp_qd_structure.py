"""The seed's Q_d DMP keeps |Q_d|: its structural bound, its frame dependence, and the variant from the start's |Q_d|.

A synthetic demonstration moves the tip along a closed-form radius
``r(s) = r0 + (r1 - r0) s + a sin(pi s)`` (``s`` minimum jerk in time) from the
origin, so the bound ``| |p(t)| - r |`` of a roll-out that keeps ``|p| = r`` is
known without the DMP: ``r1`` (the goal's radius) for ``seed`` with smoothing,
``r0`` (the start's) for ``seed-qd-start``. The sound pose DMPs must not see a
move of the world origin; the seed's must.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.algebra import quat_from_axis_angle
from optikin.data.demonstrations import PoseDemonstration, minimum_jerk, write_csv
from optikin.dmp import Gains
from optikin.dmp.pose import SeedStartDMP, pose_dmp
from optikin.problems.dmp.options import DmpOptions
from optikin.problems.dmp.report import LIMITATION
from optikin.problems.dmp.variants import variant_data
from optikin.runner import solve
from optikin.spec import load_problem
from optikin.sweep import expand, load_sweep

R0, R1, BULGE = 0.30, 0.25, 0.08
"""Start and goal distance of the tip from the origin and the outward excursion between them [m]."""
SAMPLES, RATE = 201, 50.0
VARIANTS = ["seed", "seed-qd-start", "dual-quaternion", "cartesian"]


def radius(s: np.ndarray) -> np.ndarray:
    """The demonstration's distance from the origin along its phase ``s`` in [0, 1] [m]."""
    return R0 + (R1 - R0) * s + BULGE * np.sin(np.pi * s)


def demonstration() -> PoseDemonstration:
    """The tip at ``radius(s)`` along a direction turning 0.6 rad about x, its orientation turning 0.5 rad about y."""
    t = np.arange(SAMPLES) / RATE
    s = minimum_jerk(t / t[-1])
    angle = 0.6 * s
    direction = np.stack([0.3 * np.ones_like(s), np.sin(angle), np.cos(angle)], axis=1)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    quaternion = quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), 0.5 * s)
    return PoseDemonstration(t, radius(s)[:, None] * direction, quaternion)


def problem(tmp_path: Path, shift: tuple[float, float, float] = (0.0, 0.0, 0.0), smoothing: float | None = 2.5) -> Path:
    demo = demonstration()
    write_csv(tmp_path / "demo.csv", demo)
    spec = {
        "name": "qd-structure",
        "title": "the seed's Q_d DMP on a closed-form radius",
        "kind": "dmp",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": {"source": "csv", "params": {"file": "demo.csv"}},
        "options": {
            "variants": VARIANTS,
            "n_basis": 20,
            "smoothing": smoothing,
            "regression": {"method": "lstsq"},
            "origin_shift": list(shift),
        },
    }
    path = tmp_path / "qd-structure.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def rows(path: Path) -> dict[str, dict]:
    result, _ = solve(str(path))
    assert result.succeeded
    return {row.method: row.metrics for row in result.comparison}


def bound(position: np.ndarray, kept: float) -> np.ndarray:
    """``| |p| - r |`` [mm], written out here (not the package's)."""
    return 1e3 * np.abs(np.sqrt(np.sum(position**2, axis=1)) - kept)


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> dict[float, dict[str, dict]]:
    """The rows of the problem with the origin at 0, +0.18 m and -0.36 m along z."""
    out = {}
    for z in (0.0, 0.18, -0.36):
        out[z] = rows(problem(tmp_path_factory.mktemp("qd"), (0.0, 0.0, z)))
    return out


@pytest.mark.parametrize("z", [0.0, 0.18, -0.36])
def test_the_reported_bound_is_the_closed_form_and_the_error_is_not_below_it(solved, z):
    position = demonstration().position - np.array([0.0, 0.0, z])
    start, goal = np.linalg.norm(position[0]), np.linalg.norm(position[-1])
    for variant, kept in (("seed", goal), ("seed-qd-start", start)):
        row = solved[z][f"dmp {variant} (lstsq)"]
        expected = bound(position, kept)
        assert row["distance kept from the origin [mm]"] == pytest.approx(kept * 1e3, abs=0.02)
        assert row["structural bound position max [mm]"] == pytest.approx(expected.max(), abs=0.02)
        assert row["structural bound position rms [mm]"] == pytest.approx(rms(expected), abs=0.02)
        assert row["reproduction position max [mm]"] >= expected.max() - 0.02
        assert row["reproduction position rms [mm]"] >= rms(expected) - 0.02
        assert row["limitation"] == LIMITATION
    if z == 0.0:  # the radius of the synthetic motion: bulge outward from a start farther out than the goal
        s = np.linspace(0.0, 1.0, 100001)
        assert solved[z]["dmp seed (lstsq)"]["structural bound position max [mm]"] == pytest.approx(
            1e3 * (radius(s) - R1).max(), abs=0.02
        )
        assert solved[z]["dmp seed-qd-start (lstsq)"]["structural bound position max [mm]"] == pytest.approx(
            1e3 * (radius(s) - R0).max(), abs=0.02
        )


def test_the_seed_variant_starts_at_the_goals_distance_the_start_variant_at_the_starts(solved):
    """With smoothing the seed's roll-out is |r0 - r1| off at t = 0; the start variant is not."""
    table = solved[0.0]
    assert table["dmp seed (lstsq)"]["reproduction position at t = 0 [mm]"] == pytest.approx(1e3 * (R0 - R1), abs=0.1)
    assert table["dmp seed-qd-start (lstsq)"]["reproduction position at t = 0 [mm]"] < 0.1


def test_only_the_seed_variants_move_with_the_world_origin(solved):
    key = "reproduction position max [mm]"
    for variant in ("dual-quaternion", "cartesian"):
        errors = [solved[z][f"dmp {variant} (lstsq)"][key] for z in solved]
        assert max(errors) - min(errors) < 1e-6 * max(errors)
        assert "structural bound position max [mm]" not in solved[0.0][f"dmp {variant} (lstsq)"]
    for variant in ("seed", "seed-qd-start"):
        errors = [solved[z][f"dmp {variant} (lstsq)"][key] for z in solved]
        assert max(errors) - min(errors) > 10.0


def test_seed_start_keeps_the_first_samples_dual_norm_and_is_the_seed_without_smoothing():
    demo = demonstration()
    Y = variant_data("seed", demo.position, demo.quaternion)
    options = {"n_basis": 20, "gains": Gains()}
    smoothed = SeedStartDMP(smoothing=2.5, **options)
    smoothed.imitate(demo.t, Y)
    norm = np.linalg.norm(smoothed.rollout().y[:, 4:], axis=1)
    assert np.abs(norm - R0 / 2).max() < 1e-12  # |Q_d| = |p| / 2 of the first sample, kept
    plain = [pose_dmp(v, **options) for v in ("seed", "seed-qd-start")]
    for dmp in plain:
        dmp.imitate(demo.t, Y)
    assert np.abs(plain[0].rollout().y - plain[1].rollout().y).max() < 1e-12


def test_the_origin_sweep_runs_each_variant_at_each_origin():
    spec, path = load_sweep("dmp-qd-origin")
    cells = expand(spec, path)
    seen = set()
    for cell in cells:
        problem, _ = load_problem(cell.problem, cell.overrides)
        options = DmpOptions.model_validate(problem.options)
        assert len(options.variants) == 1  # one solver row a cell, so the sweep's columns are per variant
        seen.add((options.variants[0], options.origin_shift))
    shifts = {(0.0, 0.0, 0.0), (0.0, 0.0, 0.18), (0.0, 0.0, -0.36)}
    assert seen == {(v, z) for v in VARIANTS for z in shifts}
