"""The ``nonlinear`` backends on small problems with closed-form answers, their limits and their preset errors."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from optikin.errors import SpecError
from optikin.solvers import load_backends, preset_of
from optikin.solvers.nonlinear import LeastSquaresProblem
from optikin.spec import SolverSpec

load_backends()
BACKEND_NAMES = ("gauss_newton", "newton", "ipopt", "sqpmethod", "lm", "trf")


def adapter(backend: str, options: dict | None = None, **limits):
    limits = {"max_iterations": 100, "time_limit": 5.0, "tolerance": 1e-13} | limits
    preset = SolverSpec(name=f"test-{backend.replace('_', '-')}", backend=backend, options=options or {}, limits=limits)
    return preset_of(preset).build()


def circle_line() -> LeastSquaresProblem:
    """``x0^2 + x1^2 = p0^2`` and ``x1 = p1 x0``, ``x0 >= 0``: ``x0 = p0 / sqrt(1 + p1^2)``."""
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p", 2)
    r = ca.vertcat(x[0] ** 2 + x[1] ** 2 - p[0] ** 2, x[1] - p[1] * x[0])
    return LeastSquaresProblem(
        ca.Function("circle_line", [x, p], [r]),
        np.array([0.0, -10.0]),
        np.array([10.0, 10.0]),
        np.array([False, False]),
        tolerance=1e-11,
        name="circle_line",
    )


def plane(weights) -> LeastSquaresProblem:
    """One residual ``x0 + x1 + x2 - p`` for three variables: a redundant problem."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 1)
    return LeastSquaresProblem(
        ca.Function("plane", [x, p], [ca.sum1(x) - p]),
        np.full(3, -10.0),
        np.full(3, 10.0),
        np.zeros(3, dtype=bool),
        tolerance=1e-11,
        weights=weights,
        name="plane",
    )


@pytest.mark.parametrize("backend", BACKEND_NAMES)
def test_square_system_matches_closed_form(backend):
    problem = circle_line()
    solver = adapter(backend)
    for p in ([1.0, 0.5], [2.0, -1.5], [0.3, 4.0]):
        report = solver.solve(problem, np.array([1.0, 0.0]), np.array(p))
        expected_x0 = p[0] / np.hypot(1.0, p[1])
        assert report.status == "ok", (backend, p, report)
        np.testing.assert_allclose(report.x, [expected_x0, p[1] * expected_x0], atol=1e-9)
        assert report.residual <= 1e-11 and report.iterations >= 1 and report.seconds > 0


@pytest.mark.parametrize("backend", ("gauss_newton", "newton", "ipopt", "sqpmethod"))
def test_redundant_solution_is_the_weighted_closest_point(backend):
    """Closest point of the plane ``sum x = p`` to ``x_ref`` in ``||W (x - x_ref)||``, in closed form:
    ``x = x_ref + W^-2 1 (p - sum x_ref) / sum W^-2``. Exact minimisers reach it from any start;
    Gauss-Newton's weighted minimum-norm step reaches it when started at ``x_ref``."""
    weights = np.array([1.0, 2.0, 4.0])
    problem = plane(weights)
    x_ref, p = np.array([0.5, -1.0, 2.0]), np.array([3.0])
    m_inv = 1.0 / weights**2
    expected = x_ref + m_inv * (p[0] - x_ref.sum()) / m_inv.sum()
    start = x_ref if backend == "gauss_newton" else np.array([1.0, 1.0, 1.0])
    report = adapter(backend).solve(problem, start, p, x_ref)
    assert report.status == "ok"
    np.testing.assert_allclose(report.x, expected, atol=1e-9)


@pytest.mark.parametrize("backend", BACKEND_NAMES)
def test_penalised_problem_reaches_the_closed_form_minimiser(backend):
    """``min 1/2 (sum x - p)^2 + lam/2 ||W (x - x_ref)||^2`` (seed 004 eq. (11) on a plane), not exact:
    setting the gradient to zero gives ``x = x_ref + W^-2 (p - sum x_ref) / (lam + sum W^-2)``."""
    weights, x_ref, lam, p = np.array([1.0, 2.0, 4.0]), np.array([0.5, -1.0, 2.0]), 0.3, 3.0
    x = ca.SX.sym("x", 3)
    rows = ca.vertcat(ca.sum1(x) - p, np.sqrt(lam) * weights * (x - x_ref))
    problem = LeastSquaresProblem(
        ca.Function("penalised_plane", [x, ca.SX.sym("p", 0)], [rows]),
        [-10.0] * 3,
        [10.0] * 3,
        [False] * 3,
        tolerance=1e-11,
        weights=weights,
        stationarity_tolerance=1e-10,
        exact=False,
        name="penalised_plane",
    )
    m_inv = 1.0 / weights**2
    expected = x_ref + m_inv * (p - x_ref.sum()) / (lam + m_inv.sum())
    report = adapter(backend).solve(problem, np.array([1.0, 1.0, 1.0]), np.zeros(0))
    assert report.status == "ok", (backend, report)
    np.testing.assert_allclose(report.x, expected, atol=1e-9)
    assert report.residual > 0.1  # the minimum is not a root: an exact problem would call it unreachable


@pytest.mark.parametrize("backend", ("lm", "trf"))
def test_least_squares_backends_solve_the_redundant_problem(backend):
    report = adapter(backend).solve(plane(np.ones(3)), np.zeros(3), np.array([3.0]))
    assert report.status == "ok" and abs(report.x.sum() - 3.0) < 1e-11


def test_periodic_variable_wraps_across_the_boundary():
    """``(cos x, sin x) = (cos a, sin a)`` with ``x`` an angle in [-pi, pi): from 3.0 to a = -3.0 across pi."""
    x, p = ca.SX.sym("x", 1), ca.SX.sym("p", 1)
    f = ca.Function("angle", [x, p], [ca.vertcat(ca.cos(x) - ca.cos(p), ca.sin(x) - ca.sin(p))])
    problem = LeastSquaresProblem(f, [-np.pi], [np.pi], [True], tolerance=1e-11)
    for backend in ("gauss_newton", "lm", "trf"):
        report = adapter(backend).solve(problem, np.array([3.0]), np.array([-3.0]))
        assert report.status == "ok"
        np.testing.assert_allclose(report.x, [-3.0], atol=1e-9)


def test_target_beyond_the_bounds_is_unreachable_at_the_bound():
    """``x0 = p`` with ``x0`` in [0, 1] and ``p = 2``: the closest reachable point is the bound, residual 1."""
    x, p = ca.SX.sym("x", 1), ca.SX.sym("p", 1)
    problem = LeastSquaresProblem(ca.Function("line", [x, p], [x - p]), [0.0], [1.0], [False])
    for backend in BACKEND_NAMES:
        report = adapter(backend).solve(problem, np.array([0.5]), np.array([2.0]))
        assert report.status != "ok", backend
        assert 0.0 <= report.x[0] <= 1.0 or report.status == "failed", backend
        if backend in ("gauss_newton", "trf"):
            assert report.status == "unreachable"
            np.testing.assert_allclose([report.x[0], report.residual], [1.0, 1.0], atol=1e-9)


@pytest.mark.parametrize("backend", BACKEND_NAMES)
def test_iteration_limit_is_respected_and_reported(backend):
    report = adapter(backend, max_iterations=2).solve(circle_line(), np.array([9.0, 4.5]), np.array([1.0, 0.5]))
    assert report.status == "not_converged"
    assert report.iterations <= 2
    assert np.isfinite(report.residual) and report.residual > 1e-3


@pytest.mark.parametrize("backend", ("gauss_newton", "lm", "trf", "ipopt"))
def test_time_limit_stops_the_solve(backend):
    report = adapter(backend, time_limit=1e-9).solve(circle_line(), np.array([9.0, -9.0]), np.array([1.0, 0.5]))
    assert report.status == "timeout"


def test_batched_gauss_newton_agrees_with_single_solves():
    problem = circle_line()
    rng = np.random.default_rng(0)
    P = np.column_stack([rng.uniform(0.5, 3.0, 50), rng.uniform(-3.0, 3.0, 50)])
    starts = rng.uniform([0.1, -3.0], [3.0, 3.0], (50, 2))
    solver = adapter("gauss_newton")
    batch = solver.solve_many(problem, starts, P)
    assert batch.batched
    singles = [solver.solve(problem, starts[i], P[i]) for i in range(50)]
    np.testing.assert_allclose(batch.x, [s.x for s in singles], atol=1e-12)
    assert batch.status == [s.status for s in singles]
    np.testing.assert_array_equal(batch.iterations, [s.iterations for s in singles])


def test_batched_newton_agrees_with_the_closed_form_and_single_solves():
    """The rootfinder mapped over samples: the closed form of :func:`circle_line`, the one-sample
    path's points and statuses; a redundant problem takes each sample's own ``x_ref``."""
    problem = circle_line()
    rng = np.random.default_rng(1)
    P = np.column_stack([rng.uniform(0.5, 3.0, 40), rng.uniform(-3.0, 3.0, 40)])
    solver = adapter("newton")
    batch = solver.solve_many(problem, np.array([1.0, 0.0]), P)
    assert batch.batched and batch.status == ["ok"] * 40 and np.all(batch.iterations == -1)
    x0 = P[:, 0] / np.hypot(1.0, P[:, 1])
    np.testing.assert_allclose(batch.x, np.column_stack([x0, P[:, 1] * x0]), atol=1e-9)
    singles = [solver.solve(problem, np.array([1.0, 0.0]), P[i]) for i in range(40)]
    np.testing.assert_allclose(batch.x, [s.x for s in singles], atol=1e-14)
    weights = np.array([1.0, 2.0, 4.0])
    refs = rng.uniform(-2.0, 2.0, (5, 3))
    report = solver.solve_many(plane(weights), np.zeros(3), np.full((5, 1), 3.0), x_ref=refs)
    m_inv = 1.0 / weights**2
    expected = refs + m_inv * (3.0 - refs.sum(axis=1, keepdims=True)) / m_inv.sum()
    np.testing.assert_allclose(report.x, expected, atol=1e-9)


def test_failed_samples_are_reported_not_dropped():
    """A residual that is NaN for x0 > 1: every sample comes back, the bad ones as failed."""
    x, p = ca.SX.sym("x", 1), ca.SX.sym("p", 1)
    f = ca.Function("sqrt", [x, p], [ca.sqrt(1.0 - x) - p])
    problem = LeastSquaresProblem(f, [-5.0], [5.0], [False])
    report = adapter("gauss_newton").solve_many(problem, np.array([[0.0], [3.0]]), np.array([[0.5], [0.5]]))
    assert len(report) == 2
    assert report.status[0] == "ok" and report.status[1] == "failed"


@pytest.mark.parametrize(
    "backend, options, field",
    [
        ("gauss_newton", {"dampin": 1.0}, "options.dampin"),
        ("gauss_newton", {"damping": "big"}, "options.damping"),
        ("gauss_newton", {"damping": -1.0}, "options.damping"),
        ("gauss_newton", {"compile": "yes"}, "options.compile"),
        ("gauss_newton", {"flags": "-O3"}, "options.flags"),
        ("newton", {"plugin": "kinsol-ish"}, "options.plugin"),
        ("newton", {"line_search": 1}, "options.line_search"),
        ("lm", {"x_scale": "auto"}, "options.x_scale"),
        ("lm", {"x_scale": -1.0}, "options.x_scale"),
        ("lm", {"ftol": 1e-20}, "options.ftol"),
        ("lm", {"tr_solver": "exact"}, "options.tr_solver"),
        ("trf", {"regularisation": -0.1}, "options.regularisation"),
        ("trf", {"tr_solver": "cg"}, "options.tr_solver"),
        ("ipopt", {"settings": {"not_an_ipopt_option": 1}}, "options.settings.not_an_ipopt_option"),
        ("sqpmethod", {"settings": {"qpsoll": "qrqp"}}, "options.settings.qpsoll"),
    ],
)
def test_bad_preset_options_name_the_field(backend, options, field):
    with pytest.raises(SpecError) as info:
        adapter(backend, options)
    assert info.value.field == field, str(info.value)
