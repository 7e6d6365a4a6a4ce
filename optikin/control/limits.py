"""Configuration and rate limits turned into bounds on the commanded rates over one control step.

The configuration is integrated from the commanded rate held over the step,
``q+ = q + dt qdot`` (exact for a zero-order hold). Keeping ``lower <= q+ <= upper``
and ``|qdot| <= r`` is the box

    max(-r, (lower + margin - q)/dt)  <=  qdot  <=  min(r, (upper - margin - q)/dt).

Outside a limit (a start there, a disturbance, sensor noise) the box can be
empty: ``q`` above ``upper`` by more than ``r dt`` asks for ``qdot <= (upper-q)/dt < -r``.
Both ends are therefore clipped into ``[-r, r]``, which keeps the box non-empty
and, outside a limit, commands the return at the full rate, so the excess
shrinks by ``r dt`` per step and never grows (the recurring "QP infeasible when
starting outside the limits" of differential-IK libraries such as pink and mink).
``margin`` (default 1e-9, in the variable's units) absorbs the rounding of ``q + dt qdot``.

``gain`` in (0, 1] scales the distance to a limit that one step may cover
(``gain (upper - margin - q)/dt``), as pink (0.5) and mink (0.95) do: the arm
then slows down geometrically towards a limit instead of reaching it in one
step, and returns from outside geometrically (never farther out). The default 1
is the plain "limits hold after integrating the step".

Bending-plane angles ``phi_i`` are periodic (the kinematics are 2 pi-periodic in
them): they get rate limits only and are wrapped to ``(-pi, pi]`` after integration.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence, cast

import casadi as ca
import numpy as np

from optikin.algebra import angles
from optikin.arms.base import ArmModel
from optikin.interrupt import calls_casadi

DEFAULT_RATE_LIMITS = {"S": 0.1, "theta": np.pi, "phi": 2.0 * np.pi}
"""Rate limits by variable prefix: m/s for lengths, rad/s for angles (assumed; Seleem et al. 2020 gives none)."""


def periodic_mask(arm: ArmModel, names: Sequence[str] | None = None) -> np.ndarray:
    """True for periodic variables: ``names`` if given, else the arm's own :attr:`ArmModel.periodic` flags."""
    if names is None:
        return arm.periodic.copy()
    unknown = sorted(set(names) - set(arm.config_names))
    if unknown:
        raise ValueError(f"{arm.name} has no variables {unknown}; known: {', '.join(arm.config_names)}")
    return np.array([name in names for name in arm.config_names])


def rate_limit_vector(arm: ArmModel, limits: Mapping[str, float] | Sequence[float] | None = None) -> np.ndarray:
    """Rate limit of every configuration variable.

    ``limits`` is a full vector, or a mapping from a variable name or a name prefix
    (``"S"``, ``"theta"``, ``"phi"``) to a limit; the longest matching key wins,
    unspecified variables take :data:`DEFAULT_RATE_LIMITS`.
    """
    if limits is not None and not isinstance(limits, Mapping):
        r = np.asarray(limits, dtype=float)
        if r.shape != (arm.n_config,):
            raise ValueError(f"rate limits need {arm.n_config} values, got {r.shape}")
    else:
        table = {**DEFAULT_RATE_LIMITS, **dict(limits or {})}
        r = np.empty(arm.n_config)
        for i, name in enumerate(arm.config_names):
            keys = [k for k in table if name.startswith(k)]
            if not keys:
                raise ValueError(f"no rate limit for {name}; give one in rate_limits")
            r[i] = float(table[max(keys, key=len)])
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise ValueError(f"rate limits must be positive and finite, got {r}")
    return r


class RateBounds:
    """Bounds ``lb <= qdot <= ub`` for one control step (see the module docstring).

    ``lower``/``upper`` default to the arm's bounds; ``margin`` is a scalar or
    per-variable distance kept from the configuration limits; ``gain`` the fraction
    of the distance to a limit one step may cover.

    The box is one CasADi Function (:attr:`function`, ``(q, lower, upper, rate, gain, dt) -> (lb, ub)``,
    the limits and rates as inputs set once, so its compiled code depends on ``n`` only), evaluated in
    place: :meth:`update` copies ``q`` into its input :attr:`q` and writes :attr:`lb`, :attr:`ub`. A
    controller whose task model already holds the step's configuration in a buffer can let the box
    read that buffer instead (:meth:`read_configuration_from`) and call :meth:`refresh`, which takes
    no copy. ``compiled``: evaluate C code of the Function (compiled with gcc, cached) instead of
    CasADi's virtual machine; the same bits.
    """

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        rate_limits=None,
        margin: float | Sequence[float] = 1e-9,
        periodic: Sequence[str] | None = None,
        lower=None,
        upper=None,
        gain: float = 1.0,
        compiled: bool = False,
    ):
        if not dt > 0:
            raise ValueError(f"dt must be positive, got {dt}")
        if not 0 < gain <= 1:
            raise ValueError(f"limit gain must be in (0, 1], got {gain}")
        self.dt = float(dt)
        self.rate = rate_limit_vector(arm, rate_limits)
        self.periodic = periodic_mask(arm, periodic)
        lower = np.array(arm.lower if lower is None else lower, dtype=float)
        upper = np.array(arm.upper if upper is None else upper, dtype=float)
        margins = np.broadcast_to(np.asarray(margin, dtype=float), lower.shape)
        lower, upper = lower + margins, upper - margins
        lower[self.periodic], upper[self.periodic] = -np.inf, np.inf
        if np.any(lower > upper):
            raise ValueError("margin leaves no room between the configuration limits")
        self.lower, self.upper = lower, upper
        # One CasADi call per step instead of seven numpy ufuncs on six numbers (each costs about as much).
        n = arm.n_config
        q, low, high, rate = (ca.SX.sym(name, n) for name in ("q", "lower", "upper", "rate"))
        scale, step = ca.SX.sym("gain"), ca.SX.sym("dt")
        bounds = [ca.densify(ca.fmin(ca.fmax(scale * (limit - q) / step, -rate), rate)) for limit in (low, high)]
        self.function = ca.Function(
            f"rate_bounds_{n}",
            [q, low, high, rate, scale, step],
            bounds,
            ["q", "lower", "upper", "rate", "gain", "dt"],
            ["lb", "ub"],
        )
        if compiled:
            from optikin.codegen import compile_function

            self.function = compile_function(self.function)
        self.q, self.lb, self.ub = np.zeros(n), np.zeros(n), np.zeros(n)
        self._parameters = (lower, upper, self.rate.copy(), np.array([float(gain)]), np.array([self.dt]))
        self._buffer, self._refresh = cast(Any, self.function.buffer())  # CasADi's stub asks for a byte count
        for i, array in enumerate((self.q, *self._parameters)):
            self._buffer.set_arg(i, array.data)
        self._buffer.set_res(0, self.lb.data)
        self._buffer.set_res(1, self.ub.data)

    @calls_casadi
    def update(self, q: np.ndarray) -> None:
        """Write the bounds for the step starting at ``q`` into :attr:`lb`, :attr:`ub`."""
        self.q[...] = q
        self._refresh()

    @calls_casadi
    def refresh(self) -> None:
        """Write the bounds for the step starting at the configuration now in :attr:`q` into :attr:`lb`, :attr:`ub`."""
        self._refresh()

    def read_configuration_from(self, q: np.ndarray) -> None:
        """Make :attr:`q` the array ``q`` (kept, not copied), e.g. a task model's input buffer.

        Parameters
        ----------
        q:
            ``(n,)`` C-contiguous ``float64``: :meth:`refresh` evaluates the box at its contents then.
        """
        if q.shape != self.q.shape or q.dtype != np.float64 or not q.flags.c_contiguous:
            raise ValueError(f"the configuration must be a C-contiguous float64 array of shape {self.q.shape}")
        self.q = q
        self._buffer.set_arg(0, q.data)


def limit_excess(arm: ArmModel, Q: np.ndarray, periodic: Sequence[str] | None = None) -> np.ndarray:
    """How far each configuration lies outside the arm's limits, ``(N, n)``, zero inside; periodic variables 0."""
    Q = np.atleast_2d(Q)
    excess = np.maximum(Q - arm.upper, 0.0) + np.maximum(arm.lower - Q, 0.0)
    excess[:, periodic_mask(arm, periodic)] = 0.0
    return excess


def wrap_periodic(q: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``q`` with the variables of ``mask`` wrapped into ``(-pi, pi]`` (in place; returned;
    :func:`optikin.algebra.wrap_periodic`)."""
    q[mask] = angles.wrap_periodic(q[mask], closed="upper")
    return q
