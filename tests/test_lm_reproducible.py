"""Backend ``lm`` gives bit-identical answers whatever the process did before.

scipy's MINPACK ``qrfac`` reads one double past the end of the Jacobian buffer that ``_lmder``
allocates when it recomputes the norm of the last column after cancellation, which every
rank-deficient Jacobian (a redundant problem padded with zero rows) triggers. The tests put chosen
values in the heap where that buffer is allocated and compare the answers bit for bit.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import _minpack

from optikin.solvers import load_backends, preset_of
from optikin.solvers.nonlinear import LeastSquaresProblem
from optikin.spec import SolverSpec

load_backends()
POISONS = (0.0, 1.0, 1e300)
A = np.random.default_rng(7).standard_normal((3, 6))


def redundant_problem() -> LeastSquaresProblem:
    """``A sin(x) = p``: 3 residuals, 6 bounded variables (a redundant problem, rank-deficient padded Jacobian)."""
    x, p = ca.SX.sym("x", 6), ca.SX.sym("p", 3)
    return LeastSquaresProblem(
        ca.Function("sines", [x, p], [ca.mtimes(ca.DM(A), ca.sin(x)) - p]),
        np.full(6, -1.2),
        np.full(6, 1.2),
        np.zeros(6, dtype=bool),
        tolerance=1e-10,
        name="sines",
    )


def lm_adapter(**options):
    limits = {"max_iterations": 200, "time_limit": 5.0, "tolerance": 1e-10}
    return preset_of(SolverSpec(name="test-lm", backend="lm", options=options, limits=limits)).build()


def poison_heap(value: float, doubles: int, keep: list) -> None:
    """Make the next ``doubles``-double numpy buffers come from heap chunks whose slack holds ``value``.

    numpy's cache of buffers of that size is drained (the buffers are kept in ``keep``), then buffers one
    double longer (the same malloc chunk size) filled with ``value`` are freed.
    """
    keep.extend(np.empty(doubles) for _ in range(16))
    junk = [np.full(doubles + 1, value) for _ in range(64)]
    del junk


def solve_poisoned(monkeypatch, adapter, problem, X0, P, value):
    """``adapter.solve_many`` with the heap poisoned by ``value`` as each ``_lmder`` call allocates its Jacobian."""
    real = _minpack._lmder

    def lmder(fun, *args):
        keep: list = []
        first = [True]

        def poisoned(x):
            f = fun(x)
            if first[0]:  # the Jacobian buffer is allocated right after this first call returns
                first[0] = False
                poison_heap(value, np.size(f) * np.size(x), keep)
            return f

        return real(poisoned, *args)

    with monkeypatch.context() as patch:
        patch.setattr(_minpack, "_lmder", lmder)
        return adapter.solve_many(problem, X0, P)


@pytest.mark.parametrize("options", [{}, {"x_scale": "jac"}])
def test_lm_answers_do_not_depend_on_the_heap(monkeypatch, options):
    problem = redundant_problem()
    adapter = lm_adapter(**options)
    rng = np.random.default_rng(3)
    N = 24
    X0 = rng.uniform(-1.0, 1.0, (N, 6))
    P = np.sin(rng.uniform(-1.0, 1.0, (N, 6))) @ A.T  # reachable targets
    batches = [solve_poisoned(monkeypatch, adapter, problem, X0, P, value) for value in POISONS]
    for batch in batches:  # the answers are answers: A sin(x) = p (independent of the solver)
        residual = np.sin(batch.x) @ A.T - P
        solved = np.array(batch.status) == "ok"
        assert solved.sum() >= N - 2
        assert np.abs(residual[solved]).max() < 1e-9
    for value, batch in zip(POISONS[1:], batches[1:]):
        differ = np.flatnonzero(np.any(batch.x != batches[0].x, axis=1))
        assert differ.size == 0, f"heap value {value:g} changed samples {differ.tolist()}"
        np.testing.assert_array_equal(batch.iterations, batches[0].iterations)
