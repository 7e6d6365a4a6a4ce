"""The vectorised SoA tip-pose kernel against the CasADi Function (the reference) and a closed form."""

from __future__ import annotations

import numpy as np
import pytest

from optikin import fk_soa
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.batch import batch_evaluate

TOL = 1e-14


def _kernel(m: int) -> fk_soa.SoAKernel:
    runner = fk_soa.kernel(m)
    if runner is None:
        pytest.skip("no C compiler for the SoA kernel")
    return runner


def _configurations(arm: ConstantCurvatureArm, n: int, seed: int) -> np.ndarray:
    """Random configurations with the edge cases in every section: theta = 0, +-1e-8, +-pi, phi far outside +-pi."""
    rng = np.random.default_rng(seed)
    Q = rng.uniform(arm.lower, arm.upper, (n, arm.n_config))
    theta, phi = Q[:, 1::3], Q[:, 2::3]
    edges = [0.0, 1e-8, -1e-8, np.pi, -np.pi, 1e-3, 0.999e-3]
    for k, value in enumerate(edges):
        theta[k :: 2 * len(edges)] = value
    theta[3 * len(edges) : 6 * len(edges)] = 0.0  # every section straight at once
    phi[1::5] = rng.uniform(-100.0, 100.0, phi[1::5].shape)
    return Q


@pytest.mark.parametrize("m", [1, 2, 4])
@pytest.mark.parametrize("name", ["fk_dq", "fk_position"])
def test_kernel_agrees_with_the_casadi_function(m, name):
    arm = ConstantCurvatureArm(section_lengths=tuple(0.1 + 0.05 * i for i in range(m)))
    runner = _kernel(m)
    Q = _configurations(arm, 3001, seed=m)
    reference = batch_evaluate(arm.function(name), Q)[..., 0]
    assert np.abs(runner(name, Q) - reference).max() <= TOL
    soa = runner.soa(name, np.ascontiguousarray(Q.T))
    assert np.abs(soa.T - reference).max() <= TOL
    # through ArmModel.evaluate, which takes this path for a CC arm
    assert np.array_equal(arm.evaluate(name, Q), runner(name, Q))
    assert np.array_equal(arm.evaluate(name, Q[5]), runner(name, Q[5:6])[0])


def test_one_section_closed_form():
    """Seed 000 eq. (1): p = S [cos phi (1 - cos theta)/theta, sin phi (1 - cos theta)/theta, sin theta / theta]."""
    arm = ConstantCurvatureArm(section_lengths=(0.2,))
    runner = _kernel(1)
    rng = np.random.default_rng(3)
    S, theta, phi = rng.uniform(0.1, 0.3, 500), rng.uniform(0.01, np.pi, 500), rng.uniform(-7.0, 7.0, 500)
    p = runner("fk_position", np.column_stack([S, theta, phi]))
    ratio = (1 - np.cos(theta)) / theta
    expected = S[:, None] * np.column_stack([np.cos(phi) * ratio, np.sin(phi) * ratio, np.sin(theta) / theta])
    assert np.abs(p - expected).max() <= 1e-15
    straight = runner("fk_dq", np.array([[0.2, 0.0, 1.3]]))[0]
    assert np.array_equal(straight, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1])
    assert arm.evaluate("fk_position", np.array([0.2, 0.0, 1.3]))[2] == 0.2


def test_unit_dual_quaternion_and_nan_rows():
    arm = ConstantCurvatureArm()
    runner = _kernel(2)
    Q = _configurations(arm, 999, seed=7)
    Q[4, 1] = np.nan
    dq = runner("fk_dq", Q)
    assert np.isnan(dq[4]).all() and np.isfinite(np.delete(dq, 4, axis=0)).all()
    good = np.delete(dq, 4, axis=0)
    real, dual = good[:, :4], good[:, 4:]
    assert np.abs(np.sum(real * real, axis=1) - 1.0).max() < 1e-15
    assert np.abs(np.sum(real * dual, axis=1)).max() < 1e-16


def test_empty_batch_and_other_arms():
    arm = ConstantCurvatureArm()
    _kernel(2)
    assert arm.evaluate("fk_dq", np.zeros((0, 6))).shape == (0, 8)
    assert fk_soa.soa_evaluate(arm, "fk_transform", np.zeros((1, 6))) is None

    class Bent(ConstantCurvatureArm):
        def section_frames(self, q):
            return super().section_frames(q)

    assert not fk_soa.applies(Bent(), "fk_dq")
    assert fk_soa.applies(arm, "fk_position")


def test_a_sample_gives_the_same_bits_wherever_it_sits_in_the_batch():
    """The vector loop never leaves a scalar tail, so chunking a batch cannot change a result."""
    arm = ConstantCurvatureArm()
    runner = _kernel(2)
    Q = _configurations(arm, 301, seed=11)
    whole = runner("fk_dq", Q)
    for start, stop in [(0, 1), (5, 6), (7, 40), (255, 301), (290, 301)]:
        assert np.array_equal(runner("fk_dq", Q[start:stop]), whole[start:stop])
        assert np.array_equal(runner.soa("fk_dq", np.ascontiguousarray(Q[start:stop].T)).T, whole[start:stop])
