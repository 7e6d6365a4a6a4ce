"""From a demonstration to the regression problem of the forcing-term weights (Seleem et al. 2020, eqs. 16, 21-22).

The roll-out (:mod:`optikin.dmp.rollout`) integrates the DMP on the fixed step
``dt`` of the demonstration, semi-implicitly (velocity first, then pose):

    eta_{k+1} = eta_k + dt/tau [beta (gamma e_k - eta_k) + f_k]          (Seleem et al.'s eqs. 11, 17)
    y_{k+1}   = advance(y_k, dt/tau (eta_{k+1} + alpha_s e_k))            (Seleem et al.'s eqs. 12, 18/23, 26)

with ``e_k = gap(g, y_k)`` (``g - y`` per angle, ``2 log(g conj(y))`` on a
quaternion), each on the branch continuous with the next one and the last
nearest zero (:func:`optikin.dmp.spaces.lifted_gaps`): the gap the roll-out
lifts the same way, so a turn past half or a full turn to the goal is learned
and replayed alike. The target forces are this recursion solved for ``f_k`` along the
demonstration ``y_0 .. y_{N-1}``, starting at rest (``eta_0 + alpha_s e_0 = 0``):

    eta_{k+1} = tau/dt gap(y_{k+1}, y_k) - alpha_s e_k
    f_k       = tau/dt (eta_{k+1} - eta_k) - beta (gamma e_k - eta_k),    k = 0 .. N-2.

This is Seleem et al.'s eq. (16) / (22) with the derivatives replaced by the differences
the integrator uses, so a forcing term that matched the targets exactly would
reproduce the demonstration exactly: what is left of the reproduction error is
the regression's (Seleem et al.'s eqs. 16 and 21 divide by ``g - y`` and by ``K_0``; the
amplitude scaling here divides by the start-goal gap instead, as eq. (11) and
Ude et al.'s ``D_0`` do, and only when asked).

The gains enter linearly, so :func:`target_forces` and :func:`design_matrix`
take CasADi symbols too (gain tuning differentiates through the regression).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array
from optikin.dmp import basis, regression
from optikin.dmp.canonical import goal_stopping_weight, stopped_log_phase
from optikin.dmp.smoothing import smooth_demonstration
from optikin.dmp.spaces import Space, lifted_gaps, smooth_norm
from optikin.errors import InputDataError

UNIFORM_TOLERANCE = 1e-6
"""Largest relative deviation of a sample interval from the mean that still counts as a fixed step."""


@dataclass(frozen=True)
class Demonstration:
    """A demonstration prepared for imitation: samples, step, and the gains-free data of the targets."""

    space: Space
    t: np.ndarray  # (N,)
    Y: np.ndarray  # (N, size), quaternion blocks sign-continuous
    dt: float
    tau: float
    goal_gap: np.ndarray  # (N - 1, dim): e_k = gap(g, y_k), continuous along k (spaces.lifted_gaps)
    step_rate: np.ndarray  # (N - 1, dim): tau/dt gap(y_{k+1}, y_k) (Space.step_gaps)

    @property
    def start(self) -> np.ndarray:
        return self.Y[0]

    @property
    def goal(self) -> np.ndarray:
        return self.Y[-1]


GapKernel = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``(goal (size,), Y (N, size)) -> (lifted goal gaps (N, dim), steps (N - 1, dim))``."""


def prepare(
    space: Space,
    t: np.ndarray,
    Y: np.ndarray,
    source: str = "demonstration",
    smoothing: float | None = None,
    gaps: GapKernel | None = None,
) -> Demonstration:
    """Check a demonstration (finite, fixed step, at least 3 samples) and compute its gap data.

    Quaternion blocks are made sign-continuous along the demonstration; the
    time constant ``tau`` is its duration. ``smoothing``: the cutoff [Hz] of
    the low-pass of :mod:`optikin.dmp.smoothing` applied first (``None``: the
    samples as given); start and goal are then the smoothed end samples.
    ``gaps``: computes :func:`~optikin.dmp.spaces.lifted_gaps` and
    :meth:`~optikin.dmp.spaces.Space.step_gaps` at once
    (:meth:`optikin.dmp.compiled.CompiledRollout.prepare`); ``None``: those two in numpy (the reference).
    """
    t = np.asarray(t, dtype=float)
    Y = np.asarray(Y, dtype=float)
    if Y.ndim != 2 or Y.shape[1] != space.size:
        raise InputDataError(
            f"expected samples of shape (N, {space.size}) for the space {space}, got {Y.shape}", source=source
        )
    if t.shape != (Y.shape[0],):
        raise InputDataError(f"expected {Y.shape[0]} times, got an array of shape {t.shape}", source=source, field="t")
    if Y.shape[0] < 3:
        raise InputDataError(f"a demonstration needs at least 3 samples, got {Y.shape[0]}", source=source)
    for name, values in (("t", t[:, None]), ("y", Y)):
        bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
        if bad.size:
            raise InputDataError("value is not finite", source=source, sample=int(bad[0]), field=name)
    steps = np.diff(t)
    dt = float(steps.mean())
    worst = int(np.argmax(np.abs(steps - dt)))
    if dt <= 0 or abs(steps[worst] - dt) > UNIFORM_TOLERANCE * dt:
        raise InputDataError(
            f"samples must be equally spaced in time (mean step {dt:.6g} s, this one "
            f"{steps[worst]:.6g} s); resample the demonstration first",
            source=source,
            sample=worst + 1,
            field="t",
        )
    Y = space.continuous(Y)
    if smoothing is not None:
        try:
            Y = smooth_demonstration(space, Y, dt, float(smoothing))
        except ValueError as exc:
            raise InputDataError(str(exc), source=source, field="smoothing") from None
    tau = float(t[-1] - t[0])
    if gaps is None:
        goal_gaps = lifted_gaps(space, Y[-1], Y)
        steps = space.step_gaps(Y, goal_gaps)
    else:
        goal_gaps, steps = gaps(Y[-1], Y)
    return Demonstration(
        space=space,
        t=t - t[0],
        Y=Y,
        dt=dt,
        tau=tau,
        goal_gap=goal_gaps[:-1],
        step_rate=steps * (tau / dt),
    )


def _lift(x: np.ndarray, *gains: Array) -> Array:
    """``x`` as a CasADi DM when any gain is symbolic (numpy arrays do not mix with CasADi symbols)."""
    return ca.DM(x) if B.any_casadi(*gains) else x


def target_forces(demo: Demonstration, beta: Array, gamma: Array, alpha_s: Array = 0.0) -> Array:
    """``f_k``, ``k = 0 .. N-2``, that make the discrete DMP reproduce the demonstration (eqs. 16, 22).

    Parameters
    ----------
    demo:
        From :func:`prepare`.
    beta, gamma, alpha_s:
        Gains (numbers or CasADi symbols).

    Returns
    -------
    Array
        ``(N - 1, dim)`` target forces (a CasADi matrix when a gain is symbolic).

    Notes
    -----
    The DMP starts at rest: ``eta_0 = -alpha_s e_0`` cancels the coupling
    velocity, as the roll-out does.
    """
    E = _lift(demo.goal_gap, beta, gamma, alpha_s)
    V = _lift(demo.step_rate, beta, gamma, alpha_s)
    eta_next = V - alpha_s * E
    if B.is_casadi(eta_next):
        eta = ca.vertcat(-alpha_s * E[0, :], eta_next[:-1, :])
    else:
        eta = np.vstack([-alpha_s * E[:1], eta_next[:-1]])
    return (demo.tau / demo.dt) * (eta_next - eta) - beta * (gamma * E - eta)


def demonstration_log_phase(
    demo: Demonstration, zeta: Array, alpha: Array = 0.0, phase_stopping: str = "tracking"
) -> Array:
    """``log s_k`` along the demonstration, ``k = 0 .. N-1``.

    The demonstration has no tracking error, so with ``tracking`` phase
    stopping this is eq. (15); with Seleem et al.'s it is slowed by the goal gap
    when ``alpha > 0`` (eq. 25), as its roll-out will be.
    """
    alpha_goal = goal_stopping_weight(phase_stopping) * alpha
    return stopped_log_phase(demo.dt, demo.tau, zeta, alpha_goal, smooth_norm(demo.goal_gap))


def amplitude(
    space: Space,
    start: np.ndarray,
    goal: np.ndarray,
    scale: bool,
    source: str = "",
    gap: np.ndarray | None = None,
) -> np.ndarray:
    """Per-component factor of the forcing term: ``gap(goal, start)`` (Seleem et al.'s eqs. 11, 20) or ones.

    ``gap``: the ``(dim,)`` start-goal gap on the branch the DMP uses (:meth:`~optikin.dmp.spaces.Space.lift`),
    instead of ``gap(goal, start)``.

    A component with a vanishing start-goal gap cannot be scaled (eq. 16 would
    divide by zero): that raises an :class:`InputDataError` naming it.
    """
    if not scale:
        return np.ones(space.dim)
    amp = np.asarray(space.gap(goal, start) if gap is None else gap, dtype=float)
    small = np.flatnonzero(np.abs(amp) < 1e-9)
    if small.size:
        raise InputDataError(
            f"start and goal coincide in gap component {int(small[0])}, so the forcing term "
            "cannot be scaled by the start-goal gap (Seleem et al.'s eq. 11); use "
            "scale_by_amplitude=False",
            source=source,
            field=f"gap[{int(small[0])}]",
        )
    return amp


def design_matrix(
    demo: Demonstration,
    n_basis: int,
    zeta: Array,
    alpha: Array = 0.0,
    overlap: float = basis.DEFAULT_OVERLAP,
    phase_stopping: str = "tracking",
) -> tuple[Array, Array, Array, Array, Array]:
    """``(X, s, c, h, s_end)``: the ``(N - 1, n)`` design matrix of eq. (13), the phase of its rows, centres,
    widths, and the phase below which the forcing term is off (:func:`optikin.dmp.basis.forcing_end`).

    Without phase stopping along the demonstration (``alpha = 0``, or ``tracking`` phase stopping) the
    phase depends only on the number of samples, ``dt``, ``tau`` and ``zeta``: for numeric gains the
    result is then computed once per process and returned read-only from a cache (:data:`CACHED_DESIGNS`),
    its Cholesky factor kept by :func:`optikin.dmp.regression.share_design`.
    """
    numeric = not B.any_casadi(zeta, alpha)
    key = None
    if numeric and goal_stopping_weight(phase_stopping) * float(alpha) == 0.0:
        key = (demo.goal_gap.shape[0], demo.dt, demo.tau, float(zeta), int(n_basis), float(overlap))
        with _DESIGNS_LOCK:
            if key in _DESIGNS:
                _DESIGNS.move_to_end(key)
                return _DESIGNS[key]
    log_s = demonstration_log_phase(demo, zeta, alpha, phase_stopping)
    c = basis.centres_along(log_s, n_basis)
    h = basis.widths(c, overlap)
    s = ca.exp(log_s[:-1, :]) if B.is_casadi(log_s) else np.exp(log_s[:-1])
    design = (basis.features(s, c, h), s, c, h, basis.forcing_end(log_s))
    if key is not None:
        for part in design[:4]:
            part.flags.writeable = False
        regression.share_design(design[0])
        with _DESIGNS_LOCK:
            _DESIGNS[key] = design
            while len(_DESIGNS) > CACHED_DESIGNS:
                _DESIGNS.popitem(last=False)
    return design


CACHED_DESIGNS = 8
"""Design matrices of :func:`design_matrix` kept per process (least recently used dropped first)."""
_DESIGNS: OrderedDict[tuple, tuple] = OrderedDict()
_DESIGNS_LOCK = threading.Lock()
