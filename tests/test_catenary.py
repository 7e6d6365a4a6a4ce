"""The hanging rope (`optikin.curves.catenary`), checked against a discretised chain of rigid links.

Independent reference: a chain of N equal rigid links between the two end points
whose potential energy is minimised by scipy (SLSQP) under the link-length
constraints; as N grows its joints approach the catenary. Also: total length by
summing chords, tangents by finite differences, and the closed-form limits.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from optikin.curves.catenary import catenary, solve_sinhc
from optikin.errors import InputDataError


@pytest.mark.parametrize("rho", [1 + 1e-13, 1 + 1e-6, 1.01, 2.0, 3.0, 50.0, 1e6, 1e12])
def test_sinhc_inverse(rho):
    xi = solve_sinhc(rho)
    if xi < 1e-3:
        assert 1 + xi * xi / 6 + xi**4 / 120 == pytest.approx(rho, rel=1e-15)
    else:
        # log form: log(sinh xi / xi) = xi + log(1 - e^{-2 xi}) - log(2 xi)
        assert xi + math.log1p(-math.exp(-2 * xi)) - math.log(2 * xi) == pytest.approx(math.log(rho), rel=1e-13)


CASES = [
    ([0, 0, 0], [0.5, 0.1, 0.2], 1.0),
    ([0.1, -0.2, 0.3], [0.6, 0.2, 0.0], 0.8),
    ([0, 0, 0], [0.4, 0.0, 0.0], 0.41),  # nearly taut
    ([0, 0, 0], [0.05, 0.0, -0.1], 1.5),  # very slack
]


@pytest.mark.parametrize("start,end,length", CASES)
def test_catenary_meets_its_ends_and_has_its_length(start, end, length):
    rope = catenary(start, end, length)
    assert rope.kind == "catenary"
    s = np.linspace(0, length, 200001)
    P = rope.points(s)
    np.testing.assert_allclose(P[0], start, atol=1e-14)
    np.testing.assert_allclose(P[-1], end, atol=1e-12)
    assert np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1)) == pytest.approx(length, rel=1e-9)
    tangents = rope.tangents(s[1:-1])
    finite = (P[2:] - P[:-2]) / (s[2] - s[0])
    np.testing.assert_allclose(tangents, finite, atol=1e-6)


def discrete_chain(start, end, length, n=60):
    """Joints of n rigid links of length length/n hanging in the vertical plane of start and end.

    Unknowns: the links' angles to the horizontal; minimise the height of the
    centre of mass (sum of joint heights) subject to the links reaching ``end``.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    chord = end - start
    horizontal = np.array([chord[0], chord[1], 0.0]) / np.hypot(chord[0], chord[1])
    span, rise, link = np.hypot(chord[0], chord[1]), chord[2], length / n

    def heights(angles):
        return np.cumsum(link * np.sin(angles))

    weights = link * np.arange(n, 0, -1)  # link j raises the n - j joints after it
    constraints = {
        "type": "eq",
        "fun": lambda a: [link * np.sum(np.cos(a)) - span, link * np.sum(np.sin(a)) - rise],
        "jac": lambda a: np.vstack([-link * np.sin(a), link * np.cos(a)]),
    }
    guess = np.linspace(-1.0, 1.0, n)
    res = minimize(
        lambda a: weights @ np.sin(a),
        guess,
        jac=lambda a: weights * np.cos(a),
        constraints=[constraints],
        method="SLSQP",
        options={"maxiter": 1000, "ftol": 1e-15},
    )
    assert res.success, res.message
    x = np.concatenate([[0.0], np.cumsum(link * np.cos(res.x))])
    z = np.concatenate([[0.0], heights(res.x)])
    return start + x[:, None] * horizontal + z[:, None] * np.array([0, 0, 1.0])


@pytest.mark.parametrize("start,end,length", [CASES[0], CASES[1]])
def test_catenary_matches_a_minimum_energy_link_chain(start, end, length):
    """The joints of a 60-link chain lie within 0.1% of the rope length of the catenary."""
    rope = catenary(start, end, length)
    chain = discrete_chain(start, end, length)
    s = np.linspace(0, length, chain.shape[0])
    assert np.max(np.linalg.norm(chain - rope.points(s), axis=1)) < 1e-3 * length


def test_limits_straight_and_folded():
    straight = catenary([0, 0, 0], [0.3, 0, 0.4], 0.5)
    assert straight.kind == "straight"
    np.testing.assert_allclose(straight.points(np.array([0.25])), [[0.15, 0, 0.2]], atol=1e-15)
    folded = catenary([0, 0, 0], [0, 0, 0.2], 1.0)
    assert folded.kind == "folded"
    P = folded.points(np.linspace(0, 1, 101))
    assert P[:, 2].min() == pytest.approx(-0.4)  # (1.0 - 0.2)/2 below the start
    np.testing.assert_allclose(P[-1], [0, 0, 0.2], atol=1e-15)


def test_gravity_direction_is_respected():
    rope = catenary([0, 0, 0], [0.5, 0, 0], 0.8, gravity=[0, -9.81, 0])
    P = rope.points(np.linspace(0, 0.8, 101))
    assert np.max(np.abs(P[:, 2])) < 1e-15
    assert P[:, 1].min() < -0.2


@pytest.mark.parametrize(
    "args,field",
    [
        (([0, 0, 0], [1, 0, 0], 0.9), "length"),
        (([0, 0, np.nan], [1, 0, 0], 2.0), "start"),
        (([0, 0, 0], [1, 0, 0], -1.0), "length"),
        (([0, 0, 0], [1, 0, 0], 2.0, [0, 0, 0]), "gravity"),
    ],
)
def test_bad_ropes_are_rejected(args, field):
    with pytest.raises(InputDataError, match=field):
        catenary(*args, source="rope.yaml")


def potential_energy(end, start, length, weight, n=20001):
    """``w int z ds`` of the catenary between ``start`` and ``end``, by the trapezoid rule on its points."""
    rope = catenary(start, end, length)
    z = rope.points(np.linspace(0.0, length, n))[:, 2]
    return weight * length / (n - 1) * (z.sum() - 0.5 * (z[0] + z[-1]))


@pytest.mark.parametrize("start,end,length", [CASES[0], CASES[1], CASES[3]])
def test_end_forces_are_the_gradient_of_the_potential_energy_and_carry_the_weight(start, end, length):
    """Virtual work: moving the end support by dB changes the rope's least potential energy by -F . dB,
    F the force on that support (central differences of the energy integrated along the rope)."""
    weight = 0.5
    on_start, on_end = catenary(start, end, length).end_forces(weight)
    np.testing.assert_allclose(on_start + on_end, [0.0, 0.0, -weight * length], atol=1e-12)
    h = 1e-5
    for support, force in ((1, on_end), (0, on_start)):
        gradient = np.zeros(3)
        for k in range(3):
            step = np.zeros(3)
            step[k] = h
            ends = [np.asarray(start, float), np.asarray(end, float)]
            plus, minus = [e.copy() for e in ends], [e.copy() for e in ends]
            plus[support] += step
            minus[support] -= step
            gradient[k] = (
                potential_energy(plus[1], plus[0], length, weight)
                - potential_energy(minus[1], minus[0], length, weight)
            ) / (2 * h)
        np.testing.assert_allclose(force, -gradient, atol=1e-6 * weight * length)


def test_end_forces_of_the_limits():
    folded = catenary([0, 0, 0], [0, 0, 0.2], 1.0)
    on_start, on_end = folded.end_forces(2.0)
    np.testing.assert_allclose(on_start, [0, 0, -0.8], atol=1e-15)  # 0.4 m hang from the start
    np.testing.assert_allclose(on_end, [0, 0, -1.2], atol=1e-15)  # 0.6 m from the end
    with pytest.raises(ValueError, match="infinite tension"):
        catenary([0, 0, 0], [0.3, 0, 0.4], 0.5).end_forces(1.0)
    assert np.all(catenary([0, 0, 0], [0.3, 0, 0.4], 0.5).end_forces(0.0)[0] == 0.0)
