"""The rope's lowest point and its grip sensitivities against central differences, the symmetric closed form
and a dense sampling of the catenary; a rope shorter than its grips' distance is refused naming the field."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from optikin.curves.catenary import catenary
from optikin.curves.catenary_sensitivity import G_ACCELERATION, CatenarySensitivity
from optikin.errors import InputDataError


def central_differences(f, G: np.ndarray, step: float = 1e-6) -> np.ndarray:
    columns = []
    for i in range(len(G)):
        up, down = G.copy(), G.copy()
        up[i] += step
        down[i] -= step
        columns.append((f(up) - f(down)) / (2 * step))
    return np.stack(columns, axis=-1)


@pytest.mark.parametrize(
    "A,B,gravity",
    [
        ([-0.2, 0.01, 0.3], [0.15, -0.03, 0.33], [0, 0, -1]),
        ([0.0, 0.0, 0.0], [0.4, 0.2, -0.1], [0, 0, -1]),
        ([0.1, -0.2, 0.05], [-0.2, 0.1, 0.0], [0.3, -0.2, -1.0]),
    ],
)
def test_lowest_point_jacobian_matches_central_differences(A, B, gravity):
    rope = CatenarySensitivity(0.7, mass_per_length=0.08, gravity=gravity)
    G = np.r_[A, B].astype(float)
    low = rope.lowest_point(G[:3], G[3:])
    assert low.vertex_on_rope
    numeric = central_differences(lambda g: rope.lowest_point(g[:3], g[3:]).point, G)
    assert np.allclose(low.jacobian, numeric, atol=2e-8)
    a_numeric = central_differences(lambda g: np.array([rope.lowest_point(g[:3], g[3:]).a]), G)[0]
    assert np.allclose(low.a_gradient, a_numeric, atol=1e-7)
    H_numeric = central_differences(lambda g: np.array([rope.lowest_point(g[:3], g[3:]).tension]), G)[0]
    assert np.allclose(low.tension_gradient, H_numeric, atol=1e-7)


def test_lowest_point_is_the_lowest_of_the_dense_catenary_and_tension_its_horizontal_pull():
    A, B = np.array([-0.2, 0.01, 0.3]), np.array([0.15, -0.03, 0.33])
    rope = CatenarySensitivity(0.6, mass_per_length=0.05)
    low = rope.lowest_point(A, B)
    points = catenary(A, B, 0.6).points(np.linspace(0.0, 0.6, 200_001))
    assert np.allclose(low.point, points[np.argmin(points[:, 2])], atol=1e-5)
    on_start, _ = catenary(A, B, 0.6).end_forces(0.05 * G_ACCELERATION)
    assert low.tension == pytest.approx(np.linalg.norm(on_start[:2]), rel=1e-12)


def symmetric_closed_form(c: float, L: float) -> tuple[float, float]:
    """Sag ``s(c) = a (cosh(c/a) - 1)`` of a rope of length ``L`` between grips at equal height ``2c`` apart, and
    ``ds/dc``: with ``u = c/a`` and ``2 a sinh(u) = L`` held, ``da/dc = -cosh u / (sinh u - u cosh u)`` and
    ``ds/dc = sinh u + da/dc (cosh u - 1 - u sinh u)``."""
    a = brentq(lambda a: 2 * a * math.sinh(c / a) - L, c / 50.0, 1e6 * c, xtol=1e-15, rtol=1e-15)
    u = c / a
    da = -math.cosh(u) / (math.sinh(u) - u * math.cosh(u))
    return a * (math.cosh(u) - 1.0), math.sinh(u) + da * (math.cosh(u) - 1.0 - u * math.sinh(u))


@pytest.mark.parametrize("c,L", [(0.2, 0.6), (0.1, 0.9), (0.29, 0.6)])
def test_symmetric_grips_match_the_closed_form_sag_and_its_half_span_derivative(c, L):
    z0 = 0.35
    A, B = np.array([-c, 0.0, z0]), np.array([c, 0.0, z0])
    low = CatenarySensitivity(L).lowest_point(A, B)
    sag, dsag = symmetric_closed_form(c, L)
    assert low.point == pytest.approx([0.0, 0.0, z0 - sag], abs=1e-12)
    # Half-span c: B_x = c, A_x = -c, so dP_z/dc = dP_z/dB_x - dP_z/dA_x = -ds/dc; each grip alone gives half.
    assert low.jacobian[2, 3] - low.jacobian[2, 0] == pytest.approx(-dsag, rel=1e-10)
    assert low.jacobian[2, 3] == pytest.approx(-dsag / 2, rel=1e-10)
    # Lifting both grips lifts the vertex one for one; the sideways shift follows half from each grip.
    assert low.jacobian[2, 2] + low.jacobian[2, 5] == pytest.approx(1.0, abs=1e-12)
    assert low.jacobian[1, 1] == pytest.approx(0.5, abs=1e-12) and low.jacobian[1, 4] == pytest.approx(0.5, abs=1e-12)


def test_vertex_beyond_a_grip_makes_the_lower_grip_the_lowest_point():
    A, B = np.array([0.0, 0.0, 0.0]), np.array([0.1, 0.0, 0.5])  # steep: the rope hangs below A's side
    low = CatenarySensitivity(0.52).lowest_point(A, B)
    assert not low.vertex_on_rope and low.x0 < 0
    assert np.array_equal(low.point, A) and np.array_equal(low.jacobian[:, :3], np.eye(3))


@pytest.mark.parametrize("L", [0.5, 0.4])
def test_rope_not_longer_than_its_grips_distance_is_refused_naming_the_length(L):
    with pytest.raises(InputDataError) as err:
        CatenarySensitivity(L, source="rope.yaml").lowest_point(np.zeros(3), np.array([0.3, 0.0, 0.4]))
    assert err.value.field == "length" and "cannot hang" in str(err.value) and "rope.yaml" in str(err.value)


def test_grips_on_one_vertical_and_bad_parameters_are_refused():
    with pytest.raises(InputDataError) as err:
        CatenarySensitivity(1.0).lowest_point(np.zeros(3), np.array([0.0, 0.0, 0.4]))
    assert err.value.field == "grips"
    for kwargs, field in (({"length": -1.0}, "length"), ({"length": 1.0, "mass_per_length": -0.1}, "mass_per_length")):
        with pytest.raises(InputDataError) as err:
            CatenarySensitivity(**kwargs)
        assert err.value.field == field


def test_rope_samples_are_the_catenarys_points_and_their_grip_jacobian_matches_central_differences():
    from optikin.curves.catenary_sensitivity import RopeSamples

    A, B = np.array([-0.2, 0.01, 0.3]), np.array([0.15, -0.03, 0.33])
    arc = np.linspace(0.0, 0.6, 9)
    samples = RopeSamples(CatenarySensitivity(0.6), arc)
    samples.evaluate(A, B)
    assert np.allclose(samples.P, catenary(A, B, 0.6).points(arc), atol=1e-14)
    jacobian = samples.J.copy()

    def points(G: np.ndarray) -> np.ndarray:
        samples.evaluate(G[:3], G[3:])
        return samples.P.copy()

    assert np.allclose(jacobian, central_differences(points, np.r_[A, B]), atol=2e-8)
    assert np.allclose(jacobian[0], np.c_[np.eye(3), np.zeros((3, 3))]) and np.allclose(
        jacobian[-1], np.c_[np.zeros((3, 3)), np.eye(3)], atol=1e-12
    )
