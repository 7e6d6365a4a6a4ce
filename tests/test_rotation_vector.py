"""optikin.algebra.matrix_from_rotation_vector / rotation_vector_from_matrix against scipy's rotation vectors."""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from optikin.algebra import matrix_from_rotation_vector, rotation_vector_from_matrix

W = np.random.default_rng(3).uniform(-1.5, 1.5, (20, 3))
"""Rotation vectors of angles below pi."""


def test_numpy_and_casadi_give_scipys_matrices_and_the_vector_comes_back():
    expected = Rotation.from_rotvec(W).as_matrix()
    np.testing.assert_allclose(matrix_from_rotation_vector(W), expected, atol=1e-14)
    w = ca.SX.sym("w", 3)
    f = ca.Function("R", [w], [matrix_from_rotation_vector(w)])
    for i in range(len(W)):
        np.testing.assert_allclose(np.array(f(W[i])), expected[i], atol=1e-14)
        np.testing.assert_allclose(rotation_vector_from_matrix(expected[i]), W[i], atol=1e-12)


def test_the_zero_vector_is_the_identity_with_a_finite_derivative():
    np.testing.assert_array_equal(matrix_from_rotation_vector(np.zeros(3)), np.eye(3))
    w = ca.SX.sym("w", 3)
    J = ca.Function("J", [w], [ca.jacobian(ca.vec(matrix_from_rotation_vector(w)), w)])(np.zeros(3))
    assert np.all(np.isfinite(np.array(J)))
    np.testing.assert_allclose(rotation_vector_from_matrix(np.eye(3)), np.zeros(3), atol=0)
