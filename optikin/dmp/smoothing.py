"""Low-pass smoothing of a noisy demonstration before its target forces are computed (optional).

The target forces (Seleem et al.'s eqs. 16, 22) are second differences of the samples
scaled by ``(tau/dt)^2``; on sensor data (the IMU interface: about 0.5 mm and
a few mrad of white noise per sample at 100 Hz) they are dominated by noise.
Inside the demonstration the least-squares forcing term averages most of it
out, but not at the end: the fit reproduces the last, noise-made velocity
(up to 0.1 m/s and 0.5 rad/s where the true motion is at rest), and past
``tau`` the spring has to brake it (tens of mm, up to 0.3 rad, after the
demonstration). DMP imitation presumes derivatives that describe the motion
(Ijspeert et al. 2013 build the target force from ``y, dy/dt, d2y/dt2`` of the
demonstration, Ude et al. 2014 from ``q, omega, domega/dt``) and a motion that
reaches its goal at rest, where the attractor ``(g, 0)`` takes over; on sampled
sensor data that means low-pass filtering first, as Seleem et al. do for their
Kinect data (eq. 31).

:func:`smooth_demonstration` applies a zero-phase Whittaker smoother
(penalised least squares, Whittaker 1923; Eilers 2003)

    min_z |z - x|^2 + lam |D_3 z|^2        (D_3: third differences)

to every gap component of the demonstration in the tangent space of its last
sample, ``x_k = gap(y_{N-1}, y_k)``, and maps back with
``z_k -> advance(y_{N-1}, -z_k)`` (the exact inverse of the gap for vectors,
unit quaternions and unit dual quaternions), so a smoothed quaternion is unit
and a smoothed dual quaternion a rigid pose. Away from the ends its response
to a sampled sinusoid of frequency ``f`` is
``1 / (1 + lam (2 sin(pi f dt))^6)``, a zero-phase sixth-order low-pass;
:func:`smoothing_weight` picks ``lam`` for the half-power ``cutoff``. Near
the ends it fits a local quadratic trend, so start, goal and the final
velocity come out as estimates from the samples around them instead of from
the last noisy sample. The seed's variant (:mod:`optikin.dmp.pose`) treats
``Q_d`` as a quaternion whose norm its operations cannot change, so smoothing
it through them also fixes ``|Q_d|`` at the goal's value.

Smoothing is off by default (a clean demonstration is reproduced exactly):
pass ``smoothing=<cutoff in Hz>`` to :class:`optikin.dmp.DMP` for sensor data.
Human motion has little content above 2 Hz, and a forcing term with ``n``
basis functions over ``tau`` cannot represent anything above about
``(n - 1) / (2 tau)`` (2.45 Hz for 50 over 10 s) in any case.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import solveh_banded

from optikin.dmp.spaces import Space

ORDER = 3
"""Order of the differences penalised: a local quadratic trend passes unchanged."""


def smoothing_weight(cutoff: float, dt: float, order: int = ORDER) -> float:
    """``lam`` with a half-power response at ``cutoff`` Hz for samples ``dt`` apart: ``(2 sin(pi cutoff dt))^-2d``."""
    if not 0.0 < cutoff * dt < 0.5:
        raise ValueError(
            f"the smoothing cutoff must lie between 0 and the Nyquist frequency {0.5 / dt:.4g} Hz, got {cutoff} Hz"
        )
    return (2.0 * math.sin(math.pi * cutoff * dt)) ** (-2 * order)


def _penalty_bands(n: int, order: int) -> np.ndarray:
    """``D'D`` of the ``order``-th difference matrix (``(n - order) x n``) in upper banded storage."""
    c = np.array([(-1) ** (order - i) * math.comb(order, i) for i in range(order + 1)], dtype=float)
    bands = np.zeros((order + 1, n))
    for k in range(order + 1):  # (D'D)[i, i + k] = sum_j c_j c_{j+k} over the rows r = i - j of D
        diagonal = np.zeros(n - k)
        for j in range(order + 1 - k):
            diagonal[j : n - order + j] += c[j] * c[j + k]
        bands[order - k, k:] = diagonal
    return bands


def whittaker(x: np.ndarray, lam: float, order: int = ORDER) -> np.ndarray:
    """``argmin_z |z - x|^2 + lam |D z|^2`` column by column: ``(I + lam D'D) z = x``, a banded solve. ``x (N, m)``."""
    x = np.asarray(x, dtype=float)
    if x.shape[0] <= order:
        raise ValueError(f"smoothing needs more than {order} samples, got {x.shape[0]}")
    bands = lam * _penalty_bands(x.shape[0], order)
    bands[order] += 1.0
    return solveh_banded(bands, x)


def smooth_demonstration(space: Space, Y: np.ndarray, dt: float, cutoff: float) -> np.ndarray:
    """Samples low-passed in the tangent space of the last one (Whittaker smoother, third differences).

    Parameters
    ----------
    space:
        The DMP's space.
    Y:
        ``(N, size)`` sign-continuous samples.
    dt:
        Sample step [s].
    cutoff:
        Half-power frequency [Hz], below the Nyquist frequency ``0.5 / dt``.

    Returns
    -------
    ndarray
        ``(N, size)`` smoothed samples (unit quaternions stay unit, dual quaternions rigid).
    """
    anchor = Y[-1]
    gaps = np.asarray(space.gap(anchor, Y), dtype=float)
    smoothed = whittaker(gaps, smoothing_weight(cutoff, dt))
    return space.continuous(np.asarray(space.advance(np.broadcast_to(anchor, Y.shape), -smoothed), dtype=float))
