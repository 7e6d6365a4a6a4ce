"""The canonical system of a discrete DMP: the phase ``s`` that clocks the forcing term.

Seed 000 eq. (15): ``tau ds/dt = -zeta s``, ``s(0) = 1``, so ``s(t) = exp(-zeta t / tau)``.
With phase stopping (seed eqs. 25 and 28, after Ude et al. 2014 and Ijspeert
et al. 2013, sec. 3.4) the rate is divided by ``1 + alpha |e|``, where ``e`` is
an error the motion should wait for:

    tau ds/dt = -zeta s / (1 + alpha |e|).

On a fixed step ``dt`` with ``e`` held over the step this integrates exactly to
``s_{k+1} = s_k exp(-zeta dt / (tau (1 + alpha |e_k|)))``: positive, monotone,
and equal to the closed form when ``alpha = 0``. Both the imitation
(:mod:`optikin.dmp.imitation`) and the roll-out (:mod:`optikin.dmp.rollout`)
use this update; ``zeta = -ln 0.01`` brings the phase to 0.01 at ``t = tau``
(movement_primitives' choice, the default of :class:`optikin.dmp.Gains`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.backend import Array


def stopped_log_phase(dt: float, tau: float, zeta: Array, alpha: Array, error_norms: Array) -> Array:
    """``log s_0 .. log s_K`` along ``K`` steps with errors ``|e_0| .. |e_{K-1}|`` (seed eqs. 25, 28, exact per step).

    numpy: ``error_norms`` of shape ``(K,)``, returns ``(K + 1,)``; CasADi: a
    column ``K x 1`` (gains may be symbols), returns ``(K + 1) x 1``.
    """
    if B.any_casadi(zeta, alpha, error_norms):
        e = ca.DM(error_norms) if not B.is_casadi(error_norms) else error_norms
        rates = 1.0 / (1.0 + alpha * e)
        return ca.vertcat(0.0, -(zeta * dt / tau) * ca.cumsum(rates))
    rates = 1.0 / (1.0 + alpha * np.asarray(error_norms, dtype=float))
    return np.concatenate([[0.0], -(zeta * dt / tau) * np.cumsum(rates)])
