"""Problem kind ``ik`` on the two-section constant-curvature arm, checked with an independent forward model.

Solutions are checked with a closed-form CC transform written here with rotation
matrices (``R = Rz(phi) Ry(theta) Rz(-phi)``, seed 000 section II), not with the
package's quaternion chain.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from optikin.algebra import dq_rotation, dq_translation
from optikin.errors import SpecError
from optikin.runner import solve

HOME = [0.18, 0.6, 0.0, 0.18, 0.6, 1.5707963267948966]
S_RANGE, THETA_MAX = (0.162, 0.198), 2.0943951023931953
REACH = 2 * 0.198


def rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def cc_tip_transform(q: np.ndarray) -> np.ndarray:
    """Tip transform of a CC arm from rotation matrices, section by section."""
    T = np.eye(4)
    for S, theta, phi in np.reshape(q, (-1, 3)):
        chord = (
            np.array([0.0, 0.0, S])
            if abs(theta) < 1e-12
            else S
            / theta
            * np.array([np.cos(phi) * (1 - np.cos(theta)), np.sin(phi) * (1 - np.cos(theta)), np.sin(theta)])
        )
        section = np.eye(4)
        section[:3, :3] = rz(phi) @ ry(theta) @ rz(-phi)
        section[:3, 3] = chord
        T = T @ section
    return T


def within_bounds(q: np.ndarray) -> bool:
    S, theta, phi = np.reshape(q, (-1, 3)).T
    return bool(
        np.all(
            (S >= S_RANGE[0] - 1e-12)
            & (S <= S_RANGE[1] + 1e-12)
            & (np.abs(theta) <= THETA_MAX + 1e-12)
            & (phi >= -np.pi)
            & (phi <= np.pi)
        )
    )


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def write_problem(tmp_path: Path, name: str, **fields) -> Path:
    spec: dict[str, Any] = {
        "name": name,
        "title": "test",
        "kind": "ik",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": {"source": "random", "seed": 1, "samples": 100},
        "solver": "gauss-newton",
        "options": {"target": "position", "redundancy": "minimum_norm", "start": HOME, "restarts": 2},
    }
    for key, value in fields.items():
        spec[key] = spec[key] | value if isinstance(value, dict) and key in ("data", "options") else value
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def run(path: Path):
    return solve(str(path), figures=False)[0]


def position_errors(result) -> np.ndarray:
    """Distance from each solution's tip (closed form) to its target position."""
    targets = result.arrays["targets"]
    positions = targets if targets.shape[1] == 3 else dq_translation(targets)
    tips = np.array([cc_tip_transform(q)[:3, 3] for q in result.arrays["solutions"]])
    return np.linalg.norm(tips - positions, axis=1)


def test_position_ik_best_backend_solves_999_of_1000_targets(tmp_path):
    """On 1,000 forward-kinematics targets the best backend reaches >= 99.9 % with tip error < 1e-9 m."""
    result = run(write_problem(tmp_path, "p1000", data={"samples": 1000, "seed": 4}))
    status = np.array(result.status)
    ok = status == "ok"
    assert ok.mean() >= 0.999, result.status_counts()
    errors = position_errors(result)
    assert errors[ok].max() < 1e-9
    assert all(within_bounds(q) for q in result.arrays["solutions"][ok])
    row = result.comparison[0]
    assert row.metrics["success [%]"] == pytest.approx(100.0 * ok.mean())


def test_every_backend_reports_its_success_on_the_same_targets(tmp_path):
    baselines = ["gauss-newton-compiled", "newton", "ipopt", "sqpmethod", "lm", "trf"]
    result = run(
        write_problem(tmp_path, "all", data={"samples": 25, "seed": 8}, baselines=baselines, options={"restarts": 1})
    )
    assert [row.method for row in result.comparison] == ["gauss-newton", *baselines]
    for row in result.comparison:
        m = row.metrics
        assert 0.0 <= m["success [%]"] <= 100.0
        assert m["median time per solve [us]"] > 0
        status = result.arrays[f"status_{row.method}"]
        assert len(status) == 25  # every sample reported, failed ones included
        if (status == "ok").any():
            assert m["max tip error ok [m]"] < 1e-9
    success = {row.method: row.metrics["success [%]"] for row in result.comparison}
    print("success rates [%]:", success)
    assert max(success.values()) == 100.0


def test_unreachable_targets_are_flagged_never_solved(tmp_path):
    """Targets beyond the reach bound: never ok; flagged unreachable at a configuration inside the bounds,
    whose residual is the independently recomputed tip distance and at least the gap to the reach sphere."""
    result = run(
        write_problem(
            tmp_path,
            "far",
            data={"samples": 20, "params": {"unreachable": 20}},
            baselines=["lm"],
            options={"restarts": 1},
        )
    )
    reachable = result.arrays["reachable"]
    for method in ("gauss-newton", "lm"):
        status = result.arrays[f"status_{method}"]
        assert not np.any(status[~reachable] == "ok"), method
    status = np.array(result.status)
    far = ~reachable & (status == "unreachable")
    assert far.sum() >= 16, result.status_counts()  # at least 80 % flagged, the rest not converged
    residual = result.arrays["residual_gauss-newton"]
    errors = position_errors(result)
    np.testing.assert_allclose(residual[far], errors[far], rtol=1e-9)
    gap = np.linalg.norm(result.arrays["targets"][far], axis=1) - REACH
    assert np.all(residual[far] >= gap - 1e-12)
    assert all(within_bounds(q) for q in result.arrays["solutions"][far])
    assert np.all(status[reachable] == "ok")


def test_closest_reachable_configuration_beats_random_sampling(tmp_path):
    """The unreachable verdict comes with the closest configuration: no better than 20,000 random ones."""
    from optikin.arms import ConstantCurvatureArm

    result = run(
        write_problem(tmp_path, "far2", data={"samples": 1, "params": {"unreachable": 6}}, options={"restarts": 3})
    )
    arm = ConstantCurvatureArm()
    tips = arm.evaluate("fk_position", arm.sample_configurations(20_000, np.random.default_rng(2)))
    targets, residual = result.arrays["targets"][1:], result.arrays["residual_gauss-newton"][1:]
    sampled_best = np.array([np.linalg.norm(tips - t, axis=1).min() for t in targets])
    assert np.all(residual <= sampled_best + 1e-9)


def test_trajectory_is_solved_warm_started_and_stays_close_to_the_previous_solution(tmp_path):
    result = run(
        write_problem(
            tmp_path,
            "traj",
            data={"source": "trajectory", "samples": 300, "seed": 3},
            options={"redundancy": "previous", "restarts": 0},
        )
    )
    assert result.succeeded
    assert position_errors(result).max() < 1e-9
    assert np.median(result.iterations) <= 5  # warm starts: a few Gauss-Newton steps
    steps = np.diff(result.arrays["solutions"], axis=0)
    steps[:, 2::3] = np.angle(np.exp(1j * steps[:, 2::3]))  # phi wraps
    true_steps = np.abs(np.diff(result.arrays["true_configurations"], axis=0)).max()
    assert np.abs(steps[1:]).max() < 20 * true_steps  # no jumps between solution branches


def test_pose_ik_matches_position_and_orientation(tmp_path):
    result = run(write_problem(tmp_path, "pose", data={"samples": 200, "seed": 5}, options={"target": "pose"}))
    ok = np.array(result.status) == "ok"
    assert ok.mean() >= 0.99, result.status_counts()
    angles = []
    for q, target in zip(result.arrays["solutions"][ok], result.arrays["targets"][ok]):
        R = cc_tip_transform(q)[:3, :3]
        relative = quaternion_matrix(dq_rotation(target)).T @ R
        angles.append(np.arccos(np.clip((np.trace(relative) - 1) / 2, -1, 1)))
    assert position_errors(result)[ok].max() < 1e-9
    assert max(angles) < 1e-7  # arccos loses half the digits near zero


def test_rest_redundancy_gives_a_solution_no_farther_from_rest_than_the_generating_configuration(tmp_path):
    """ipopt minimises ||W (q - q_rest)|| on the solution set, which contains the configuration that made
    the target: the answer can be no farther from rest (a local minimiser from the rest start)."""
    result = run(
        write_problem(
            tmp_path,
            "rest",
            data={"samples": 15, "seed": 6},
            solver="ipopt",
            options={"redundancy": "rest", "start": "rest", "restarts": 0, "rest": [0.18, 0.3, 0.0, 0.18, 0.3, 0.0]},
        )
    )
    rest = np.array([0.18, 0.3, 0.0, 0.18, 0.3, 0.0])
    weights = 1.0 / np.array([0.036, 2 * THETA_MAX, 2 * np.pi] * 2)

    def distance(q):
        d = q - rest
        d[2::3] = 2 * np.sin(d[2::3] / 2)  # the objective's chord distance for wrapping angles
        return np.linalg.norm(weights * d)

    ok = np.array(result.status) == "ok"
    assert ok.sum() >= 12
    for q, true in zip(result.arrays["solutions"][ok], result.arrays["true_configurations"][ok]):
        assert distance(q) <= distance(true) + 1e-9


@pytest.mark.parametrize(
    "fields, field",
    [
        ({"options": {"targett": "position"}}, "options.targett"),
        ({"options": {"redundancy": "closest"}}, "options.redundancy"),
        ({"options": {"start": [0.18, 0.0, 0.0]}}, "options.start"),
        ({"options": {"rest": [0.5, 0.0, 0.0, 0.18, 0.0, 0.0]}}, "options.rest"),
        ({"options": {"tolerance": -1.0}}, "options.tolerance"),
        ({"data": {"params": {"unreachable": -2}}}, "data.params.unreachable"),
        ({"baselines": ["casadi-map"]}, "baselines.0"),
    ],
)
def test_bad_problem_fields_are_named(tmp_path, fields, field):
    with pytest.raises(SpecError) as info:
        run(write_problem(tmp_path, "bad", **({"data": {"samples": 2}} | fields)))
    assert field in str(info.value)
