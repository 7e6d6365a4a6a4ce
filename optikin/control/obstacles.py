"""Obstacles around the whole arm: signed distances of backbone samples and their rows in the tracking QP.

Obstacles. Spheres (centre, radius), capsules (segment ``a``-``b``, radius), axis-aligned
boxes (centre, half extents) and half-spaces (a point on the plane, the outward normal: the
obstacle is the side ``n'(p - p0) < 0``), each static or translated along a path of
offsets ``(t, dx, dy, dz)`` interpolated linearly in time and held beyond its ends.
Every distance is the exact signed distance (negative inside), hence 1-Lipschitz in the point.

The backbone as samples. The arm's backbone is sampled at ``points_per_section`` equal
arc-length steps per section (:meth:`optikin.arms.base.ArmModel.backbone_points`), spacing
``h <= S_max / points_per_section``. A backbone point lies within arc length (so within
distance) ``h/2`` of a sample, and a signed distance is 1-Lipschitz, so the continuous
backbone keeps at least ``min_samples d - h/2`` from every obstacle: with samples held at
``d >= d_safe`` and ``h/2 <= d_safe / 2`` (the default density ``ceil(S_max / d_safe)``) no
point of the curve comes within ``d_safe / 2``. Samples are used rather than the distance to
each section's arc because the arc-to-obstacle distance has no closed form (a circle against a
capsule or box needs an inner minimisation whose derivative is not smooth where the closest
point jumps), while the sampled distances and their Jacobian are one CasADi expression.

Barrier rows. With ``h_ij = d_ij - d_safe`` for obstacle ``i`` and sample ``j``, the
discrete-time control barrier function condition (Agrawal & Sreenath 2017)
``h(q_{k+1}, t_{k+1}) >= (1 - gamma dt) h(q_k, t_k)``, ``0 < gamma dt <= 1``, linearised
about ``(q_k, t_k)``, ``h + dt D qdot - G' dc >= (1 - gamma dt) h``, is the row

    D qdot >= -gamma (d - d_safe) + G' dc / dt

with ``D = d d / d q = G' d p_j / d q`` from CasADi (``G = d d / d p``, the chain rule through
the backbone Jacobian) and ``dc`` the obstacle's translation over the step (``d`` depends on
``p - c``; zero for a static obstacle, where the row is ``d_dot >= -gamma (d - d_safe)``).
Only the ``points_per_obstacle`` samples nearest to each obstacle at this step enter the QP,
so it keeps a fixed size: a barrier row limits a sample only near ``d_safe``, and the nearest
samples reach it first; :meth:`optikin.control.simulate.TrackingRun` metrics check all the
samples along the run, so a sample that was left out and came too close would show.

Feasibility. The task enters the QP as a least-squares objective, i.e. its slack is free
(``s = J qdot - v``, penalised); the barrier rows and the rate box are hard. With every sample
at ``d >= d_safe`` and a static obstacle, ``qdot = 0`` satisfies every row, so the QP stays
feasible wherever the reference goes, through an obstacle included; a moving obstacle can
ask for more than the rate limits give, and the QP's failure is then reported as such.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Sequence

import casadi as ca
import numpy as np

from optikin.arms.base import ArmModel
from optikin.fastcall import BufferedFunction
from optikin.interrupt import calls_casadi

Shape = Literal["sphere", "capsule", "box", "halfspace"]
_TABLE_STEPS = 1 << 15  # moving obstacles' offsets tabulated per control step, at most this many
_TINY = 1e-12  # keeps the gradient of a Euclidean norm finite at zero; shifts distances by at most 1e-12 m


def _norm(v: ca.SX) -> ca.SX:
    return ca.sqrt(ca.sumsqr(v) + _TINY**2) - _TINY


@dataclass(frozen=True)
class Obstacle:
    """One obstacle: its shape, geometry (metres, base frame) and motion.

    Parameters
    ----------
    shape:
        ``sphere`` (``center``, ``radius``), ``capsule`` (``a``, ``b``, ``radius``),
        ``box`` (``center``, ``half_extents``, axis-aligned) or ``halfspace`` (``point``, ``normal``).
    center, radius, a, b, half_extents, point, normal:
        The geometry at zero offset.
    path:
        ``(t, dx, dy, dz)`` rows, times increasing [s, m]: the offset added to the geometry;
        ``None``: static.
    """

    shape: Shape
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    a: tuple[float, float, float] = (0.0, 0.0, 0.0)
    b: tuple[float, float, float] = (0.0, 0.0, 0.0)
    half_extents: tuple[float, float, float] = (0.0, 0.0, 0.0)
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    path: tuple[tuple[float, float, float, float], ...] | None = None

    def __post_init__(self):
        if self.shape in ("sphere", "capsule") and not self.radius > 0:
            raise ValueError(f"a {self.shape} needs a positive radius, got {self.radius}")
        if self.shape == "box" and not min(self.half_extents) > 0:
            raise ValueError(f"a box needs positive half extents, got {self.half_extents}")
        if self.shape == "halfspace" and not np.linalg.norm(self.normal) > 0:
            raise ValueError("a half-space needs a non-zero normal")
        if self.path is not None:
            times = np.array([row[0] for row in self.path])
            if len(times) < 1 or np.any(np.diff(times) <= 0):
                raise ValueError("path times must increase")

    def offset(self, t: float | np.ndarray) -> np.ndarray:
        """The translation at time(s) ``t`` [s], ``(3,)`` or ``(len(t), 3)`` [m]."""
        if self.path is None:
            return np.zeros(np.shape(t) + (3,))
        rows = np.asarray(self.path, dtype=float)
        return np.stack([np.interp(t, rows[:, 0], rows[:, 1 + j]) for j in range(3)], axis=-1)

    def distance(self, p: ca.SX, offset: ca.SX) -> ca.SX:
        """Signed distance of point ``p`` (3 x 1) to the obstacle translated by ``offset`` [m]."""
        if self.shape == "sphere":
            return _norm(p - (ca.DM(self.center) + offset)) - self.radius
        if self.shape == "capsule":
            a, b = ca.DM(self.a) + offset, ca.DM(self.b) - ca.DM(self.a)
            along = ca.fmin(ca.fmax(ca.dot(p - a, b) / max(float(ca.sumsqr(b)), _TINY), 0.0), 1.0)
            return _norm(p - a - along * b) - self.radius
        if self.shape == "box":
            gap = ca.fabs(p - (ca.DM(self.center) + offset)) - ca.DM(self.half_extents)
            return _norm(ca.fmax(gap, 0.0)) + ca.fmin(ca.mmax(gap), 0.0)
        n = np.asarray(self.normal, dtype=float)
        return ca.dot(ca.DM(n / np.linalg.norm(n)), p - (ca.DM(self.point) + offset))

    def distances(self, points: np.ndarray, t: float | np.ndarray = 0.0) -> np.ndarray:
        """Signed distances of ``points`` ``(3, K)`` at time ``t`` (one, or one per point), ``(K,)`` [m]."""
        p, c = ca.SX.sym("p", 3), ca.SX.sym("c", 3)
        count = points.shape[1]
        offsets = np.broadcast_to(self.offset(t), (count, 3)).T
        f = ca.Function("d", [p, c], [self.distance(p, c)]).map(count)
        return np.asarray(f(points, offsets)).ravel()

    def surface(self, t: float = 0.0, count: int = 400, extent: float = 0.15) -> np.ndarray:
        """About ``count`` points on the surface at time ``t``, ``(M, 3)`` [m] (for drawing).

        Points on a sphere around the obstacle projected along the distance gradient,
        ``p - d(p) grad d(p)`` (exact for these signed distances outside the obstacle); for a
        half-space a square of side ``2 extent`` [m] of its plane around ``point``.
        """
        offset = self.offset(t)
        if self.shape == "halfspace":
            n = np.asarray(self.normal, dtype=float) / np.linalg.norm(self.normal)
            u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
            u /= np.linalg.norm(u)
            w = np.cross(n, u)
            side = np.linspace(-extent, extent, int(np.sqrt(count)))
            a, b = np.meshgrid(side, side)
            return np.asarray(self.point) + offset + a.reshape(-1, 1) * u + b.reshape(-1, 1) * w
        middle = {"sphere": self.center, "box": self.center}.get(self.shape)
        centre = 0.5 * (np.add(self.a, self.b)) if middle is None else np.asarray(middle, dtype=float)
        k = np.arange(count) + 0.5  # a Fibonacci sphere: evenly spread directions
        polar, azimuth = np.arccos(1.0 - 2.0 * k / count), np.pi * (1.0 + 5**0.5) * k
        directions = np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)])
        reach = 2.0 * (
            self.radius + float(np.linalg.norm(self.half_extents)) + float(np.linalg.norm(np.subtract(self.b, self.a)))
        )
        points = (centre + offset)[:, None] + reach * directions
        p, c = ca.SX.sym("p", 3), ca.SX.sym("c", 3)
        dist = self.distance(p, c)
        f = ca.Function("projection", [p, c], [p - dist * ca.gradient(dist, p)]).map(count)
        return np.asarray(f(points, np.tile(offset[:, None], count))).T


def sampling_density(arm: ArmModel, margin: float) -> int:
    """Points per section whose half spacing is at most ``margin / 2``: ``ceil(S_max / margin)`` (module docstring)."""
    return max(1, int(np.ceil(max_section_length(arm) / margin - 1e-9)))


def max_section_length(arm: ArmModel) -> float:
    """The longest any section can get [m] (upper limit of the ``S*`` variables)."""
    lengths = [arm.upper[i] for i, name in enumerate(arm.config_names) if name.startswith("S")]
    if not lengths:
        raise ValueError(f"{arm.name} has no section-length variables S*; the backbone spacing is unknown")
    return float(max(lengths))


@dataclass
class BackboneDistances:
    """The Function ``(q, offsets) -> (d, G, D)`` of every obstacle and backbone sample.

    :attr:`d` is ``(n_obstacles, K)``, the signed distances with every obstacle translated by
    its column of ``offsets`` ``(3, n_obstacles)``; :attr:`G_rows` ``(n_obstacles K, 3)`` their
    gradients with respect to the sample's position (row ``i K + j``: obstacle ``i``,
    sample ``j``); :attr:`D` ``(n_obstacles K, n)`` the distance Jacobian, row ``i K + j``
    being ``G_rows[iK+j] d p_j / d q`` (chain rule through the backbone Jacobian);
    :attr:`b_static` ``(n_obstacles K,)`` the barrier bound ``-gamma (d - margin)`` of every pair
    (the rows' ``b`` without the obstacles' motion; zero with the default ``gamma``).
    """

    arm: ArmModel
    obstacles: Sequence[Obstacle]
    points_per_section: int
    compiled: bool = False
    margin: float = 0.0
    gamma: float = 0.0
    function: ca.Function = field(init=False)

    def __post_init__(self):
        if not self.obstacles:
            raise ValueError("no obstacles")
        n, count = self.arm.n_config, len(self.obstacles)
        q, offsets, p = ca.SX.sym("q", n), ca.SX.sym("offsets", 3, count), ca.SX.sym("p", 3)
        points = self.arm.backbone_points(q, self.points_per_section)
        self.samples = K = int(points.shape[1])
        self._points = ca.Function("backbone", [q], [points])
        d_rows, g_cols = [], []
        for i, ob in enumerate(self.obstacles):
            c = ca.SX.sym("c", 3)
            dist = ob.distance(p, c)
            one = ca.Function("one", [p, c], [dist, ca.gradient(dist, p)]).map(K)
            d, g = one(points, ca.repmat(offsets[:, i], 1, K))
            d_rows.append(d)
            g_cols.append(g)
        sample_jacobian = ca.jacobian(ca.vec(points), q)
        gradients = ca.horzcat(*g_cols)
        distance_jacobian = ca.vertcat(
            *[gradients[:, i * K + j].T @ sample_jacobian[3 * j : 3 * j + 3, :] for i in range(count) for j in range(K)]
        )
        self.function = ca.Function(
            "backbone_distances",
            [q, offsets],
            [
                ca.vertcat(*d_rows).T,
                gradients,
                distance_jacobian.T,
                -self.gamma * (ca.vertcat(*d_rows).T - self.margin),
            ],
            ["q", "offsets"],
            ["d", "G", "D", "b_static"],
            {"cse": True},
        )
        self._f = BufferedFunction(self.function, compiled=self.compiled)
        self._q, self._offsets = self._f.inputs
        # Transposed outputs, so that the column-major buffers read as row-major (n_obstacles, K),
        # (n_obstacles K, 3) and (n_obstacles K, n) arrays without copies.
        self.d_flat = self._f.outputs[0]
        self.d = self.d_flat.reshape(count, K)
        self.G_rows = self._f.outputs[1].reshape(count * K, 3)
        self.D = self._f.outputs[2].reshape(count * K, n)
        self.b_static = self._f.outputs[3]
        self.moving = [i for i, ob in enumerate(self.obstacles) if ob.path is not None]
        self._static = np.zeros((3, count))
        self._offsets[:] = 0.0
        self._holds_static = True

    def points_at(self, q: np.ndarray) -> np.ndarray:
        """The backbone samples of configuration ``q``, ``(3, K)`` [m]."""
        return np.asarray(self._points(q))

    def offsets(self, t: float) -> np.ndarray:
        """Every obstacle's translation at ``t``, ``(3, n_obstacles)`` [m] (not to be modified)."""
        if not self.moving:
            return self._static
        out = self._static.copy()
        for i in self.moving:
            out[:, i] = self.obstacles[i].offset(t)
        return out

    @calls_casadi
    def evaluate(self, q: np.ndarray, offsets: np.ndarray) -> None:
        """Refresh :attr:`d`, :attr:`G_rows`, :attr:`D` (views, valid until the next call)."""
        self._q[:] = q
        if offsets is not self._static or not self._holds_static:  # static obstacles: written once
            self._offsets[:] = offsets.ravel(order="F")
            self._holds_static = offsets is self._static
        self._f._trigger()

    @calls_casadi
    def evaluate_flat(self, q: np.ndarray, offsets_flat: np.ndarray) -> None:
        """:meth:`evaluate` with the offsets given column-major flattened, ``(3 n_obstacles,)`` [m]."""
        self._q[:] = q
        self._offsets[:] = offsets_flat
        self._holds_static = False
        self._f._trigger()

    def jacobian(self, flat: np.ndarray) -> np.ndarray:
        """``d d / d q`` of the (obstacle, sample) pairs ``flat`` (``i K + j``), ``(len(flat), n)``."""
        return self.D[flat]

    def sampled(self, Q: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Distances of every sample along a run: ``(N, n_obstacles, K)`` for configurations ``Q`` ``(N, n)``."""
        out = np.empty((len(t), len(self.obstacles), self.samples))
        for k, (q, tk) in enumerate(zip(Q, t)):
            self.evaluate(q, self.offsets(tk))
            out[k] = self.d
        return out


class BarrierRows:
    """The QP's inequality rows ``A qdot >= b`` of the backbone barrier (module docstring).

    Parameters
    ----------
    arm, dt:
        The arm and the control period [s].
    obstacles:
        The obstacles.
    margin:
        ``d_safe`` [m], the distance kept by every sample.
    gamma:
        Barrier rate [1/s], ``0 < gamma dt <= 1``.
    points_per_obstacle:
        Samples per obstacle entering the QP each step (the nearest).
    points_per_section:
        Backbone samples per section; ``None``: :func:`sampling_density` of ``margin``.
    compiled:
        Compile the distance Function with a C compiler.

    Attributes
    ----------
    A, b:
        ``(rows, n)`` and ``(rows,)``, ``rows = n_obstacles points_per_obstacle``, refreshed by :meth:`update`.
    selected:
        ``(rows,)`` the row's sample as an index into :attr:`BackboneDistances.D` (``obstacle samples +
        sample``), refreshed by :meth:`update`.
    """

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        obstacles: Sequence[Obstacle],
        margin: float = 0.01,
        gamma: float = 20.0,
        points_per_obstacle: int = 3,
        points_per_section: int | None = None,
        compiled: bool = False,
    ):
        if not margin > 0:
            raise ValueError(f"margin must be positive, got {margin}")
        if not 0 < gamma * dt <= 1:
            raise ValueError(f"gamma dt must be in (0, 1], got gamma {gamma} 1/s at dt {dt} s")
        self.dt, self.margin, self.gamma = float(dt), float(margin), float(gamma)
        pps = sampling_density(arm, margin) if points_per_section is None else int(points_per_section)
        self.spacing = max_section_length(arm) / pps
        self.distances = BackboneDistances(arm, obstacles, pps, compiled, self.margin, self.gamma)
        self.points_per_obstacle = min(int(points_per_obstacle), self.distances.samples)
        if self.points_per_obstacle < 1:
            raise ValueError("points_per_obstacle must be at least 1")
        count = len(obstacles)
        self.rows = count * self.points_per_obstacle
        self.A = np.zeros((self.rows, arm.n_config))
        self.b = np.full(self.rows, -np.inf)
        self._base = (np.arange(count) * self.distances.samples)[:, None]
        self._flat = np.empty((count, self.points_per_obstacle), dtype=np.intp)
        self.selected = self._flat.reshape(-1)
        if self.points_per_obstacle == self.distances.samples:
            self._flat[:] = self._base + np.arange(self.distances.samples)
        self._G = np.empty((self.rows, 3))
        self._G_by_obstacle = self._G.reshape(count, self.points_per_obstacle, 3)
        self._moved = np.empty((count, self.points_per_obstacle, 1))
        self._moved_rows = self._moved.reshape(-1)
        self._table_offsets, self._table_steps, self._settled = self._offset_table()
        self.step = 0

    def _offset_table(self) -> tuple[np.ndarray, np.ndarray, int]:
        """The moving obstacles' offsets per control step, tabulated once.

        Returns
        -------
        offsets:
            ``(S + 1, 3 n_obstacles)`` [m]: row ``s < S`` the offsets at ``t = s dt`` (column-major),
            the last row those held beyond every path's end.
        changes:
            ``(S + 1, n_obstacles, 3, 1)`` [m/s]: ``(offset(s dt + dt) - offset(s dt)) / dt``, zero in the
            last row.
        settled:
            The first step from which every path is held. ``S = min(settled, _TABLE_STEPS)``; steps
            from ``S`` to ``settled`` are left to :meth:`update` to compute.
        """
        d = self.distances
        count = len(d.obstacles)
        if not d.moving:
            return np.zeros((0, 3 * count)), np.zeros((0, count, 3, 1)), 0
        end = max(float(d.obstacles[i].path[-1][0]) for i in d.moving)
        settled = max(0, int(np.ceil(end / self.dt)) + 1)
        stored = min(settled, _TABLE_STEPS) + 1  # the extra row: the held offsets
        t = np.arange(stored) * self.dt
        t[-1] = max(end, t[-1])
        now = np.zeros((stored, 3, count))
        after = np.zeros((stored, 3, count))
        for i in d.moving:
            now[:, :, i] = d.obstacles[i].offset(t)
            after[:, :, i] = d.obstacles[i].offset(t + self.dt)
        change = np.ascontiguousarray(((after - now) / self.dt).transpose(0, 2, 1))[:, :, :, None]
        change[-1] = 0.0
        return np.ascontiguousarray(now.transpose(0, 2, 1)).reshape(stored, 3 * count), change, settled

    def reset(self) -> None:
        """Start a run at ``t = 0``."""
        self.step = 0

    def update(self, q: np.ndarray) -> None:
        """The rows for the step from ``q`` at ``t = step dt`` to the next instant (then counts the step).

        The ``points_per_obstacle`` nearest samples of each obstacle, in the order of
        ``np.argpartition(distances.d, points_per_obstacle - 1, axis=1)``; written in place into
        :attr:`A` and :attr:`b`.
        """
        dt, d, s = self.dt, self.distances, self.step
        self.step += 1
        change = None
        if not d.moving:
            d.evaluate(q, d._static)
        elif 0 <= s < len(self._table_offsets) - 1 or s >= self._settled:
            row = min(s, len(self._table_offsets) - 1)
            d.evaluate_flat(q, self._table_offsets[row])
            change = self._table_steps[row]
        else:  # before the paths' end but beyond the table, or a negative step
            now = d.offsets(s * dt)
            d.evaluate(q, now)
            change = ((d.offsets(s * dt + dt) - now) / dt).T[:, :, None]
        k, flat = self.points_per_obstacle, self.selected
        if k < d.samples:
            np.add(d.d.argpartition(k - 1, axis=1)[:, :k], self._base, out=self._flat)
        np.take(d.D, flat, axis=0, out=self.A)
        np.take(d.b_static, flat, out=self.b)
        if change is not None:
            # The obstacle's own step: d(q, t + dt) - d(q, t) = -G' (c(t + dt) - c(t)) to first order.
            np.take(d.G_rows, flat, axis=0, out=self._G)
            np.matmul(self._G_by_obstacle, change, out=self._moved)
            np.add(self.b, self._moved_rows, out=self.b)
