"""Seed 004's models on the Cosserat CBHA, MATLAB's normalisation, the tube-driven database, Fig. 9's split.

References: MATLAB's ``mapminmax`` formula ``y = 2 (x - x_min) / (x_max - x_min) - 1`` written
out; Table I typed in again and the fractions of Fig. 6 worked by hand; the printed
eqs. (7)-(9); a straight rod under equal chamber pressures and no gravity (its axial strain
``3 p A / (E A)`` and the tubes' length ``sqrt(l^2 + (rho_0 - rho_1)^2)`` in closed form); the
chain of eq. (5) in numpy (:func:`tests.test_nn_problems.chain_tips`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from optikin.arms.cbha import CBHAGeometry, printed_leg_lengths
from optikin.baselines.nn_database import DatabaseSpec, build_database, section_tube_lengths, split_tube_lengths
from optikin.baselines.nn_models import SETTINGS, affine_map, forward_tasks, goal_babbling, split_mse, train_model
from optikin.data.cosserat_markers import CosseratMarkerParams
from optikin.data.cosserat_nn import cosserat_postures
from optikin.problems.nn_shared import constant_curvature_lengths, constant_curvature_tips
from optikin.runner import solve
from optikin.spec import load_problem, project_root
from tests.test_nn_problems import Q_MAX_MM, Q_MIN_MM, RADII, chain_tips

SECTION = np.repeat([0, 1], 8)


def test_minmax_is_matlabs_mapminmax():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(50, 4)) * [1e-3, 1.0, 10.0, 0.0] + [0.01, 0.0, -3.0, 2.0]
    offset, scale = affine_map(A, "minmax")
    lo, hi = A.min(axis=0), A.max(axis=0)
    expected = 2 * (A[:, :3] - lo[:3]) / (hi[:3] - lo[:3]) - 1
    np.testing.assert_allclose(((A - offset) / scale)[:, :3], expected, atol=1e-12)
    assert scale[3] == 1.0  # a constant column is shifted, not divided by zero
    assert SETTINGS["seed"].scaling == "minmax" and SETTINGS["seed-raw"].scaling is False
    assert SETTINGS["seed"].solver == SETTINGS["seed-raw"].solver == "sgd"


@pytest.fixture(scope="module")
def tubes_db():
    return build_database(CBHAGeometry(), DatabaseSpec(candidates=1500, seed=3, coupling="tubes"))


def test_the_normalised_seed_setting_learns_where_the_raw_one_predicts_the_mean(tubes_db):
    task = forward_tasks(tubes_db)[0]
    _, Y = task.arrays(tubes_db, tubes_db.test)
    variance = float(Y.var(axis=0).mean())  # the MSE of predicting the mean
    small = {n: dataclasses.replace(SETTINGS[n].small(), neurons=(8,), max_epochs=30) for n in ("seed", "seed-raw")}
    normalised = split_mse(train_model(task, tubes_db, small["seed"]), tubes_db)
    raw = split_mse(train_model(task, tubes_db, small["seed-raw"]), tubes_db)
    assert normalised < 0.3 * variance < 0.3 * raw


def test_fig6_split_by_hand():
    g = CBHAGeometry()
    lo1, hi1 = Q_MIN_MM[:8].sum() / 1e3, Q_MAX_MM[:8].sum() / 1e3  # 65 and 150 mm
    lo2, hi2 = Q_MIN_MM[8:].sum() / 1e3, Q_MAX_MM[8:].sum() / 1e3  # 58 and 147 mm
    L = np.array([[[lo1, hi1, (lo1 + hi1) / 2], [lo2, 0.25 * lo2 + 0.75 * hi2, hi2]]])
    legs = split_tube_lengths(g, L).reshape(16, 3)
    f = np.array([[0.0, 1.0, 0.5], [0.0, 0.75, 1.0]])[SECTION]  # (platform, tube)
    np.testing.assert_allclose(legs, (Q_MIN_MM[:, None] + f * (Q_MAX_MM - Q_MIN_MM)[:, None]) / 1e3, atol=1e-15)
    np.testing.assert_allclose(section_tube_lengths(g, legs.reshape(1, -1)), L, atol=1e-15)


def test_tube_driven_rows_have_every_leg_at_its_tubes_fraction(tubes_db):
    Q = tubes_db.configurations.reshape(len(tubes_db), 16, 3)
    legs = np.stack([np.stack(printed_leg_lengths(*Q[:, k].T, RADII[k], RADII[k + 1]), -1) for k in range(16)], 1)
    f = (legs * 1e3 - Q_MIN_MM[None, :, None]) / (Q_MAX_MM - Q_MIN_MM)[None, :, None]  # (row, platform, tube)
    for s in (0, 1):
        block = f[:, SECTION == s]
        np.testing.assert_allclose(block, np.broadcast_to(block[:, :1], block.shape), atol=1e-9)
    assert f.min() >= -1e-9 and f.max() <= 1 + 1e-9
    np.testing.assert_allclose(tubes_db.tip, chain_tips(tubes_db.configurations), atol=1e-12)


def test_cosserat_postures_stretch_straight_as_a_rod_in_closed_form():
    params = CosseratMarkerParams(gravity=(0.0, 0.0, 0.0), steps_per_segment=8)
    p = 0.6e5
    out = cosserat_postures(params, np.full((1, 2, 3), p), compiled=False)
    strain = 3 * p * params.chamber_area / params.axial_stiffness
    L = np.array(params.section_lengths) * (1 + strain)
    np.testing.assert_allclose(out["tip"][0], [0, 0, L.sum()], atol=1e-9)
    np.testing.assert_allclose(out["section_ends"][0, 0], [0, 0, L[0]], atol=1e-9)
    r0, r1 = params.tube_radius
    drho = (r1 - r0) * np.array(params.section_lengths) / params.length
    np.testing.assert_allclose(out["tube_lengths"][0], np.sqrt(L**2 + drho**2)[:, None].repeat(3, 1), rtol=1e-7)


@pytest.mark.parametrize("kind", ["fkm", "ikm"])
def test_the_scaled_table_i_holds_the_recorded_tube_lengths(kind):
    spec, _ = load_problem(f"cbha-nn-{kind}-cosserat")
    g = CBHAGeometry(**spec.arm.params["geometry"])
    np.testing.assert_allclose(np.array(g.leg_min) * 1e3, 1.8 * Q_MIN_MM, atol=1e-9)
    np.testing.assert_allclose(np.array(g.leg_max) * 1e3, 1.8 * Q_MAX_MM, atol=1e-9)


def small_cosserat(tmp_path, kind: str, **options) -> str:
    data = yaml.safe_load((project_root() / "problems" / f"cbha-nn-{kind}-cosserat.yaml").read_text())
    data["data"]["samples"] = 80
    data["data"]["params"]["model_samples"] = 60_000
    data["options"] |= {"variants": ["seed"], "exact_samples": 3, "latency_repeats": 3, **options}
    data["name"] = f"small-{kind}-cosserat"
    path = tmp_path / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


@pytest.fixture(scope="module")
def fkm_cosserat(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fkmc")
    return solve(small_cosserat(folder, "fkm"), out=folder / "out")[0]


def test_cosserat_fkm_feeds_fig9_legs_and_scores_on_the_cosserat_tips(fkm_cosserat):
    a, rows = fkm_cosserat.arrays, {r.method: r.metrics for r in fkm_cosserat.comparison}
    assert set(rows) == {"mlp-seed-fig9", "newton-fig9", "constant-curvature", "direct-mlp"}
    spec, _ = load_problem("cbha-nn-fkm-cosserat")
    g = CBHAGeometry(**spec.arm.params["geometry"])
    f = (a["leg_lengths"].reshape(-1, 16, 3) - np.array(g.leg_min)[None, :, None]) / (
        np.array(g.leg_max) - np.array(g.leg_min)
    )[None, :, None]
    for s in (0, 1):  # every leg of a section at its tube's fraction: Fig. 6
        block = f[:, SECTION == s]
        np.testing.assert_allclose(block, np.broadcast_to(block[:, :1], block.shape), atol=1e-12)
    errors = np.linalg.norm(a["tip_seed-fig9"] - a["tip"], axis=1) * 1e3
    assert rows["mlp-seed-fig9"]["tip error median [mm]"] == pytest.approx(np.median(errors), rel=1e-12)
    np.testing.assert_allclose(a["tip_seed-fig9"], chain_tips(a["configurations_seed-fig9"]), atol=1e-14)
    assert rows["newton-fig9"]["samples"] == 3 and rows["direct-mlp"]["samples"] == len(a["tip"])
    assert np.all(np.linalg.norm(a["tip"], axis=1) > 0.3)  # the Cosserat arm's size, not the vertebra model's


@pytest.mark.slow
def test_cosserat_ikm_drives_the_lengths_on_the_arm(tmp_path):
    result, _ = solve(small_cosserat(tmp_path, "ikm", direct=False, goal_babbling=200), out=tmp_path / "out")
    rows = {r.method: r.metrics for r in result.comparison}
    assert set(rows) == {"mlp-seed", "ipopt", "constant-curvature", "goal-babbling", "true-lengths"}
    assert rows["true-lengths"]["tube length error RMS, median [mm]"] == 0.0
    errors = np.linalg.norm(result.arrays["tip_seed"] - result.arrays["targets"], axis=1) * 1e3
    assert rows["mlp-seed"]["tip error median [mm]"] == pytest.approx(np.median(errors), rel=1e-12)
    assert rows["ipopt"]["samples"] == 3


def arc_tube_lengths_and_tip(L, theta, phi, r):
    """Independent geometry of a bent section: the tubes at ``r u_m`` (u_1 at 180 deg, u_2 at 60, u_3 at -60)
    are concentric arcs about the bending axis, at ``1 / kappa - r cos(angle_m - phi)`` from it."""
    kappa = theta / L
    angles = np.radians([180.0, 60.0, -60.0])
    lengths = theta * (1 / kappa - r * np.cos(angles - phi))
    tip = np.array(
        [np.cos(phi) * (1 - np.cos(theta)) / kappa, np.sin(phi) * (1 - np.cos(theta)) / kappa, np.sin(theta) / kappa]
    )
    axis = np.array([-np.sin(phi), np.cos(phi), 0.0])
    return lengths, tip, Rotation.from_rotvec(theta * axis)


def test_constant_curvature_rows_invert_arcs_built_by_hand():
    radii = np.array([0.037, 0.032])
    (l1, p1, R1), (l2, p2, _) = (
        arc_tube_lengths_and_tip(0.2, 1.1, 0.4, radii[0]),
        arc_tube_lengths_and_tip(0.22, 0.7, -2.0, radii[1]),
    )
    tip = constant_curvature_tips(np.array([[l1, l2]]), radii)[0]
    np.testing.assert_allclose(tip, p1 + R1.apply(p2), atol=1e-12)
    lower, upper = np.array([0.12, 0.10]), np.array([0.27, 0.26])
    lengths = constant_curvature_lengths(np.array([p1 + R1.apply(p2)]), radii, lower, upper)[0]
    assert np.all(lengths >= lower[:, None] - 1e-12) and np.all(lengths <= upper[:, None] + 1e-12)
    reached = []
    for s in (0, 1):  # the lengths found, turned back into arcs by hand
        L = lengths[s].mean()
        k = 2 / (3 * radii[s] * L) * ((L - lengths[s]) @ np.array([[-1, 0], [0.5, 3**0.5 / 2], [0.5, -(3**0.5) / 2]]))
        reached.append(arc_tube_lengths_and_tip(L, np.linalg.norm(k) * L, np.arctan2(k[1], k[0]), radii[s]))
    np.testing.assert_allclose(reached[0][0], lengths[0], atol=1e-12)
    np.testing.assert_allclose(reached[0][1] + reached[0][2].apply(reached[1][1]), p1 + R1.apply(p2), atol=1e-6)


def test_goal_babbling_learns_to_reach_goals_of_a_linear_arm():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 6))  # x = A q: every goal in the span has a 3-parameter family of commands

    def arm(q):
        return A @ q

    goals = rng.uniform(0.5, 1.5, (200, 6)) @ A.T
    model = goal_babbling(arm, np.ones(6), goals, np.random.default_rng(1), steps=1000, noise=0.3)
    test = rng.uniform(0.6, 1.4, (50, 6)) @ A.T
    errors = np.linalg.norm(model.predict(test) @ A.T - test, axis=1)
    spread = np.linalg.norm(test - goals.mean(axis=0), axis=1)
    assert np.median(errors) < 0.02 * np.median(spread) and model.samples == 1000
