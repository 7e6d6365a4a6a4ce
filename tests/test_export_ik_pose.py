"""``optikin export --what ik-trajectory`` on tip-pose targets: the C warm-start chain against the Python path.

Targets are the unit dual quaternions of ``problems/cc-ik-pose-trajectory.yaml``'s trajectory with
unreachable poses put inside it: two beyond the reach bound and two twisted about the tip axis (a
torsion-free two-section arm cannot twist its tip: the reachable poses form a 5-D set), so the chain
is checked to go on after a failure. The C example (``main.c``) solves them with one call of
``optikin_ik_trajectory_trajectory``; Python with ``GaussNewton.solve_many(warm_start=True)``.

Inextensible sections (4 bending variables for 6 residuals): the solution is isolated, and statuses,
iterations, residuals and configurations agree (1e-10). Extensible sections (6 variables, pose
Jacobian of rank 5): each reachable pose has a curve of solutions; rounding in the nearly singular
step sets where along it each path lands, so the check is the pose reached (``fk_dq``, 1e-9) and the
rule of ``redundancy: previous`` (:func:`test_rank_five_pose_trajectory_stays_as_close_to_the_previous_solution`).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from optikin.algebra import dq_from_rotation_translation, dq_rotation, dq_translation, quat_multiply
from optikin.data.targets import unreachable_targets
from optikin.export import export, ik_setup
from optikin.export.context import context
from test_export import STATUS, numeric, run_example

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler cc on PATH")

PROBLEM = "cc-ik-pose-trajectory"
INEXTENSIBLE = [("arm.params.length_range", [1.0, 1.0])]
FAR, TWISTED = (50, 51), (120, 121)


def twisted(dq: np.ndarray, angle: float) -> np.ndarray:
    """Pose ``dq`` (8) turned by ``angle`` [rad] about its own z axis (the tip's tangent), same position."""
    turn = np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])
    return dq_from_rotation_translation(quat_multiply(dq_rotation(dq), turn), dq_translation(dq))


def with_unreachable_poses(targets: np.ndarray, arm) -> np.ndarray:
    P = targets.copy()
    P[list(FAR)] = unreachable_targets(arm, len(FAR), "pose", np.random.default_rng(1), (1.1, 1.5))
    for k, angle in zip(TWISTED, (0.2, 0.02)):
        P[k] = twisted(P[k], angle)
    return P


def chains(tmp_path, overrides=()):
    """The setup, the targets, the arm, the C example's rows and the Python warm-started batch."""
    setup = ik_setup(PROBLEM, overrides)
    arm = context(PROBLEM, ("ik",), "--what ik-trajectory", overrides).arm
    P = with_unreachable_poses(setup.targets, arm)
    out = numeric(run_example(export(PROBLEM, "ik-trajectory", tmp_path, overrides=overrides), P, tmp_path))
    batch = setup.adapter.solve_many(setup.problem, setup.start, P, warm_start=True)
    return setup, P, arm, out, batch


def pose_errors(arm, X: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Largest entry of ``fk_dq(x) - p`` per row, the nearer of the two signs of the dual quaternion."""
    reached = arm.evaluate("fk_dq", X)
    return np.minimum(np.abs(reached - P).max(axis=1), np.abs(reached + P).max(axis=1))


def check_failures(out: np.ndarray, batch, P: np.ndarray) -> None:
    """The four unreachable poses end unreachable in both paths, at the same distance; beyond the reach
    bound the residual is at least the distance of the target's position from the reach ball."""
    for k in FAR + TWISTED:
        assert STATUS[int(out[k, 0])] == batch.status[k] == "unreachable", k
        assert abs(out[k, 2] - batch.residual[k]) <= 1e-9
    for k in FAR:
        assert out[k, 2] >= np.linalg.norm(dq_translation(P[k])) - 0.396 - 1e-12


def test_inextensible_pose_trajectory_agrees_with_gauss_newton(tmp_path):
    setup, P, arm, out, batch = chains(tmp_path, INEXTENSIBLE)
    assert setup.problem.reduced.n == 4 and setup.problem.m == 6
    assert [STATUS[int(s)] for s in out[:, 0]] == list(batch.status)
    assert list(out[:, 1].astype(int)) == list(batch.iterations)
    np.testing.assert_allclose(out[:, 2], batch.residual, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out[:, 3:], batch.x, rtol=0, atol=1e-10)
    check_failures(out, batch, P)
    ok = out[:, 0] == 0
    assert ok.sum() == len(P) - 4
    assert pose_errors(arm, out[ok, 3:], P[ok]).max() < 1e-9


def weighted_moves(problem, X: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """``||W dist(x_k, x_prev_k)||`` per row: the weighted distance of ``redundancy: previous`` (chord
    ``2 sin(d/2)`` for angles that wrap, ``W`` the problem's weights, the inverse ranges)."""
    d = X - previous
    d = np.where(problem.periodic, 2.0 * np.sin(d / 2.0), d)
    return np.linalg.norm(problem.weights * d, axis=1)


def test_rank_five_pose_trajectory_stays_as_close_to_the_previous_solution(tmp_path):
    """Extensible sections: a curve of solutions per reachable pose. The rule tested, per target k:

    * statuses equal Python's warm-started chain; an ``ok`` C answer reaches the pose to 1e-9;
    * from the same start (the C answer to target k - 1), C's answer is no farther from that start
      than Python's Gauss-Newton answer, up to 5 % (``d_C <= 1.05 d_Python + 1e-9``, ``d`` the weighted
      distance of :func:`weighted_moves`), and where the curve is regular (both bending angles at least
      0.3 rad at both ends) the two answers agree to 1e-6;
    * along the whole trajectory C's path is no longer than Python's chain's, up to 1 %.

    Near a straight section (bending angle near 0) the curve of solutions turns sharply and the
    minimum-norm steps from nearly equal points part there (up to 0.05 rad apart along the curve).
    """
    setup, P, arm, out, batch = chains(tmp_path)
    problem = setup.problem
    assert problem.reduced.n == 6 and problem.m == 6
    assert [STATUS[int(s)] for s in out[:, 0]] == list(batch.status)
    check_failures(out, batch, P)
    ok = out[:, 0] == 0
    assert ok.sum() == len(P) - 4
    XC = out[:, 3:]
    assert pose_errors(arm, XC[ok], P[ok]).max() < 1e-9

    starts = np.vstack([setup.start, XC[:-1]])
    same_start = [setup.adapter.solve(problem, s, p) for s, p in zip(starts, P)]
    assert [STATUS[int(s)] for s in out[:, 0]] == [s.status for s in same_start]
    XP = np.array([s.x for s in same_start])
    d_c, d_p = weighted_moves(problem, XC, starts), weighted_moves(problem, XP, starts)
    assert np.all(d_c[ok] <= 1.05 * d_p[ok] + 1e-9), np.max((d_c - d_p)[ok] / d_p[ok])
    theta = [problem.variable_names.index(name) for name in ("theta1", "theta2")]
    regular = ok & (np.abs(XC[:, theta]).min(axis=1) >= 0.3) & (np.abs(starts[:, theta]).min(axis=1) >= 0.3)
    assert regular.sum() >= len(P) // 2
    np.testing.assert_allclose(XC[regular], XP[regular], rtol=0, atol=1e-6)

    chain = weighted_moves(problem, batch.x, np.vstack([setup.start, batch.x[:-1]]))
    assert d_c.sum() <= 1.01 * chain.sum()
