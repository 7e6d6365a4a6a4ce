"""The gains of a DMP, named as in Seleem et al. (2020), and the bounds that keep the fixed-step roll-out stable.

====================  =========================================================  ==========
name                  role                                                       Seleem et al.'s eq.
====================  =========================================================  ==========
``beta``              damping of the transformation system (``alpha_z`` in       11, 17
                      Ijspeert et al. 2013, ``alpha_y`` in movement_primitives)
``gamma``             spring to damping ratio (``beta_z``, ``beta_y``)           11, 17
``zeta``              decay of the phase                                         15
``beta_g0``           rate of the goal filter (``inf``: the goal jumps)          24
``alpha_s``           coupling of the velocity to the goal and reference gaps    26, 27
``alpha``             phase stopping by the goal and reference gaps              25, 28
====================  =========================================================  ==========

``beta_g0`` is a number or one rate per gap component (the diagonal matrix of
eq. 24; Seleem et al. report four values per DMP, Figs. 18-19, for the three
components of ``log``: on the pure quaternion ``(0, v)`` the first multiplies
the zero scalar part and does nothing, so their ``Q_r`` diagonal
``(991.35, 76.96, 407.93, 682.71)`` acts as ``(76.96, 407.93, 682.71)``).

``beta = 4 gamma`` is critically damped; the defaults (25, 6.25, ``-ln 0.01``)
are movement_primitives' so the two can be compared on the same data.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Literal, get_args

import numpy as np

GainName = Literal["beta", "gamma", "zeta", "beta_g0", "alpha_s", "alpha"]
"""The name of one gain (the table above)."""
GAIN_NAMES: tuple[GainName, ...] = get_args(GainName)
"""Every gain, in the order of :meth:`Gains.vector` and of the roll-out's ``gains`` input."""


@dataclass(frozen=True)
class Gains:
    """The gains of one DMP (the module's table); all >= 0, ``beta, gamma, zeta > 0``, only ``beta_g0`` may be inf.

    Raises
    ------
    ValueError
        A gain outside those bounds.
    """

    beta: float = 25.0
    gamma: float = 6.25
    zeta: float = -math.log(0.01)
    beta_g0: float | tuple[float, ...] = math.inf
    alpha_s: float = 0.0
    alpha: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.beta_g0, (int, float)):
            object.__setattr__(self, "beta_g0", tuple(float(v) for v in self.beta_g0))
            if not self.beta_g0:
                raise ValueError("a diagonal beta_g0 needs one rate per gap component, got none")
        for name, value in asdict(self).items():
            for v in value if isinstance(value, tuple) else (value,):
                if not v >= 0 or (math.isinf(v) and name != "beta_g0"):
                    raise ValueError(f"DMP gain {name} must be finite and >= 0 (beta_g0 may be inf), got {value}")
        if self.beta <= 0 or self.gamma <= 0 or self.zeta <= 0:
            raise ValueError("DMP gains beta, gamma and zeta must be positive")

    def vector(self) -> np.ndarray:
        """``(6,)`` gains in the order of :data:`GAIN_NAMES` (a diagonal ``beta_g0`` as its largest rate)."""
        return np.array([max(np.atleast_1d(getattr(self, n))) for n in GAIN_NAMES], dtype=float)

    def goal_rates(self, dim: int) -> np.ndarray:
        """``(dim,)`` rates of the goal filter (eq. 24), one per gap component.

        Raises
        ------
        ValueError
            A diagonal ``beta_g0`` of another length.
        """
        rates = np.broadcast_to(np.asarray(self.beta_g0, dtype=float), (dim,)) if np.ndim(self.beta_g0) == 0 else None
        if rates is None:
            rates = np.asarray(self.beta_g0, dtype=float)
            if rates.shape != (dim,):
                raise ValueError(f"beta_g0 has {rates.size} rates for a DMP with {dim} gap components")
        return np.array(rates)

    def with_values(self, **values: float) -> "Gains":
        """These gains with some replaced (checked again)."""
        return replace(self, **values)


def stable_bounds(dt: float, tau: float, margin: float = 0.5) -> dict[str, tuple[float, float]]:
    """Upper bounds on ``beta``, ``gamma`` and ``alpha_s`` under which the semi-implicit roll-out is stable.

    Parameters
    ----------
    dt, tau:
        Step and time constant [s].
    margin:
        Fraction of the stability limit of ``k1 = beta dt / tau`` kept, at most 1.

    Returns
    -------
    dict
        ``{"beta": (low, high), "gamma": (low, high), "alpha_s": (low, high)}``.

    Notes
    -----
    Linearised about the goal, one gap component of the roll-out
    (:mod:`optikin.dmp.imitation`) with ``k1 = beta dt / tau`` and
    ``k2 = beta gamma (dt / tau)^2`` follows ``u' = (1 - k1) u - k2 e``,
    ``e' = e + u'`` (``u = dt/tau eta``, ``e`` the error): the matrix
    ``[[1-k1, -k2], [1-k1, 1-k2]]`` has determinant ``1 - k1`` and trace
    ``2 - k1 - k2``, and the Jury conditions give ``0 < k1 < 2``,
    ``0 < k2 < 4 - 2 k1``. ``beta <= margin tau/dt`` and
    ``gamma <= 2 tau/dt`` keep ``k1 <= margin`` and ``k2 <= 2 margin``, inside
    the region for ``margin <= 1``. The coupling ``alpha_s`` alone is a first
    order step ``e' = (1 - alpha_s dt/tau) e``: stable below ``2 tau/dt``.
    """
    ratio = tau / dt
    return {"beta": (1e-3, margin * ratio), "gamma": (1e-3, 2.0 * ratio), "alpha_s": (0.0, margin * ratio)}
