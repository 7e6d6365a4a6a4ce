"""Weight regression of `optikin.dmp.regression`: cvxpy against closed forms and independent solvers.

References: ``numpy.linalg.lstsq`` and the normal equations (unconstrained and
ridge), ``scipy.optimize.lsq_linear`` (bounded least squares, a different
algorithm), per-basis weighted least squares written out with lstsq (LWR), and
movement_primitives' own design matrix and ridge regression.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from movement_primitives.dmp._dmp import determine_forces, ridge_regression
from movement_primitives.dmp._forcing_term import ForcingTerm
from scipy.optimize import lsq_linear

from optikin.data.demonstrations import smooth_pose_demonstration
from optikin.dmp import DMP, Euclidean, UnitQuaternion
from optikin.dmp.regression import fit_cvxpy, fit_lstsq, fit_lwr


@pytest.fixture(scope="module")
def problem():
    demo = smooth_pose_demonstration(samples=400, duration=4.0, seed=8)
    return DMP(UnitQuaternion(), n_basis=15).regression_problem(demo.t, demo.quaternion)


def test_cvxpy_equals_the_closed_form_without_constraints(problem):
    closed = np.linalg.lstsq(problem.X, problem.F, rcond=None)[0].T
    fit = fit_cvxpy(problem.X, problem.F)
    assert fit.status == "optimal"
    np.testing.assert_allclose(fit.weights, closed, rtol=1e-5, atol=1e-6 * np.abs(closed).max())
    assert fit.residual == pytest.approx(fit_lstsq(problem.X, problem.F).residual, rel=1e-8)
    np.testing.assert_allclose(fit_lstsq(problem.X, problem.F).weights, closed, rtol=1e-12)


def test_ridge_fits_equal_the_normal_equations(problem):
    X, F, ridge = problem.X, problem.F, 0.05
    normal = np.linalg.solve(X.T @ X + ridge * np.eye(X.shape[1]), X.T @ F).T
    np.testing.assert_allclose(fit_lstsq(X, F, ridge).weights, normal, rtol=1e-9, atol=1e-9 * np.abs(normal).max())
    np.testing.assert_allclose(fit_cvxpy(X, F, ridge).weights, normal, rtol=1e-5, atol=1e-6 * np.abs(normal).max())


def test_bounded_fit_equals_scipy_lsq_linear(problem):
    X, F = problem.X, problem.F
    free = fit_lstsq(X, F).weights
    bound = 0.5 * np.abs(free).max()
    fit = fit_cvxpy(X, F, lower=-bound, upper=bound)
    assert np.all(np.abs(fit.weights) <= bound * (1 + 1e-7))
    assert np.any(np.abs(free) > bound)  # the bound is active
    for d in range(F.shape[1]):
        reference = lsq_linear(X, F[:, d], bounds=(-bound, bound), tol=1e-12, lsmr_tol="auto").x
        np.testing.assert_allclose(fit.weights[d], reference, atol=1e-5 * bound)
    assert fit.residual > fit_lstsq(X, F).residual


def test_lwr_is_a_separate_weighted_fit_per_basis(problem):
    fit = fit_lwr(problem.phase, problem.activations, problem.X, problem.F)
    for j in range(problem.activations.shape[1]):
        root = np.sqrt(problem.activations[:, j])
        w = np.linalg.lstsq((root * problem.phase)[:, None], root[:, None] * problem.F, rcond=None)[0][0]
        np.testing.assert_allclose(fit.weights[:, j], w, rtol=1e-10)
    assert fit.residual >= fit_lstsq(problem.X, problem.F).residual
    assert all(f.seconds > 0 for f in (fit, fit_lstsq(problem.X, problem.F)))


def test_regression_on_movement_primitives_targets_gives_its_weights():
    """movement_primitives' design matrix and target forces, fitted here, give the weights it computes itself."""
    demo = smooth_pose_demonstration(samples=300, duration=3.0, seed=4)
    zeta = -math.log(0.01)
    forcing = ForcingTerm(3, 12, demo.t[-1], 0.0, 0.8, zeta)
    X = forcing.design_matrix(demo.t).T
    F = determine_forces(demo.t, demo.position, np.full(3, 25.0), np.full(3, 6.25), zeta, False)[0]
    expected = ridge_regression(X.T, F, 0.0)
    np.testing.assert_allclose(fit_lstsq(X, F).weights, expected, rtol=1e-6, atol=1e-8 * np.abs(expected).max())
    # and optikin's design matrix along the same demonstration is movement_primitives'
    ours = DMP(Euclidean(3), n_basis=12).regression_problem(demo.t, demo.position)
    np.testing.assert_allclose(ours.X, X[:-1], rtol=1e-12, atol=1e-15)
