"""Build and solve an ``ik`` problem: the formulations of the options, the methods compared, the answers' checks.

:func:`solve` turns a :class:`~optikin.problems.ProblemContext` into an
:class:`IkOutcome`: the targets, the setup, and per compared method its
:class:`~optikin.solvers.base.SolutionBatch` with the checks of its answers made
independently of the solver (:func:`answer_checks`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from optikin.algebra import dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm
from optikin.data.targets import Targets, reach_bound
from optikin.ik.cbha import distribution_deviation, leg_checks, leg_margins
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.platform import solve_platforms
from optikin.problems import ProblemContext
from optikin.problems.ik.options import FormulationOptions, IkOptions
from optikin.solvers import build_preset
from optikin.solvers.base import SolutionBatch
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter

Problem = LeastSquaresProblem | list[LeastSquaresProblem]
"""One least-squares problem, or one per CBHA platform (leg-length targets)."""


# --------------------------------------------------------------------------------------- setup
@dataclass(frozen=True, eq=False)
class IkSetup:
    """The options checked against the arm: the main formulation, its variants, the start and the restarts."""

    target: str
    formulation: Formulation
    start: np.ndarray
    restarts: int
    variants: dict[str, Formulation]


def setup_of(ctx: ProblemContext) -> IkSetup:
    """The :class:`IkSetup` of ``ctx.options``; errors name the option (``options.variants.<label>.<field>``
    for a field a variant sets)."""
    options: IkOptions = ctx.options
    if options.target == "legs" and not isinstance(ctx.arm, CBHAArm):
        raise ctx.error("options.target", f"leg-length targets need a cbha arm, not {ctx.spec.arm.type!r}")
    formulation = formulation_of(ctx, options.target, options, lambda key: f"options.{key}")
    start = formulation.rest if options.start == "rest" else configuration(ctx, "options.start", options.start)
    variants = {}
    for label, variant in options.variants.items():
        merged = FormulationOptions(
            **{
                key: getattr(variant if key in variant.model_fields_set else options, key)
                for key in FormulationOptions.model_fields
            }
        )

        def where(key: str, label: str = label, variant: FormulationOptions = variant) -> str:
            return f"options.variants.{label}.{key}" if key in variant.model_fields_set else f"options.{key}"

        variants[label] = formulation_of(ctx, options.target, merged, where)
    return IkSetup(options.target, formulation, start, options.restarts, variants)


def formulation_of(ctx: ProblemContext, target: str, o: FormulationOptions, where: Callable[[str], str]) -> Formulation:
    """A :class:`Formulation` of ``target`` from options ``o`` on ``ctx.arm``; ``where(field)`` names an error."""
    arm = ctx.arm
    if o.elongation != "free" and not isinstance(arm, CBHAArm):
        raise ctx.error(where("elongation"), f"the elongation distribution needs a cbha arm, not {ctx.spec.arm.type!r}")
    if target == "legs" and (o.elongation != "free" or o.redundancy == "penalty"):
        key = "elongation" if o.elongation != "free" else "redundancy"
        raise ctx.error(where(key), "leg-length targets have a unique solution: no penalty, no distribution")
    rest = rest_configuration(arm) if o.rest is None else configuration(ctx, where("rest"), o.rest)
    weights = vector(ctx, where("weights"), default_weights(arm) if o.weights is None else o.weights)
    orientation_length = 1.0
    if target == "pose":
        orientation_length = reach_bound(arm) if o.orientation_length is None else o.orientation_length
    return Formulation(
        target=target,
        redundancy=o.redundancy,
        rest=rest,
        weights=weights,
        tolerance=o.tolerance,
        orientation_length=orientation_length,
        penalty=o.penalty,
        penalty_on=o.penalty_on,
        elongation=o.elongation,
    )


def default_weights(arm: ArmModel) -> np.ndarray:
    """The inverse ranges ``1 / (upper - lower)``; 1 for a fixed variable (``lower = upper``: not solved for)."""
    span = arm.upper - arm.lower
    return 1.0 / np.where(span > 0, span, 1.0)


def vector(ctx: ProblemContext, field: str, value: object) -> np.ndarray:
    """``value`` as one number per configuration variable of ``ctx.arm``; else an error naming ``field``."""
    v = np.asarray(value, dtype=float)
    if v.shape != (ctx.arm.n_config,):
        raise ctx.error(
            field, f"expected {ctx.arm.n_config} numbers ({', '.join(ctx.arm.config_names)}), got {value!r}"
        )
    return v


def configuration(ctx: ProblemContext, field: str, value: object) -> np.ndarray:
    """:func:`vector` inside the arm's bounds (to a relative 1e-12 of each range)."""
    q = vector(ctx, field, value)
    arm = ctx.arm
    span = arm.upper - arm.lower
    outside = (q < arm.lower - 1e-12 * span) | (q > arm.upper + 1e-12 * span)
    if outside.any():
        j = int(np.argmax(outside))
        raise ctx.error(
            field, f"{arm.config_names[j]} = {q[j]:.6g} outside its bounds [{arm.lower[j]:.6g}, {arm.upper[j]:.6g}]"
        )
    return q


# --------------------------------------------------------------------------------------- methods
@dataclass(eq=False)
class Method:
    """One row of the comparison: a backend on a formulation of the targets."""

    name: str
    role: str
    adapter: NonlinearAdapter
    formulation: Formulation
    problem: Problem


def methods_of(ctx: ProblemContext, setup: IkSetup) -> list[Method]:
    """The problem's solver, each baseline preset not already listed, then the solver on each variant."""
    assert ctx.solver is not None
    problem = build_problem(ctx.arm, setup.formulation)
    adapter = ctx.backend(NonlinearAdapter)
    methods = [Method(ctx.solver.name, "solver", adapter, setup.formulation, problem)]
    for name in ctx.spec.baselines:
        if name in [m.name for m in methods]:
            continue
        # the runner checked that it is a preset of this kind's family
        methods.append(Method(name, "baseline", build_preset(name), setup.formulation, problem))
    for label, formulation in setup.variants.items():
        methods.append(
            Method(f"{ctx.solver.name} [{label}]", "variant", adapter, formulation, build_problem(ctx.arm, formulation))
        )
    return methods


Solve = Callable[[np.ndarray, np.ndarray, bool, "np.ndarray | None"], SolutionBatch]
"""``(starts, targets, warm_start, x_ref) -> SolutionBatch``: one backend on one kind of target."""


def solver_of(adapter: NonlinearAdapter, problem: Problem) -> Solve:
    """How ``adapter`` solves ``problem`` for a batch of targets (platform by platform for CBHA legs)."""
    if isinstance(problem, list):
        platforms = problem
        return lambda X0, P, warm, x_ref: solve_platforms(adapter, platforms, P, X0, warm)
    return lambda X0, P, warm, x_ref: adapter.solve_many(problem, X0, P, warm_start=warm, x_ref=x_ref)


def solve_targets(
    solve: Solve, targets: Targets, setup: IkSetup, formulation: Formulation, ctx: ProblemContext
) -> SolutionBatch:
    """Solve every target: warm-started along a trajectory; else batched, then the samples not solved retried
    ``setup.restarts`` times, first from the solution of the nearest solved target, then from random
    admissible configurations (seeded), keeping the better point; a sample's time and iterations include
    its retries."""
    x_ref = formulation.rest if formulation.redundancy == "rest" else None
    if targets.trajectory:
        return solve(setup.start, targets.values, True, x_ref)
    report = solve(setup.start, targets.values, False, x_ref)
    for attempt in range(setup.restarts):
        status = np.array(report.status)
        retry = np.flatnonzero(status != "ok")
        if retry.size == 0:
            break
        if attempt == 0 and (status == "ok").any():
            starts = nearest_solutions(targets.values, report.x, status == "ok", retry)
        else:
            starts = ctx.arm.sample_configurations(retry.size, ctx.rng(100 + attempt))
        keep_better(report, retry, solve(starts, targets.values[retry], False, x_ref))
    return report


def keep_better(report: SolutionBatch, retry: np.ndarray, again: SolutionBatch) -> None:
    """Fold the retries ``again`` of samples ``retry`` into ``report``: iterations and time add up, the point
    is replaced when the retry is ``ok`` or has a residual no larger."""
    for j, i in enumerate(retry):
        better = again.status[j] == "ok" or (
            np.isfinite(again.residual[j]) and not again.residual[j] >= report.residual[i]
        )
        report.iterations[i] += again.iterations[j]
        report.seconds[i] += again.seconds[j]
        if better:
            report.x[i], report.status[i] = again.x[j], again.status[j]
            report.residual[i], report.messages[i] = again.residual[j], again.messages[j]


def nearest_solutions(values: np.ndarray, X: np.ndarray, solved: np.ndarray, retry: np.ndarray) -> np.ndarray:
    """For each sample in ``retry``, the solution of the solved target nearest to its own target.

    Dual quaternions ``Q`` and ``-Q`` are the same pose: the distance takes the nearer sign.
    """
    candidates = np.flatnonzero(solved)
    a, b = values[retry][:, None, :], values[candidates][None, :, :]
    distance = np.linalg.norm(a - b, axis=2)
    if values.shape[1] == 8:
        distance = np.minimum(distance, np.linalg.norm(a + b, axis=2))
    return X[candidates[np.argmin(distance, axis=1)]]


# --------------------------------------------------------------------------------------- checks of answers
def tip_errors(arm: ArmModel, targets: Targets, X: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Position error [m] and, for poses, rotation error [rad] of solutions ``X``, recomputed with ``fk_dq``."""
    finite = np.all(np.isfinite(X), axis=1)
    reached = arm.evaluate("fk_dq", np.where(finite[:, None], X, rest_configuration(arm)))
    position_error = np.linalg.norm(dq_translation(reached) - targets.positions, axis=1)
    position_error[~finite] = np.nan
    if targets.kind == "position":
        return position_error, None
    relative = quat_multiply(quat_conjugate(targets.values[:, :4]), reached[:, :4])
    angle = quat_angle(relative)
    angle[~finite] = np.nan
    return position_error, angle


def rest_distances(arm: ArmModel, formulation: Formulation, X: np.ndarray) -> np.ndarray:
    """``||W dist(q, q_rest)||`` per solution (chord distance ``2 sin(d/2)`` for angles that wrap)."""
    d = X - formulation.rest
    with np.errstate(invalid="ignore"):  # a failed sample's NaN stays NaN
        d = np.where(arm.periodic, 2.0 * np.sin(d / 2.0), d)
    return np.linalg.norm(formulation.weights * d, axis=1)


def answer_checks(arm: ArmModel, targets: Targets, formulation: Formulation, X: np.ndarray) -> dict[str, np.ndarray]:
    """Per-sample checks of solutions ``X (N, n_config)``, independent of the solver's own residual.

    Leg targets: the largest leg error [m] (seed 004 eqs. (7)-(9) as printed) and whether every leg
    lies within Table I. Tip targets: the tip error [m] (and angle error [rad] for poses) by ``fk_dq``,
    the weighted distance from rest; on a CBHA also the smallest leg margin to Table I [m], the
    deviation from the elongation distribution [m] and the six tube lengths [m] (section, tube), the
    output of seed 004's inverse model.
    """
    if targets.kind == "legs":
        if not isinstance(arm, CBHAArm):
            raise ValueError(f"leg-length targets need a CBHA arm, not {arm.name}")
        leg_error, within = leg_checks(arm, targets.values, X)
        return {"leg_error": leg_error, "within_table_i": within}
    position_error, angle_error = tip_errors(arm, targets, X)
    checks = {"tip_error": position_error, "rest_distance": rest_distances(arm, formulation, X)}
    if angle_error is not None:
        checks["angle_error"] = angle_error
    if isinstance(arm, CBHAArm):
        checks["leg_margin"] = leg_margins(arm, X)
        rule = "distributed" if formulation.elongation == "free" else formulation.elongation
        checks["distribution_deviation"] = distribution_deviation(arm, X, rule)
        finite = np.all(np.isfinite(X), axis=1)
        tubes = arm.evaluate("tube_lengths", np.where(finite[:, None], X, rest_configuration(arm)))
        checks["tube_lengths"] = np.where(finite[:, None], tubes.reshape(len(X), -1), np.nan)
    return checks


# --------------------------------------------------------------------------------------- the run
@dataclass(eq=False)
class MethodRun:
    """One method's answers: the batch, the checks of :func:`answer_checks`, the wall time of all solves [s]."""

    method: Method
    report: SolutionBatch
    checks: dict[str, np.ndarray]
    wall: float


@dataclass(eq=False)
class IkOutcome:
    """What an ``ik`` run produced; ``runs[0]`` is the problem's solver. ``solution_tips`` (leg targets only):
    the tip positions ``(N, 3)`` [m] of the solver's configurations (the start where one is not finite)."""

    setup: IkSetup
    targets: Targets
    runs: list[MethodRun]
    solution_tips: np.ndarray | None = None

    @property
    def main(self) -> MethodRun:
        return self.runs[0]


def solve(ctx: ProblemContext) -> IkOutcome:
    """Check the options, load the targets, and solve them with every method (module docstring)."""
    setup = setup_of(ctx)
    assert ctx.data_source is not None
    targets: Targets = ctx.data_source.load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path, kind=setup.target)
    methods = methods_of(ctx, setup)
    runs = []
    with ctx.progress.task(f"ik: {len(targets)} targets x {len(methods)} methods", total=len(methods)) as advance:
        for method in methods:
            solve_batch = solver_of(method.adapter, method.problem)
            solve_batch(setup.start, targets.values[:1], False, None)  # build (and compile) before timing
            started = time.perf_counter()
            report = solve_targets(solve_batch, targets, setup, method.formulation, ctx)
            wall = time.perf_counter() - started
            runs.append(MethodRun(method, report, answer_checks(ctx.arm, targets, method.formulation, report.x), wall))
            advance()
    outcome = IkOutcome(setup, targets, runs)
    if targets.kind == "legs":
        X = outcome.main.report.x
        outcome.solution_tips = ctx.arm.evaluate("fk_position", np.where(np.isfinite(X), X, setup.start))
    return outcome
