"""Run a ``dynamics`` problem: the arm at rest under the initial commands, then one implicit step per sample.

:func:`solve` builds the stepper (:class:`optikin.physics.dynamics.RodDynamics`) from the arm and
the options, evaluates the commands (:mod:`optikin.problems.dynamics.commands`) at every step's
time, and steps until the end or the first step whose BVP does not converge (the run stops
there: the trajectory is partial and says so, never a silent jump). Its outcome,
:class:`DynamicsOutcome`, goes to :mod:`optikin.problems.dynamics.report`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from optikin.arms.cosserat import CosseratArm
from optikin.errors import InputDataError, SpecError
from optikin.physics import ShootingOptions, ShootingSolver
from optikin.physics.dynamics import (
    Damping,
    DynamicsOptions,
    DynamicState,
    RodDynamics,
    StepError,
    first_bending_period,
)
from optikin.problems import ProblemContext
from optikin.problems.dynamics.commands import Commands
from optikin.problems.dynamics.options import DynamicsKindOptions


@dataclass
class DynamicsOutcome:
    """What a ``dynamics`` run computed.

    Attributes
    ----------
    t : numpy.ndarray
        ``(T + 1,)`` the planned times, the start first [s].
    command, actuation, tip_force : numpy.ndarray
        ``(T + 1, n_act)`` the commanded and the applied actuation (the chamber pressures lagging their
        commands with ``options.pressure_time_constant``), ``(T + 1, 3)`` the tip force, at those times.
    states : list of DynamicState
        The start and every converged step, without their stage arrays (``history``, ``rates``: empty).
    step_seconds : numpy.ndarray
        Wall time of every converged step [s].
    build_seconds : float
        Building (and compiling) the stepper [s].
    failure : StepError or None
        The step that did not converge.
    static_positions : numpy.ndarray or None
        ``(K, 3)`` the static equilibrium under the last step's loads (same grid), if it converged.
    first_period : float
        Euler-Bernoulli first bending period of the arm [s] (:func:`~optikin.physics.dynamics.first_bending_period`).
    s : numpy.ndarray
        ``(K,)`` arc length of the nodes [m].
    """

    t: np.ndarray
    command: np.ndarray
    actuation: np.ndarray
    tip_force: np.ndarray
    states: list[DynamicState]
    step_seconds: np.ndarray
    build_seconds: float
    failure: StepError | None
    static_positions: np.ndarray | None
    first_period: float
    s: np.ndarray


def fixed_loads(arm: CosseratArm, options: DynamicsKindOptions) -> np.ndarray:
    """The load entries that do not change: tip couple, distributed force, gravity (``(12,)``, tip force zero)."""
    g = np.asarray(arm.params.gravity, dtype=float) if options.gravity else np.zeros(3)
    return np.concatenate([np.zeros(3), options.tip_couple, options.distributed_force, g])


def load_rows(arm: CosseratArm, options: DynamicsKindOptions, actuation: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """``(T, n_P)`` load vectors of the commands."""
    rows = np.tile(fixed_loads(arm, options), (actuation.shape[0], 1))
    rows[:, 0:3] = tip
    return np.hstack([rows, actuation])


def stepper(ctx: ProblemContext, arm: CosseratArm, options: DynamicsKindOptions) -> RodDynamics:
    """The stepper; an unusable ``dt`` or arm is a :class:`SpecError` naming the field."""
    settings = DynamicsOptions(
        dt=options.dt,
        alpha=options.alpha,
        steps_per_segment=arm.steps_per_segment,
        tolerance=options.tolerance,
        max_iterations=options.max_iterations,
        tip_mass=options.payload,
        compiled=options.compiled,
        flags=options.flags,
    )
    damping = tuple(
        Damping.kelvin_voigt(seg.rod, options.damping.viscosity, options.damping.drag) for seg in arm.rod_arm.segments
    )
    try:
        return RodDynamics(arm.rod_arm, settings, damping)
    except InputDataError as exc:
        field = "options.dt" if exc.field == "dt" else f"arm.params ({exc.field})"
        raise SpecError(ctx.path, field, str(exc).split(": ", 1)[-1]) from None


def pressure_lag(
    ctx: ProblemContext, arm: CosseratArm, options: DynamicsKindOptions, commanded: np.ndarray
) -> np.ndarray:
    """The chamber pressures after a first-order lag of the commands, ``(T + 1, n_act)``; tensions unchanged.

    ``tau p' = p_cmd - p`` with the command held over each step (exact:
    ``p_i = p_{i-1} + (1 - exp(-dt / tau)) (p_cmd,i - p_{i-1})``), starting at rest at the first command.

    Raises
    ------
    SpecError
        On ``options.pressure_time_constant`` when a list does not have one entry per chamber.
    """
    tau = options.pressure_time_constant
    chambers = np.nonzero(~np.asarray(arm.tendon_mask, dtype=bool))[0]
    if tau is None or chambers.size == 0:
        return commanded
    taus = np.asarray(tau if isinstance(tau, list) else [tau] * chambers.size, dtype=float)
    if taus.shape != chambers.shape:
        raise ctx.error(
            "options.pressure_time_constant", f"give one value or one per chamber ({chambers.size}), got {taus.size}"
        )
    share = 1.0 - np.exp(-options.dt / taus)
    out = commanded.copy()
    for i in range(1, out.shape[0]):
        out[i, chambers] = out[i - 1, chambers] + share * (commanded[i, chambers] - out[i - 1, chambers])
    return out


def checked_commands(ctx: ProblemContext, arm: CosseratArm, actuation: np.ndarray) -> None:
    """Refuse a negative tendon tension or a non-finite command, naming the step and the actuator."""
    source = f"{ctx.path.name}: data ({ctx.spec.data.source})"
    tendons = np.asarray(arm.tendon_mask, dtype=bool)[None, :]
    bad = ~np.isfinite(actuation) | ((actuation < 0) & tendons)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputDataError(
            f"{actuation[i, j]:.6g} is not a usable command (a tendon cannot push)",
            source=source,
            sample=int(i),
            field=arm.config_names[j],
        )


def solve(ctx: ProblemContext) -> DynamicsOutcome:
    """Simulate the problem (module docstring)."""
    arm = ctx.arm
    if not isinstance(arm, CosseratArm):
        raise ctx.error("arm.type", f"kind dynamics needs arm.type cosserat, got {ctx.arm_type!r}")
    options: DynamicsKindOptions = ctx.options
    commands: Commands = ctx.load_data()
    steps = ctx.spec.data.samples
    t = options.dt * np.arange(steps + 1)
    actuation, tip = commands.at(t[1:])
    actuation = np.vstack([commands.initial_actuation[None, :], actuation])
    tip = np.vstack([commands.initial_tip_force[None, :], tip])
    checked_commands(ctx, arm, actuation)
    commanded, actuation = actuation, pressure_lag(ctx, arm, options, actuation)
    loads = load_rows(arm, options, actuation, tip)
    start = time.perf_counter()
    dyn = stepper(ctx, arm, options)
    build = time.perf_counter() - start
    state = dyn.rest(loads[0])
    light = np.empty((0, 0))
    states, seconds, failure = [replace(state, history=light, rates=light)], [], None
    chunk = max(1, steps // 100)
    with ctx.progress.task(f"dynamics: {steps} time steps", total=steps) as advance:
        for i in range(1, steps + 1):
            begin = time.perf_counter()
            try:
                state = dyn.step(state, loads[i])
            except StepError as exc:
                failure = exc
                break
            seconds.append(time.perf_counter() - begin)
            states.append(replace(state, history=light, rates=light))
            if i % chunk == 0:
                advance(chunk)
    static = None
    if failure is None:
        solution = ShootingSolver(arm.rod_arm, ShootingOptions(steps_per_segment=arm.steps_per_segment)).solve(
            loads[-1], state.wrench
        )
        static = solution.positions if solution.ok else None
    return DynamicsOutcome(
        t=t,
        command=commanded,
        actuation=actuation,
        tip_force=tip,
        states=states,
        step_seconds=np.array(seconds),
        build_seconds=build,
        failure=failure,
        static_positions=static,
        first_period=first_bending_period(arm.rod_arm),
        s=dyn.s,
    )
