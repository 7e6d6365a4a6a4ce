"""The fast DMP path (the demonstration's gaps in one C call, the design matrix and its Cholesky factor cached,
roll-out as generated C with the features of every step in advance) against the reference (gaps in numpy, SVD
least squares, roll-out in CasADi's virtual machine) on position, unit-quaternion and dual-quaternion DMPs."""

from __future__ import annotations

import numpy as np
import pytest
import pytransform3d.rotations as pr

from optikin.algebra import dq_from_rotation_translation
from optikin.data.demonstrations import smooth_pose_demonstration
from optikin.dmp import DMP, Euclidean, Gains, GoalLogQuaternion, Product, UnitDualQuaternion, UnitQuaternion, basis
from optikin.dmp import compiled as compiled_module
from optikin.dmp import imitation, regression
from optikin.dmp.imitation import prepare
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
        assert fast.residual == pytest.approx(np.sqrt(np.mean((X @ reference.weights.T - F) ** 2)), rel=1e-12)
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
    dmp.imitate(demo.t, data, engine="numpy")
    with pytest.raises(ValueError, match="engine"):
        dmp.rollout(engine="fast")


# ---------------------------------------------------------------- the demonstration's gaps, tables and caches
AXIS = np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93])
SPACES = {
    "position": Euclidean(3),
    "unit quaternion": UnitQuaternion(),
    "goal-log quaternion": GoalLogQuaternion(),
    "dual quaternion": UnitDualQuaternion(),
    "cartesian": Product(Euclidean(3), UnitQuaternion()),
}


def _motion(space, total_deg: float, samples: int = 300, duration: float = 3.0):
    """A minimum-jerk turn by ``total_deg`` about a fixed axis (pytransform3d's quaternions) with a straight
    translation, in the layout of ``space``; ``total_deg = 0`` and no translation is a constant demonstration."""
    t = np.linspace(0.0, duration, samples)
    s = t / duration
    s = 10 * s**3 - 15 * s**4 + 6 * s**5
    q = np.array([pr.quaternion_from_axis_angle(np.r_[AXIS, a]) for a in np.deg2rad(total_deg) * s])
    q *= np.concatenate([[1.0], np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))])[:, None]
    p = (s[:, None] * np.array([0.1, -0.05, 0.1]) if total_deg else np.zeros((samples, 3))) + [0.02, 0.01, 0.3]
    layout = {
        "R3": p,
        "S3": q,
        "S3-log": q,
        "DQ": dq_from_rotation_translation(q, p),
        "R3 x S3": np.hstack([p, q]),
    }
    return t, layout[space.name]


@pytest.fixture(scope="module", params=list(SPACES))
def kernels(request):
    space = SPACES[request.param]
    runner = compiled_module.compiled_rollout(space, BASIS)
    if runner is None:
        pytest.skip("no C compiler for the roll-out")
    return space, runner


@pytest.mark.parametrize("total_deg", [0.0, 90.0, 181.0, 270.0, 350.0])
def test_compiled_gaps_agree_with_numpy(kernels, total_deg):
    """The goal gaps lifted from the last sample back and the steps, in one C call, against the numpy path
    (which lifts sample by sample where a branch changes: past half a turn for these goals)."""
    space, runner = kernels
    t, Y = _motion(space, total_deg)
    fast = prepare(space, t, Y, gaps=runner.prepare)
    reference = prepare(space, t, Y)
    assert np.abs(fast.goal_gap - reference.goal_gap).max() <= 1e-12
    assert np.abs(fast.step_rate - reference.step_rate).max() <= 1e-12 * max(1.0, np.abs(reference.step_rate).max())
    if total_deg == 0.0:
        assert np.abs(fast.goal_gap).max() <= 1e-15 and np.abs(fast.step_rate).max() <= 1e-13
    if total_deg == 270.0 and space.name == "S3":  # the lifted gap at the start: the whole turn, not -90 degrees
        assert np.linalg.norm(fast.goal_gap[0]) == pytest.approx(np.deg2rad(270.0), abs=1e-9)
    assert runner.gap(Y[-1], Y[0]) == pytest.approx(np.asarray(space.gap(Y[-1], Y[0])), abs=1e-14)


@pytest.mark.parametrize("total_deg", [0.0, 270.0])
def test_fast_pipeline_agrees_with_the_reference(kernels, total_deg):
    """Imitation (C gaps, cached design and factor) and roll-out (tabulated features, the plain step) against
    numpy gaps, SVD and CasADi's virtual machine, on a turn past half a turn and a constant demonstration."""
    space, _ = kernels
    t, Y = _motion(space, total_deg)
    fast, reference = DMP(space, n_basis=BASIS), DMP(space, n_basis=BASIS)
    fast.imitate(t, Y, engine="compiled")
    for cache in (imitation._DESIGNS, regression._FACTORS, basis._TABLES):
        cache.clear()
    reference.imitate(t, Y, factorisation="svd", engine="numpy")
    scale = max(np.abs(reference.weights).max(), 1.0)
    assert np.abs(fast.weights - reference.weights).max() <= 1e-10 * scale
    out, ref = fast.rollout(engine="compiled"), reference.rollout(engine="casadi")
    for name in ("y", "eta", "phase", "goal"):
        assert np.abs(getattr(out, name) - getattr(ref, name)).max() <= 1e-10, name
    assert np.abs(out.y[-1] - Y[-1]).max() <= 2e-3  # the demonstration replayed to its goal
    if total_deg == 0.0:
        assert np.abs(out.y - Y[0]).max() <= 1e-12  # at rest on the goal it stays


def test_tabulated_features_are_the_phase_of_the_reference(demo):
    """The features passed to the C loop are those of the phase CasADi's roll-out integrates (eq. 15), gated."""
    dmp, data = _cases(demo)["position"]
    dmp.imitate(demo.t, data)
    ref = dmp.rollout(duration=4.0, tau=2.5, engine="casadi")
    c, h, s_end = dmp.centres, dmp.widths, dmp.forcing_end
    table = basis.rollout_features(ref.t.size - 1, dmp.dt, 2.5, dmp.gains.zeta, c, h, s_end)
    s = ref.phase[:-1]
    psi = np.exp(-h * (s[:, None] - c) ** 2)
    expected = np.where(s[:, None] > s_end, s[:, None] * psi / psi.sum(axis=1, keepdims=True), 0.0)
    assert np.abs(table - expected).max() <= 1e-14
    assert not table.flags.writeable
    assert 0 < np.count_nonzero(s <= s_end) < s.size  # the gate is inside this roll-out


def test_phase_stopping_uses_the_full_step(demo):
    """With ``alpha > 0`` the phase depends on the state: no table; the full C step against the reference,
    coupled to a lagging reference so that the phase really stops."""
    dmp, data = _cases(demo)["unit quaternion"]
    dmp.imitate(demo.t, data)
    slow = Gains(alpha=5.0, alpha_s=2.0)
    reference = data[np.maximum(np.arange(len(data) - 1) - 20, 0)]
    out = dmp.rollout(engine="compiled", gains=slow, reference=reference)
    ref = dmp.rollout(engine="casadi", gains=slow, reference=reference)
    free = dmp.rollout(engine="casadi")
    assert out.phase[-1] > 1.5 * free.phase[-1]  # the phase was slowed
    for name in ("y", "eta", "phase", "goal"):
        assert np.abs(getattr(out, name) - getattr(ref, name)).max() <= 1e-12, name


def test_caches_follow_the_demonstration_timing(demo):
    """A second demonstration with another step misses the design cache; both fits match the reference."""
    dmp = DMP(Euclidean(3), n_basis=BASIS)
    for stretch in (1.0, 2.0, 1.0):
        t = demo.t * stretch
        dmp.imitate(t, demo.position)
        problem = dmp.regression_problem(t, demo.position)
        assert not problem.X.flags.writeable  # from the cache
        reference = DMP(Euclidean(3), n_basis=BASIS)
        for cache in (imitation._DESIGNS, regression._FACTORS):
            cache.clear()
        reference.imitate(t, demo.position, factorisation="svd", engine="numpy")
        assert np.abs(dmp.weights - reference.weights).max() <= 1e-10 * np.abs(reference.weights).max()
    with pytest.raises(ValueError, match="imitation engine"):
        dmp.imitate(demo.t, demo.position, engine="casadi")


def test_only_shared_designs_keep_their_factor():
    """A read-only view of a changing matrix is factorised on every fit; a shared design only once."""
    rng = np.random.default_rng(5)
    base, F = rng.normal(size=(120, 8)), rng.normal(size=(120, 2))
    view = base.view()
    view.flags.writeable = False
    first = fit_lstsq(view, F, factorisation="cholesky")
    base[:, 0] *= 3.0
    second = fit_lstsq(view, F, factorisation="cholesky")
    assert np.abs(second.weights - fit_lstsq(base, F).weights).max() <= 1e-12
    assert np.abs(second.weights - first.weights).max() > 1e-3
    with pytest.raises(ValueError, match="read-only"):
        regression.share_design(base)
    shared = base.copy()
    shared.flags.writeable = False
    regression.share_design(shared)
    for ridge in (0.0, 0.5, 0.0):
        fit = fit_lstsq(shared, F, ridge, factorisation="cholesky")
        assert np.abs(fit.weights - fit_lstsq(shared, F, ridge).weights).max() <= 1e-12
    assert set(regression._FACTORS[id(shared)][1]) == {0.0, 0.5}
