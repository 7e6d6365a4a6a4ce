"""Spatial PH quintic Hermite interpolants (`optikin.curves.ph_quintic`), checked by independent means.

References: scipy's ``Rotation`` for ``A i A* = |A|^2 R(A) x``; adaptive quadrature
(``scipy.integrate.quad``) for arc length and for the integral of the hodograph;
finite differences of sampled points for curvature and torsion; the
Bernstein-to-power matrix printed in seed 002 eq. (13) for points; Farouki's
textbook root of ``A i A* = v`` (which divides by ``1 + lambda``) where it is defined.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.spatial.transform import Rotation

from optikin.curves import hermite_family, ph_quintic_hermite, preimage
from optikin.errors import InputDataError

RNG_SEED = 20240611


def random_data(n: int, seed: int = RNG_SEED):
    """Batches of Hermite data of mixed scales, and free angles."""
    rng = np.random.default_rng(seed)
    p0 = rng.normal(size=(n, 3))
    p1 = p0 + rng.normal(size=(n, 3)) * rng.uniform(0.1, 2.0, size=(n, 1))
    d0 = rng.normal(size=(n, 3)) * rng.uniform(0.2, 3.0, size=(n, 1))
    d1 = rng.normal(size=(n, 3)) * rng.uniform(0.2, 3.0, size=(n, 1))
    angles = rng.uniform(-np.pi, np.pi, size=(n, 3))
    return p0, d0, p1, d1, angles


def rotate_i(A: np.ndarray) -> np.ndarray:
    """``A i A*`` through scipy: ``|A|^2`` times the rotation of ``A`` applied to ``(1, 0, 0)``."""
    A = np.atleast_2d(A)
    norm2 = np.sum(A * A, axis=-1)
    rot = Rotation.from_quat(A[:, [1, 2, 3, 0]])  # scipy: (x, y, z, w)
    return rot.apply([1.0, 0.0, 0.0]) * norm2[:, None]


SPECIAL_VECTORS = [
    [-1.0, 0.0, 0.0],  # the textbook root divides by zero here
    [-2.5, 1e-12, -1e-12],
    [0.0, 1.0, 0.0],  # on the switch between the two poles
    [0.0, 0.0, -3.0],
    [1e-9, 0.0, 0.0],
    [5.0, 0.0, 0.0],
]


@pytest.mark.parametrize("v", SPECIAL_VECTORS)
def test_preimage_solves_a_i_a_conj_equals_v(v):
    v = np.asarray(v)
    np.testing.assert_allclose(rotate_i(preimage(v))[0], v, rtol=0, atol=1e-14 * np.linalg.norm(v))


def test_preimage_random_batch_and_same_family_as_textbook_root():
    rng = np.random.default_rng(RNG_SEED)
    v = rng.normal(size=(500, 3)) * rng.uniform(0.01, 10.0, size=(500, 1))
    A = preimage(v)
    np.testing.assert_allclose(rotate_i(A), v, rtol=0, atol=1e-13 * np.max(np.abs(v)))
    # Farouki's root (phi = 0): sqrt(|v|(1+l)/2) (i + j mu/(1+l) + k nu/(1+l)), defined for l > -1.
    n = np.linalg.norm(v, axis=1)
    lam, mu, nu = (v / n[:, None]).T
    components = np.stack([0 * lam, 1 + 0 * lam, mu / (1 + lam), nu / (1 + lam)], -1)
    textbook = np.sqrt(n * (1 + lam) / 2)[:, None] * components
    # Same family: textbook = A exp(i phi) for some phi, i.e. A* textbook has no j, k part.
    rel = (Rotation.from_quat(A[:, [1, 2, 3, 0]]).inv() * Rotation.from_quat(textbook[:, [1, 2, 3, 0]])).as_quat()
    np.testing.assert_allclose(rel[:, 1:3], 0.0, atol=1e-10)  # scipy (x, y, z, w): y, z are the j, k parts


def test_interpolation_conditions_hold():
    p0, d0, p1, d1, ang = random_data(400)
    curve = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2], ang[:, 1])
    scale = np.max(np.abs(np.concatenate([p0, p1, d0, d1], axis=1)), axis=1, keepdims=True)
    ends = curve.point(np.array([0.0, 1.0]))
    speeds = curve.hodograph(np.array([0.0, 1.0]))
    for value, expected in ((ends[:, 0], p0), (ends[:, 1], p1), (speeds[:, 0], d0), (speeds[:, 1], d1)):
        assert np.max(np.abs(value - expected) / scale) < 1e-12


DEGENERATE_CASES = {
    "d0 along -x (textbook root singular)": ([0, 0, 0], [-1, 0, 0], [0.3, 0.4, 0.1], [0, 1, 0]),
    "antiparallel end derivatives": ([0, 0, 0], [0, 0, 0.5], [0.2, 0, 0], [0, 0, -0.5]),
    "antiparallel, both along x": ([0, 0, 0], [-0.4, 0, 0], [0, 0.3, 0], [0.4, 0, 0]),
    "straight segment": ([0, 0, 0], [0.2, 0.1, 0.3], [0.2, 0.1, 0.3], [0.2, 0.1, 0.3]),
    "parallel, chord a quarter of the speed (alpha passes 0)": ([0, 0, 0], [0, 0, 1.0], [0, 0, 0.25], [0, 0, 1.0]),
    "coincident end points (closed loop)": ([1, 2, 3], [0, 0.3, 0], [1, 2, 3], [0, 0.3, 0]),
    "coincident end points, opposite directions": ([0, 0, 0], [0.3, 0, 0], [0, 0, 0], [-0.3, 0, 0]),
}


@pytest.mark.parametrize("name", list(DEGENERATE_CASES))
def test_degenerate_data_is_interpolated_for_all_angles(name):
    p0, d0, p1, d1 = (np.asarray(x, dtype=float) for x in DEGENERATE_CASES[name])
    a = np.linspace(-np.pi, np.pi, 13)
    phi0, phi2 = (x.ravel() for x in np.meshgrid(a, a))
    curve = ph_quintic_hermite(p0, d0, p1, d1, phi0, phi2)
    assert np.all(np.isfinite(curve.A1))
    ends = curve.point(np.array([0.0, 1.0]))
    speeds = curve.hodograph(np.array([0.0, 1.0]))
    np.testing.assert_allclose(ends[:, 0], np.broadcast_to(p0, ends[:, 0].shape), atol=1e-13)
    np.testing.assert_allclose(ends[:, 1], np.broadcast_to(p1, ends[:, 1].shape), atol=1e-13)
    np.testing.assert_allclose(speeds[:, 0], np.broadcast_to(d0, speeds[:, 0].shape), atol=1e-13)
    np.testing.assert_allclose(speeds[:, 1], np.broadcast_to(d1, speeds[:, 1].shape), atol=1e-13)


def test_members_vary_smoothly_with_the_angles():
    """The root Q(alpha) never switches branch inside one family: A1 is continuous in (phi0, phi2)."""
    for name, data in DEGENERATE_CASES.items():
        if "alpha passes 0" in name:
            continue  # |Q| = sqrt|alpha| is continuous but not Lipschitz there
        fam = hermite_family(*(np.asarray(x, dtype=float) for x in data))
        a = np.linspace(-np.pi, np.pi, 721)
        A1 = fam.member(a, 0.3 + 0 * a).A1
        jumps = np.max(np.linalg.norm(np.diff(A1, axis=0), axis=1))
        scale = np.max(np.linalg.norm(A1, axis=1))
        assert jumps < 0.05 * scale, name


@pytest.mark.parametrize(
    "field,data",
    [
        ("d0", ([0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0])),
        ("d1", ([0, 0, 0], [1, 0, 0], [1, 0, 0], [1e-14, 0, 0])),
        ("p1", ([0, 0, 0], [1, 0, 0], [np.nan, 0, 0], [1, 0, 0])),
        ("d0", ([0, 0, 0], [1, 0], [1, 0, 0], [1, 0, 0])),
    ],
)
def test_bad_data_is_rejected_naming_the_field(field, data):
    with pytest.raises(InputDataError, match=field):
        ph_quintic_hermite(*(np.asarray(x, dtype=float) for x in data), source="markers.csv")


def test_bad_sample_of_a_batch_is_named():
    p0, d0, p1, d1, _ = random_data(6)
    d1[4] = 0.0
    with pytest.raises(InputDataError, match="sample 4: d1"):
        ph_quintic_hermite(p0, d0, p1, d1, source="trajectory")


def test_pythagorean_property_at_random_parameters():
    p0, d0, p1, d1, ang = random_data(200)
    curve = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2], ang[:, 1])
    t = np.random.default_rng(1).uniform(0, 1, size=50)
    # Hodograph from the control points (Bezier derivative 5 (P_{k+1} - P_k)), not from A(t).
    P = np.stack(curve.control_points(), axis=-2)  # (n, 6, 3)
    diffs = 5.0 * np.diff(P, axis=-2)
    b4 = np.stack([np.array([1, 4, 6, 4, 1])[k] * (1 - t) ** (4 - k) * t**k for k in range(5)], -1)
    hodograph = np.einsum("mk,nkd->nmd", b4, diffs)
    sigma = curve.parametric_speed(t)
    np.testing.assert_allclose(np.sum(hodograph**2, axis=-1), sigma**2, rtol=1e-12)


def test_points_match_seed_power_basis_matrix():
    """r(t) = [1 t ... t^5] M [P0..P5] with the matrix printed in seed 002 eq. (13)."""
    M = np.array(
        [
            [1, 0, 0, 0, 0, 0],
            [-5, 5, 0, 0, 0, 0],
            [10, -20, 10, 0, 0, 0],
            [-10, 30, -30, 10, 0, 0],
            [5, -20, 30, -20, 5, 0],
            [-1, 5, -10, 10, -5, 1],
        ]
    )
    p0, d0, p1, d1, ang = random_data(20)
    curve = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2])
    P = np.stack(curve.control_points(), axis=-2)
    t = np.linspace(0, 1, 9)
    T = np.vander(t, 6, increasing=True)
    np.testing.assert_allclose(curve.point(t), np.einsum("mk,kj,njd->nmd", T, M, P), atol=1e-12)


def test_control_points_integrate_the_hodograph():
    p0, d0, p1, d1, ang = random_data(5, seed=7)
    for n in range(5):
        curve = ph_quintic_hermite(p0[n], d0[n], p1[n], d1[n], *ang[n])
        for t in (0.2, 0.55, 1.0):
            integral = [quad(lambda s: curve.hodograph(s)[k], 0, t, epsabs=1e-13, epsrel=1e-13)[0] for k in range(3)]
            np.testing.assert_allclose(curve.point(t) - p0[n], integral, rtol=1e-12, atol=1e-13)


def test_closed_form_arc_length_equals_adaptive_quadrature():
    p0, d0, p1, d1, ang = random_data(8, seed=3)
    for n in range(8):
        curve = ph_quintic_hermite(p0[n], d0[n], p1[n], d1[n], *ang[n])
        speed = lambda s: np.linalg.norm(curve.hodograph(s))  # noqa: E731
        total = quad(speed, 0, 1, epsabs=0, epsrel=1e-13, limit=200)[0]
        assert abs(curve.arc_length() - total) <= 1e-10 * total
        partial = quad(speed, 0, 0.37, epsabs=0, epsrel=1e-13, limit=200)[0]
        assert abs(curve.arc_length_at(0.37) - partial) <= 1e-10 * total


def finite_difference_derivatives(curve, t, h=1e-2):
    """Central differences of orders h^6, h^4, h^4: exact for a quintic up to rounding."""
    r = {k: curve.point(t + k * h) for k in range(-3, 4)}
    d1 = (r[3] - 9 * r[2] + 45 * r[1] - 45 * r[-1] + 9 * r[-2] - r[-3]) / (60 * h)
    d2 = (-r[2] + 16 * r[1] - 30 * r[0] + 16 * r[-1] - r[-2]) / (12 * h * h)
    d3 = (-r[3] + 8 * r[2] - 13 * r[1] + 13 * r[-1] - 8 * r[-2] + r[-3]) / (8 * h**3)
    return d1, d2, d3


def test_curvature_and_torsion_match_finite_differences_of_points():
    p0, d0, p1, d1, ang = random_data(30, seed=11)
    curve = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2], ang[:, 1])
    t = np.linspace(0.1, 0.9, 9)
    f1, f2, f3 = finite_difference_derivatives(curve, t)
    c = np.cross(f1, f2)
    kappa = np.linalg.norm(c, axis=-1) / np.linalg.norm(f1, axis=-1) ** 3
    tau = np.einsum("...i,...i", c, f3) / np.einsum("...i,...i", c, c)
    np.testing.assert_allclose(curve.curvature(t), kappa, rtol=1e-7)
    assert np.max(np.abs(curve.torsion(t) - tau) / (np.abs(tau) + kappa)) < 1e-7


def test_euler_rodrigues_frame_is_orthonormal_with_tangent_first():
    p0, d0, p1, d1, ang = random_data(10, seed=5)
    curve = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2])
    t = np.linspace(0, 1, 7)
    e1, e2, e3 = curve.frame_vectors(t)
    R = np.stack([e1, e2, e3], axis=-1)
    np.testing.assert_allclose(R.swapaxes(-1, -2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    tangent = curve.hodograph(t)
    np.testing.assert_allclose(e1, tangent / np.linalg.norm(tangent, axis=-1, keepdims=True), atol=1e-12)
    q = curve.frame(t)
    np.testing.assert_allclose(
        Rotation.from_quat(q.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_matrix(), R.reshape(-1, 3, 3), atol=1e-12
    )


def test_adding_one_angle_to_all_three_leaves_the_curve_unchanged():
    p0, d0, p1, d1, ang = random_data(50, seed=13)
    theta = np.random.default_rng(2).uniform(-np.pi, np.pi, size=50)
    a = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2], ang[:, 1])
    b = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0] + theta, ang[:, 2] + theta, ang[:, 1] + theta)
    np.testing.assert_allclose(np.stack(a.control_points()), np.stack(b.control_points()), atol=1e-12)
    c = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0] + 0.5, ang[:, 2], ang[:, 1])
    assert np.min(np.max(np.abs(np.stack(a.control_points()) - np.stack(c.control_points())), axis=(0, 2))) > 1e-6


def test_casadi_symbols_give_the_numpy_values():
    p0, d0, p1, d1, ang = random_data(3, seed=17)
    data = [ca.SX.sym(n, 3) for n in ("p0", "d0", "p1", "d1")]
    phi = ca.SX.sym("phi", 3)
    curve = ph_quintic_hermite(*data, phi[0], phi[2], phi[1])
    t = ca.DM([[0.0, 0.3, 0.8, 1.0]])
    f = ca.Function(
        "ph",
        [*data, phi],
        [curve.point(t), curve.hodograph(t), curve.curvature(t), curve.torsion(t), curve.arc_length(), curve.frame(t)],
    )
    for n in range(3):
        out = f(p0[n], d0[n], p1[n], d1[n], ang[n])
        ref = ph_quintic_hermite(p0[n], d0[n], p1[n], d1[n], *ang[n][[0, 2, 1]])
        tn = np.array([0.0, 0.3, 0.8, 1.0])
        np.testing.assert_allclose(np.array(out[0]).T, ref.point(tn), atol=1e-12)
        np.testing.assert_allclose(np.array(out[1]).T, ref.hodograph(tn), atol=1e-12)
        np.testing.assert_allclose(np.array(out[2]).ravel(), ref.curvature(tn), rtol=1e-10)
        np.testing.assert_allclose(np.array(out[3]).ravel(), ref.torsion(tn), rtol=1e-9)
        np.testing.assert_allclose(float(out[4]), ref.arc_length(), rtol=1e-13)
        np.testing.assert_allclose(np.array(out[5]).T, ref.frame(tn), atol=1e-12)


def test_parametrisation_does_not_depend_on_the_coordinate_frame():
    """Rotating the data rotates the member of the same free angles (the family is rotation-invariant)."""
    p0, d0, p1, d1, ang = random_data(100, seed=19)
    R = Rotation.random(100, random_state=4)
    a = ph_quintic_hermite(p0, d0, p1, d1, ang[:, 0], ang[:, 2])
    b = ph_quintic_hermite(R.apply(p0), R.apply(d0), R.apply(p1), R.apply(d1), ang[:, 0], ang[:, 2])
    rotated = np.stack([R.apply(P) for P in a.control_points()])
    np.testing.assert_allclose(np.stack(b.control_points()), rotated, atol=1e-12)
