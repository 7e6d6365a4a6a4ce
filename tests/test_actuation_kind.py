"""Kind ``actuation``: the tendon-rod physics model against an arc it must give and the synthetic lab's own
equilibria, its fit on the lab's truth, and the learning curve of the physics model and the regressors on the
same folds."""

from __future__ import annotations

import numpy as np
import pytest

from optikin.calibration import actuation as physics
from optikin.simulate.tendon_lab import TendonLabParams, exit_pose, lab_recording

LAB = TendonLabParams()
EI = LAB.youngs_modulus * np.pi * LAB.backbone_radius**4 / 4
DENSITY = LAB.density * np.pi * LAB.backbone_radius**2
SMALL = [("options.postures", 60), ("options.fractions", [0.1, 1.0]), ("options.max_evaluations", 10)]


@pytest.fixture(scope="module")
def lab():
    """The lab's 729 postures (cached equilibria), as the shipped problem reads them."""
    return lab_recording(LAB, 729, np.random.default_rng([3, 0]))


def test_one_tendon_without_gravity_bends_a_section_into_the_arc_of_curvature_tau_r_over_EI():
    """Rucker & Webster's straight-routing result, written out: a circular arc, toward the tendon."""
    tension = np.array([[2.0, 0, 0, 0, 0, 0]])
    shapes = physics.solve_shapes(
        np.full((1, 3), EI), np.array([[0.1, 0.1, 0.1]]), tension, np.zeros((1, 3)), np.zeros(1), 0.012, 0.0, 16
    )
    kappa, L = 2.0 * 0.012 / EI, 0.1
    expected = np.array([(1 - np.cos(kappa * L)) / kappa, 0.0, np.sin(kappa * L) / kappa])  # tendon at angle 0: +x
    assert shapes.converged.all()
    assert np.linalg.norm(shapes.positions[0, 0] - expected) < 1e-6
    # sections 2 and 3 carry no tendon moment: straight along the first's end tangent
    t = shapes.rotations[0, 0][:, 2]
    assert np.linalg.norm(shapes.positions[0, 2] - (shapes.positions[0, 0] + 0.2 * t)) < 1e-9


def test_at_the_true_parameters_the_model_reproduces_the_labs_equilibria(lab):
    """The lab solves the full Cosserat statics by RK4 shooting with Rucker & Webster's tendon loads; the model
    (moments only, 8 midpoint steps per section) is another code. A few of the lab's postures sit on another
    equilibrium branch (the trunk folded up, reached by its continuation from a neighbouring posture)."""
    rng = np.random.default_rng(0)
    index = np.sort(rng.choice(len(lab.lab.tensions), 120, replace=False))
    p0, R0 = exit_pose(LAB)
    n = len(index)
    shapes = physics.solve_shapes(
        np.full((n, 3), EI),
        np.tile(LAB.section_lengths, (n, 1)),
        lab.lab.tensions[index],
        np.tile(R0.T @ physics.GRAVITY, (n, 1)),
        np.full(n, LAB.payload),
        LAB.tendon_offset,
        DENSITY,
        8,
    )
    params = physics.ActuationParams(
        np.full(3, EI), np.zeros(6), LAB.payload, np.array(LAB.section_lengths), R0, p0,
        np.array(LAB.marker_offsets), LAB.tendon_offset, DENSITY,
    )  # fmt: skip
    markers = physics.markers_of(params, shapes)
    error = np.linalg.norm(markers - lab.truth.clean_markers[index], axis=2).max(axis=1) * 1e3
    assert shapes.converged.all()
    assert np.median(error) < 0.5
    assert np.mean(error < 3.0) > 0.9


def test_the_fit_from_the_truths_neighbourhood_stays_near_it_and_predicts_held_out_postures(lab):
    """Inputs the lab's true tensions (no friction left to model), started from the true lengths (within 3 %),
    10 % off in stiffness and payload: the payload comes back within 10 %, the stiffness within 30 % (it trades
    with the lengths), the held-out markers within 1.5 mm (median; 0.3 mm noise, 15 mm marker offsets)."""
    rng = np.random.default_rng(1)
    order = rng.permutation(len(lab.lab.tensions))
    train, test = order[:40], order[40:100]
    measured = lab.marker_array(["disk1", "disk2", "disk3"])
    start = physics.start_params(np.array(LAB.section_lengths), 1.1 * EI, 0.9 * LAB.payload, LAB.tendon_offset, DENSITY)
    fitted = physics.fit(lab.lab.tensions[train], measured[train], start, (0.97, 1.03), 4, 30)
    assert np.all(np.abs(fitted.params.stiffness / EI - 1) < 0.3), fitted.params.stiffness
    assert fitted.params.payload == pytest.approx(LAB.payload, rel=0.1)
    predicted = physics.predict(fitted.params, lab.lab.tensions[test], 4)
    error = np.linalg.norm(predicted - measured[test], axis=2)
    seen = ~np.isnan(measured[test]).any(axis=2)
    assert not np.isnan(predicted).any()
    largest = np.where(seen, error, -np.inf).max(axis=1) * 1e3
    assert np.median(largest[seen.any(axis=1)]) < 1.5


@pytest.mark.slow
def test_the_learning_curve_on_the_same_folds(solved):
    """Every method is scored on every held-out posture, the regressors improve with data (an honest score, not
    a memorised one), and the verdict on physics against the best regressor is the arrays' own."""
    result = solved("trunk-lab-actuation", SMALL)
    fold, N = result.arrays["fold"], 60
    assert fold.shape == (N,) and set(fold) == {0, 1, 2, 3}
    training = result.arrays["training"]
    assert training.shape == (4, 2) and np.all(training[:, 0] < training[:, 1])
    assert np.all(training[:, 1] == np.bincount(fold, minlength=4).sum() - np.bincount(fold, minlength=4))
    medians = {}
    for name in ("physics", "knn", "mlp", "gp"):
        e = result.arrays[f"errors_{name}"]
        assert e.shape == (2, N) and not np.isnan(e).all(axis=0).any()
        medians[name] = np.median(e, axis=1)
    for name in ("knn", "mlp", "gp"):
        assert medians[name][1] < medians[name][0], name
    verdict = result.metrics["physics vs the best regressor"]
    for i, key in ((0, "smallest share (0.1)"), (1, "full share (1)")):
        best = min(("knn", "mlp", "gp"), key=lambda m: medians[m][i])
        assert verdict[key]["best regressor"] == best
        assert verdict[key]["physics beats it"] == bool(medians["physics"][i] < medians[best][i])
