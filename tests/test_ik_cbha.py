"""Problem kind ``ik`` on the CBHA (seed 004): platform leg lengths -> (Z_k, theta_k, psi_k), and tip IK.

Checks use a transcription of seed 004 written here: eqs. (7)-(9) for the leg
lengths and the matrices of eq. (5) chained for the tip, with Table I limits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.arms.cbha import CBHAArm, CBHAGeometry
from optikin.data.markers import configurations_from_fractions
from optikin.errors import SpecError
from optikin.ik.cbha import distributed_tube_range, distribution_deviation
from optikin.runner import solve

TABLE_I_MIN_MM = [8.5, 8.5, 8.5, 7, 7, 7, 8.5, 10, 6.5, 8, 8, 7.5, 7.5, 7, 7, 6.5]
TABLE_I_MAX_MM = [19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5, 20.5, 19, 19, 18, 18, 16]


def legs_eqs_7_to_9(Z, t, p, rk, rk1):
    """Seed 004 eqs. (7)-(9): the three leg lengths of a platform."""
    s3, common = np.sqrt(3.0), Z**2 + rk1**2 + rk**2
    q1 = common + 2 * Z * rk1 * np.sin(t) - 2 * rk1 * rk * np.cos(t)
    q2 = (
        common
        + Z * rk1 * (s3 * np.cos(t) * np.sin(p) - np.sin(t))
        - rk1 * rk * (s3 / 2 * np.sin(t) * np.sin(p) + 1.5 * np.cos(p) + 0.5 * np.cos(t))
    )
    q3 = (
        common
        - Z * rk1 * (s3 * np.cos(t) * np.sin(p) + np.sin(t))
        + rk1 * rk * (s3 / 2 * np.sin(t) * np.sin(p) - 1.5 * np.cos(p) - 0.5 * np.cos(t))
    )
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
    spec = {
        "name": name,
        "title": "test",
        "kind": "ik",
        "arm": {"type": "cbha"},
        "data": {"source": "random", "seed": 3, "samples": samples},
        "solver": "gauss-newton",
        "options": options,
    } | fields
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_platform_leg_lengths_are_reproduced_to_1e_12_m_within_table_i(tmp_path):
    """Platform solutions reproduce the given leg lengths to 1e-12 m and stay inside Table I."""
    result = solve(str(write_problem(tmp_path, "legs", {"target": "legs", "tolerance": 1e-12}, 40)), figures=False)[0]
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


# ------------------------------------------------------------------ seed 004's whole-CBHA inverse problem
PENALTY = 1e-5
PRINTED_PENALTY = 0.01
WEIGHTS = np.tile([100.0, 1.0, 1.0], 16)  # 1/(10 mm) for Z_k, 1/rad for the angles: chosen here


def straight_mid_range() -> np.ndarray:
    """Every leg at the middle of Table I, platforms untilted: Z_k = sqrt(q^2 - (r_k - r_k+1)^2)."""
    r = CBHAGeometry().radii
    q = (np.array(TABLE_I_MIN_MM) + np.array(TABLE_I_MAX_MM)) / 2e3
    return np.column_stack([np.sqrt(q**2 - np.diff(r) ** 2), np.zeros(16), np.zeros(16)]).ravel()


def tip_jacobian(x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """3 x 48 central differences of the chain of eq. (5)."""
    columns = []
    for j in range(x.size):
        step = np.zeros_like(x)
        step[j] = h
        columns.append((tip_eq_5(x + step) - tip_eq_5(x - step)) / (2 * h))
    return np.array(columns).T


@pytest.fixture(scope="module")
def formulations(tmp_path_factory):
    """One run: exact tip closest to rest, and as variants eq. (11) on the configuration and as printed,
    and the elongation distribution of section IV in both readings."""
    options = {
        "target": "position",
        "redundancy": "rest",
        "restarts": 1,
        "weights": WEIGHTS.tolist(),
        "variants": {
            "penalty": {"redundancy": "penalty", "penalty": PENALTY},
            "printed": {"redundancy": "penalty", "penalty_on": "position", "penalty": PRINTED_PENALTY},
            "distributed": {"elongation": "distributed"},
            "affine": {"elongation": "affine"},
        },
    }
    path = write_problem(tmp_path_factory.mktemp("cbha"), "forms", options, 8)
    return solve(str(path), figures=False)[0]


def test_eq_11_penalty_minimiser_satisfies_its_optimality_condition(formulations):
    """At an interior minimiser of 1/2 |tip(q) - p*|^2 + lam/2 |W (q - q_rest)|^2 the gradient vanishes:
    J^T e + lam W^2 d = 0, with J by finite differences of the eq. (5) chain. The tip misses the target by
    about lam, and the cost is no higher than at the configuration that made the target (zero tip error)."""
    result = formulations
    rest, targets = straight_mid_range(), result.arrays["targets"]
    ok = result.arrays["status_gauss-newton_penalty"] == "ok"
    assert ok.sum() >= 7
    checked = 0
    for x, target, true in zip(
        result.arrays["solutions_gauss-newton_penalty"][ok], targets[ok], result.arrays["true_configurations"][ok]
    ):
        e, d = tip_eq_5(x) - target, x - rest
        gradient_terms = (tip_jacobian(x).T @ e, PENALTY * WEIGHTS**2 * d)
        assert 1e-8 < np.linalg.norm(e) < 1e-3
        assert np.linalg.norm(sum(gradient_terms)) <= 1e-6 * np.linalg.norm(gradient_terms[1])
        cost = 0.5 * e @ e + 0.5 * PENALTY * np.sum((WEIGHTS * d) ** 2)
        assert cost <= 0.5 * PENALTY * np.sum((WEIGHTS * (true - rest)) ** 2)
        checked += 1
    assert checked == ok.sum()


def test_eq_11_as_printed_pulls_the_tip_towards_the_base(formulations):
    """With X the tip position, 1/2 |X_d - X|^2 + lam/2 |X|^2 is least at X = X_d / (1 + lam)."""
    result = formulations
    ok = result.arrays["status_gauss-newton_printed"] == "ok"
    assert ok.sum() >= 7
    tips = np.array([tip_eq_5(x) for x in result.arrays["solutions_gauss-newton_printed"][ok]])
    np.testing.assert_allclose(tips, result.arrays["targets"][ok] / (1 + PRINTED_PENALTY), atol=1e-9)


def test_elongation_distribution_of_section_iv(formulations):
    """Every leg a fixed share of its section's tube, the share of the Table I mid-range lengths, and the
    tip on its target (eqs. (7)-(9) and the eq. (5) chain, transcribed here)."""
    result = formulations
    ok = result.arrays["status_gauss-newton_distributed"] == "ok"
    assert ok.sum() >= 7
    solutions = result.arrays["solutions_gauss-newton_distributed"][ok]
    legs = all_legs(solutions).reshape(-1, 16, 3)
    mid = (np.array(TABLE_I_MIN_MM) + np.array(TABLE_I_MAX_MM)) / 2
    for section in (slice(0, 8), slice(8, 16)):
        share = legs[:, section] / legs[:, section].sum(axis=1, keepdims=True)
        expected = mid[section] / mid[section].sum()
        np.testing.assert_allclose(share, np.broadcast_to(expected[None, :, None], share.shape), atol=1e-10)
    tips = np.array([tip_eq_5(x) for x in solutions])
    assert np.abs(tips - result.arrays["targets"][ok]).max() < 1e-9
    assert within_table_i(all_legs(solutions)).all()


def test_affine_elongation_distribution_of_section_iv(formulations):
    """Every leg at one fraction of its Table I range, shared by the platforms of its section and tube,
    and the tip on its target (eqs. (7)-(9) and the eq. (5) chain, transcribed here)."""
    result = formulations
    ok = result.arrays["status_gauss-newton_affine"] == "ok"
    assert ok.sum() >= 7
    solutions = result.arrays["solutions_gauss-newton_affine"][ok]
    legs = all_legs(solutions).reshape(-1, 16, 3)
    lo, hi = (np.array(v)[None, :, None] / 1e3 for v in (TABLE_I_MIN_MM, TABLE_I_MAX_MM))
    fraction = (legs - lo) / (hi - lo)
    for section in (slice(0, 8), slice(8, 16)):
        f = fraction[:, section]
        np.testing.assert_allclose(f, np.broadcast_to(f[:, :1], f.shape), atol=1e-9)
    tips = np.array([tip_eq_5(x) for x in solutions])
    assert np.abs(tips - result.arrays["targets"][ok]).max() < 1e-9
    assert within_table_i(all_legs(solutions)).all()


def test_the_synthetic_recording_moves_the_legs_by_the_affine_distribution():
    """The recorder sets the legs from one fraction per section and tube and solves the platform poses;
    the affine rows vanish on its configurations, the mid-range ones do not."""
    arm = CBHAArm()
    fractions = np.random.default_rng(5).uniform(0.0, 1.0, size=(20, 2, 3))
    X = configurations_from_fractions(arm, fractions)
    assert distribution_deviation(arm, X, "affine").max() < 1e-12
    assert distribution_deviation(arm, X, "distributed").min() > 1e-5
    lower, upper = distributed_tube_range(arm.geometry, "affine")
    np.testing.assert_allclose(lower * 1e3, [sum(TABLE_I_MIN_MM[:8]), sum(TABLE_I_MIN_MM[8:])])
    np.testing.assert_allclose(upper * 1e3, [sum(TABLE_I_MAX_MM[:8]), sum(TABLE_I_MAX_MM[8:])])


def test_formulations_are_compared_in_one_result(formulations):
    """Tip error, leg margins and tube lengths of every row, recomputed here from its solutions."""
    result = formulations
    rows = {row.method: row for row in result.comparison}
    assert set(rows) == {
        "gauss-newton",
        "gauss-newton [penalty]",
        "gauss-newton [printed]",
        "gauss-newton [distributed]",
        "gauss-newton [affine]",
    }
    assert [row.role for row in rows.values()] == ["solver", "variant", "variant", "variant", "variant"]
    lo, hi = np.repeat(TABLE_I_MIN_MM, 3), np.repeat(TABLE_I_MAX_MM, 3)
    for name, row in rows.items():
        key = name.replace(" [", "_").rstrip("]")
        solutions = result.arrays[f"solutions_{key}"]
        tips = np.array([tip_eq_5(x) for x in solutions])
        errors = np.linalg.norm(tips - result.arrays["targets"], axis=1)
        legs = all_legs(solutions) * 1e3
        margins = np.minimum(legs - lo, hi - legs).min(axis=1)
        assert row.metrics["median tip error [m]"] == pytest.approx(np.median(errors), rel=1e-6, abs=1e-15)
        assert row.metrics["min leg margin [mm]"] == pytest.approx(margins.min(), rel=1e-9)
        assert row.metrics["median time per solve [us]"] > 0
        tubes = legs.reshape(-1, 2, 8, 3).sum(axis=2) / 1e3  # (sample, section, tube): sums of the legs
        np.testing.assert_allclose(result.arrays[f"tube_lengths_{key}"], tubes.reshape(-1, 6), atol=1e-15)
    exact = ("gauss-newton", "gauss-newton [distributed]", "gauss-newton [affine]")
    assert all(rows[n].metrics["tip within tolerance [%]"] == 100.0 for n in exact)
    assert rows["gauss-newton [penalty]"].metrics["tip within tolerance [%]"] == 0.0
    assert rows["gauss-newton [distributed]"].metrics["median deviation from distribution [mm]"] < 1e-9
    assert rows["gauss-newton"].metrics["median deviation from distribution [mm]"] > 1e-3


@pytest.mark.parametrize(
    "options, field",
    [
        ({"target": "legs", "redundancy": "penalty"}, "options.redundancy"),
        ({"variants": {"v": {"elongation": "spread"}}}, "options.variants.v.elongation"),
        ({"variants": {"v": {"target": "pose"}}}, "options.variants.v.target"),
        ({"variants": {"v": {"redundancy": "penalty", "penalty": -1.0}}}, "options.variants.v.penalty"),
    ],
)
def test_bad_formulation_options_are_named(tmp_path, options, field):
    with pytest.raises(SpecError) as info:
        solve(str(write_problem(tmp_path, "bad", {"target": "position"} | options, 2)), figures=False)
    assert field in str(info.value)


def test_leg_targets_need_a_cbha(tmp_path):
    spec = {
        "name": "bad",
        "title": "t",
        "kind": "ik",
        "arm": {"type": "constant_curvature"},
        "data": {"source": "random", "samples": 2},
        "options": {"target": "legs"},
    }
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(SpecError, match="options.target"):
        solve(str(path), figures=False)
