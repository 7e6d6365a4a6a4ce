"""The in-place barrier rows against a straightforward computation from the distance Function.

The reference evaluates ``BackboneDistances.function`` through CasADi's ordinary call (no buffers),
interpolates every obstacle's path at ``t`` and ``t + dt`` with ``np.interp``, picks the nearest
samples with ``np.argpartition`` and forms ``-gamma (d - d_safe) + G' dc / dt`` row by row.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control import obstacles as obstacles_module
from optikin.control.obstacles import BarrierRows, Obstacle

ARM = ConstantCurvatureArm()
DT = 0.002
MOVING_PATH = ((0.0, 0.0, 0.0, 0.0), (0.1, 0.02, -0.01, 0.0), (0.3, -0.03, 0.02, 0.01))
OBSTACLES = [
    Obstacle("sphere", center=(0.1, 0.0, 0.25), radius=0.04),
    Obstacle("capsule", a=(-0.1, 0.05, 0.1), b=(-0.1, -0.05, 0.3), radius=0.02),
    Obstacle("box", center=(0.0, 0.15, 0.2), half_extents=(0.03, 0.03, 0.05), path=MOVING_PATH),
    Obstacle("halfspace", point=(0.0, 0.0, -0.01), normal=(0.0, 0.0, 1.0)),
]


def reference_rows(barrier: BarrierRows, q: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of the step ``step`` from ``q``, computed without any of the update's buffers or tables."""
    dist = barrier.distances
    k, dt = barrier.points_per_obstacle, barrier.dt
    t = step * dt

    def offsets(time: float) -> np.ndarray:
        out = np.zeros((3, len(dist.obstacles)))
        for i, ob in enumerate(dist.obstacles):
            if ob.path is not None:
                rows = np.asarray(ob.path, dtype=float)
                out[:, i] = [np.interp(time, rows[:, 0], rows[:, 1 + j]) for j in range(3)]
        return out

    now = offsets(t)
    d, G, D = (np.asarray(value) for value in dist.function(q, now)[:3])
    d = d.T  # (n_obstacles, K)
    D = D.T  # (n_obstacles K, n)
    G = G.T  # (n_obstacles K, 3)
    change = offsets(t + dt) - now
    A, b = [], []
    for i in range(len(dist.obstacles)):
        nearest = np.argpartition(d[i], k - 1)[:k] if k < dist.samples else np.arange(dist.samples)
        for j in nearest:
            row = i * dist.samples + j
            A.append(D[row])
            b.append(-barrier.gamma * (d[i, j] - barrier.margin) + G[row] @ change[:, i] / dt)
    return np.array(A), np.array(b)


def random_configurations(rng: np.random.Generator, count: int) -> list[np.ndarray]:
    lower, upper = np.asarray(ARM.lower, dtype=float), np.asarray(ARM.upper, dtype=float)
    lower, upper = np.maximum(lower, -3.0), np.minimum(upper, 3.0)
    return [lower + (upper - lower) * rng.random(ARM.n_config) for _ in range(count)]


@pytest.mark.parametrize("points_per_obstacle", [1, 3])
def test_in_place_rows_match_the_reference_over_random_configurations_and_a_moving_obstacle(points_per_obstacle):
    barrier = BarrierRows(ARM, DT, OBSTACLES, margin=0.01, gamma=20.0, points_per_obstacle=points_per_obstacle)
    rng = np.random.default_rng(7)
    # steps before, at and after the path's breakpoints and its end (0.3 s = step 150), and far beyond
    steps = [0, 1, 49, 50, 51, 120, 149, 150, 151, 400, 10**6]
    for q, step in zip(random_configurations(rng, len(steps)), steps):
        barrier.step = step
        barrier.update(q)
        A, b = reference_rows(barrier, q, step)
        np.testing.assert_allclose(barrier.A, A, rtol=0, atol=1e-12)
        np.testing.assert_allclose(barrier.b, b, rtol=0, atol=1e-12)
        assert barrier.step == step + 1


def test_ties_pick_the_same_samples_as_argpartition():
    """A straight arm along a half-space: every sample at the same height ties with the others of its section."""
    flat = Obstacle("halfspace", point=(0.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0))
    barrier = BarrierRows(ARM, DT, [flat, OBSTACLES[0]], margin=0.01, gamma=20.0, points_per_obstacle=4)
    straight = np.array([0.18, 0.0, 0.0, 0.18, 0.0, 0.0])  # on the z axis: every sample at x = 0
    for q in [straight, *random_configurations(np.random.default_rng(3), 4)]:
        barrier.step = 0
        barrier.update(q)
        if q is straight:
            assert np.ptp(np.abs(barrier.distances.d[0])) == 0.0  # all samples tie
        A, b = reference_rows(barrier, q, 0)
        np.testing.assert_allclose(barrier.A, A, rtol=0, atol=1e-12)
        np.testing.assert_allclose(barrier.b, b, rtol=0, atol=1e-12)


def test_steps_beyond_the_offset_table_are_computed_on_the_fly(monkeypatch):
    monkeypatch.setattr(obstacles_module, "_TABLE_STEPS", 40)
    barrier = BarrierRows(ARM, DT, OBSTACLES[1:3], margin=0.01, gamma=20.0)
    assert len(barrier._table_offsets) == 41  # 40 steps and the held offsets
    rng = np.random.default_rng(11)
    steps = [39, 40, 41, 100, 149, 150, 151, 5000]
    for q, step in zip(random_configurations(rng, len(steps)), steps):
        barrier.step = step
        barrier.update(q)
        A, b = reference_rows(barrier, q, step)
        np.testing.assert_allclose(barrier.A, A, rtol=0, atol=1e-12)
        np.testing.assert_allclose(barrier.b, b, rtol=0, atol=1e-12)


def test_update_writes_into_the_same_arrays():
    barrier = BarrierRows(ARM, DT, OBSTACLES, margin=0.01, gamma=20.0)
    A, b = barrier.A, barrier.b
    for q in random_configurations(np.random.default_rng(5), 3):
        barrier.update(q)
        assert barrier.A is A and barrier.b is b
