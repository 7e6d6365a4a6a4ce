"""optikin.algebra.wrap_periodic: whole periods taken off, the range's ends as stated, NaN kept."""

from __future__ import annotations

import math

import numpy as np

from optikin.algebra import wrap_periodic


def test_whole_turns_come_off_and_the_range_is_half_open_at_the_stated_end():
    pi = math.pi
    x = np.array([0.5, 0.5 + 2 * pi, 0.5 - 6 * pi, pi, -pi, 3 * pi])
    np.testing.assert_allclose(wrap_periodic(x), [0.5, 0.5, 0.5, -pi, -pi, -pi], atol=1e-14)
    np.testing.assert_allclose(wrap_periodic(x, closed="upper"), [0.5, 0.5, 0.5, pi, pi, pi], atol=1e-14)
    assert np.isnan(wrap_periodic(np.nan))


def test_any_range_and_its_period_broadcast_against_the_values():
    lower, upper = np.array([0.0, -1.0]), np.array([10.0, 1.0])
    x = np.array([[23.0, 2.5], [-0.5, -1.0]])
    np.testing.assert_allclose(wrap_periodic(x, lower, upper), [[3.0, 0.5], [9.5, -1.0]], atol=1e-14)
    np.testing.assert_allclose(wrap_periodic(x, lower, upper, closed="upper"), [[3.0, 0.5], [9.5, 1.0]], atol=1e-14)


def test_it_agrees_with_the_angle_of_the_unit_complex_number():
    x = np.random.default_rng(0).uniform(-50.0, 50.0, 1000)
    np.testing.assert_allclose(wrap_periodic(x), np.angle(np.exp(1j * x)), atol=1e-12)
