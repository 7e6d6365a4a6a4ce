"""Fast exact CBHA tube lengths (:mod:`optikin.baselines.exact_tubes`) against independent references.

References: finite differences of the chain (the geometric Jacobian), the dense 48 x 48 Newton
step solved by LAPACK (numpy), the postures' own tube lengths in closed form (the recording's
rule: every leg at the same fraction of its Table I range), and the slow path it replaces,
CasADi's rootfinder through :func:`~optikin.baselines.ph_comparators.newton_raphson_step`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from optikin.arms.cbha import CBHAArm
from optikin.baselines.exact_tubes import ExactTubeLengths, newton_step_function, section_ends_jacobian
from optikin.baselines.ph_comparators import (
    NR_PRESET,
    newton_raphson_problem,
    newton_raphson_step,
    newton_raphson_tube_lengths,
    relative_section_ends,
    section_end_markers,
)
from optikin.data.markers import configurations_from_fractions
from optikin.ik.cbha import section_slices
from optikin.problems.ph_shared import recording_of
from optikin.solvers import build_preset


@pytest.fixture(scope="module")
def arm():
    return CBHAArm()


@pytest.fixture(scope="module")
def fast(arm):
    return ExactTubeLengths(arm)


@pytest.fixture(scope="module")
def reference(arm):
    return newton_raphson_problem(arm), build_preset(NR_PRESET)


def fractions(n: int, seed: int) -> np.ndarray:
    """Random elongation fractions ``(n + 5, sections, tubes)`` plus the edge cases first: straight (all 0.5),
    every leg at its Table I minimum, at its maximum, and two postures with tubes at opposite limits."""
    rng = np.random.default_rng(seed)
    edge = np.array(
        [
            np.full((2, 3), 0.5),
            np.zeros((2, 3)),
            np.ones((2, 3)),
            [[0.0, 1.0, 0.0], [1.0, 0.0, 1.0]],
            [[1.0, 1.0, 0.0], [0.0, 0.5, 1.0]],
        ]
    )
    return np.concatenate([edge, rng.uniform(0, 1, (n, 2, 3))])


def ends_of(arm: CBHAArm, X: np.ndarray) -> np.ndarray:
    frames = arm.section_frames(X)
    return np.concatenate([pos for _, pos in frames], axis=-1)


def closed_form_tube_lengths(arm: CBHAArm, F: np.ndarray) -> np.ndarray:
    """Whole tube lengths ``(N, 3)`` of fractions ``F``: ``sum_k q_min,k + f_s sum_k (q_max,k - q_min,k)``."""
    lo, hi = np.asarray(arm.geometry.leg_min), np.asarray(arm.geometry.leg_max)
    return sum(lo[s].sum() + F[:, i, :] * (hi[s] - lo[s]).sum() for i, s in enumerate(section_slices(arm.geometry)))


def test_geometric_jacobian_matches_finite_differences(arm):
    x = ca.SX.sym("x", arm.n_config)
    f = ca.Function("ends", [x], list(section_ends_jacobian(arm, x)))
    X = configurations_from_fractions(arm, fractions(3, 0))
    for q in X:
        ends, P = (np.asarray(v) for v in f(q))
        np.testing.assert_allclose(ends.ravel(), ends_of(arm, q), rtol=0, atol=1e-15)
        h = 1e-6
        fd = np.column_stack(
            [(ends_of(arm, q + h * e) - ends_of(arm, q - h * e)) / (2 * h) for e in np.eye(arm.n_config)]
        )
        np.testing.assert_allclose(P, fd, rtol=0, atol=1e-9)


def test_block_eliminated_step_is_the_dense_newton_step(arm, reference):
    """The step at straight, limit and random points (targets of other postures) equals ``-J^-1 r`` of the
    48 x 48 system, solved densely by LAPACK; the check-only Function gives the same residuals."""
    problem, _ = reference
    step, check = newton_step_function(arm), newton_step_function(arm, step=False)
    X = configurations_from_fractions(arm, fractions(4, 1))
    E = ends_of(arm, X)
    n = arm.n_config
    for i, x in enumerate(X):
        target = E[(i + 1) % len(E)]
        r, J = (np.asarray(v) for v in problem.residual_jacobian(x, target))
        dense = -np.linalg.solve(J, r.ravel())
        out = np.asarray(step(np.concatenate([x, target]))).ravel()
        expected = np.clip(x + dense, arm.lower, arm.upper)  # the step's end point is clipped to the bounds
        np.testing.assert_allclose(out[:n], expected, rtol=0, atol=1e-12 * max(1.0, np.abs(dense).max()))
        assert out[n] == pytest.approx(np.abs(r).max(), rel=1e-12)
        assert out[n + 1] == pytest.approx(np.linalg.norm(r), rel=1e-12)
        checked = np.asarray(check(np.concatenate([x, target]))).ravel()
        np.testing.assert_allclose(checked[[0, 1, 3, 4, 5, 6]], out[n:][[0, 1, 3, 4, 5, 6]], rtol=1e-12, atol=1e-15)


def test_postures_match_closed_form_and_slow_path(arm, fast, reference):
    """Random postures and the edge cases, cold from the straight configuration and warm from a nearby
    posture: the tube lengths of the closed form and the rootfinder's answer, both to 1e-10."""
    problem, newton = reference
    F = fractions(25, 2)
    X = configurations_from_fractions(arm, F)
    E, L = ends_of(arm, X), closed_form_tube_lengths(arm, F)
    nearby = configurations_from_fractions(arm, np.clip(F + 0.03, 0.0, 1.0))
    rest = arm.straight_configuration()
    solved_cold = 0
    for i in range(len(X)):
        for start in (None, nearby[i]):
            posture = fast.solve(E[i], start)
            slow, slow_lengths, _ = newton_raphson_step(arm, newton, problem, rest if start is None else start, E[i])
            if start is not None or slow.status == "ok":
                assert posture.status == "ok", (i, start is None, posture.message)
            if posture.status != "ok":
                continue
            solved_cold += start is None
            np.testing.assert_allclose(posture.lengths, L[i], rtol=0, atol=1e-10)
            np.testing.assert_allclose(posture.x, X[i], rtol=0, atol=1e-10)
            assert slow.status == "ok"
            np.testing.assert_allclose(posture.x, slow.x, rtol=0, atol=1e-10)
            np.testing.assert_allclose(posture.lengths, slow_lengths, rtol=0, atol=1e-10)
    assert solved_cold >= len(X) - 3
    straight = fast.solve(E[0])  # the straight posture is the start itself
    assert straight.status == "ok" and np.abs(straight.x - rest).max() <= 1e-15


def test_unreachable_ends_are_not_ok(arm, fast, reference):
    problem, newton = reference
    X = configurations_from_fractions(arm, fractions(0, 3))
    for ends in (ends_of(arm, X[1]) * 3.0, ends_of(arm, X[2]) + np.array([0, 0, 0.05, 0, 0, 0.05])):
        posture = fast.solve(ends, X[1])
        assert posture.status != "ok"
        assert np.all(np.isnan(posture.lengths))
        assert newton_raphson_step(arm, newton, problem, X[1], ends)[0].status != "ok"


def test_recording_matches_the_newton_raphson_comparator(arm, fast):
    """The recording of ``cbha-ph-shape`` (100 noisy postures, in order, warm-started): the comparator's
    statuses and tube lengths to 1e-10."""
    recording = recording_of("cbha-ph-shape").with_fixed_base()
    targets = relative_section_ends(recording, section_end_markers(arm, recording, "test"))
    run = fast.run(targets)
    slow = newton_raphson_tube_lengths(arm, recording, "sections")
    assert run.status == slow.status
    assert run.status.count("ok") == len(targets)
    np.testing.assert_allclose(run.lengths, slow.lengths, rtol=0, atol=1e-10)
    assert np.mean(np.abs(run.lengths - recording.tube_lengths)) < 1e-3  # the comparator's 0.5 mm
