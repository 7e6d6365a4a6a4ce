"""The C-backed Gauss-Newton IK batch (:mod:`optikin.native.ik`) against the Python path it replaces.

The reference is :meth:`GaussNewton.solve_many` with the C path turned off (``OPTIKIN_NATIVE=0``):
statuses, messages and iterations equal target by target, configurations and residuals within 1e-12
(the C evaluates the same step Functions, code-generated). Independently of both, a solved position
target is reached by the arm's forward kinematics.
"""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

import optikin.native
import optikin.native.ik as native_ik
from optikin.export import ik_setup
from optikin.native.ik import native_solve_many, solve_many

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler gcc on PATH")


@pytest.fixture(scope="module")
def position():
    return ik_setup("cc-ik-position")


@pytest.fixture(scope="module")
def trajectory():
    return ik_setup("cc-ik-trajectory")


def reference(setup, X0, P, warm, monkeypatch):
    """The Python path: the adapter's own solve_many with the C path turned off."""
    monkeypatch.setenv(optikin.native.ENVIRONMENT, "0")
    try:
        assert native_solve_many(setup.adapter, setup.problem, X0, P, warm) is None
        return setup.adapter.solve_many(setup.problem, X0, P, warm_start=warm)
    finally:
        monkeypatch.delenv(optikin.native.ENVIRONMENT)


def assert_same(ours, theirs):
    assert ours.status == theirs.status
    assert ours.messages == theirs.messages
    np.testing.assert_array_equal(ours.iterations, theirs.iterations)
    np.testing.assert_allclose(ours.x, theirs.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.residual, theirs.residual, rtol=0, atol=1e-12)


def test_a_trajectory_matches_the_warm_started_python_path(trajectory, monkeypatch):
    P = trajectory.targets[:300]
    ours = native_solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P, True)
    assert ours is not None and ours.batched
    assert_same(ours, reference(trajectory, trajectory.start, P, True, monkeypatch))
    assert ours.status.count("ok") == len(P)


def test_independent_targets_match_the_batched_python_path(position, monkeypatch):
    """The first 400 targets of cc-ik-position, some not converged within the iteration limit."""
    P = position.targets[:400]
    ours = native_solve_many(position.adapter, position.problem, position.start, P, False)
    assert ours is not None
    assert_same(ours, reference(position, position.start, P, False, monkeypatch))
    assert ours.status.count("ok") >= 380


def test_solved_targets_are_reached_by_the_forward_kinematics(position):
    """Independent of both solvers: ||fk_position(x) - p|| is the residual, within the tolerance."""
    from optikin.runner import prepare

    arm = prepare("cc-ik-position")[1].arm
    P = position.targets[:50]
    batch = native_solve_many(position.adapter, position.problem, position.start, P, False)
    assert batch is not None
    for x, p, status, residual in zip(batch.x, P, batch.status, batch.residual):
        distance = np.linalg.norm(np.asarray(arm.fk_position(x)).ravel() - p)
        assert abs(distance - residual) <= 1e-12
        if status == "ok":
            assert distance <= position.problem.tolerance


def test_unreachable_targets_take_the_newton_switch_as_in_python(monkeypatch):
    """Targets beyond reach: the stalled samples switch to the Newton model and end ``unreachable``, with the
    Python path's message (or, for a few, not converged within the iteration limit, as in Python), independent
    and along a trajectory."""
    setup = ik_setup("cc-ik-unreachable")
    outside = np.flatnonzero(np.linalg.norm(setup.targets, axis=1) > 0.396)[:10]
    P = setup.targets[np.concatenate([np.arange(10), outside])]
    for warm in (False, True):
        ours = native_solve_many(setup.adapter, setup.problem, setup.start, P, warm)
        assert ours is not None
        assert_same(ours, reference(setup, setup.start, P, warm, monkeypatch))
        assert ours.status[10:].count("unreachable") >= 8 and "ok" not in ours.status[10:]
        assert np.all(ours.residual[10:] >= np.linalg.norm(P[10:], axis=1) - 0.396 - 1e-12)


def test_pose_targets_along_a_trajectory_match(monkeypatch):
    setup = ik_setup("cc-ik-pose-trajectory")
    P = setup.targets[:150]
    ours = native_solve_many(setup.adapter, setup.problem, setup.start, P, True)
    assert ours is not None
    assert_same(ours, reference(setup, setup.start, P, True, monkeypatch))


def test_fixed_variables_are_substituted_and_put_back(monkeypatch):
    """cc-ik-points: inextensible sections, solved over the free variables and returned at their value."""
    setup = ik_setup("cc-ik-points")
    P = setup.targets[:20]
    fixed = setup.problem.fixed
    assert fixed.any()
    ours = native_solve_many(setup.adapter, setup.problem, setup.start, P, False)
    assert ours is not None
    np.testing.assert_array_equal(ours.x[:, fixed], np.broadcast_to(setup.problem.lower[fixed], (20, fixed.sum())))
    assert_same(ours, reference(setup, setup.start, P, False, monkeypatch))


@pytest.mark.parametrize("warm", [False, True], ids=["independent", "trajectory"])
def test_a_start_per_target_and_chunks(trajectory, monkeypatch, warm):
    """Rows of X0 as starts (a trajectory: until the first solution), and batches split into C calls of 7
    targets: the chain of warm starts carries over from one call to the next."""
    rng = np.random.default_rng(3)
    P = trajectory.targets[:40]
    X0 = trajectory.problem.lower + rng.uniform(0, 1, (40, trajectory.problem.n)) * trajectory.problem.span
    monkeypatch.setattr(native_ik, "CHUNK", 7)
    ours = native_solve_many(trajectory.adapter, trajectory.problem, X0, P, warm)
    assert ours is not None
    assert_same(ours, reference(trajectory, X0, P, warm, monkeypatch))


def test_what_the_c_does_not_cover_runs_the_python_path(trajectory, monkeypatch):
    """Turned off, a non-finite target, another backend: None from the C path, and solve_many gives the
    adapter's own answer."""
    from optikin.solvers import build_preset

    P = trajectory.targets[:5].copy()
    monkeypatch.setenv(optikin.native.ENVIRONMENT, "off")
    assert native_solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P) is None
    monkeypatch.delenv(optikin.native.ENVIRONMENT)
    optikin.native.use_native(False)
    try:
        assert native_solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P) is None
    finally:
        optikin.native.use_native(None)
    P[2, 0] = np.nan
    assert native_solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P) is None
    batch = solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P)
    assert batch.status == trajectory.adapter.solve_many(trajectory.problem, trajectory.start, P).status
    assert batch.status[2] != "ok"
    lm = build_preset("lm")
    assert native_solve_many(lm, trajectory.problem, trajectory.start, P[:2]) is None


def test_without_a_compiler_one_log_line_and_the_python_path(monkeypatch, caplog, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(optikin.native, "_reported", set())
    setup = ik_setup("cc-ik-trajectory")  # a fresh problem: nothing compiled for it in this process
    P = setup.targets[:5]
    with caplog.at_level(logging.INFO, logger="optikin.native"):
        for _ in range(2):
            assert native_solve_many(setup.adapter, setup.problem, setup.start, P, True) is None
        batch = solve_many(setup.adapter, setup.problem, setup.start, P, warm_start=True)
    lines = [r.getMessage() for r in caplog.records if r.name == "optikin.native"]
    assert len(lines) == 1 and "gcc" in lines[0] and "reference path" in lines[0]
    assert batch.status == ["ok"] * 5


@pytest.mark.slow
def test_cbha_platforms_through_the_c_match(monkeypatch):
    """solve_platforms (16 platform problems of the CBHA, one C library each) with and without the C path."""
    from optikin.arms.cbha import CBHAArm
    from optikin.ik.formulation import rest_configuration
    from optikin.ik.platform import platform_problems, solve_platforms
    from optikin.solvers import build_preset

    arm = CBHAArm()
    legs = arm.evaluate("leg_lengths", arm.sample_configurations(30, np.random.default_rng(5))).reshape(30, -1)
    problems, adapter, rest = platform_problems(arm, 1e-12), build_preset("gauss-newton"), rest_configuration(arm)
    ours = solve_platforms(adapter, problems, legs, rest)
    assert ours.batched and ours.status == ["ok"] * 30
    monkeypatch.setenv(optikin.native.ENVIRONMENT, "0")
    assert_same(ours, solve_platforms(adapter, problems, legs, rest))


def test_threads_share_the_library(trajectory):
    """Each C call owns its work arrays: batches in two threads at once give the answers of one."""
    from concurrent.futures import ThreadPoolExecutor

    P = trajectory.targets[:200]
    alone = native_solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P, True)

    def run(_):
        return native_solve_many(trajectory.adapter, trajectory.problem, trajectory.start, P, True)

    with ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(run, [0, 1]))
    for batch in runs:
        assert_same(batch, alone)
