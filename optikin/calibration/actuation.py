"""Actuation to shape by physics: a tendon-driven Kirchhoff rod whose lab parameters are fitted to recorded postures.

The model
---------
Each section ``k`` of the arm is an inextensible, unshearable rod (Kirchhoff) of length ``L_k``, bending
stiffness ``EI_k`` and torsional stiffness ``EI_k / (1 + nu)`` (a round backbone), straight at rest, carrying
its own weight (``linear_density`` [kg/m]) and a tip ``payload`` [kg]. Motor ``j`` (0-based) pulls a tendon
routed straight at ``tendon_offset`` from the backbone at the angle ``60 deg x j`` in the cross-section; the
tendons of motors ``2k, 2k + 1`` end at the end disk of section ``k``. Its tension is the motor input less a
per-motor offset, never negative, and zero for a motor at rest::

    tau_j = max(0, a_j - o_j)   (a_j > 0),    tau_j = 0   (a_j = 0).

The inputs are therefore read as commanded tensions [N]; a lab that commands tendon displacements needs the
tensions solved from the tendon path lengths, which this module does not do.

The section wrench carried by rod and tendons together obeys the rod equations with the external loads only
(Rucker & Webster 2011; :mod:`optikin.physics.tendons`): ``N(s) = F_tip + lambda g (L - s)`` is known, and
``M' = -p' x N``. With straight routing and no shear the tendon tangent is the backbone's up to torsion, so
the rod's own moment in the material frame is ``R^T M - sum_j tau_j (r_j x e3)`` over the tendons crossing
``s``, and the curvature is that moment over the stiffness. :func:`solve_shapes` shoots: the unknown base
moment ``M(0)`` (3 per posture) is found by Newton so that the tip carries no moment, every posture and every
parameter set side by side (rows), the integration a second-order Lie-group midpoint rule.

Calibration
-----------
:func:`fit` estimates, from training postures only, the bending stiffness of each section, the offset of each
motor, the payload mass, the section lengths and the base orientation by bounded nonlinear least squares
(:func:`scipy.optimize.least_squares`), with the base position and the marker offsets (one per disk, in the
disk's frame) eliminated by linear least squares at every step (variable projection). The tendon offset and
the backbone's linear density are given (a scale the data cannot separate from the stiffness: ``tau r / EI``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

MOTORS = 6
"""Tendons (and motors): two per section, three sections."""
SECTIONS = 3
GRAVITY = np.array([0.0, 0.0, -9.81])
"""Gravity in optikin's z-up frame [m/s^2]."""
POISSON = 0.33
"""Poisson ratio of the backbone: the torsional stiffness is ``EI / (1 + nu)``."""
NEWTON_TOLERANCE = 1e-11
"""Largest tip moment of an equilibrium [N m]."""
NEWTON_ITERATIONS = 30
STAGE_ITERATIONS = 8
"""Newton steps at most on the intermediate tensions of a continuation."""
LINE_SEARCH = 6
"""Step reductions (by 4) of a Newton step that does not reduce the tip moment, at most."""
FIT_ITERATIONS = 8
"""Newton steps at most of a warm-started solve inside the fit."""
HOMOTOPY = 4
"""Equal steps of the tensions from the nearest solved posture in :func:`predict`."""
REWEIGHTS = 5
"""Solves of the reweighted linear least squares of the base position and the marker offsets."""
NEAR = 1e-5
"""Tip moment [N m] below which a Newton step is taken whole, untested (the quadratic range)."""
CONTINUATION = (4, 16)
"""Equal steps of the tensions from the straight hanging rod when no start is given, tried in turn on the rows
not converged."""
"""Step reductions (by 4) of a Newton step that does not reduce the tip moment, at most."""
FD_STEP = 1e-6
"""Relative step of the finite differences of the shooting and of the parameter Jacobian."""


@dataclass(frozen=True)
class ActuationParams:
    """The parameters of the physics model (module docstring).

    Attributes
    ----------
    stiffness:
        ``(3,)`` bending stiffness ``EI`` of each section [N m^2].
    motor_offsets:
        ``(6,)`` tension lost by each motor [N].
    payload:
        Mass at the tip [kg].
    section_lengths:
        ``(3,)`` [m].
    base_rotation:
        ``(3, 3)`` the backbone's material frame at the base (its z the exit direction) in the recording frame.
    base_position:
        ``(3,)`` where the backbone starts [m].
    marker_offsets:
        ``(3, 3)`` each disk's marker in the disk's frame [m].
    tendon_offset:
        Distance of the tendons from the backbone [m].
    linear_density:
        Mass of the backbone per length [kg/m].
    """

    stiffness: np.ndarray
    motor_offsets: np.ndarray
    payload: float
    section_lengths: np.ndarray
    base_rotation: np.ndarray
    base_position: np.ndarray
    marker_offsets: np.ndarray
    tendon_offset: float = 0.012
    linear_density: float = 0.0099


def hanging_rotation() -> np.ndarray:
    """``(3, 3)`` the base frame of a backbone leaving straight down, its x along the recording's x."""
    return np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def _coefficients(theta2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin t / t`` and ``(1 - cos t) / t^2`` of ``t^2`` (no branch at zero)."""
    t = np.sqrt(theta2) / np.pi
    return np.sinc(t), 0.5 * np.sinc(t / 2) ** 2


def rotvec_matrix(w: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotation matrices of rotation vectors ``w (..., 3)`` [rad] (Rodrigues)."""
    w = np.asarray(w, dtype=float)
    theta2 = np.einsum("...i,...i->...", w, w)
    a, b = _coefficients(theta2)
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    outer = w[..., :, None] * w[..., None, :]
    return (1 - b * theta2)[..., None, None] * np.eye(3) + a[..., None, None] * K + b[..., None, None] * outer


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of ``(R, 3)`` arrays."""
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def _rotate(w: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``exp(w^) v`` row-wise for rotation vectors ``w (R, 3)`` and vectors ``v (R, 3)``."""
    theta2 = np.einsum("ni,ni->n", w, w)
    a, b = _coefficients(theta2)
    wv = _cross(w, v)
    return v + a[:, None] * wv + b[:, None] * _cross(w, wv)


def tensions(inputs: np.ndarray, motor_offsets: np.ndarray) -> np.ndarray:
    """``(..., 6)`` tendon tensions [N] from motor inputs ``(..., 6)`` [N] (module docstring)."""
    inputs = np.asarray(inputs, dtype=float)
    return np.where(inputs > 0, np.maximum(0.0, inputs - motor_offsets), 0.0)


def tendon_moments(tension: np.ndarray, tendon_offset: float) -> np.ndarray:
    """``(R, 3, 3)`` the tendons' moment on the rod in the material frame in each section, ``sum tau (r x e3)``
    over the tendons crossing it [N m], from tensions ``(R, 6)``."""
    angle = np.radians(60.0) * np.arange(MOTORS)
    r_cross_e3 = tendon_offset * np.stack([np.sin(angle), -np.cos(angle), np.zeros(MOTORS)], axis=1)
    per_motor = tension[:, :, None] * r_cross_e3[None]
    section_of = np.arange(MOTORS) // 2
    return np.stack([per_motor[:, section_of >= k].sum(axis=1) for k in range(SECTIONS)], axis=1)


Batch = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""Per-row arrays of a batch of rods: stiffness, lengths, tensions or moments, base-frame gravity, payload."""


def _take(batch: Batch, index: np.ndarray | slice) -> Batch:
    """The rows ``index`` of every array of ``batch``."""
    stiffness, lengths, actuation, g_base, payload = batch
    return stiffness[index], lengths[index], actuation[index], g_base[index], payload[index]


def _integrate(
    M0: np.ndarray,
    stiffness: np.ndarray,
    lengths: np.ndarray,
    moments: np.ndarray,
    g_base: np.ndarray,
    payload: np.ndarray,
    density: float,
    steps: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate rows from the base moment ``M0 (R, 3)``: disk positions ``(R, 3, 3)``, rotations ``(R, 3, 3, 3)``
    (in the base frame) and the tip moment ``(R, 3)``. ``stiffness, lengths (R, 3)``, ``moments (R, 3, 3)``,
    ``g_base (R, 3)``, ``payload (R,)``."""
    n = len(M0)
    p = np.zeros((n, 3))
    R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    M = M0.copy()
    total = lengths.sum(axis=1)
    tip_force = payload[:, None] * g_base
    weight = density * g_base
    positions = np.empty((n, SECTIONS, 3))
    rotations = np.empty((n, SECTIONS, 3, 3))
    e3 = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (n, 3))
    s = np.zeros(n)
    for k in range(SECTIONS):
        h = (lengths[:, k] / steps)[:, None]
        Kinv = np.stack([1 / stiffness[:, k], 1 / stiffness[:, k], (1 + POISSON) / stiffness[:, k]], axis=1)
        a = moments[:, k]
        for _ in range(steps):
            N_mid = tip_force + weight * (total - s - h[:, 0] / 2)[:, None]
            half = Kinv * (np.einsum("nji,nj->ni", R, M) - a) * h / 2
            t_half = np.einsum("nij,nj->ni", R, _rotate(half, e3))
            M_half = M - _cross(t_half * h / 2, N_mid)
            u = Kinv * (_rotate(-half, np.einsum("nji,nj->ni", R, M_half)) - a)
            dp = h * np.einsum("nij,nj->ni", R, _rotate(u * h / 2, e3))
            R = R @ rotvec_matrix(u * h)
            M = M - _cross(dp, N_mid)
            p = p + dp
            s = s + h[:, 0]
        positions[:, k], rotations[:, k] = p, R
    return positions, rotations, M


@dataclass(frozen=True)
class Shapes:
    """Equilibria of rows (postures x parameter sets) in the base frame.

    Attributes
    ----------
    positions, rotations:
        ``(R, 3, 3)`` disk positions [m] and ``(R, 3, 3, 3)`` disk frames, base frame.
    base_moment:
        ``(R, 3)`` the base moment solved [N m] (a warm start for the next solve).
    converged:
        ``(R,)`` bool: the tip moment is below :data:`NEWTON_TOLERANCE` (an equilibrium, on the branch reached
        from the start).
    """

    positions: np.ndarray
    rotations: np.ndarray
    base_moment: np.ndarray
    converged: np.ndarray


def _tip_jacobian(
    M0: np.ndarray,
    stiffness: np.ndarray,
    lengths: np.ndarray,
    moments: np.ndarray,
    g_base: np.ndarray,
    payload: np.ndarray,
    density: float,
    steps: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The tip moment ``(R, 3)`` [N m] at base moments ``M0 (R, 3)`` and its derivative ``(R, 3, 3)`` by forward
    differences, the four integrations of a row side by side."""
    n = len(M0)
    d = FD_STEP * (1e-3 + np.abs(moments).max(axis=(1, 2)))
    stacked = np.repeat(M0, 4, axis=0).reshape(n, 4, 3)
    for i in range(3):
        stacked[:, i + 1, i] += d
    repeated = np.repeat(np.arange(n), 4)
    _, _, tip = _integrate(
        stacked.reshape(-1, 3), *_take((stiffness, lengths, moments, g_base, payload), repeated), density, steps
    )
    tip = tip.reshape(n, 4, 3)
    return tip[:, 0], (tip[:, 1:] - tip[:, :1]).transpose(0, 2, 1) / d[:, None, None]


def _newton(
    stiffness: np.ndarray,
    lengths: np.ndarray,
    tension: np.ndarray,
    g_base: np.ndarray,
    payload: np.ndarray,
    tendon_offset: float,
    density: float,
    steps: int,
    start: np.ndarray,
    iterations: int = NEWTON_ITERATIONS,
) -> Shapes:
    """:func:`solve_shapes` by Newton with backtracking from the base moments ``start (R, 3)`` alone, at most
    ``iterations`` steps."""
    moments = tendon_moments(tension, tendon_offset)
    M0 = np.array(start, dtype=float)
    active = np.ones(len(tension), dtype=bool)
    for _ in range(iterations):
        rows = np.flatnonzero(active)
        if not len(rows):
            break
        batch: Batch = (stiffness, lengths, moments, g_base, payload)
        tip, J = _tip_jacobian(M0[rows], *_take(batch, rows), density, steps)
        norm = np.linalg.norm(tip, axis=1)
        done = norm < NEWTON_TOLERANCE
        active[rows[done]] = False
        rows, tip, J, norm = rows[~done], tip[~done], J[~done], norm[~done]
        if not len(rows):
            break
        step = np.linalg.solve(J, -tip[:, :, None])[:, :, 0]
        near = norm < NEAR
        M0[rows[near]] += step[near]
        lam = np.ones(len(rows))
        pending = np.flatnonzero(~near)
        for _ in range(LINE_SEARCH if len(pending) else 0):
            trial = M0[rows[pending]] + lam[pending, None] * step[pending]
            _, _, tip_trial = _integrate(trial, *_take(batch, rows[pending]), density, steps)
            better = np.linalg.norm(tip_trial, axis=1) < norm[pending]
            M0[rows[pending[better]]] = trial[better]
            pending = pending[~better]
            if not len(pending):
                break
            lam[pending] /= 4
    positions, rotations, tip = _integrate(M0, stiffness, lengths, moments, g_base, payload, density, steps)
    converged = np.linalg.norm(tip, axis=1) < 10 * NEWTON_TOLERANCE
    return Shapes(positions, rotations, M0, converged)


def solve_shapes(
    stiffness: np.ndarray,
    lengths: np.ndarray,
    tension: np.ndarray,
    g_base: np.ndarray,
    payload: np.ndarray,
    tendon_offset: float,
    density: float,
    steps: int = 8,
    start: np.ndarray | None = None,
) -> Shapes:
    """The equilibria of rows by shooting on the base moment (module docstring).

    Newton from ``start`` where given; rows without one, or not converged from it, by continuation from the
    straight hanging rod in equal steps of the tensions (:data:`CONTINUATION`) (a hanging rod has other
    equilibria, the payload above the base, which Newton from far may find instead).

    Parameters
    ----------
    stiffness, lengths:
        ``(R, 3)`` per section [N m^2], [m].
    tension:
        ``(R, 6)`` tendon tensions [N].
    g_base:
        ``(R, 3)`` gravity in the base frame [m/s^2].
    payload:
        ``(R,)`` [kg].
    tendon_offset, density:
        [m], [kg/m].
    steps:
        Integration steps per section.
    start:
        ``(R, 3)`` base moments to start Newton from [N m].
    """
    args: Batch = (stiffness, lengths, tension, g_base, payload)
    if start is not None:
        shapes = _newton(*args, tendon_offset, density, steps, start)
        if shapes.converged.all():
            return shapes
        redo = np.flatnonzero(~shapes.converged)
    else:
        shapes, redo = None, np.arange(len(tension))
    again = None
    for stages in CONTINUATION:
        if not len(redo):
            break
        M = np.zeros((len(redo), 3))
        for fraction in np.arange(1, stages + 1) / stages:
            k, L, t, g, w = _take(args, redo)
            iterations = NEWTON_ITERATIONS if fraction == 1 else STAGE_ITERATIONS
            step = _newton(k, L, t * fraction, g, w, tendon_offset, density, steps, M, iterations)
            M = step.base_moment
        if again is None:
            again, rows = step, redo
        else:
            put = np.searchsorted(rows, redo)
            for name in ("positions", "rotations", "base_moment", "converged"):
                getattr(again, name)[put] = getattr(step, name)
        redo = redo[~step.converged]
    if shapes is None or again is None:
        result = shapes if again is None else again
        assert result is not None  # the loop ran: a start with every row converged returned above
        return result
    for name in ("positions", "rotations", "base_moment", "converged"):
        getattr(shapes, name)[rows] = getattr(again, name)
    return shapes


def markers_of(params: ActuationParams, shapes: Shapes) -> np.ndarray:
    """``(N, 3, 3)`` marker positions [m] in the recording frame of the base-frame ``shapes``."""
    R0 = params.base_rotation
    local = shapes.positions + np.einsum("nsij,sj->nsi", shapes.rotations, params.marker_offsets)
    return params.base_position + np.einsum("ij,nsj->nsi", R0, local)


def predict(
    params: ActuationParams, inputs: np.ndarray, steps: int = 8, known: tuple[np.ndarray, np.ndarray] | None = None
) -> np.ndarray:
    """``(N, 3, 3)`` marker positions [m] predicted for motor inputs ``(N, 6)`` [N]; NaN for a posture without an
    equilibrium converged. ``known``: inputs ``(K, 6)`` [N] and the base moments ``(K, 3)`` [N m] of
    solved postures (a fit's training postures, :class:`Fit`); each posture is then reached from the nearest one by
    :data:`HOMOTOPY` equal steps of the tensions, from its base moment (a posture not reached so, and every posture
    without ``known``, by :func:`solve_shapes` from the straight rod).

    Raises
    ------
    ValueError
        ``inputs`` is not ``(N, 6)``.
    """
    inputs = np.asarray(inputs, dtype=float)
    if inputs.ndim != 2 or inputs.shape[1] != MOTORS:
        raise ValueError(f"inputs: expected (N, {MOTORS}) motor inputs, got shape {inputs.shape}")
    n = len(inputs)
    tension = tensions(inputs, params.motor_offsets)
    args: Batch = (
        np.tile(params.stiffness, (n, 1)),
        np.tile(params.section_lengths, (n, 1)),
        tension,
        np.tile(params.base_rotation.T @ GRAVITY, (n, 1)),
        np.full(n, params.payload),
    )
    if known is None or not len(known[0]):
        shapes = solve_shapes(*args, params.tendon_offset, params.linear_density, steps)
    else:
        nearest = np.argmin(((inputs[:, None, :] - known[0][None]) ** 2).sum(axis=2), axis=1)
        origin = tensions(known[0][nearest], params.motor_offsets)
        M = known[1][nearest].copy()
        for fraction in np.arange(1, HOMOTOPY + 1) / HOMOTOPY:
            step = (*args[:2], origin + fraction * (tension - origin), *args[3:])
            shapes = _newton(*step, params.tendon_offset, params.linear_density, steps, M)
            M = shapes.base_moment
        redo = np.flatnonzero(~shapes.converged)
        if len(redo):
            again = solve_shapes(*_take(args, redo), params.tendon_offset, params.linear_density, steps)
            for name in ("positions", "rotations", "base_moment", "converged"):
                getattr(shapes, name)[redo] = getattr(again, name)
    markers = markers_of(params, shapes)
    markers[~shapes.converged] = np.nan
    return markers


# --- calibration ---------------------------------------------------------------------------------------------

N_NONLINEAR = 3 + MOTORS + 1 + SECTIONS + 3
"""Parameters fitted by the nonlinear least squares: log EI (3), motor offsets (6), payload, lengths (3), the
base's rotation vector from the start (3)."""


def _unpack(theta: np.ndarray) -> tuple[np.ndarray, ...]:
    """``theta (G, 16)`` -> stiffness ``(G, 3)``, offsets ``(G, 6)``, payload ``(G,)``, lengths ``(G, 3)``, rotvec."""
    return np.exp(theta[:, 0:3]), theta[:, 3:9], theta[:, 9], theta[:, 10:13], theta[:, 13:16]


def _linear_fit(
    positions: np.ndarray, rotations: np.ndarray, R0: np.ndarray, measured: np.ndarray, scale: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Base position ``(3,)`` and marker offsets ``(3, 3)`` by linear least squares, reweighted with Huber
    weights of each posture's largest marker error over ``scale`` [m], :data:`REWEIGHTS` solves (a posture far
    from the model does not move them), and the residuals ``(N, 3, 3)`` [m] (NaN where unseen), for base-frame
    shapes ``(N, 3, 3)``, ``(N, 3, 3, 3)``."""
    world_p = np.einsum("ij,nsj->nsi", R0, positions)
    world_R = np.einsum("ij,nsjk->nsik", R0, rotations)
    seen = ~np.isnan(measured).any(axis=2)
    n = len(measured)
    A = np.zeros((n, SECTIONS, 3, 12))
    A[:, :, :, 0:3] = np.eye(3)
    for s in range(SECTIONS):
        A[:, s, :, 3 + 3 * s : 6 + 3 * s] = world_R[:, s]
    b = np.where(seen[..., None], measured, 0.0) - world_p
    rows = np.repeat(seen[..., None], 3, axis=2)
    weights = np.ones(n)
    for _ in range(REWEIGHTS):
        w = np.sqrt(np.broadcast_to(weights[:, None, None], rows.shape)[rows])
        x, *_ = np.linalg.lstsq(A[rows] * w[:, None], b[rows] * w, rcond=None)
        predicted = world_p + np.einsum("nsik,k->nsi", A, x)
        residual = np.where(seen[..., None], predicted - measured, np.nan)
        largest = np.nanmax(np.where(seen, np.linalg.norm(np.nan_to_num(residual), axis=2), np.nan), axis=1)
        weights = scale / np.maximum(scale, np.nan_to_num(largest))
    return x[0:3], x[3:].reshape(3, 3), residual


@dataclass
class _Problem:
    inputs: np.ndarray
    measured: np.ndarray
    R_start: np.ndarray
    tendon_offset: float
    density: float
    steps: int
    scale: float
    warm: np.ndarray | None = None

    def rows(self, thetas: np.ndarray) -> tuple[list[Shapes], np.ndarray]:
        """The shapes of every posture under each parameter set ``thetas (G, 16)``, and the base rotations.

        The first set is solved: by :func:`solve_shapes` the first time, then by Newton alone from the last
        solve's base moments (a posture it does not converge for keeps its last converged start); the others,
        a finite-difference Jacobian's small steps from it, by one Newton step from its base moments with its
        tip Jacobian: the shapes to first order in the step, as the implicit function theorem gives them.
        """
        n, G = len(self.inputs), len(thetas)
        stiffness, offsets, payload, lengths, w = _unpack(thetas)
        R0 = np.einsum("ij,gjk->gik", self.R_start, rotvec_matrix(w))
        g_base = np.einsum("gji,j->gi", R0, GRAVITY)
        rows: Batch = (
            np.repeat(stiffness, n, axis=0),
            np.repeat(lengths, n, axis=0),
            tensions(np.tile(self.inputs, (G, 1)), np.repeat(offsets, n, axis=0)),
            np.repeat(g_base, n, axis=0),
            np.repeat(payload, n),
        )
        if self.warm is None:
            base = solve_shapes(*_take(rows, slice(None, n)), self.tendon_offset, self.density, self.steps)
            self.warm = base.base_moment.copy()
        else:
            base = _newton(
                *_take(rows, slice(None, n)), self.tendon_offset, self.density, self.steps, self.warm, FIT_ITERATIONS
            )
            self.warm[base.converged] = base.base_moment[base.converged]
        groups = [base]
        if G > 1:
            moments = tendon_moments(rows[2][n:], self.tendon_offset)
            _, J = _tip_jacobian(
                base.base_moment,
                rows[0][:n],
                rows[1][:n],
                moments[:n],
                rows[3][:n],
                rows[4][:n],
                self.density,
                self.steps,
            )
            M = np.tile(base.base_moment, (G - 1, 1))
            args = (rows[0][n:], rows[1][n:], moments, rows[3][n:], rows[4][n:], self.density, self.steps)
            _, _, tip = _integrate(M, *args)
            M = M - np.linalg.solve(np.tile(J, (G - 1, 1, 1)), tip[:, :, None])[:, :, 0]
            positions, rotations, _ = _integrate(M, *args)
            for g in range(G - 1):
                part = slice(g * n, (g + 1) * n)
                groups.append(Shapes(positions[part], rotations[part], M[part], base.converged))
        return groups, R0

    def residuals(self, thetas: np.ndarray) -> np.ndarray:
        """``(G, n_seen)`` projected residuals [m] of each parameter set."""
        groups, R0 = self.rows(thetas)
        seen = ~np.isnan(self.measured)
        return np.stack(
            [_linear_fit(g.positions, g.rotations, R, self.measured, self.scale)[2][seen] for g, R in zip(groups, R0)]
        )


@dataclass(frozen=True)
class Fit:
    """A fitted physics model.

    Attributes
    ----------
    params:
        The estimates.
    rms:
        In-sample RMS marker error [m].
    iterations:
        Residual evaluations of the least squares.
    success:
        The least squares converged.
    inputs, base_moments:
        ``(N, 6)`` the training postures' inputs [N] and ``(N, 3)`` their solved base moments [N m] (starts for
        :func:`predict`).
    """

    params: ActuationParams
    rms: float
    iterations: int
    success: bool
    inputs: np.ndarray
    base_moments: np.ndarray


def start_params(
    section_lengths: np.ndarray,
    stiffness: float = 0.01,
    payload: float = 0.1,
    tendon_offset: float = 0.012,
    linear_density: float = 0.0099,
) -> ActuationParams:
    """A start of :func:`fit`: nominal lengths, one stiffness, zero motor offsets, hanging straight down."""
    return ActuationParams(
        stiffness=np.full(SECTIONS, stiffness),
        motor_offsets=np.zeros(MOTORS),
        payload=payload,
        section_lengths=np.asarray(section_lengths, dtype=float),
        base_rotation=hanging_rotation(),
        base_position=np.zeros(3),
        marker_offsets=np.zeros((3, 3)),
        tendon_offset=tendon_offset,
        linear_density=linear_density,
    )


def fit(
    inputs: np.ndarray,
    measured: np.ndarray,
    start: ActuationParams,
    length_range: tuple[float, float] = (0.7, 1.3),
    steps: int = 8,
    max_evaluations: int = 60,
    loss_scale: float = 0.003,
) -> Fit:
    """The physics model's parameters from postures by bounded least squares (module docstring).

    Parameters
    ----------
    inputs:
        ``(N, 6)`` motor inputs [N].
    measured:
        ``(N, 3, 3)`` the disks' markers [m], recording frame, NaN where unseen.
    start:
        The start (its tendon offset and linear density are held).
    length_range:
        Bounds of each section length relative to the start's.
    steps:
        Integration steps per section.
    max_evaluations:
        Jacobian evaluations of the least squares at most.
    loss_scale:
        Marker error [m] beyond which the soft-L1 loss (and the Huber weights of the base position and the
        marker offsets) count a residual less than its square: a posture the model cannot reach, e.g. a
        recorded equilibrium of another branch, does not move the estimates.

    Raises
    ------
    ValueError
        Shapes that do not match, or no marker seen.
    """
    inputs = np.asarray(inputs, dtype=float)
    measured = np.asarray(measured, dtype=float)
    if inputs.ndim != 2 or inputs.shape[1] != MOTORS or measured.shape != (len(inputs), SECTIONS, 3):
        raise ValueError(f"inputs (N, 6) and measured (N, 3, 3) expected, got {inputs.shape} and {measured.shape}")
    if np.isnan(measured).all():
        raise ValueError("measured: no marker seen")
    problem = _Problem(
        inputs, measured, start.base_rotation, start.tendon_offset, start.linear_density, steps, loss_scale
    )
    theta0 = np.concatenate(
        [np.log(start.stiffness), start.motor_offsets, [start.payload], start.section_lengths, np.zeros(3)]
    )
    nominal = start.section_lengths
    lower = np.concatenate([np.full(3, np.log(1e-4)), np.full(6, -3.0), [0.0], nominal * length_range[0], -np.ones(3)])
    upper = np.concatenate([np.full(3, np.log(10.0)), np.full(6, 3.0), [5.0], nominal * length_range[1], np.ones(3)])
    theta0 = np.clip(theta0, lower + 1e-9, upper - 1e-9)
    steps_of = np.concatenate([np.full(3, 1e-4), np.full(6, 1e-4), [1e-5], np.full(3, 1e-6), np.full(3, 1e-6)])

    def fun(theta: np.ndarray) -> np.ndarray:
        return problem.residuals(theta[None])[0]

    def jac(theta: np.ndarray) -> np.ndarray:
        thetas = np.tile(theta, (N_NONLINEAR + 1, 1))
        thetas[1:] += np.diag(steps_of)
        r = problem.residuals(thetas)
        return ((r[1:] - r[0]) / steps_of[:, None]).T

    solution = least_squares(
        fun,
        theta0,
        jac=jac,
        bounds=(lower, upper),
        x_scale="jac",
        max_nfev=max_evaluations,
        xtol=1e-10,
        loss="cauchy",
        f_scale=loss_scale,
    )
    stiffness, offsets, payload, lengths, w = (x[0] for x in _unpack(solution.x[None]))
    R0 = start.base_rotation @ rotvec_matrix(w)
    groups, _ = problem.rows(solution.x[None])
    p0, offsets_m, residual = _linear_fit(groups[0].positions, groups[0].rotations, R0, measured, loss_scale)
    params = replace(
        start,
        stiffness=stiffness,
        motor_offsets=offsets,
        payload=float(payload),
        section_lengths=lengths,
        base_rotation=R0,
        base_position=p0,
        marker_offsets=offsets_m,
    )
    rms = float(np.sqrt(np.nanmean(residual**2)))
    good = groups[0].converged
    return Fit(params, rms, int(solution.nfev), bool(solution.success), inputs[good], groups[0].base_moment[good])
