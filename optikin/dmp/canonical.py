"""The canonical system of a discrete DMP: the phase ``s`` that clocks the forcing term.

Seleem et al. (2020) eq. (15): ``tau ds/dt = -zeta s``, ``s(0) = 1``, so ``s(t) = exp(-zeta t / tau)``.
With phase stopping the rate is divided by ``1 + alpha |e|``, where ``e`` is
an error the motion should wait for:

    tau ds/dt = -zeta s / (1 + alpha |e|).

Which error (:data:`PHASE_STOPPING`, chosen per DMP):

``tracking`` (default)
    the tracking error alone, ``e = r = gap(y_ref, y)`` between the pose the
    robot actually has (the reference of eq. 27) and the DMP's: Ijspeert et
    al. (2013) slow the phase by ``|y_actual - y|``, Ude et al. (2014) by the
    orientation tracking error. Without a tracking error the phase is exactly
    eq. (15): phase stopping changes nothing in an undisturbed motion and the
    demonstration's phase needs no correction. The reference must be the pose
    the robot actually reaches (it follows the DMP, so it waits with it), not a
    path that runs on in time such as the demonstration: against that, the lag
    the stopping creates raises the gap and so the lag (growing at about
    ``alpha |dy_ref/dt|``): with ``alpha = alpha_s = 5`` the undisturbed
    roll-out coupled to the IMU demonstration drifts 2.9 rad off it.
``seed``
    Seleem et al. (2020) as printed: eq. (25) slows the phase by the goal gap
    ``|gap(g, y)|`` and eq. (28) by ``|e| + |r|``. The goal gap is large for
    most of any motion, so the phase lags even without a disturbance (0.57
    instead of 0.01 at ``tau`` with ``alpha = 5`` on the IMU demonstration)
    and the forcing term must be fitted along that slowed phase (eq. 25 in
    the imitation). Kept, labelled, to reproduce Seleem et al.'s Figs. 20-21.

On a fixed step ``dt`` with ``e`` held over the step this integrates exactly to
``s_{k+1} = s_k exp(-zeta dt / (tau (1 + alpha |e_k|)))``: positive, monotone,
and equal to the closed form when ``alpha = 0``. Both the imitation
(:mod:`optikin.dmp.imitation`) and the roll-out (:mod:`optikin.dmp.rollout`)
use this update; ``zeta = -ln 0.01`` brings the phase to 0.01 at ``t = tau``
(movement_primitives' choice, the default of :class:`optikin.dmp.Gains`).
"""

from __future__ import annotations

from typing import Literal, get_args

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array

PhaseStopping = Literal["tracking", "seed"]
"""Which error slows the phase (the module docstring)."""
PHASE_STOPPING: tuple[PhaseStopping, ...] = get_args(PhaseStopping)


def goal_stopping_weight(mode: str) -> float:
    """Weight of the goal gap in the phase-stopping error: 0 for ``tracking``, 1 for Seleem et al.'s eqs. (25), (28)."""
    if mode not in PHASE_STOPPING:
        raise ValueError(f"unknown phase stopping {mode!r}; choose from {PHASE_STOPPING}")
    return 1.0 if mode == "seed" else 0.0


def stopped_log_phase(dt: float, tau: float, zeta: Array, alpha: Array, error_norms: Array) -> Array:
    """``log s_0 .. log s_K`` along ``K`` steps with errors ``|e_0| .. |e_{K-1}|`` (exact per step).

    numpy: ``error_norms`` of shape ``(K,)``, returns ``(K + 1,)``; CasADi: a
    column ``K x 1`` (gains may be symbols), returns ``(K + 1) x 1``.
    """
    if B.any_casadi(zeta, alpha, error_norms):
        e = ca.DM(error_norms) if not B.is_casadi(error_norms) else error_norms
        rates = 1.0 / (1.0 + alpha * e)
        return ca.vertcat(0.0, -(zeta * dt / tau) * ca.cumsum(rates))
    rates = 1.0 / (1.0 + alpha * np.asarray(error_norms, dtype=float))
    return np.concatenate([[0.0], -(zeta * dt / tau) * np.cumsum(rates)])
