"""The fast DMP path (Cholesky fit shared by every dimension, roll-out as generated C) against the reference
(SVD least squares, roll-out in CasADi's virtual machine) on position, unit-quaternion and dual-quaternion DMPs."""

from __future__ import annotations

import numpy as np
import pytest

from optikin.data.demonstrations import smooth_pose_demonstration
from optikin.dmp import DMP, Euclidean, UnitQuaternion
from optikin.dmp import compiled as compiled_module
from optikin.dmp.pose import dual_quaternion_dmp
from optikin.dmp.regression import fit_lstsq
from optikin.errors import SolverError

BASIS = 20


@pytest.fixture(scope="module")
def demo():
    return smooth_pose_demonstration(samples=300, duration=3.0, seed=4)


def _cases(demo):
    return {
        "position": (DMP(Euclidean(3), n_basis=BASIS), demo.position),
        "unit quaternion": (DMP(UnitQuaternion(), n_basis=BASIS), demo.quaternion),
        "dual quaternion": (dual_quaternion_dmp(n_basis=BASIS), demo.dual_quaternion),
    }


@pytest.fixture(scope="module", params=["position", "unit quaternion", "dual quaternion"])
def case(request, demo):
    dmp, data = _cases(demo)[request.param]
    if compiled_module.compiled_rollout(dmp.space, BASIS) is None:
        pytest.skip("no C compiler for the roll-out")
    return dmp, data


def test_fit_and_rollout_agree_with_the_reference(demo, case):
    dmp, data = case
    problem = dmp.regression_problem(demo.t, data)
    fast = fit_lstsq(problem.X, problem.F, factorisation="cholesky")
    reference = fit_lstsq(problem.X, problem.F)
    scale = np.abs(reference.weights).max()
    assert np.abs(fast.weights - reference.weights).max() <= 1e-10 * scale
    assert abs(fast.residual - reference.residual) <= 1e-10 * max(reference.residual, 1e-300) + 1e-15

    dmp.imitate(demo.t, data)  # the Cholesky fit
    out = dmp.rollout(engine="compiled")
    ref = dmp.rollout(engine="casadi", weights=reference.weights)
    for name in ("y", "eta", "phase", "goal"):
        assert np.abs(getattr(out, name) - getattr(ref, name)).max() <= 1e-10, name
    # the same weights: the C loop is the virtual machine's arithmetic
    same = dmp.rollout(engine="casadi")
    assert np.abs(out.y - same.y).max() <= 1e-12


def test_every_per_step_input_reaches_the_compiled_loop(demo, case):
    """Goal switch, disturbance, coupling to a reference, output offset and a new tau and dt."""
    dmp, data = case
    dmp.imitate(demo.t, data)
    steps = 250
    t = np.arange(steps) * 0.01
    dim = dmp.space.dim
    disturbance = np.sin(t)[:, None] * np.linspace(0.5, 2.0, dim)
    offset = 1e-3 * np.cos(3 * t)[:, None] * np.ones(dim)
    reference = data[np.minimum(np.arange(steps), len(data) - 1)]
    kwargs = dict(
        duration=2.5,
        tau=2.0,
        dt=0.01,
        goal_switches=[(1.0, data[len(data) // 2])],
        disturbance=disturbance,
        reference=reference,
        offset=offset,
    )
    out = dmp.rollout(engine="compiled", **kwargs)
    ref = dmp.rollout(engine="casadi", **kwargs)
    assert out.y.shape == (steps + 1, dmp.space.size)
    for name in ("y", "eta", "phase", "goal"):
        assert np.abs(getattr(out, name) - getattr(ref, name)).max() <= 1e-12, name


def test_ridge_and_ill_conditioned_designs():
    rng = np.random.default_rng(2)
    X, F = rng.normal(size=(200, 12)), rng.normal(size=(200, 4))
    for ridge in (0.0, 1e-3, 10.0):
        fast, reference = fit_lstsq(X, F, ridge, factorisation="cholesky"), fit_lstsq(X, F, ridge)
        assert np.abs(fast.weights - reference.weights).max() <= 1e-12
        # stationarity of the ridge objective: X^T (X W^T - F) + ridge W^T = 0
        assert np.abs(X.T @ (X @ fast.weights.T - F) + ridge * fast.weights.T).max() <= 1e-10
    # two equal columns: the Gram matrix is singular; the SVD fallback gives the minimum-norm solution
    X[:, 3] = X[:, 2]
    fast = fit_lstsq(X, F, factorisation="cholesky")
    assert np.array_equal(fast.weights, fit_lstsq(X, F).weights)
    with pytest.raises(ValueError, match="factorisation"):
        fit_lstsq(X, F, factorisation="lu")


def test_auto_engine_waits_for_a_built_library(demo, monkeypatch):
    """``auto`` looks in the cache once, then compiles only after AUTO_BUILD_AFTER requests."""
    calls = []

    class Recorder:
        def __init__(self, space, n_basis, build=True):
            calls.append(build)
            if not build:
                raise SolverError("not built yet")

    monkeypatch.setattr(compiled_module, "CompiledRollout", Recorder)
    monkeypatch.setattr(compiled_module, "_ROLLOUTS", {})
    monkeypatch.setattr(compiled_module, "_UNBUILT", {})
    monkeypatch.setattr(compiled_module, "AUTO_BUILD_AFTER", 3)
    space = Euclidean(3)
    got = [compiled_module.compiled_rollout(space, BASIS, build=False) for _ in range(4)]
    assert got[:2] == [None, None] and isinstance(got[2], Recorder) and got[3] is got[2]
    assert calls == [False, True]
    dmp, data = _cases(demo)["position"]
    dmp.imitate(demo.t, data)
    with pytest.raises(ValueError, match="engine"):
        dmp.rollout(engine="fast")
