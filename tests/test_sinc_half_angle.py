"""``B.sinc`` and ``B.one_minus_cos_over_square`` in half-angle form: same values and derivatives as the
square-root form they replace (``sin(sqrt(x^2))/sqrt(x^2)``), at ``x = 0``, around the series band and
beyond, and the constant-curvature FK evaluates one sine and one cosine per angle."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from optikin.algebra import backend as B
from optikin.arms.constant_curvature import ConstantCurvatureArm

BAND = B.SERIES_BAND
POINTS = [0.0, 1e-9, 5e-4, BAND * (1 - 1e-9), BAND * (1 + 1e-9), 2 * BAND * (1 + 1e-9), 1e-2, 0.3, 1.0, 2.0, 3.0]
POINTS += [-x for x in POINTS[1:]]


def old_sinc(x):
    return B.sinc_of_square(x * x)


def old_one_minus_cos(x):
    half = B.sinc_of_square(0.25 * x * x)
    return 0.5 * half * half


def series(offset):
    """``x -> (f, f', f'')`` of ``f = sum_k (-1)^k x^2k / (2k + offset)!`` summed term by term (no cancellation):
    offset 1 is ``sin(x)/x``, offset 2 ``(1 - cos x)/x^2``."""

    def values(x):
        f = d = dd = 0.0
        for k in range(30):
            c = (-1) ** k / math.factorial(2 * k + offset)
            f += c * x ** (2 * k)
            if k:
                d += c * 2 * k * x ** (2 * k - 1)
                dd += c * 2 * k * (2 * k - 1) * x ** (2 * k - 2)
        return np.array([f, d, dd])

    return values


def derivatives(f):
    """``x -> (f, f', f'')`` by CasADi's automatic differentiation."""
    x = ca.SX.sym("x")
    y = f(x)
    dy = ca.gradient(y, x)
    return ca.Function("d", [x], [y, dy, ca.gradient(dy, x)])


def tolerance(x):
    """Rounding of the closed form outside the band: ``eps / x^k`` for the k-th derivative."""
    scale = max(abs(x), BAND)
    return 4e-16 * np.array([1.0, 1 / scale, 1 / scale**2]) + 1e-15


@pytest.mark.parametrize(
    "new, old, offset",
    [(B.sinc, old_sinc, 1), (B.one_minus_cos_over_square, old_one_minus_cos, 2)],
)
def test_values_and_derivatives_match_the_square_root_form_and_the_series(new, old, offset):
    d_new, d_old, truth = derivatives(new), derivatives(old), series(offset)
    for x in POINTS:
        got = np.array([float(v) for v in d_new(x)])
        want = np.array([float(v) for v in d_old(x)])
        assert np.all(np.abs(got - truth(x)) <= tolerance(x)), (x, got - truth(x))
        assert np.all(np.abs(got - want) <= 2 * tolerance(x)), (x, got - want)
        assert float(new(np.float64(x))) == pytest.approx(got[0], rel=1e-15, abs=0)  # numpy path


def test_the_limits_at_zero():
    s, ds, dds = (float(v) for v in derivatives(B.sinc)(0.0))
    assert (s, ds) == (1.0, 0.0) and dds == pytest.approx(-1 / 3, rel=1e-15)
    c, dc, ddc = (float(v) for v in derivatives(B.one_minus_cos_over_square)(0.0))
    assert (c, dc) == (0.5, 0.0) and ddc == pytest.approx(-1 / 12, rel=1e-15)
    np.testing.assert_allclose(B.sinc(np.array([0.0, 0.2])), np.sinc(np.array([0.0, 0.2]) / np.pi), rtol=1e-15)


def test_cc_forward_kinematics_evaluates_each_half_angle_once():
    """Per section sin and cos of theta/2 (quaternion and position alike) and of phi: no square root."""
    arm = ConstantCurvatureArm()
    for name in ("fk_dq", "fk_position"):
        f = getattr(arm, name)
        ops = [f.instruction_id(k) for k in range(f.n_instructions())]
        assert ops.count(ca.OP_SIN) == 2 * arm.n_sections, name
        assert ops.count(ca.OP_COS) == 2 * arm.n_sections, name
        assert ops.count(ca.OP_SQRT) == 0, name
