"""The hybrid comparator of seed 002 Table III: shipped networks, legs summed per tube, refused stores.

References: the legs of eqs. (7)-(9) printed in seed 004 (``printed_leg_lengths``, numpy)
summed by hand per tube; the arm's own ``tube_lengths`` Function (section by section); the
exact forward kinematics for the predicted configurations; the database settings read from
``problems/cbha-nn-ikm.yaml``.
"""

from __future__ import annotations

from dataclasses import replace

import shutil

import numpy as np
import pytest

from optikin.arms.cbha import CBHAArm, CBHAGeometry, printed_leg_lengths
from optikin.baselines.nn_database import DatabaseSpec
from optikin.baselines.nn_models import SETTINGS, hybrid_inverse_configurations
from optikin.baselines.nn_store import read_metadata
from optikin.errors import InputDataError
from optikin.problems.nn_shared import database_spec
from optikin.baselines.hybrid_tubes import SHIPPED_STORE, SHIPPED_STORES, hybrid_tube_lengths, load_hybrid_models
from optikin.runner import prepare


@pytest.fixture(scope="module")
def arm():
    return CBHAArm()


@pytest.fixture(scope="module")
def models(arm):
    return load_hybrid_models(arm)


@pytest.fixture(scope="module")
def tips(arm):
    """Tips of admissible arms drawn as the learning database draws them (Fig. 7)."""
    return arm.evaluate("fk_position", arm.sample_configurations(40, np.random.default_rng(5)))


@pytest.mark.parametrize("problem", sorted(SHIPPED_STORES))
def test_shipped_stores_hold_the_models_of_their_problem(arm, problem):
    models = load_hybrid_models(arm, SHIPPED_STORES[problem])
    assert [m.task.key for m in models] == ["ikm_nn1", "ikm_nn2", "ikm_nn3", "ikm_nn4"]
    meta = read_metadata(SHIPPED_STORES[problem])
    assert CBHAGeometry(**meta["geometry"]) == CBHAGeometry()
    _, ctx = prepare(problem)
    assert DatabaseSpec(**meta["database"]) == database_spec(ctx)
    for model in models:
        assert model.setting == SETTINGS["adam"] and model.penalty == ctx.options.penalty


def test_shipped_networks_reach_the_tips_they_are_given(arm, models, tips):
    """Exact FK of the predicted configurations lands near the asked tips (BENCHMARKS: 1.5 mm median)."""
    reached = arm.evaluate("fk_position", hybrid_inverse_configurations(models, tips))
    assert np.median(np.linalg.norm(reached - tips, axis=1)) < 4e-3


def test_hybrid_lengths_are_the_printed_legs_summed_per_tube(arm, models, tips):
    lengths, seconds = hybrid_tube_lengths(arm, tips, models)
    Q = hybrid_inverse_configurations(models, tips).reshape(len(tips), 16, 3)
    r = CBHAGeometry().radii
    legs = np.stack([np.stack(printed_leg_lengths(*Q[:, k].T, r[k], r[k + 1]), -1) for k in range(16)], 1)
    np.testing.assert_allclose(lengths, legs.sum(axis=1), rtol=1e-12, atol=1e-14)
    by_section = np.stack([np.asarray(arm.tube_lengths(q.ravel())) for q in Q])  # (N, section, tube)
    np.testing.assert_allclose(lengths, by_section.sum(axis=1), rtol=1e-12, atol=1e-14)
    assert seconds.shape == (len(tips),) and np.all(seconds > 0)


def test_a_given_section_1_end_replaces_nn1(arm, models):
    Q_true = arm.sample_configurations(10, np.random.default_rng(6))
    tips = arm.evaluate("fk_position", Q_true)
    ends = arm.evaluate("vertebra_positions", Q_true)[:, :, 8]  # vertebra 9 ends section 1
    lengths, _ = hybrid_tube_lengths(arm, tips, models, ends)
    Q = hybrid_inverse_configurations(models[1:], tips, ends)
    by_section = np.stack([np.asarray(arm.tube_lengths(q)) for q in Q])  # (N, section, tube)
    np.testing.assert_allclose(lengths, by_section.sum(axis=1), rtol=1e-12, atol=1e-14)
    assert not np.allclose(lengths, hybrid_tube_lengths(arm, tips, models)[0], rtol=0, atol=1e-6)


def test_store_for_another_geometry_or_no_store_is_refused(tmp_path):
    with pytest.raises(InputDataError, match="trained with 0.04") as err:
        load_hybrid_models(CBHAArm(CBHAGeometry(r_max=0.042)))
    assert err.value.field == "geometry.r_max" and err.value.source == str(SHIPPED_STORE)
    with pytest.raises(InputDataError) as err:
        load_hybrid_models(CBHAArm(CBHAGeometry(tool_offset=0.05)))
    assert err.value.field == "geometry.tool_offset"
    with pytest.raises(InputDataError, match="not a model store") as err:
        load_hybrid_models(CBHAArm(), tmp_path / "missing")
    assert err.value.source == str(tmp_path / "missing")
    copy = shutil.copytree(SHIPPED_STORE, tmp_path / "store")
    with pytest.raises(InputDataError) as err:
        load_hybrid_models(CBHAArm(), copy, penalty=0.0)
    assert err.value.field == "models.ikm_nn1.penalty" and err.value.source == str(copy)


@pytest.mark.parametrize(
    "tips, ends, source, field",
    [
        (np.zeros((2, 2)), None, "tip positions", ""),
        (np.array([[0.0, np.nan, 0.3]]), None, "tip positions", "y"),
        (np.zeros((2, 3)), np.zeros((1, 3)), "section 1 ends", ""),
        (np.zeros((1, 3)), np.array([[np.inf, 0.0, 0.1]]), "section 1 ends", "x"),
    ],
)
def test_bad_positions_are_refused(arm, models, tips, ends, source, field):
    with pytest.raises(InputDataError) as err:
        hybrid_tube_lengths(arm, tips, models, ends)
    assert err.value.field == field and err.value.source == source


def test_implausible_predictions_still_give_the_networks_own_lengths(arm, models, tips):
    """NN2 (every Z_k) shifted by -20 mm predicts negative lengths: a checked arm Function refuses them, the
    hybrid row reports the networks' own tube lengths (scored, not refused)."""
    shifted = [replace(m, y_offset=m.y_offset - 0.02) if m.task.key == "ikm_nn2" else m for m in models]
    Q = hybrid_inverse_configurations(shifted, tips)
    assert np.min(Q[:, 0::3]) < 0
    with pytest.raises(ValueError, match="not positive"):
        arm.evaluate("leg_lengths", Q)
    lengths, _ = hybrid_tube_lengths(arm, tips, shifted)
    assert np.all(np.isfinite(lengths))
    np.testing.assert_allclose(lengths, arm.evaluate("leg_lengths", Q, check=False).reshape(-1, 16, 3).sum(axis=1))
