"""Solve a ``statics`` problem: equilibria along actuation samples (forward) or actuations for tip targets (inverse).

:func:`solve` checks the arm, options and baselines, then runs :func:`forward` or
:func:`inverse` and returns their typed outcome (:class:`ForwardOutcome`,
:class:`InverseOutcome`), which :mod:`optikin.problems.statics.report` turns into a Result.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from optikin.algebra import dq_translation, quat_angle, quat_conjugate, quat_multiply, quat_vector
from optikin.arms.cosserat import CosseratArm
from optikin.data.actuations import Actuations
from optikin.errors import InputDataError
from optikin.physics import (
    CollocationOptions,
    CollocationSolver,
    RodSolution,
    ShootingOptions,
    ShootingSolver,
)
from optikin.problems import ProblemContext
from optikin.problems.statics.equilibrium import TipEquilibrium, tip_function
from optikin.problems.statics.options import LoadOptions, StaticsOptions
from optikin.solvers import build_preset
from optikin.solvers.base import SolutionBatch
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter
from optikin.status import Status

COLLOCATION = "collocation"
"""The kind's own baseline: the same equilibria by Gauss-Legendre collocation and IPOPT (forward mode)."""
RAMP = (0.25, 0.5, 0.75)
"""Load fractions the collocation baseline solves first when it has no previous solution to start from."""
TARGET_SOURCES = ("target_csv", "cosserat")
"""The ``actuations`` sources that give tip targets (inverse only), called with the target kind."""
RECHECK_FACTOR = 10.0
"""An inverse answer counted ``ok`` by its backend is ``failed`` when its recomputed tip error exceeds
this many times ``target_tolerance``."""


def fixed_loads(arm: CosseratArm, loads: LoadOptions) -> np.ndarray:
    """The load vector's entries before the actuation (:data:`optikin.physics.LOAD_NAMES`), ``(12,)``.

    The payload hangs at the tip: its weight ``m g`` adds to the tip force (zero without gravity).
    """
    g = np.asarray(arm.params.gravity, dtype=float) if loads.gravity else np.zeros(3)
    tip_force = np.asarray(loads.tip_force, dtype=float) + loads.payload * g
    return np.concatenate([tip_force, np.asarray(loads.tip_couple, dtype=float), np.zeros(3), g])


def shooting_solver(arm: CosseratArm, options: StaticsOptions) -> ShootingSolver:
    """Shooting for ``arm`` on its grid (``steps_per_segment``), compiled unless ``options.compiled`` is off."""
    settings = ShootingOptions(
        steps_per_segment=arm.steps_per_segment,
        tolerance=options.tolerance,
        compiled=options.compiled,
        flags=options.flags,
    )
    return ShootingSolver(arm.rod_arm, settings)


def checked_actuations(ctx: ProblemContext, values: np.ndarray) -> np.ndarray:
    """``values (N, n_act)`` finite and within the bounds; a negative tension is named as such.

    Raises
    ------
    InputDataError
        Naming the data source, the sample and the actuator (``tendons.0``).
    """
    source = f"{ctx.path.name}: data ({ctx.spec.data.source})"
    arm: CosseratArm = ctx.arm  # type: ignore[assignment]
    values = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        negative = (values < 0) & arm.tendon_mask[None, :]
    if negative.any():
        i, j = np.argwhere(negative)[0]
        raise InputDataError(
            f"tension {values[i, j]:.6g} N is negative (a tendon cannot push)",
            source=source,
            sample=int(i),
            field=arm.config_names[j],
        )
    return arm.validate(values, source=source)


# --------------------------------------------------------------------------------------- forward
@dataclass
class ForwardRun:
    """One method's equilibria: the solutions and the wall time of each solve [s]."""

    name: str
    solutions: list[RodSolution]
    seconds: np.ndarray
    build_seconds: float


@dataclass
class ForwardOutcome:
    """What a forward ``statics`` run computed: the actuations, the shooting run and the collocation run, if any."""

    actuations: np.ndarray
    t: np.ndarray | None
    shooting: ForwardRun
    collocation: ForwardRun | None
    skipped_rows: int = 0


def equilibria(solve, loads: np.ndarray, guesses: bool) -> tuple[list[RodSolution], np.ndarray]:
    """``solve(P, guess)`` for every row of ``loads`` in order, each started from the solutions before.

    With ``guesses`` the start is the previous base wrench extrapolated from the two before it
    (:meth:`optikin.physics.ShootingSolver.solve_sequence`); otherwise ``guess`` is the previous
    solver-specific start (``None`` for the first).
    """
    out: list[RodSolution] = []
    seconds = np.zeros(len(loads))
    for k, P in enumerate(loads):
        start = None
        if guesses and out and out[-1].ok:
            start = out[-1].base_wrench
            if len(out) >= 2 and out[-2].ok:
                start = 2 * out[-1].base_wrench - out[-2].base_wrench
        began = time.perf_counter()
        out.append(solve(P, start))
        seconds[k] = time.perf_counter() - began
    return out, seconds


def forward(ctx: ProblemContext, samples: Actuations) -> ForwardOutcome:
    """Equilibria of every actuation sample by compiled shooting, and by collocation when it is a baseline."""
    options: StaticsOptions = ctx.options
    arm: CosseratArm = ctx.arm  # type: ignore[assignment]
    if samples.values is None:
        raise ctx.error("data.source", "forward statics needs actuations, not targets")
    A = checked_actuations(ctx, samples.values)
    loads = np.column_stack([np.tile(fixed_loads(arm, options.loads), (len(A), 1)), A])
    began = time.perf_counter()
    solver = shooting_solver(arm, options)
    build = time.perf_counter() - began
    with ctx.progress.task(f"statics: {len(A)} equilibria", total=1 + (COLLOCATION in ctx.spec.baselines)) as advance:
        solutions, seconds = equilibria(solver.solve, loads, True)
        advance()
        shooting = ForwardRun("shooting" + (" (compiled)" if options.compiled else ""), solutions, seconds, build)
        colloc = None
        if COLLOCATION in ctx.spec.baselines:
            began = time.perf_counter()
            c = CollocationSolver(
                arm.rod_arm,
                CollocationOptions(
                    intervals_per_segment=options.collocation_intervals,
                    degree=options.collocation_degree,
                    tolerance=options.tolerance,
                ),
            )
            c_build = time.perf_counter() - began
            previous: list[np.ndarray | None] = [None]

            def collocate(P: np.ndarray, _: object) -> RodSolution:
                if previous[0] is None:  # no start: ramp the loads from zero, as the shooting does
                    for fraction in RAMP:
                        ramped = c.solve(fraction * P, previous[0])
                        previous[0] = c.unknowns if ramped.ok else None
                solution = c.solve(P, previous[0])
                previous[0] = c.unknowns if solution.ok else None
                return solution

            c_solutions, c_seconds = equilibria(collocate, loads, False)
            colloc = ForwardRun(COLLOCATION, c_solutions, c_seconds, c_build)
            advance()
    return ForwardOutcome(A, samples.t, shooting, colloc, samples.skipped_rows)


# --------------------------------------------------------------------------------------- inverse
@dataclass
class InverseRun:
    """One backend's answers: the batch, the recomputed tip errors [m] (and angle errors [rad] for poses)."""

    name: str
    role: str
    report: SolutionBatch
    tip_error: np.ndarray
    angle_error: np.ndarray | None
    equilibria_per_target: float


@dataclass
class InverseOutcome:
    """Targets ``(N, 3)`` positions or ``(N, 7)`` ``(p, q)`` poses, the actuations that made them (NaN when
    read from a file), whether they form a trajectory, and one :class:`InverseRun` per method."""

    targets: np.ndarray
    target_actuations: np.ndarray
    t: np.ndarray | None
    trajectory: bool
    runs: list[InverseRun] = field(default_factory=list)
    dropped: int = 0
    skipped_rows: int = 0


def tip_pose(solution: RodSolution) -> np.ndarray:
    """``(p_tip, q_tip)`` (7) of an equilibrium."""
    return np.concatenate([solution.positions[-1], solution.orientations[-1]])


def inverse_problem(
    arm: CosseratArm, equilibrium: TipEquilibrium, options: StaticsOptions
) -> tuple[LeastSquaresProblem, ca.Function]:
    """The bounded least-squares problem over the actuation and the tip Function it calls (keep it alive).

    ``r = p_tip(a) - p*`` for positions; ``(p_tip(a) - p*, 2 L vec(q*^-1 q_tip(a)))`` for poses
    (the orientation error of :mod:`optikin.problems.ik`, scaled by ``L``: ``orientation_length``,
    default the arm's length), both in metres.
    """
    tip = tip_function(equilibrium)
    a = ca.SX.sym("a", arm.n_config)
    y = tip(a)
    if options.target == "position":
        p = ca.SX.sym("p", 3)
        r = y[0:3] - p
    else:
        p = ca.SX.sym("p", 7)
        length = options.orientation_length or arm.rod_arm.length
        r = ca.vertcat(y[0:3] - p[0:3], 2 * length * quat_vector(quat_multiply(quat_conjugate(p[3:7]), y[3:7])))
    residual = ca.Function("statics_inverse", [a, p], [r], ["a", "p"], ["r"])
    span = arm.upper - arm.lower
    problem = LeastSquaresProblem(
        residual,
        arm.lower,
        arm.upper,
        np.zeros(arm.n_config, dtype=bool),
        tolerance=options.target_tolerance,
        weights=1.0 / np.where(span > 0, span, 1.0),
        name="statics_inverse",
        variable_names=arm.config_names,
    )
    return problem, tip


def inverse_targets(ctx: ProblemContext, samples: Actuations, solver: ShootingSolver) -> InverseOutcome:
    """The targets: forward equilibria of the actuation samples (reachable), or the targets of ``target_csv``."""
    options: StaticsOptions = ctx.options
    arm: CosseratArm = ctx.arm  # type: ignore[assignment]
    width = 3 if options.target == "position" else 7
    if samples.targets is not None:
        T = samples.targets
        poses = T if T.shape[1] == 3 else np.column_stack([dq_translation(T), T[:, :4]])
        return InverseOutcome(
            poses[:, :width],
            np.full((len(T), arm.n_config), np.nan),
            samples.t,
            samples.trajectory,
            skipped_rows=samples.skipped_rows,
        )
    assert samples.values is not None
    A = checked_actuations(ctx, samples.values)
    loads = np.column_stack([np.tile(fixed_loads(arm, options.loads), (len(A), 1)), A])
    solutions, _ = equilibria(solver.solve, loads, True)
    ok = np.array([s.ok for s in solutions])
    poses = np.array([tip_pose(s) for s in solutions])[ok]
    t = None if samples.t is None else samples.t[ok]
    return InverseOutcome(poses[:, :width], A[ok], t, samples.trajectory, dropped=int((~ok).sum()))


def start_of(ctx: ProblemContext) -> np.ndarray:
    """The start actuation of ``options.start``."""
    options: StaticsOptions = ctx.options
    arm = ctx.arm
    if options.start == "middle":
        return 0.5 * (arm.lower + arm.upper)
    if options.start == "lower":
        return arm.lower.copy()
    start = np.asarray(options.start, dtype=float)
    if start.shape != (arm.n_config,):
        raise ctx.error("options.start", f"expected {arm.n_config} numbers ({', '.join(arm.config_names)})")
    if np.any(start < arm.lower) or np.any(start > arm.upper):
        raise ctx.error("options.start", "outside the actuation bounds")
    return start


def recheck(
    solver: ShootingSolver, fixed: np.ndarray, targets: np.ndarray, report: SolutionBatch, tolerance: float
) -> tuple[np.ndarray, np.ndarray | None]:
    """Tip errors [m] (and angle errors [rad]) of the answers, from equilibria solved again from zero load.

    An answer its backend counted ``ok`` whose recomputed equilibrium fails, or whose tip error passes
    :data:`RECHECK_FACTOR` times ``tolerance``, is marked ``failed`` in ``report``.
    """
    n = len(targets)
    position_error, angle_error = np.full(n, np.nan), np.full(n, np.nan)
    for i in range(n):
        x = report.x[i]
        if not np.all(np.isfinite(x)):
            continue
        solution = solver.solve(np.concatenate([fixed, x]))
        if not solution.ok:
            if report.status[i] == Status.OK:
                report.status[i], report.messages[i] = Status.FAILED, f"recomputed equilibrium: {solution.message}"
            continue
        pose = tip_pose(solution)
        position_error[i] = float(np.linalg.norm(pose[:3] - targets[i, :3]))
        if targets.shape[1] == 7:
            angle_error[i] = float(quat_angle(quat_multiply(quat_conjugate(targets[i, 3:7]), pose[3:7])))
        if report.status[i] == Status.OK and not position_error[i] <= RECHECK_FACTOR * tolerance:
            report.status[i] = Status.FAILED
            report.messages[i] = f"recomputed tip error {position_error[i]:.3g} m"
    return position_error, (angle_error if targets.shape[1] == 7 else None)


def inverse(ctx: ProblemContext, samples: Actuations) -> InverseOutcome:
    """Solve every target with the solver preset and each baseline preset, warm-started along a trajectory."""
    options: StaticsOptions = ctx.options
    arm: CosseratArm = ctx.arm  # type: ignore[assignment]
    assert ctx.solver is not None
    solver = shooting_solver(arm, options)
    outcome = inverse_targets(ctx, samples, solver)
    fixed = fixed_loads(arm, options.loads)
    start = start_of(ctx)
    methods: list[tuple[str, str, NonlinearAdapter]] = [(ctx.solver.name, "solver", ctx.backend(NonlinearAdapter))]
    methods += [(name, "baseline", build_preset(name)) for name in ctx.spec.baselines if name != ctx.solver.name]
    n = len(outcome.targets)
    with ctx.progress.task(f"statics inverse: {n} targets x {len(methods)} methods", total=len(methods)) as advance:
        for name, role, adapter in methods:
            equilibrium = TipEquilibrium(solver, fixed, options.flags)
            problem, _tip = inverse_problem(arm, equilibrium, options)  # _tip: the Callback, kept alive
            adapter.solve_many(problem, start, outcome.targets[:1])  # build the backend's Functions before timing
            equilibrium.forget()
            count = equilibrium.equilibria
            report = adapter.solve_many(problem, start, outcome.targets, warm_start=outcome.trajectory)
            per_target = (equilibrium.equilibria - count) / max(n, 1)
            position_error, angle_error = recheck(solver, fixed, outcome.targets, report, options.target_tolerance)
            outcome.runs.append(InverseRun(name, role, report, position_error, angle_error, per_target))
            advance()
    return outcome


# --------------------------------------------------------------------------------------- entry
def check_baselines(ctx: ProblemContext) -> None:
    """Forward mode compares with ``collocation`` only; inverse mode with ``nonlinear`` presets only."""
    mode = ctx.options.mode
    for i, name in enumerate(ctx.spec.baselines):
        if mode == "forward" and name != COLLOCATION:
            raise ctx.error(f"baselines.{i}", f"forward statics compares with {COLLOCATION!r} only, not {name!r}")
        if mode == "inverse" and name == COLLOCATION:
            raise ctx.error(f"baselines.{i}", f"{COLLOCATION!r} is a forward baseline; inverse takes nonlinear presets")


def solve(ctx: ProblemContext) -> ForwardOutcome | InverseOutcome:
    """Check the arm and the baselines, load the samples and run the mode of ``options.mode``."""
    if not isinstance(ctx.arm, CosseratArm):
        raise ctx.error("arm.type", f"kind statics needs a cosserat arm, not {ctx.arm_type!r}")
    check_baselines(ctx)
    options: StaticsOptions = ctx.options
    assert ctx.data_source is not None
    extra = {"kind": options.target} if ctx.spec.data.source in TARGET_SOURCES else {}
    samples: Actuations = ctx.data_source.load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path, **extra)
    if options.mode == "forward":
        return forward(ctx, samples)
    return inverse(ctx, samples)
