"""``BufferedFunction``: the zero-copy caller against CasADi's ordinary ``f(x)`` call and a hand-written Newton."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from optikin.fastcall import BufferedFunction


def two_outputs() -> ca.Function:
    """A matrix input, a sparse (diagonal) output and a dense 2 x 3 one."""
    a, b = ca.SX.sym("a", 2, 3), ca.SX.sym("b", 2)
    return ca.Function("f", [a, b], [ca.diag(b) * 2.0, ca.sin(a) + ca.repmat(b, 1, 3)], ["a", "b"], ["d", "m"])


def test_call_with_arguments_matches_the_ordinary_call():
    f = two_outputs()
    fast = BufferedFunction(f)
    rng = np.random.default_rng(0)
    for _ in range(3):
        a, b = rng.normal(size=(2, 3)), rng.normal(size=2)
        d, m = fast(a, b)
        np.testing.assert_array_equal(d, np.asarray(ca.densify(f(a, b)[0])).ravel(order="F"))
        np.testing.assert_array_equal(fast.output_matrix(1), np.asarray(f(a, b)[1]))
        assert m is fast.outputs[1]  # the preallocated arrays, overwritten by the next call


def test_in_place_inputs_and_arguments_give_the_same_outputs():
    fast = BufferedFunction(two_outputs())
    a, b = np.arange(6.0).reshape(2, 3), np.array([0.5, -1.0])
    expected = [o.copy() for o in fast(a, b)]
    fast.inputs[0][:] = 0.0
    fast.inputs[0][:] = a.ravel(order="F")
    fast.inputs[1][:] = b
    assert fast() is fast.outputs
    for got, want in zip(fast.outputs, expected):
        np.testing.assert_array_equal(got, want)


def test_arguments_not_given_keep_their_values_and_too_many_are_refused():
    fast = BufferedFunction(two_outputs())
    a = np.ones((2, 3))
    first = fast(a, np.array([1.0, 2.0]))[1].copy()
    np.testing.assert_array_equal(fast(a)[1], first)
    with pytest.raises(TypeError):
        fast(a, np.zeros(2), np.zeros(1))


def test_compiled_function_agrees_with_the_virtual_machine():
    f = two_outputs()
    a, b = np.linspace(-1.0, 1.0, 6).reshape(2, 3), np.array([0.3, 0.7])
    vm, compiled = BufferedFunction(f)(a, b), BufferedFunction(f, compiled=True)(a, b)
    for x, y in zip(vm, compiled):
        np.testing.assert_allclose(x, y, rtol=1e-15, atol=1e-15)


def test_solver_statistics_are_those_of_the_last_buffered_call():
    """Newton on ``x^2 - c = 0`` from 1: the root sqrt(c), and the iteration count the ordinary call reports
    for the same inputs (c = 1 starts at the root: one evaluation; c = 10 needs several)."""
    x, c = ca.SX.sym("x"), ca.SX.sym("c")
    g = ca.Function("g", [x, c], [x * x - c])
    solver = ca.rootfinder("sqrt", "newton", g, {"abstol": 1e-14, "max_iter": 50})
    fast = BufferedFunction(solver)
    counts = []
    for value in (10.0, 1.0, 2.0):
        root = fast(1.0, value)[0][0]
        assert root == pytest.approx(np.sqrt(value), rel=1e-15)
        buffered = fast.stats()["iter_count"]
        solver(1.0, value)
        assert buffered == solver.stats()["iter_count"]
        counts.append(buffered)
    assert counts[1] == 1 and counts[0] > 3


def test_a_single_sparse_output_is_densified():
    x = ca.SX.sym("x", 3)
    f = ca.Function("diag_only", [x], [ca.diag(x) * 3.0])
    fast = BufferedFunction(f)
    (d,) = fast(np.array([1.0, 2.0, 4.0]))
    np.testing.assert_array_equal(d.reshape(3, 3, order="F"), np.diag([3.0, 6.0, 12.0]))


def test_an_arm_jacobian_with_one_sparse_output_matches_finite_differences():
    from optikin.arms.constant_curvature import ConstantCurvatureArm

    arm = ConstantCurvatureArm()
    q = 0.5 * (arm.lower + arm.upper) + 0.1
    fast = BufferedFunction(arm.jac_dq)
    fast(q)
    J = fast.output_matrix(0)
    h = 1e-6
    fd = np.column_stack(
        [
            (np.asarray(arm.fk_dq.unchecked(q + h * e)).ravel() - np.asarray(arm.fk_dq.unchecked(q - h * e)).ravel())
            / (2 * h)
            for e in np.eye(arm.n_config)
        ]
    )
    np.testing.assert_allclose(J, fd, atol=1e-8)
