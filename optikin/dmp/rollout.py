"""The DMP roll-out as one CasADi Function: the whole loop runs in CasADi's virtual machine.

One step (Seleem et al. 2020, eqs. 11-12 / 17-18, 15, 23-28, in the gap units of
:mod:`optikin.dmp.spaces`) on the state ``x = (y, eta, s, g, e_prev)``:

    e   = lift(gap(g, y), e_prev)        goal gap (eq. 19: 2 log(g conj(y))) on the branch nearest
                                         the step before's (:meth:`~optikin.dmp.spaces.Space.lift`)
    r   = m gap(y_ref, y)                gap to a reference (eq. 27), m in {0, 1}
    f   = a * (W psi(s)) s / sum psi(s)  forcing term (eqs. 13, 20), a the amplitude scaling,
          for s > s_end only           (off past the demonstration's phase, :func:`optikin.dmp.basis.forcing_end`)
    eta <- eta + dt/tau [beta (gamma e - eta) + f + d]                       (eqs. 11, 17; d a disturbance)
    y   <- advance(advance(y, dt/tau (eta + alpha_s (e + r))), o)            (eqs. 12, 23, 26, 27;
                                                                          o an output displacement)
    s   <- s exp(-zeta dt / (tau (1 + alpha (w |e| + |r|))))                 (eqs. 15, 25, 28)
    g   <- advance(g, (1 - exp(-beta_g0 dt/tau)) gap(g_new, g))              (eq. 24; beta_g0 one rate
                                                                          per gap component, the diagonal)
    e_prev <- e

The pose update ``advance(y, v) = exp(v/2) y`` (for Koutras & Doulgeri's DMP,
:class:`~optikin.dmp.spaces.GoalLogQuaternion`, a step of the gap itself:
``y <- exp(-(e - v)/2) g``) keeps a unit quaternion (or
unit dual quaternion) unit to rounding; the goal filter and the phase are
integrated exactly for gaps held over the step. ``e_prev`` starts at the
gap the imitation learned at the start (:mod:`optikin.dmp.imitation`), so a
rotation past half or a full turn to the goal is one continuous gap in both. The coupling uses the filtered
goal ``g`` (Seleem et al. write the new goal in eq. 26, which would make the
velocity jump at a switch, what the filter is there to prevent). Phase
stopping (:mod:`optikin.dmp.canonical`) uses the tracking error ``|r|`` alone
(``w = 0``, the default) or, as Seleem et al.'s eq. (28), the sum of the two gap
norms (``w = 1``).

The loop is a ``mapaccum`` of the step wrapped in an MX Function per number of
steps (cached): no Python runs per sample, and the same graph gives exact
derivatives with respect to gains and weights for tuning
(:mod:`optikin.dmp.tuning`).
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca

from optikin.dmp.gains import GAIN_NAMES
from optikin.dmp.spaces import Space, smooth_norm


def state_size(space: Space) -> int:
    """``(y, eta, s, g, e_prev)``."""
    return 2 * space.size + 2 * space.dim + 1


def input_size(space: Space) -> int:
    """Per-step inputs ``(d, y_ref, m, g_new, o)``: force, reference, its switch, new goal, output displacement."""
    return 2 * space.dim + 2 * space.size + 1


@lru_cache(maxsize=32)
def step_function(space: Space, n_basis: int, tabulated: bool = False, plain: bool = False) -> ca.Function:
    """One step of the roll-out, ``(x, u, W, c, h, amplitude, gains, tau, dt, s_end, w, goal_rates) -> x_next`` (SX).

    ``gains`` are the six of :data:`~optikin.dmp.gains.GAIN_NAMES` (its ``beta_g0`` unused) and ``goal_rates``
    the ``(dim,)`` diagonal of eq. (24) (:meth:`~optikin.dmp.Gains.goal_rates`). ``tabulated``: a thirteenth
    input ``forcing (dim,)`` holds the step's forcing term ``f = a * W (s > s_end) s psi(s) / sum psi(s)``
    (computed in advance where the phase does not depend on the state, ``alpha = 0``:
    :func:`optikin.dmp.basis.rollout_features`), and ``W``, ``c``, ``h``, ``amplitude`` and ``s_end`` are unused.
    ``plain`` (tabulated only): the step of an undisturbed stretch, valid where ``m = 0``, ``o = 0`` and
    ``g_new = g``: no reference gap (``r = 0``), no output displacement, and the goal held (``g_next = g``,
    where the full step moves it by the rounding of ``gap(g, g)``).
    """
    if plain and not tabulated:
        raise ValueError("the plain step is a tabulated step")
    size, dim = space.size, space.dim
    x = ca.SX.sym("x", state_size(space))
    u = ca.SX.sym("u", input_size(space))
    W = ca.SX.sym("W", dim, n_basis)
    c = ca.SX.sym("c", n_basis)
    h = ca.SX.sym("h", n_basis)
    amp = ca.SX.sym("amplitude", dim)
    gains = ca.SX.sym("gains", len(GAIN_NAMES))
    tau = ca.SX.sym("tau")
    dt = ca.SX.sym("dt")
    s_end = ca.SX.sym("s_end")
    w = ca.SX.sym("goal_stopping")
    beta_g0 = ca.SX.sym("goal_rates", dim)
    beta, gamma, zeta, _, alpha_s, alpha = (gains[i] for i in range(len(GAIN_NAMES)))

    y, eta, s = x[:size], x[size : size + dim], x[size + dim]
    g, e_prev = x[size + dim + 1 : 2 * size + dim + 1], x[2 * size + dim + 1 :]
    d, ref, m = u[:dim], u[dim : dim + size], u[dim + size]
    g_new, o = u[dim + size + 1 : dim + 2 * size + 1], u[dim + 2 * size + 1 :]

    e = space.lift(space.gap(g, y), e_prev)
    r = ca.SX.zeros(dim) if plain else m * space.gap(ref, y)
    inputs = [x, u, W, c, h, amp, gains, tau, dt, s_end, w, beta_g0]
    names = ["x", "u", "W", "c", "h", "amplitude", "gains", "tau", "dt", "s_end", "goal_stopping", "goal_rates"]
    if tabulated:
        f = ca.SX.sym("forcing", dim)
        inputs, names = inputs + [f], names + ["forcing"]
    else:
        psi = ca.exp(-h * (s - c) ** 2)
        f = amp * ca.mtimes(W, psi) * (s / ca.sum1(psi)) * (s > s_end)
    eta_next = eta + dt / tau * (beta * (gamma * e - eta) + f + d)
    y_next = space.toward(y, dt / tau * (eta_next + alpha_s * (e + r)), g, e)
    s_next = s * ca.exp(-zeta * dt / (tau * (1.0 + alpha * (w * smooth_norm(e) + smooth_norm(r)))))
    if plain:
        g_next = g
    else:
        y_next = space.advance(y_next, o)
        g_next = space.advance(g, (1.0 - ca.exp(-beta_g0 * dt / tau)) * space.gap(g_new, g))
    name = f"dmp_step_{'plain' if plain else 'tab' if tabulated else 'full'}_{n_basis}"
    return ca.Function(name, inputs, [ca.vertcat(y_next, eta_next, s_next, g_next, e)], names, ["x_next"])


@lru_cache(maxsize=32)
def gap_functions(space: Space) -> tuple[ca.Function, ca.Function, ca.Function]:
    """The gaps of a demonstration as SX Functions (generated as C with the roll-out, :mod:`optikin.dmp.compiled`).

    Returns
    -------
    tuple
        ``dmp_gap(target, y) -> gap(target, y)``, ``dmp_lift(e, previous) -> lift(e, previous)`` and
        ``dmp_step_gap(y_next, y, e_next, e) -> step_gap(...)`` (:class:`~optikin.dmp.spaces.Space`).
    """
    size, dim = space.size, space.dim
    target, y, y_next = ca.SX.sym("target", size), ca.SX.sym("y", size), ca.SX.sym("y_next", size)
    e, previous, e_next = ca.SX.sym("e", dim), ca.SX.sym("previous", dim), ca.SX.sym("e_next", dim)
    return (
        ca.Function("dmp_gap", [target, y], [space.gap(target, y)]),
        ca.Function("dmp_lift", [e, previous], [space.lift(e, previous)]),
        ca.Function("dmp_step_gap", [y_next, y, e_next, e], [space.step_gap(y_next, y, e_next, e)]),
    )


@lru_cache(maxsize=64)
def rollout_function(space: Space, n_basis: int, steps: int) -> ca.Function:
    """``(x0, U, W, c, h, amplitude, gains, tau, dt, s_end, goal_stopping, goal_rates) -> X``: ``steps`` steps,
    ``X`` of shape ``nx x (steps + 1)``.

    ``U`` holds one column of per-step inputs per step; ``c``, ``h`` and
    ``s_end`` are the basis centres, widths and end phase learned with the
    weights; ``goal_stopping`` is the weight ``w`` of the goal gap in phase stopping.
    """
    if steps < 1:
        raise ValueError(f"a roll-out needs at least one step, got {steps}")
    step = step_function(space, n_basis)
    loop = step.mapaccum("dmp_loop", steps)
    x0 = ca.MX.sym("x0", state_size(space))
    U = ca.MX.sym("U", input_size(space), steps)
    W = ca.MX.sym("W", space.dim, n_basis)
    amp = ca.MX.sym("amplitude", space.dim)
    c = ca.MX.sym("c", n_basis)
    h = ca.MX.sym("h", n_basis)
    gains = ca.MX.sym("gains", len(GAIN_NAMES))
    tau = ca.MX.sym("tau")
    dt = ca.MX.sym("dt")
    s_end = ca.MX.sym("s_end")
    w = ca.MX.sym("goal_stopping")
    rates = ca.MX.sym("goal_rates", space.dim)
    X = loop(x0, U, W, c, h, amp, gains, tau, dt, s_end, w, rates)
    return ca.Function(
        f"dmp_rollout_{n_basis}_{steps}",
        [x0, U, W, c, h, amp, gains, tau, dt, s_end, w, rates],
        [ca.horzcat(x0, X)],
        ["x0", "U", "W", "c", "h", "amplitude", "gains", "tau", "dt", "s_end", "goal_stopping", "goal_rates"],
        ["X"],
    )
