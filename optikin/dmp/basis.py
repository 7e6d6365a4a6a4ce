"""Gaussian basis of the forcing term (Seleem et al. 2020, eqs. 13-14, 20).

``f(s) = s sum_j w_j psi_j(s) / sum_j psi_j(s)`` with ``psi_j(s) = exp(-h_j (s - c_j)^2)``.
(The extracted text of eqs. 13 and 20 prints the factor ``s`` inside and again
outside the sum; the DMPs it cites (Ijspeert et al. 2013, Ude et al. 2014)
have it once, which is what is used here.)

The centres are the phase at equally spaced times of the demonstration and
each width makes neighbouring Gaussians cross at ``overlap``:
``h_j = -ln(overlap) / (c_{j+1} - c_j)^2`` (the last one repeats its
neighbour). With the phase of eq. (15) the centres are
``c_j = exp(-zeta j / (n - 1))``, the construction of movement_primitives'
``ForcingTerm``, so learned weights are comparable with that library. With
phase stopping (eq. 25) the demonstration's phase is no longer that
exponential; :func:`centres_along` takes the centres from the phase the
demonstration actually has, which covers both cases. Everything accepts
CasADi symbols, so gains can be tuned through the basis
(:mod:`optikin.dmp.tuning`).

The forcing term is switched off below the demonstration's final phase
(:func:`forcing_end`). The weights are fitted on the phases the demonstration
visits, ``[s_end, 1]``; below ``s_end`` the normalised sum is an extrapolation
that no sample constrains: it returns ``s`` times the last weights, which a
least-squares fit of noisy targets makes large and of alternating sign
(``1e5``-``1e6`` on the IMU demonstration, whose final target forces are
sensor noise divided by ``s_end = 0.01``), so it kept pushing for seconds
after ``tau`` while ``s`` decayed with the time constant ``tau / zeta`` (on
the 10 s IMU demonstration the dual-quaternion DMP's tip went 0.2 m off the
goal within a second after ``tau``, and was metres off after 5 tau). Ijspeert
et al. (2013) and Ude et al. (2014) rely on ``s -> 0`` alone for ``f -> 0``,
which bounds the forcing term only asymptotically. With the gate
the DMP past ``s_end`` is exactly the critically damped spring of eqs. (11) /
(17) with ``f = 0``: it converges to the goal from wherever ``tau`` leaves it,
and the roll-out within the demonstration is unchanged (every phase it fits
lies above the threshold).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array

DEFAULT_OVERLAP = 0.8


def centres_along(log_phase: Array, n_basis: int) -> Array:
    """Centres at ``n_basis`` equally spaced times along a sampled phase, given as ``log s_0 .. log s_K``.

    ``log s`` is interpolated linearly between samples, which is exact for the
    phase of :mod:`optikin.dmp.canonical` (a constant rate over each step), so
    with ``alpha = 0`` this returns ``exp(-zeta j / (n - 1))`` to rounding.
    """
    if n_basis < 2:
        raise ValueError(f"a DMP needs at least 2 basis functions, got {n_basis}")
    samples = log_phase.shape[0]
    position = np.arange(n_basis) * (samples - 1) / (n_basis - 1)
    lower = np.minimum(np.floor(position).astype(int), samples - 2)
    fraction = position - lower
    A = np.zeros((n_basis, samples))
    A[np.arange(n_basis), lower] = 1.0 - fraction
    A[np.arange(n_basis), lower + 1] = fraction
    if B.is_casadi(log_phase):
        return ca.exp(ca.mtimes(ca.sparsify(ca.DM(A)), log_phase))
    return np.exp(A @ np.asarray(log_phase, dtype=float))


def forcing_end(log_phase: Array) -> Array:
    """Phase below which the forcing term is off: between the last two samples of the demonstration's phase.

    ``log_phase`` holds ``log s_0 .. log s_{N-1}``; the targets are fitted at
    ``s_0 .. s_{N-2}`` (one per step), so the threshold is their geometric
    midpoint ``sqrt(s_{N-2} s_{N-1})``: every fitted phase lies above it, and a
    roll-out on the demonstration's step switches the forcing term off from
    the first step after ``tau`` on, whatever the rounding of ``s``.
    """
    if log_phase.shape[0] < 2:
        raise ValueError("the phase of a demonstration has at least two samples")
    if B.is_casadi(log_phase):
        return ca.exp(0.5 * (log_phase[-2] + log_phase[-1]))
    log_phase = np.asarray(log_phase, dtype=float)
    return float(np.exp(0.5 * (log_phase[-2] + log_phase[-1])))


def widths(c: Array, overlap: float = DEFAULT_OVERLAP) -> Array:
    """``h_j = -ln(overlap) / (c_{j+1} - c_j)^2``, the last width equal to the one before."""
    if not 0.0 < overlap < 1.0:
        raise ValueError(f"the overlap of neighbouring basis functions must lie in (0, 1), got {overlap}")
    log_overlap = -math.log(overlap)
    if B.is_casadi(c):
        h = log_overlap / (c[1:] - c[:-1]) ** 2
        return ca.vertcat(h, h[-1])
    h = log_overlap / np.diff(c) ** 2
    return np.append(h, h[-1])


def features(s: Array, c: Array, h: Array) -> Array:
    """Rows ``s psi(s) / sum psi(s)`` of the design matrix: ``(K, n)`` for ``K`` phases.

    numpy: ``s`` of shape ``(K,)``; CasADi: ``s`` a column ``K x 1`` (``1 x 1`` in a step).
    ``f(s) = features(s) @ W.T`` for weights ``W`` of shape ``(dim, n)``.
    """
    if B.any_casadi(s, c, h):
        rows = s.shape[0]
        n = c.shape[0]
        diff = ca.repmat(s, 1, n) - ca.repmat(ca.DM(c).T if not B.is_casadi(c) else c.T, rows, 1)
        hh = ca.repmat(ca.DM(h).T if not B.is_casadi(h) else h.T, rows, 1)
        psi = ca.exp(-hh * diff**2)
        return ca.repmat(s / ca.sum2(psi), 1, n) * psi
    s = np.asarray(s, dtype=float)
    psi = np.exp(-h[None, :] * (s[:, None] - c[None, :]) ** 2)
    return (s / psi.sum(axis=1))[:, None] * psi


def activations(s: np.ndarray, c: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Unnormalised ``psi_j(s_k)``, ``(K, n)``: the local weights of locally weighted regression."""
    return np.exp(-h[None, :] * (np.asarray(s, dtype=float)[:, None] - c[None, :]) ** 2)


CACHED_TABLES = 8
"""Feature tables of :func:`rollout_features` kept per process (least recently used dropped first)."""
_TABLES: OrderedDict[tuple, np.ndarray] = OrderedDict()
_TABLES_LOCK = threading.Lock()


def rollout_features(
    steps: int, dt: float, tau: float, zeta: float, c: np.ndarray, h: np.ndarray, s_end: float
) -> np.ndarray:
    """The forcing term's features at the steps of a roll-out whose phase is eq. (15) alone (no phase stopping).

    The phase is the roll-out's recurrence ``s_0 = 1``, ``s_{k+1} = s_k exp(-zeta dt / tau)``
    (:mod:`optikin.dmp.canonical` with ``alpha = 0``), so the features depend only on the step count, the
    time constants and the basis: they are computed once per process (cached, read-only) and passed to the
    compiled roll-out (:mod:`optikin.dmp.compiled`) instead of ``n`` exponentials per step.

    Parameters
    ----------
    steps:
        Roll-out steps ``K``.
    dt, tau:
        Step and time constant [s].
    zeta:
        Phase decay rate (eq. 15).
    c, h:
        ``(n,)`` centres and widths.
    s_end:
        Phase below which the forcing term is off (:func:`forcing_end`).

    Returns
    -------
    numpy.ndarray
        ``(K, n)`` rows ``(s_k > s_end) s_k psi(s_k) / sum psi(s_k)`` (:func:`features`), ``k = 0 .. K-1``.
    """
    c, h = np.ascontiguousarray(c, dtype=float), np.ascontiguousarray(h, dtype=float)
    key = (int(steps), float(dt), float(tau), float(zeta), float(s_end), c.tobytes(), h.tobytes())
    with _TABLES_LOCK:
        table = _TABLES.get(key)
        if table is not None:
            _TABLES.move_to_end(key)
            return table
    s = np.full(int(steps), math.exp(-float(zeta) * float(dt) / float(tau)))
    s[0] = 1.0
    s = np.cumprod(s)  # sequential products: the roll-out's own recurrence
    table = features(s, c, h) * (s > s_end)[:, None]
    table.flags.writeable = False
    with _TABLES_LOCK:
        _TABLES[key] = table
        while len(_TABLES) > CACHED_TABLES:
            _TABLES.popitem(last=False)
    return table
