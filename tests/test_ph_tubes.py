"""Tube lengths along a PH backbone (`optikin.curves.tubes`), seed 002 section V.B.

Independent references: the closed form ``(R - rho cos(angle)) theta`` of a tube
around a circular arc (and ``S - rho cos(angle) * turning`` around any planar
curve); polylines through densely sampled offset points, carried by a
rotation-minimising frame computed with the double-reflection method (Wang,
Juttler, Zheng & Liu, ACM TOG 27 (2008)) or by the Euler-Rodrigues frame vectors of
:class:`PHQuintic`; and the CBHA vertebra model's own ``tube_lengths`` (sums of its
leg lengths, seed 004 eqs. 3-6).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from optikin.algebra import dq_rotation, dq_translation, quat_rotate
from optikin.arms.cbha import CBHAArm, CBHAGeometry
from optikin.curves import PHQuintic, ShapeData, ShapeEnergyModel, ph_quintic_hermite
from optikin.curves.tubes import (
    CBHA_TUBE_ANGLES,
    DEFAULT_TUBE_NODES,
    TubeLayout,
    carried_frame,
    tube_lengths,
    tube_points,
)
from optikin.errors import InputDataError


@pytest.fixture(scope="module")
def free_model():
    return ShapeEnergyModel(free_speeds=True)


def arc_data(theta: float, length: float, azimuth: float) -> ShapeData:
    """End poses of a circular arc leaving the origin along +z, bending by ``theta`` towards ``azimuth``."""
    kappa = theta / length
    u = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    z = np.array([0.0, 0.0, 1.0])
    p1 = (1 - np.cos(theta)) / kappa * u + np.sin(theta) / kappa * z
    return ShapeData.checked(np.zeros(3), z, p1, np.sin(theta) * u + np.cos(theta) * z, length=length)


def spatial_curves() -> list[PHQuintic]:
    """Three PH quintics shaped like CBHA backbones (0.2-0.3 m, bends of 40-120 degrees, out of plane)."""
    rng = np.random.default_rng(11)
    curves = []
    for _ in range(3):
        t0 = np.array([0.0, 0.0, 1.0])
        t1 = rng.normal(size=3) * 0.6 + t0
        p1 = np.array([rng.uniform(-0.08, 0.08), rng.uniform(-0.08, 0.08), rng.uniform(0.15, 0.2)])
        curves.append(
            ph_quintic_hermite(np.zeros(3), 0.22 * t0, p1, 0.22 * t1 / np.linalg.norm(t1), *rng.uniform(-1.0, 1.0, 2))
        )
    return curves


def double_reflection_frames(points: np.ndarray, tangents: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """Rotation-minimising normals at ``points`` by the double-reflection method (Wang et al. 2008)."""
    normals = np.empty_like(points)
    r = r0 - (r0 @ tangents[0]) * tangents[0]
    normals[0] = r / np.linalg.norm(r)
    for i in range(len(points) - 1):
        v1 = points[i + 1] - points[i]
        c1 = v1 @ v1
        rL = normals[i] - (2.0 / c1) * (v1 @ normals[i]) * v1
        tL = tangents[i] - (2.0 / c1) * (v1 @ tangents[i]) * v1
        v2 = tangents[i + 1] - tL
        c2 = v2 @ v2
        normals[i + 1] = rL - (2.0 / c2) * (v2 @ rL) * v2 if c2 > 0 else rL
    return normals


def polyline_tube_lengths(curve: PHQuintic, n0: np.ndarray, layout: TubeLayout, n: int) -> np.ndarray:
    """Tube lengths from ``n`` offset points per tube, frames computed independently of the module."""
    t = np.linspace(0.0, 1.0, n + 1)
    points = curve.point(t)
    if layout.frame == "rmf":
        tangents = curve.hodograph(t)
        tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
        f2 = double_reflection_frames(points, tangents, n0)
        f3 = np.cross(tangents, f2)
    else:
        _, e2, e3 = curve.frame_vectors(t)
        # angle 0 at the part of n0 across the start tangent, then carried by the ER frame
        c, s = n0 @ e2[0], n0 @ e3[0]
        c, s = c / np.hypot(c, s), s / np.hypot(c, s)
        f2, f3 = c * e2 + s * e3, c * e3 - s * e2
    # radius linear in arc length, arc length by the closed form of the PH speed
    fraction = curve.arc_length_at(t) / curve.arc_length()
    rho = (layout.radius_start + (layout.radius_end - layout.radius_start) * fraction)[:, None]
    out = []
    for a in layout.angles:
        tube = points + rho * (np.cos(a) * f2 + np.sin(a) * f3)
        out.append(np.linalg.norm(np.diff(tube, axis=0), axis=1).sum())
    return np.array(out)


# -- closed forms -------------------------------------------------------------------


@pytest.mark.parametrize("frame", ["rmf", "euler_rodrigues"])
@pytest.mark.parametrize("theta, azimuth", [(0.4, 0.0), (1.2, 0.7), (2.0, -2.1)])
def test_tubes_around_a_circular_arc(free_model, frame, theta, azimuth):
    """Arc of radius R through theta, tube at angle psi from the direction of the centre: (R - rho cos psi) theta.

    The minimum-energy PH quintic of an arc's end poses (its length held) is planar,
    and for any planar curve the tube length is ``S - rho cos(psi) * turning``, with
    ``S = R theta`` held by the constraint.
    """
    length, rho = 0.25, 0.035
    data = arc_data(theta, length, azimuth)
    curve = free_model.curve(free_model.solve_nlp(data), data)
    angles = (0.0, 0.9, np.pi / 2, np.pi, -2.5)
    layout = TubeLayout(rho, rho, angles, frame)
    n0 = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])  # towards the centre of the arc
    R = length / theta
    expected = (R - rho * np.cos(angles)) * theta
    np.testing.assert_allclose(tube_lengths(curve, n0, layout), expected, rtol=0, atol=1e-12)


def test_tubes_around_a_planar_curve_that_is_not_an_arc():
    """A planar PH quintic turning by phi: ``L = S -/+ rho phi`` on the inside / outside, any frame."""
    curve = ph_quintic_hermite([0, 0, 0], [0, 0, 0.3], [0.1, 0, 0.2], [0.3, 0, 0.1], 0.0, 0.0)
    t = np.linspace(0, 1, 101)
    assert np.max(np.abs(curve.point(t)[:, 1])) < 1e-15  # stays in the x-z plane
    d1 = curve.hodograph(1.0)
    turning = np.arctan2(d1[0], d1[2])  # from +z towards +x
    rho = 0.012
    for frame in ("rmf", "euler_rodrigues"):
        L = tube_lengths(curve, [1.0, 0.0, 0.0], TubeLayout(rho, rho, (0.0, np.pi), frame))
        np.testing.assert_allclose(L, curve.arc_length() + np.array([-rho, rho]) * turning, rtol=0, atol=1e-12)


# -- spatial curves against polylines of offset points -----------------------------------


@pytest.mark.parametrize("frame", ["rmf", "euler_rodrigues"])
def test_tube_lengths_equal_polylines_of_offset_points(frame):
    """Richardson-extrapolated polylines (2,000 and 4,000 segments) agree to 1e-9 relative."""
    layout = TubeLayout(0.040, 0.029, CBHA_TUBE_ANGLES, frame)
    n0 = np.array([1.0, 0.0, 0.0])
    for curve in spatial_curves():
        coarse, fine = (polyline_tube_lengths(curve, n0, layout, n) for n in (2000, 4000))
        reference = (4.0 * fine - coarse) / 3.0
        np.testing.assert_allclose(tube_lengths(curve, n0, layout), reference, rtol=1e-9)


def test_the_two_frames_give_different_lengths_on_twisted_curves():
    """Out of plane the ER frame turns about the tangent and the tubes wind: millimetres apart."""
    n0 = np.array([1.0, 0.0, 0.0])
    difference = max(
        np.abs(tube_lengths(c, n0, TubeLayout()) - tube_lengths(c, n0, TubeLayout(frame="euler_rodrigues"))).max()
        for c in spatial_curves()
    )
    assert difference > 1e-4


def test_carried_frame_is_the_double_reflection_frame_and_tube_points_sit_on_it():
    curve = spatial_curves()[0]
    n0 = np.array([1.0, 0.2, 0.0])
    t = np.linspace(0, 1, 4001)
    f1, f2, f3 = carried_frame(curve, n0, t)
    tangents = curve.hodograph(t) / curve.parametric_speed(t)[:, None]
    reference = double_reflection_frames(curve.point(t), tangents, n0)
    np.testing.assert_allclose(f1, tangents, atol=1e-14)
    np.testing.assert_allclose(f2, reference, atol=1e-9)  # double reflection is 4th order: ~(1/4000)^4
    np.testing.assert_allclose(f3, np.cross(f1, f2), atol=1e-14)
    layout = TubeLayout()
    points = tube_points(curve, n0, t[[0, -1]], layout)
    for m, a in enumerate(layout.angles):
        offset = points[m] - curve.point(t[[0, -1]])
        np.testing.assert_allclose(np.linalg.norm(offset, axis=1), [layout.radius_start, layout.radius_end], atol=1e-14)
        np.testing.assert_allclose(offset[0], layout.radius_start * (np.cos(a) * f2[0] + np.sin(a) * f3[0]), atol=1e-15)


def test_default_quadrature_is_converged():
    """DEFAULT_TUBE_NODES agrees with a 96-point rule to 1e-12 relative (rho kappa up to 0.87 here)."""
    for layout in (TubeLayout(), TubeLayout(frame="euler_rodrigues")):
        for curve in spatial_curves():
            reference = tube_lengths(curve, [1.0, 0, 0], layout, 96)
            errors = [
                np.max(np.abs(tube_lengths(curve, [1.0, 0, 0], layout, n) / reference - 1))
                for n in (6, 12, DEFAULT_TUBE_NODES)
            ]
            assert errors[-1] < 1e-12
            assert errors[0] >= errors[1] >= errors[2]


# -- CBHA vertebra model -----------------------------------------------------------


def cbha_end_data(arm: CBHAArm, q: np.ndarray) -> tuple[ShapeData, np.ndarray]:
    """Base and tip poses of the vertebra model, its backbone length (sum of Z_k) and the base x axis."""
    frames = arm.evaluate("vertebra_frames", q[None])[0].T
    rotation, position = dq_rotation(frames), dq_translation(frames)
    z = quat_rotate(rotation, np.array([0.0, 0.0, 1.0]))
    length = q.reshape(-1, 3)[:, 0].sum()
    data = ShapeData.checked(position[0], z[0], position[-1], z[-1], length=length)
    return data, quat_rotate(rotation[0], np.array([1.0, 0.0, 0.0]))


def test_cbha_tube_lengths_converge_to_the_ph_tubes_as_vertebrae_multiply(free_model):
    """A planar bend of 1.2 rad over 0.2 m split into N equal platforms (tubes at 35 mm, no taper).

    The model's tubes are polylines (sums of leg lengths); the PH tubes are smooth, so
    the two agree as the vertebrae multiply, with the second-order error of a chord
    sum: measured 0.034 mm (N = 16), 2.1 um (N = 64).
    """
    differences = []
    for N in (16, 64):
        geometry = CBHAGeometry(
            n_vertebrae=N + 1,
            r_max=0.035,
            r_min=0.035,
            leg_min=(0.001,) * N,
            leg_max=(0.1,) * N,
            platforms_per_section=(N // 2, N // 2),
        )
        arm = CBHAArm(geometry)
        q = np.column_stack([np.full(N, 0.2 / N), np.full(N, 1.2 / N), np.zeros(N)]).ravel()
        model_lengths = arm.evaluate("tube_lengths", q[None])[0].sum(axis=0)  # section 1 + section 2
        data, n0 = cbha_end_data(arm, q)
        ph = tube_lengths(free_model.curve(free_model.solve_nlp(data), data), n0, TubeLayout.cbha(geometry))
        np.testing.assert_allclose(
            model_lengths, [0.2 + 0.035 * 1.2, 0.2 - 0.0175 * 1.2, 0.2 - 0.0175 * 1.2], atol=0.2 / N**2
        )
        differences.append(np.max(np.abs(ph - model_lengths)))
    assert differences[1] < 5e-6
    assert 10 < differences[0] / differences[1] < 22  # second order: 16 expected


def test_cbha_tube_lengths_from_its_own_end_poses(free_model):
    """Default CBHA (tapered tubes, Table I poses): PH tubes within a millimetre of the vertebra model.

    The PH backbone is rebuilt from the base and tip poses alone with the backbone
    length held; the difference is the PH shape against the model's (measured: largest
    tube difference 0.20-0.59 mm over these 5 poses), not quadrature.
    """
    arm = CBHAArm()
    Q = arm.sample_configurations(5, np.random.default_rng(0))
    for q in Q:
        data, n0 = cbha_end_data(arm, q)
        ph = tube_lengths(free_model.curve(free_model.solve_nlp(data), data), n0, TubeLayout.cbha(arm.geometry))
        model_lengths = arm.evaluate("tube_lengths", q[None])[0].sum(axis=0)
        assert np.max(np.abs(ph - model_lengths)) < 1e-3


# -- numpy batches, CasADi, bad input --------------------------------------------------


def test_batch_and_casadi_give_the_single_curve_values():
    curves = spatial_curves()
    batch = PHQuintic(*(np.stack([getattr(c, k) for c in curves]) for k in ("p0", "A0", "A1", "A2")))
    n0 = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 1.0, 0.3]])
    for layout in (TubeLayout(), TubeLayout(0.03, 0.03, frame="euler_rodrigues")):
        single = np.array([tube_lengths(c, n, layout) for c, n in zip(curves, n0)])
        np.testing.assert_allclose(tube_lengths(batch, n0, layout), single, rtol=1e-14)
        A = [ca.SX.sym(k, 4) for k in ("A0", "A1", "A2")]
        n = ca.SX.sym("n0", 3)
        f = ca.Function("tubes", [*A, n], [tube_lengths(PHQuintic(ca.DM.zeros(3), *A), n, layout)])
        for c, n_i, expected in zip(curves, n0, single):
            np.testing.assert_allclose(np.asarray(f(c.A0, c.A1, c.A2, n_i)).ravel(), expected, rtol=1e-13)


def test_bad_input_is_rejected():
    curve = spatial_curves()[0]
    tangent = curve.hodograph(0.0)
    with pytest.raises(InputDataError, match="reference_normal"):
        tube_lengths(curve, 2.0 * tangent, source="poses.csv")
    batch = PHQuintic(*(np.stack([getattr(curve, k)] * 2) for k in ("p0", "A0", "A1", "A2")))
    with pytest.raises(InputDataError, match="sample 1: reference_normal"):
        tube_lengths(batch, np.stack([[1.0, 0, 0], tangent]))
    with pytest.raises(ValueError, match="frame"):
        TubeLayout(frame="frenet")
    with pytest.raises(ValueError, match="radii"):
        TubeLayout(-0.01, 0.02)
