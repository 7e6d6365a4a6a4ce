"""The public PH API of `optikin.curves`: the backbone of two end poses in five lines.

Independent references: the closed forms of a circular arc (its length, its circle,
the energy ``theta^2 / L``) and of a straight segment (energy 0, points on the chord).
"""

from __future__ import annotations

import doctest

import numpy as np
import pytest

import optikin.curves
from optikin.curves import EnergySettings, PHQuintic, ShapeData, ShapeEnergyModel, arc_length_estimate


def test_the_docstring_example_runs():
    result = doctest.testmod(optikin.curves, raise_on_error=False)
    assert result.attempted >= 6 and result.failed == 0


def five_lines(p0, t0, p1, t1, free_speeds):
    """The docstring's example, on other end poses."""
    data = ShapeData.checked(p0, t0, p1, t1, length=arc_length_estimate(p0, t0, p1, t1))
    model = ShapeEnergyModel(EnergySettings(), free_speeds=free_speeds)
    solution = model.solve_newton(data)
    return data, solution, model.curve(solution, data)


@pytest.mark.parametrize("free_speeds", [False, True])
def test_quarter_circle_against_its_closed_form(free_speeds):
    """End poses of a quarter circle of radius R: length pi R / 2 exactly; the curve within 0.6 % of the
    length from the circle (0.3 % with the length held), energy within 2 % of theta^2 / L."""
    R = 0.2
    p0, t0, p1, t1 = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([R, 0.0, R]), np.array([1.0, 0.0, 0.0])
    data, solution, curve = five_lines(p0, t0, p1, t1, free_speeds)
    length = np.pi * R / 2
    assert data.length == pytest.approx(length, rel=1e-12)
    assert solution.status == "ok" and isinstance(curve, PHQuintic)
    points = curve.point(np.linspace(0, 1, 201))
    np.testing.assert_allclose(points[:, 1], 0.0, atol=1e-12)  # planar data, planar optimum
    radial = np.hypot(points[:, 0] - R, points[:, 2]) - R
    assert np.max(np.abs(radial)) < (3e-3 if free_speeds else 6e-3) * length
    assert solution.energy == pytest.approx((np.pi / 2) ** 2 / length, rel=2e-2)
    assert solution.residual == solution.energy
    if free_speeds:
        assert float(curve.arc_length()) == pytest.approx(length, rel=1e-10)


def test_straight_segment_is_rebuilt_exactly():
    direction = np.array([0.2, -0.3, 0.9]) / np.linalg.norm([0.2, -0.3, 0.9])
    p0 = np.array([0.1, 0.0, 0.0])
    p1 = p0 + 0.3 * direction
    data, solution, curve = five_lines(p0, direction, p1, direction, False)
    assert data.length == pytest.approx(0.3, rel=1e-12)
    assert solution.energy < 1e-12
    points = curve.point(np.linspace(0, 1, 21)) - p0
    along = points @ direction
    np.testing.assert_allclose(points - np.outer(along, direction), 0.0, atol=1e-7)
    assert along.min() >= -1e-9 and along.max() <= 0.3 + 1e-9
    np.testing.assert_allclose(curve.point(1.0), p1, atol=1e-14)


def test_a_batch_of_curves_keeps_failed_samples_as_nan():
    model = ShapeEnergyModel()
    good = ShapeData.checked(np.zeros(3), [0, 0, 1.0], [0.05, 0.0, 0.3], [0, 0, 1.0], length=0.32)
    solution = model.solve_newton(good)
    failed = type(solution)(np.full(2, np.nan), "failed")
    batch = model.curves([solution, failed], [good, good])
    np.testing.assert_allclose(batch.point(0.3)[0], model.curve(solution, good).point(0.3), rtol=0, atol=0)
    assert np.all(np.isnan(batch.A1[1])) and batch.p0.shape == (2, 3)
