"""Saved networks come back identical, as plain arrays, and refuse to load for a problem they were not trained for."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import zipfile

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


def test_round_trip_gives_the_same_models_and_metadata(store, trained):
    db, models = trained
    loaded = load_models(store, CBHAGeometry(), SPEC, required())
    X = db.leg_lengths[db.test]
    for original, again in zip(models, loaded):
        cols = list(original.task.inputs[1])
        np.testing.assert_array_equal(again.predict(X[:, cols]), original.predict(X[:, cols]))
        assert (again.task, again.setting, again.penalty, again.neurons) == (
            original.task,
            original.setting,
            original.penalty,
            original.neurons,
        )
        assert (again.search, again.epochs, again.training_time) == (
            original.search,
            original.epochs,
            original.training_time,
        )
        for a, b in zip(
            again.network.coefs + again.network.intercepts, original.network.coefs + original.network.intercepts
        ):
            np.testing.assert_array_equal(a, b)
    meta = read_metadata(store)
    assert meta["versions"]["scikit-learn"] == sklearn.__version__
    assert meta["geometry"]["leg_max"] == pytest.approx(
        [v / 1000 for v in (19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5, 20.5, 19, 19, 18, 18, 16)]
    )
    assert meta["database"]["seed"] == 21 and meta["database"]["candidates"] == 40_000
    assert [m["test MSE"] for m in meta["models"]] == [split_mse(m, db, "test") for m in models]
    assert meta["database rows"]["test"] == len(db.test)


@pytest.mark.parametrize(
    "geometry, spec, field",
    [
        (CBHAGeometry(r_max=0.041), SPEC, "geometry.r_max"),
        (CBHAGeometry(leg_max=tuple(v / 1000 for v in (19.5,) * 8 + (16,) * 8)), SPEC, "geometry.leg_max"),
        (CBHAGeometry(), dataclasses.replace(SPEC, seed=22), "database.seed"),
        (CBHAGeometry(), dataclasses.replace(SPEC, coupling="section"), "database.coupling"),
    ],
)
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


def rewrite_weights(store, change):
    """Apply ``change`` to the arrays of ``weights.npz`` and record the new checksum (a consistent but wrong store)."""
    with np.load(store / "weights.npz") as weights:
        arrays = dict(weights)
    change(arrays)
    with open(store / "weights.npz", "wb") as fh:
        np.savez(fh, **arrays)
    meta = json.loads((store / "metadata.json").read_text())
    meta["sha256"] = hashlib.sha256((store / "weights.npz").read_bytes()).hexdigest()
    (store / "metadata.json").write_text(json.dumps(meta))


def test_store_holds_plain_arrays_only(store, trained):
    _, models = trained
    assert sorted(p.name for p in store.iterdir()) == ["metadata.json", "weights.npz"]
    with zipfile.ZipFile(store / "weights.npz") as archive:
        assert all(name.endswith(".npy") for name in archive.namelist())
    with np.load(store / "weights.npz", allow_pickle=False) as weights:
        arrays = {name: weights[name] for name in weights.files}  # would raise on an object (pickled) array
    assert all(a.dtype.kind in "fiU" for a in arrays.values())
    np.testing.assert_array_equal(arrays["fkm_section2.coef1"], models[1].network.coefs[1])
    assert str(arrays["fkm_section1.activation"]) == SETTING.activation


def test_store_loads_whatever_the_scikit_learn_version(store, trained):
    db, models = trained
    meta = json.loads((store / "metadata.json").read_text())
    meta["versions"]["scikit-learn"] = "0.24.2"
    (store / "metadata.json").write_text(json.dumps(meta))
    loaded = load_models(store, CBHAGeometry(), SPEC, required())
    X = db.leg_lengths[db.test, :24]
    np.testing.assert_array_equal(loaded[0].predict(X), models[0].predict(X))


def test_damaged_weights_old_format_or_no_store_is_refused(store, tmp_path):
    meta_path = store / "metadata.json"
    meta = json.loads(meta_path.read_text())
    (store / "weights.npz").write_bytes((store / "weights.npz").read_bytes() + b"\0")
    with pytest.raises(InputDataError, match="checksum") as err:
        load_models(store, CBHAGeometry(), SPEC, required())
    assert err.value.field == "sha256" and err.value.source == str(store)
    (store / "weights.npz").unlink()
    with pytest.raises(InputDataError, match="cannot read weights.npz") as err:
        load_models(store, CBHAGeometry(), SPEC, required())
    assert err.value.field == "weights.npz"
    meta["format_version"] = 1
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputDataError, match="format version 1") as err:
        load_models(store, CBHAGeometry(), SPEC, required())
    assert err.value.field == "format_version"
    with pytest.raises(InputDataError, match="not a model store"):
        load_models(tmp_path / "nothing", CBHAGeometry(), SPEC, required())


@pytest.mark.parametrize(
    "change, field, message",
    [
        (lambda a: a.pop("fkm_section1.coef1"), "models.fkm_section1.coef1", "no array"),
        (lambda a: a.update({"fkm_section1.x_scale": np.ones(3)}), "models.fkm_section1.x_scale", r"shape \(3,\)"),
        (lambda a: a.update({"fkm_section1.coef1": np.ones((5, 4))}), "models.fkm_section1.network", "do not chain"),
        (
            lambda a: a.update({"fkm_section1.activation": np.array("softsign")}),
            "models.fkm_section1.network",
            "activation",
        ),
        (
            lambda a: a.update({"fkm_section1.intercept0": np.array([print], dtype=object)}),
            "models.fkm_section1.intercept0",
            "allow_pickle",
        ),
    ],
)
def test_inconsistent_arrays_are_refused_naming_the_field(store, change, field, message):
    rewrite_weights(store, change)
    with pytest.raises(InputDataError, match=message) as err:
        load_models(store, CBHAGeometry(), SPEC, required())
    assert err.value.field == field and err.value.source == str(store)


def test_saving_again_replaces_the_store(store, trained):
    db, models = trained
    save_models(store, models[:1], db)
    assert [m["task"] for m in read_metadata(store)["models"]] == ["fkm_section1"]
    assert not list(store.parent.glob(".fkm*"))
