"""The Gauss-Newton step Function of large systems: size, and its values against numpy and scipy.

A system of more than ``SYMBOLIC_SOLVE_MAX`` unknowns is solved numerically when the step is
evaluated instead of by a QR expanded into the step's instructions (on the 48 x 48 CBHA system
that expansion, twice, was 532,682 instructions against 26,804 for the residual and Jacobian).
References: the step's formula in numpy (LAPACK solves, the Hessian by finite differences) and
``scipy.optimize.least_squares`` for whole solves.
"""

from __future__ import annotations

import shutil

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import least_squares

from optikin.arms.cbha import CBHAArm
from optikin.baselines.ph_comparators import newton_raphson_problem
from optikin.data.markers import configurations_from_fractions
from optikin.solvers import build_preset
from optikin.solvers.gauss_newton import LAMBDA_FLOOR, SYMBOLIC_SOLVE_MAX, step_function
from optikin.solvers.nonlinear import LeastSquaresProblem


def instructions(f: ca.Function) -> int:
    """Instructions of ``f`` and of every SX or MX Function it calls (a call is one instruction of its caller)."""
    inner = [g for g in f.find_functions() if g.class_name() in ("SXFunction", "MXFunction")]
    return f.n_instructions() + sum(g.n_instructions() for g in inner)


@pytest.fixture(scope="module")
def cbha():
    arm = CBHAArm()
    return arm, newton_raphson_problem(arm)


def cbha_postures(arm: CBHAArm, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Configurations ``(n + 4, 48)`` and their section ends: straight, every leg at its Table I minimum
    (``Z`` at its lower bound), at its maximum, tubes at opposite limits, then random."""
    rng = np.random.default_rng(seed)
    edge = np.array([np.full((2, 3), 0.5), np.zeros((2, 3)), np.ones((2, 3)), [[0.0, 1.0, 0.0], [1.0, 0.0, 1.0]]])
    X = configurations_from_fractions(arm, np.concatenate([edge, rng.uniform(0, 1, (n, 2, 3))]))
    return X, np.concatenate([pos for _, pos in arm.section_frames(X)], axis=-1)


def numpy_step(problem: LeastSquaresProblem, x, p, mu, second_order=False) -> tuple[np.ndarray, bool]:
    """The step of the ``gauss_newton`` module docstring, in numpy: ``x_new`` and whether a bound blocked
    a component of the first direction."""
    r, J = (np.asarray(v) for v in problem.residual_jacobian(x, p))
    r = r.ravel()
    n, m = problem.n, problem.m
    D = np.ones(n) if problem.weights is None else problem.weights**2
    g, rn = J.T @ r, np.linalg.norm(r)
    lam = mu * rn * rn + LAMBDA_FLOOR * np.sum(J * J / D) / m
    span = problem.upper - problem.lower
    lower_active, upper_active = x <= problem.lower + 1e-12 * span, x >= problem.upper - 1e-12 * span
    if second_order:
        h = 1e-6

        def gradient(z):
            rz, Jz = (np.asarray(v) for v in problem.residual_jacobian(z, p))
            return Jz.T @ rz.ravel()

        H = np.column_stack([(gradient(x + h * e) - gradient(x - h * e)) / (2 * h) for e in np.eye(n)])
        H = 0.5 * (H + H.T)
    else:
        H = J.T @ J

    def direction(free):
        if m < n and not second_order:
            mf = free / D
            return -mf * (J.T @ np.linalg.solve(J @ np.diag(mf) @ J.T + lam * np.eye(m), r))
        F = np.diag(free)
        return -free * np.linalg.solve(F @ H @ F + np.diag(1 - free) + lam * np.diag(D), free * g)

    first = direction(np.ones(n))
    blocked = (lower_active & (first < 0)) | (upper_active & (first > 0))
    return np.clip(x + direction(1.0 - blocked), problem.lower, problem.upper), bool(blocked.any())


def synthetic(n: int, m: int, seed: int) -> LeastSquaresProblem:
    """``r = A tanh(x) + B x^2 / 2 - p`` with random ``A``, ``B`` ``(m, n)``, bounds ``[-1, 1]``, random weights."""
    rng = np.random.default_rng(seed)
    A, B = rng.normal(size=(m, n)), 0.3 * rng.normal(size=(m, n))
    x, p = ca.SX.sym("x", n), ca.SX.sym("p", m)
    r = ca.mtimes(ca.DM(A), ca.tanh(x)) + ca.mtimes(ca.DM(B), x * x / 2) - p
    residual = ca.Function(f"synthetic_{n}_{m}", [x, p], [r], ["x", "p"], ["r"])
    return LeastSquaresProblem(
        residual, -np.ones(n), np.ones(n), np.zeros(n, dtype=bool), weights=rng.uniform(0.5, 2.0, n)
    )


def test_cbha_step_stays_near_the_size_of_residual_and_jacobian(cbha):
    """Fails on the expanded solve: 532,682 instructions, 20 times the residual and Jacobian."""
    _, problem = cbha
    residual_jacobian = problem.residual_jacobian.n_instructions()
    assert instructions(step_function(problem)) <= 1.3 * residual_jacobian
    x, p, r, J = problem.symbols
    with_hessian = ca.Function("rJH", [x, p], [r, J, ca.hessian(0.5 * ca.sumsqr(r), x)[0]]).n_instructions()
    assert instructions(step_function(problem, second_order=True)) <= 1.1 * with_hessian


def test_cbha_step_matches_numpy(cbha):
    """Random points, straight and at the Table I limits (``Z`` at its lower bound, so a bound blocks the
    step), targets of other postures, large and small damping."""
    arm, problem = cbha
    step = step_function(problem)
    X, E = cbha_postures(arm, 4, 0)
    n = problem.n
    blocked = 0
    targets = [E[(i + 1) % len(E)] for i in range(len(X))]
    targets[1] = E[1] - np.array([0, 0, 1e-3, 0, 0, 2e-3])  # shorter than the shortest: Z pushed below its bound
    for x, target in zip(X, targets):
        for mu in (10.0, 1e-8):
            expected, was_blocked = numpy_step(problem, x, target, mu)
            got = np.asarray(step(np.concatenate([x, target, [mu]]))).ravel()
            np.testing.assert_allclose(got[:n], expected, rtol=0, atol=1e-10)
            blocked += was_blocked
    assert blocked > 0  # the restricted second solve was exercised


@pytest.mark.parametrize("n, m, second_order", [(16, 25, False), (20, 14, False), (16, 25, True)])
def test_numeric_step_forms_match_numpy_and_compile(n, m, second_order):
    """The ``n x n`` form, the ``m x m`` form (fewer residuals than unknowns) and the Newton model, evaluated
    by CasADi's virtual machine and compiled to C, with points on the bounds."""
    from optikin.codegen import CompiledFunction

    problem = synthetic(n, m, seed=n + m)
    assert min(n, m) > SYMBOLIC_SOLVE_MAX
    step = step_function(problem, second_order)
    compiled = CompiledFunction(step)
    rng = np.random.default_rng(1)
    for k in range(4):
        x = rng.uniform(-0.9, 0.9, n)
        if k >= 2:
            x[: 2 * k] = np.sign(rng.normal(size=2 * k))  # on the bounds
        p = rng.normal(size=m)
        for mu in (1.0, 1e-6):
            expected, _ = numpy_step(problem, x, p, mu, second_order)
            packed = np.concatenate([x, p, [mu]])
            got = np.asarray(step(packed)).ravel()[:n]
            tol = 1e-6 if second_order else 1e-10  # the finite-difference Hessian
            np.testing.assert_allclose(got, expected, rtol=0, atol=tol * max(1.0, np.abs(expected).max()))
            np.testing.assert_allclose(compiled.raw(packed[None])[0, :n], got, rtol=0, atol=1e-13)


@pytest.mark.parametrize("preset", ["gauss-newton", "gauss-newton-compiled"])
def test_cbha_solves_match_scipy_least_squares(cbha, preset):
    """Whole solves from the straight configuration and from a nearby posture agree with scipy's MINPACK
    ``lm`` (given the same residual and Jacobian; unbounded: ``trf`` keeps strictly inside the bounds, so
    misses the roots on them by 6e-9) and with the posture itself, to 1e-10."""
    if preset == "gauss-newton-compiled":
        if shutil.which("gcc") is None:
            pytest.skip("no gcc")
    arm, problem = cbha
    solver = build_preset(preset)
    X, E = cbha_postures(arm, 3, 1)
    rest = arm.straight_configuration()
    for x_true, target in zip(X, E):
        for start in (rest, np.clip(x_true + 1e-3, problem.lower, problem.upper)):
            solution = solver.solve(problem, start, target)
            assert solution.status == "ok"
            reference = least_squares(
                lambda z: np.asarray(problem.residual(z, target)).ravel(),
                start,
                jac=lambda z: np.asarray(problem.residual_jacobian(z, target)[1]),
                method="lm",
                xtol=1e-15,
                ftol=1e-15,
                gtol=1e-15,
            )
            np.testing.assert_allclose(solution.x, reference.x, rtol=0, atol=1e-10)
            np.testing.assert_allclose(solution.x, x_true, rtol=0, atol=1e-10)
