"""Saved networks come back identical, and refuse to load for a problem they were not trained for."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import sklearn

from optikin.arms.cbha import CBHAGeometry
from optikin.baselines.nn_database import DatabaseSpec, build_database
from optikin.baselines.nn_models import SETTINGS, forward_tasks, split_mse, train_model
from optikin.baselines.nn_store import load_models, read_metadata, save_models
from optikin.errors import InputDataError

SPEC = DatabaseSpec(candidates=40_000, seed=21)
SETTING = dataclasses.replace(SETTINGS["adam"].small(), neurons=(4,), max_epochs=5)


@pytest.fixture(scope="module")
def trained():
    db = build_database(CBHAGeometry(), SPEC)
    return db, [train_model(task, db, SETTING) for task in forward_tasks(db)]


@pytest.fixture
def store(tmp_path, trained):
    db, models = trained
    return save_models(tmp_path / "fkm", models, db)


def required(setting=SETTING):
    return {"fkm_section1": (setting, 0.0), "fkm_section2": (setting, 0.0)}


def test_round_trip_gives_the_same_predictions_and_metadata(store, trained):
    db, models = trained
    loaded = load_models(store, CBHAGeometry(), SPEC, required())
    X = db.leg_lengths[db.test]
    for original, again in zip(models, loaded):
        cols = list(original.task.inputs[1])
        np.testing.assert_array_equal(again.predict(X[:, cols]), original.predict(X[:, cols]))
    meta = read_metadata(store)
    assert meta["versions"]["scikit-learn"] == sklearn.__version__
    assert meta["geometry"]["leg_max"] == pytest.approx([v / 1000 for v in
                                                         (19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5,
                                                          20.5, 19, 19, 18, 18, 16)])
    assert meta["database"]["seed"] == 21 and meta["database"]["candidates"] == 40_000
    assert [m["test MSE"] for m in meta["models"]] == [split_mse(m, db, "test") for m in models]
    assert meta["database rows"]["test"] == len(db.test)


@pytest.mark.parametrize("geometry, spec, field", [
    (CBHAGeometry(r_max=0.041), SPEC, "geometry.r_max"),
    (CBHAGeometry(leg_max=tuple(v / 1000 for v in (19.5,) * 8 + (16,) * 8)), SPEC, "geometry.leg_max"),
    (CBHAGeometry(), dataclasses.replace(SPEC, seed=22), "database.seed"),
    (CBHAGeometry(), dataclasses.replace(SPEC, coupling="section"), "database.coupling"),
])
def test_other_geometry_or_database_is_refused(store, geometry, spec, field):
    with pytest.raises(InputDataError) as err:
        load_models(store, geometry, spec, required())
    assert err.value.field == field and err.value.source == str(store)


def test_other_setting_penalty_or_missing_model_is_refused(store):
    longer = dataclasses.replace(SETTING, max_epochs=6)
    with pytest.raises(InputDataError, match="max_epochs") as err:
        load_models(store, CBHAGeometry(), SPEC, required(longer))
    assert err.value.field == "models.fkm_section1.setting.max_epochs"
    with pytest.raises(InputDataError) as err:
        load_models(store, CBHAGeometry(), SPEC, {"fkm_section1": (SETTING, 0.1)})
    assert err.value.field == "models.fkm_section1.penalty"
    with pytest.raises(InputDataError, match="no model 'ikm_nn1'"):
        load_models(store, CBHAGeometry(), SPEC, {"ikm_nn1": (SETTING, 0.0)})


def test_other_sklearn_version_damaged_pickle_or_no_store_is_refused(store, tmp_path):
    meta_path = store / "metadata.json"
    meta = json.loads(meta_path.read_text())
    (store / "models.pkl").write_bytes((store / "models.pkl").read_bytes() + b"\0")
    with pytest.raises(InputDataError) as err:
        load_models(store, CBHAGeometry(), SPEC, required())
    assert err.value.field == "sha256"
    meta["versions"]["scikit-learn"] = "0.24.2"
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputDataError, match="scikit-learn 0.24.2") as err:
        load_models(store, CBHAGeometry(), SPEC, required())
    assert err.value.field == "versions.scikit-learn"
    with pytest.raises(InputDataError, match="not a model store"):
        load_models(tmp_path / "nothing", CBHAGeometry(), SPEC, required())


def test_saving_again_replaces_the_store(store, trained):
    db, models = trained
    save_models(store, models[:1], db)
    assert [m["task"] for m in read_metadata(store)["models"]] == ["fkm_section1"]
    assert not list(store.parent.glob(".fkm*"))
