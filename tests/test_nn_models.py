"""Networks of seed 004 sections IV-V: scores from the test split only, the width search, eq. (11).

References: MSEs recomputed here from the database arrays with columns picked by hand;
scikit-learn's own ``MLPRegressor.predict`` on the networks before their weights are copied;
a database whose training and validation rows are poisoned with NaN (any score that
touched them would be NaN); the minimiser of eq. (11), ``X_d / (1 + lambda)``.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import sklearn.neural_network
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor

from optikin.arms.cbha import CBHAGeometry
from optikin.baselines.nn_database import DatabaseSpec, build_database
from optikin.baselines.nn_models import (
    SETTINGS,
    Network,
    forward_pass,
    forward_tasks,
    hybrid_forward_configurations,
    hybrid_inverse_configurations,
    inverse_tasks,
    split_mse,
    train_model,
)

SMALL = SETTINGS["adam"].small()


@pytest.fixture(scope="module")
def db():
    return build_database(CBHAGeometry(), DatabaseSpec(candidates=40_000, seed=11))


@pytest.fixture(scope="module")
def forward(db):
    return [train_model(task, db, SMALL) for task in forward_tasks(db)]


def poisoned(db):
    """A copy of ``db`` whose training and validation rows hold NaN targets and absurd inputs.

    (scikit-learn refuses NaN inputs, so inputs get 1 km instead: any score that read them would change.)
    """
    bad = np.concatenate([db.train, db.validation])
    configurations, legs, ends = db.configurations.copy(), db.leg_lengths.copy(), db.section_ends.copy()
    configurations[bad] = np.nan
    legs[bad] = 1e3
    ends[bad] = np.nan
    return dataclasses.replace(db, configurations=configurations, leg_lengths=legs, section_ends=ends)


def test_reported_mse_is_the_test_split_mse(db, forward):
    section1, section2 = forward
    t = db.test
    by_hand = np.mean((section1.predict(db.leg_lengths[t, :24]) - db.configurations[t, :24]) ** 2)
    assert split_mse(section1, db) == pytest.approx(by_hand, rel=1e-12)
    by_hand = np.mean((section2.predict(db.leg_lengths[t, 24:]) - db.configurations[t, 24:]) ** 2)
    assert split_mse(section2, db) == pytest.approx(by_hand, rel=1e-12)


def test_reported_mse_never_reads_training_or_validation_rows(db, forward):
    dirty = poisoned(db)
    for model in forward:
        clean = split_mse(model, db, "test")
        assert np.isfinite(split_mse(model, dirty, "test")) and split_mse(model, dirty, "test") == clean
        assert np.isnan(split_mse(model, dirty, "train"))  # the poison is where it should be
        assert split_mse(model, db, "train") != clean


def test_width_search_keeps_the_best_validation_width(db, forward):
    for model in forward:
        assert sorted(model.search) == list(SMALL.neurons)
        assert model.neurons == min(model.search, key=model.search.get)
        assert model.network.hidden_layer_sizes == (model.neurons, model.neurons)
        X = db.leg_lengths[db.validation][:, list(model.task.inputs[1])]
        Y = db.configurations[db.validation][:, list(model.task.outputs[1])]
        assert np.mean((model.predict(X) - Y) ** 2) == pytest.approx(model.search[model.neurons], rel=1e-9)


def test_predict_is_scikit_learns_predict_on_the_trained_network(db, monkeypatch):
    """The kept weights give what the trained ``MLPRegressor`` itself predicts, and nothing holds it any more."""
    trained = []

    class Recorded(MLPRegressor):
        def partial_fit(self, X, y):
            if not trained or trained[-1] is not self:
                trained.append(self)
            return super().partial_fit(X, y)

    monkeypatch.setattr(sklearn.neural_network, "MLPRegressor", Recorded)  # train_model imports it when it runs
    model = train_model(forward_tasks(db)[1], db, dataclasses.replace(SMALL, max_epochs=6))
    (network,) = [n for n in trained if n.hidden_layer_sizes == (model.neurons, model.neurons)]
    X = db.leg_lengths[db.test][:, list(model.task.inputs[1])]
    by_sklearn = network.predict((X - model.x_offset) / model.x_scale) * model.y_scale + model.y_offset
    np.testing.assert_allclose(model.predict(X), by_sklearn, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(model.predict(X[0]), by_sklearn[:1], rtol=1e-12, atol=1e-15)
    assert not any(isinstance(v, MLPRegressor) for v in vars(model).values())
    network.coefs_[0][:] = 0.0  # the model holds copies
    np.testing.assert_allclose(model.predict(X), by_sklearn, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("activation", ["tanh", "logistic", "relu", "identity"])
def test_forward_pass_of_the_converted_weights_is_scikit_learns_predict(activation):
    rng = np.random.default_rng(3)
    X, Y = rng.normal(size=(200, 5)), rng.normal(size=(200, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        mlp = MLPRegressor(hidden_layer_sizes=(7, 3), activation=activation, max_iter=20, random_state=0).fit(X, Y)
    network = Network.from_sklearn(mlp)
    assert network.hidden_layer_sizes == (7, 3) and network.activation == activation
    np.testing.assert_allclose(forward_pass(network, X), mlp.predict(X), rtol=1e-12, atol=1e-14)


def test_network_refuses_layers_that_do_not_chain():
    W, b = np.ones((3, 4)), np.ones(4)
    with pytest.raises(ValueError, match="layer 1"):
        Network((W, np.ones((5, 2))), (b, np.ones(2)), "tanh")
    with pytest.raises(ValueError, match="activation"):
        Network((W,), (b,), "softsign")
    with pytest.raises(ValueError, match="bias"):
        Network((W,), (np.ones(3),), "tanh")


def test_training_is_reproducible(db, forward):
    again = train_model(forward_tasks(db)[0], db, SMALL)
    X = db.leg_lengths[db.test, :24]
    np.testing.assert_array_equal(again.predict(X), forward[0].predict(X))


def test_hybrid_forward_fills_every_platform_from_its_section(db, forward):
    Q = hybrid_forward_configurations(forward, db.leg_lengths[db.test])
    np.testing.assert_allclose(Q[:, :24], forward[0].predict(db.leg_lengths[db.test, :24]), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(Q[:, 24:], forward[1].predict(db.leg_lengths[db.test, 24:]), rtol=1e-12, atol=1e-15)


def test_penalty_of_eq11_shrinks_predictions_to_its_minimiser(db):
    """Eq. (11) is minimised by X = X_d / (1 + lambda): with lambda = 1 the Z_k network predicts half."""
    nn2 = next(t for t in inverse_tasks(db) if t.key == "ikm_nn2")
    setting = dataclasses.replace(SMALL, neurons=(8,), max_epochs=60, patience=10)
    plain, penalised = train_model(nn2, db, setting, 0.0), train_model(nn2, db, setting, 1.0)
    ends = np.concatenate([db.tip, db.section_ends[:, 0]], axis=1)[db.test]
    Z = db.configurations[db.test][:, 0::3]
    assert plain.predict(ends).mean() == pytest.approx(Z.mean(), rel=0.05)
    assert penalised.predict(ends).mean() == pytest.approx(Z.mean() / 2, rel=0.05)
    with pytest.raises(ValueError, match="inverse models only"):
        train_model(forward_tasks(db)[0], db, setting, 0.5)


def test_hybrid_inverse_routes_nn1_into_nn2_to_nn4(db):
    setting = dataclasses.replace(SMALL, neurons=(4,), max_epochs=3)
    models = [train_model(t, db, setting) for t in inverse_tasks(db)]
    tip = db.tip[db.test]
    ends = np.concatenate([tip, models[0].predict(tip)], axis=1)
    Q = hybrid_inverse_configurations(models, tip)
    for i in range(3):
        np.testing.assert_allclose(Q[:, i::3], models[i + 1].predict(ends), rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="ikm_nn4"):
        hybrid_inverse_configurations(models[:3], tip)
    end1 = db.section_ends[db.test, 0]  # the true end of section 1 replaces NN1, which is then not needed
    given = hybrid_inverse_configurations(models[1:], tip, end1)
    for i in range(3):
        np.testing.assert_allclose(
            given[:, i::3], models[i + 1].predict(np.concatenate([tip, end1], axis=1)), rtol=1e-12, atol=1e-15
        )
    with pytest.raises(ValueError, match="ikm_nn1"):
        hybrid_inverse_configurations(models[1:], tip)
