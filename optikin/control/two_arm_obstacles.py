"""Obstacles kept off both arms' tubes and the rope they hold: barrier rows of the joint two-arm QP.

The obstacles are those of :mod:`optikin.control.obstacles` (spheres, capsules, axis-aligned boxes,
half-spaces, static or moving along a path), written in the shared frame. The bodies are the two
arms' backbone samples (:class:`optikin.control.self_collision.PlacedArm`, tube radius ``r_k``) and,
with a rope, its samples (:class:`optikin.curves.catenary_sensitivity.RopeSamples`, radius 0). For
obstacle ``o`` and a sample ``p`` of a body the clearance is ``d = d_o(p - c_o(t)) - r`` (the exact
signed distance, 1-Lipschitz); its derivative is ``g' dp/dq`` with ``g = d d_o / d p`` from CasADi and
``dp/dq`` the arm's sample Jacobian, or, for the rope, ``dp/dG dG/dq`` through the catenary's implicit
function and the tips' Jacobians. The row of the discrete-time barrier (as in :mod:`optikin.control.obstacles`)

    (d d / d q) qdot >= -gamma (d - margin) + g' (c_o(t + dt) - c_o(t)) / dt

enters the QP for the ``points_per_obstacle`` samples of each body nearest to each obstacle. Between
samples a body keeps at least ``d - h / 2`` (``h`` its sample spacing).
"""

from __future__ import annotations

from typing import Sequence

import casadi as ca
import numpy as np

from optikin.control.obstacles import Obstacle
from optikin.control.two_arm import TwoArmModel
from optikin.fastcall import BufferedFunction


class TwoArmObstacleRows:
    """The QP's rows keeping both tubes and the rope ``margin`` off every obstacle (module docstring).

    Parameters
    ----------
    model:
        Both arms and the task (the rope's samples, when it has them, are a third body).
    obstacles:
        The obstacles, in the shared frame.
    margin, gamma, dt:
        Clearance kept [m], barrier rate [1/s] (``0 < gamma dt <= 1``), control period [s].
    points_per_obstacle:
        Samples per body and obstacle in the QP (the nearest).

    Attributes
    ----------
    A, b:
        ``(rows, n_1 + n_2)`` and ``(rows,)``, refreshed by :meth:`update`.
    bodies:
        Names of the bodies: ``arm 1``, ``arm 2`` (and ``rope``).
    """

    def __init__(
        self,
        model: TwoArmModel,
        obstacles: Sequence[Obstacle],
        margin: float,
        gamma: float,
        dt: float,
        points_per_obstacle: int = 3,
    ):
        if not obstacles:
            raise ValueError("no obstacles")
        if not (margin > 0 and 0 < gamma * dt <= 1 and points_per_obstacle >= 1):
            raise ValueError(
                f"need margin > 0, 0 < gamma dt <= 1, points_per_obstacle >= 1; got {margin}, {gamma * dt}"
            )
        self.model, self.obstacles = model, list(obstacles)
        self.margin, self.gamma, self.dt = float(margin), float(gamma), float(dt)
        first, second = model.arms
        self.rope = model.rope.samples if model.rope is not None else None
        sizes = [first.samples, second.samples] + ([len(self.rope.arc_lengths)] if self.rope is not None else [])
        self.bodies = ["arm 1", "arm 2"] + (["rope"] if self.rope is not None else [])
        edges = np.concatenate([[0], np.cumsum(sizes)])
        self.slices = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
        self.radii = [first.radius, second.radius, 0.0][: len(sizes)]
        self.k = [min(int(points_per_obstacle), size) for size in sizes]
        N = int(edges[-1])
        p, c = ca.SX.sym("p", 3), ca.SX.sym("c", 3)
        self._functions = []
        for ob in self.obstacles:
            dist = ob.distance(p, c)
            one = ca.Function("one", [p, c], [dist, ca.gradient(dist, p)]).map(N)
            P, C = ca.SX.sym("P", 3, N), ca.SX.sym("C", 3)
            d, g = one(P, ca.repmat(C, 1, N))
            self._functions.append(BufferedFunction(ca.Function("obstacle", [P, C], [d, g], {"cse": True})))
        self.rows = len(self.obstacles) * sum(self.k)
        self.A, self.b = np.zeros((self.rows, model.n)), np.zeros(self.rows)
        self.step = 0

    def reset(self) -> None:
        """Start a run at ``t = 0``."""
        self.step = 0

    def _points(self) -> list[np.ndarray]:
        first, second = self.model.arms
        return [first.P, second.P] + ([self.rope.P] if self.rope is not None else [])

    def distances(self, t: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per obstacle the clearances ``(N,)`` of every sample of every body (radii subtracted) and their position
        gradients ``(N, 3)``, at the model's last evaluation and time ``t`` (views, valid until the next call)."""
        points = np.concatenate(self._points()).T
        out = []
        for ob, f in zip(self.obstacles, self._functions):
            d, g = f(points, ob.offset(t))
            clearance = d.copy()
            for part, radius in zip(self.slices, self.radii):
                clearance[part] -= radius
            out.append((clearance, g.reshape(-1, 3)))
        return out

    def update(self) -> None:
        """The rows of the step from the model's last evaluation at ``t = step dt`` (then counts the step)."""
        m = self.model
        first, second = m.arms
        t = self.step * self.dt
        self.step += 1
        row = 0
        for ob, (clearance, gradient) in zip(self.obstacles, self.distances(t)):
            moved = ob.offset(t + self.dt) - ob.offset(t)
            for body, (part, k) in enumerate(zip(self.slices, self.k)):
                local = clearance[part]
                idx = np.argpartition(local, k - 1)[:k] if k < len(local) else np.arange(len(local))
                g = gradient[part][idx]
                rows = slice(row, row + k)
                self.A[rows] = 0.0
                if body == 0:
                    self.A[rows, : m.n1] = np.einsum("rk,rkn->rn", g, first.J[idx])
                elif body == 1:
                    self.A[rows, m.n1 :] = np.einsum("rk,rkn->rn", g, second.J[idx])
                else:
                    assert self.rope is not None
                    along = np.einsum("rk,rkg->rg", g, self.rope.J[idx])
                    self.A[rows, : m.n1] = along[:, :3] @ first.tip_jacobian
                    self.A[rows, m.n1 :] = along[:, 3:] @ second.tip_jacobian
                self.b[rows] = -self.gamma * (local[idx] - self.margin) + (g @ moved) / self.dt
                row += k

    def least(self, t: float) -> np.ndarray:
        """The least clearance of each body to any obstacle at the model's last evaluation, ``(bodies,)`` [m]."""
        found = np.full(len(self.bodies), np.inf)
        for clearance, _ in self.distances(t):
            for body, part in enumerate(self.slices):
                found[body] = min(found[body], float(clearance[part].min()))
        return found
