"""Problem kind ``ik`` on the CBHA (seed 004): platform leg lengths -> (Z_k, theta_k, psi_k), and tip IK.

Checks use a transcription of seed 004 written here: eqs. (7)-(9) for the leg
lengths and the matrices of eq. (5) chained for the tip, with Table I limits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.arms.cbha import CBHAGeometry
from optikin.errors import SpecError
from optikin.runner import solve

TABLE_I_MIN_MM = [8.5, 8.5, 8.5, 7, 7, 7, 8.5, 10, 6.5, 8, 8, 7.5, 7.5, 7, 7, 6.5]
TABLE_I_MAX_MM = [19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5, 20.5, 19, 19, 18, 18, 16]


def legs_eqs_7_to_9(Z, t, p, rk, rk1):
    """Seed 004 eqs. (7)-(9): the three leg lengths of a platform."""
    s3, common = np.sqrt(3.0), Z**2 + rk1**2 + rk**2
    q1 = common + 2 * Z * rk1 * np.sin(t) - 2 * rk1 * rk * np.cos(t)
    q2 = (common + Z * rk1 * (s3 * np.cos(t) * np.sin(p) - np.sin(t))
          - rk1 * rk * (s3 / 2 * np.sin(t) * np.sin(p) + 1.5 * np.cos(p) + 0.5 * np.cos(t)))
    q3 = (common - Z * rk1 * (s3 * np.cos(t) * np.sin(p) + np.sin(t))
          + rk1 * rk * (s3 / 2 * np.sin(t) * np.sin(p) - 1.5 * np.cos(p) - 0.5 * np.cos(t)))
    return np.sqrt(np.stack([q1, q2, q3], axis=-1))


def all_legs(X: np.ndarray) -> np.ndarray:
    r = CBHAGeometry().radii
    Z, t, p = np.moveaxis(X.reshape(len(X), 16, 3), 2, 0)
    return legs_eqs_7_to_9(Z, t, p, r[:-1], r[1:]).reshape(len(X), 48)


def within_table_i(legs: np.ndarray) -> np.ndarray:
    lo, hi = np.repeat(TABLE_I_MIN_MM, 3) / 1e3, np.repeat(TABLE_I_MAX_MM, 3) / 1e3
    return np.all((legs >= lo - 1e-12) & (legs <= hi + 1e-12), axis=1)


def tip_eq_5(x: np.ndarray) -> np.ndarray:
    """Chain of the platform transforms of eq. (5), as 4x4 matrices."""
    T = np.eye(4)
    for Z, t, p in x.reshape(16, 3):
        ct, st, cp, sp = np.cos(t), np.sin(t), np.cos(p), np.sin(p)
        T = T @ np.array([[ct, st * sp, st * cp, 0], [0, cp, -sp, 0], [-st, sp * ct, ct * cp, Z], [0, 0, 0, 1]])
    return T[:3, 3]


def write_problem(tmp_path: Path, name: str, options: dict, samples: int, **fields) -> Path:
    spec = {"name": name, "title": "test", "kind": "ik", "arm": {"type": "cbha"},
            "data": {"source": "random", "seed": 3, "samples": samples}, "solver": "gauss-newton",
            "options": options} | fields
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_platform_leg_lengths_are_reproduced_to_1e_12_m_within_table_i(tmp_path):
    """Issue 4: platform solutions reproduce the given leg lengths to 1e-12 m and stay inside Table I."""
    result = solve(str(write_problem(tmp_path, "legs", {"target": "legs", "tolerance": 1e-12}, 40)),
                   figures=False)[0]
    assert result.succeeded, result.status_counts()
    given = result.arrays["targets"]
    np.testing.assert_allclose(given, all_legs(result.arrays["true_configurations"]), atol=1e-15)
    legs = all_legs(result.arrays["solutions"])
    assert np.abs(legs - given).max() <= 1e-12
    assert within_table_i(legs).all()


def test_tip_ik_reaches_the_targets_with_legs_within_table_i(tmp_path):
    options = {"target": "position", "redundancy": "rest", "restarts": 1}
    result = solve(str(write_problem(tmp_path, "tip", options, 15, baselines=["ipopt"])), figures=False)[0]
    for method in ("gauss-newton", "ipopt"):
        status = result.arrays[f"status_{method}"]
        assert (status == "ok").mean() >= 0.9, (method, status)
    ok = np.array(result.status) == "ok"
    solutions = result.arrays["solutions"][ok]
    tips = np.array([tip_eq_5(x) for x in solutions])
    assert np.abs(tips - result.arrays["targets"][ok]).max() < 1e-9
    assert within_table_i(all_legs(solutions)).all()


def test_leg_targets_need_a_cbha(tmp_path):
    spec = {"name": "bad", "title": "t", "kind": "ik", "arm": {"type": "constant_curvature"},
            "data": {"source": "random", "samples": 2}, "options": {"target": "legs"}}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(SpecError, match="options.target"):
        solve(str(path), figures=False)
