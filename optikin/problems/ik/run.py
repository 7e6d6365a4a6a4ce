"""Build and solve an ``ik`` problem: the formulations of the options, the methods compared, the answers' checks.

:func:`solve` turns a :class:`~optikin.problems.ProblemContext` into an
:class:`IkOutcome`: the targets, the setup, and per compared method its
:class:`~optikin.solvers.base.SolutionBatch` with the checks of its answers made
independently of the solver (:func:`answer_checks`).
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import yaml

from optikin.algebra import dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm
from optikin.data.targets import Targets, reach_bound
from optikin.ik.cbha import distribution_deviation, leg_checks, leg_margins
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.platform import solve_platforms
from optikin.ik.points import COMPONENTS, MeasuredPoint, PointSet
from optikin.problems import ProblemContext
from optikin.problems.ik.options import FormulationOptions, IkOptions
from optikin.solvers import build_preset
from optikin.results import SOLVED
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
    noise: float | None = None


def setup_of(ctx: ProblemContext) -> IkSetup:
    """The :class:`IkSetup` of ``ctx.options``; errors name the option (``options.variants.<label>.<field>``
    for a field a variant sets)."""
    options: IkOptions = ctx.options
    if options.target == "legs" and not isinstance(ctx.arm, CBHAArm):
        raise ctx.error("options.target", f"leg-length targets need a cbha arm, not {ctx.arm_type!r}")
    points = point_set_of(ctx, options)
    noise = calibrated_noise(ctx) if options.noise == "calibrated" else options.noise
    formulation = formulation_of(ctx, options.target, options, lambda key: f"options.{key}", points, noise)
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

        variants[label] = formulation_of(ctx, options.target, merged, where, points, noise)
    return IkSetup(options.target, formulation, start, options.restarts, variants, noise)


def calibrated_noise(ctx: ProblemContext) -> float:
    """``calibration.noise_level`` [m] of the arm file the problem file's ``arm:`` names (written by kind
    ``calibrate``: the 95th percentile of its held-out postures' RMS marker errors); a :class:`SpecError` on
    ``options.noise`` when the arm is not included from such a file."""
    try:
        arm = yaml.safe_load(ctx.path.read_text()).get("arm")
    except (OSError, yaml.YAMLError, AttributeError) as exc:
        raise ctx.error("options.noise", f"cannot read the problem file again: {exc}") from None
    if not isinstance(arm, str):
        raise ctx.error("options.noise", "calibrated needs arm: <file> naming a calibrated arm file (kind calibrate)")
    included = (ctx.path.parent / arm).resolve()
    try:
        facts = yaml.safe_load(included.read_text()).get("calibration") or {}
    except (OSError, yaml.YAMLError, AttributeError) as exc:
        raise ctx.error("options.noise", f"cannot read {included}: {exc}") from None
    level = facts.get("noise_level")
    if not isinstance(level, (int, float)) or isinstance(level, bool) or not level > 0:
        raise ctx.error(
            "options.noise",
            f"{included} has no calibration.noise_level (written by kind calibrate with a held-out test): "
            "calibrate again, or give the noise in metres",
        )
    return float(level)


def point_set_of(ctx: ProblemContext, options: IkOptions) -> PointSet | None:
    """The measured points of ``target: points`` (None for other targets), checked against ``ctx.arm``."""
    if options.target != "points":
        if options.points is not None:
            raise ctx.error("options.points", f"points are the targets of target: points, not {options.target}")
        return None
    if not options.points:
        raise ctx.error("options.points", "target points needs the points: name -> {section, at, offset, measure}")
    points = []
    for name, p in options.points.items():
        if p.section > ctx.arm.n_sections:
            raise ctx.error(
                f"options.points.{name}.section", f"{ctx.arm.name} has {ctx.arm.n_sections} sections, not {p.section}"
            )
        point = MeasuredPoint(
            name=name,
            section=p.section - 1,
            fraction=p.at,
            offset=p.offset,
            components=tuple(c for c in COMPONENTS if c in p.measure),
            weight=p.weight,
        )
        try:
            PointSet((point,)).check(ctx.arm)
        except ValueError as error:
            raise ctx.error(f"options.points.{name}.at", str(error)) from None
        points.append(point)
    return PointSet(tuple(points))


def formulation_of(
    ctx: ProblemContext,
    target: str,
    o: FormulationOptions,
    where: Callable[[str], str],
    points: PointSet | None = None,
    noise: float | None = None,
) -> Formulation:
    """A :class:`Formulation` of ``target`` from options ``o`` on ``ctx.arm``; ``where(field)`` names an error."""
    arm = ctx.arm
    if o.elongation != "free" and not isinstance(arm, CBHAArm):
        raise ctx.error(where("elongation"), f"the elongation distribution needs a cbha arm, not {ctx.arm_type!r}")
    if target == "legs" and (o.elongation != "free" or o.redundancy == "penalty"):
        key = "elongation" if o.elongation != "free" else "redundancy"
        raise ctx.error(where(key), "leg-length targets have a unique solution: no penalty, no distribution")
    rest = rest_configuration(arm) if o.rest is None else configuration(ctx, where("rest"), o.rest)
    weights = vector(ctx, where("weights"), default_weights(arm) if o.weights is None else o.weights)
    orientation_length = 1.0
    if target in ("pose", "points"):
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
        points=points,
        noise=noise,
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
    not_applicable: str | None = None


APPLICABILITY_SAMPLES = 8
"""Random configurations (with the first targets) at which a backend's applicability is judged."""


def methods_of(ctx: ProblemContext, setup: IkSetup, targets: Targets | None = None) -> list[Method]:
    """The problem's solver, each baseline preset not already listed, then the solver on each variant;
    with ``targets``, each method's :attr:`Method.not_applicable` (:func:`applicability`)."""
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
    if targets is not None:
        for method in methods:
            method.not_applicable = applicability(ctx, method, targets)
    return methods


def applicability(ctx: ProblemContext, method: Method, targets: Targets) -> str | None:
    """Why ``method``'s backend cannot solve its formulation (None when it can), judged at
    :data:`APPLICABILITY_SAMPLES` random admissible configurations with the first targets
    (:meth:`~optikin.solvers.nonlinear.NonlinearAdapter.not_applicable`)."""
    if isinstance(method.problem, list):
        return None
    k = min(APPLICABILITY_SAMPLES, len(targets))
    X = ctx.arm.sample_configurations(k, ctx.rng(99))
    return method.adapter.not_applicable(method.problem, X, targets.values[:k])


Solve = Callable[[np.ndarray, np.ndarray, bool, "np.ndarray | None"], SolutionBatch]
"""``(starts, targets, warm_start, x_ref) -> SolutionBatch``: one backend on one kind of target."""


def solver_of(adapter: NonlinearAdapter, problem: Problem) -> Solve:
    """How ``adapter`` solves ``problem`` for a batch of targets (platform by platform for CBHA legs)."""
    if isinstance(problem, list):
        platforms = problem
        return lambda X0, P, warm, x_ref: solve_platforms(adapter, platforms, P, X0, warm)
    return lambda X0, P, warm, x_ref: adapter.solve_many(problem, X0, P, warm_start=warm, x_ref=x_ref)


def reference_of(formulation: Formulation, problem: Problem) -> np.ndarray | None:
    """The ``x_ref`` the backends are given: the rest configuration for ``redundancy: rest``, else None (each
    start).

    None too where no backend's answer depends on it: a fit (not :attr:`~optikin.ik.formulation.Formulation.exact`)
    with at least as many residual rows as free variables is ``min ||r||`` whatever the reference (``newton``
    solves ``J^T r = 0``, ``ipopt`` and ``sqpmethod`` minimise ``||r||^2``, ``lm`` and ``trf`` add their pull
    rows only to a redundant problem, ``gauss_newton`` never reads it). Passing it would only keep
    ``gauss_newton`` off its generated-C path (:mod:`optikin.native.ik`), ten times slower per posture.
    """
    if formulation.redundancy != "rest":
        return None
    if isinstance(problem, LeastSquaresProblem) and not formulation.exact:
        if problem.m >= int(np.count_nonzero(~problem.fixed)):
            return None
    return formulation.rest


def solve_targets(
    solve: Solve,
    targets: Targets,
    setup: IkSetup,
    formulation: Formulation,
    ctx: ProblemContext,
    x_ref: np.ndarray | None = None,
) -> SolutionBatch:
    """Solve every target: warm-started along a trajectory; else batched, then the samples not solved retried
    ``setup.restarts`` times, first from the solution of the nearest solved target, then from random
    admissible configurations (seeded), keeping the better point; a sample's time and iterations include
    its retries. With ``setup.noise``, minima within the noise are fits (:func:`mark_fits`). ``x_ref``: the
    reference of every solve (:func:`reference_of`); the first batch from a start equal to it is given None
    (each start, the same reference)."""
    if targets.trajectory:
        return mark_fits(solve(setup.start, targets.values, True, x_ref), ctx.arm, targets, formulation, setup.noise)
    first = None if x_ref is not None and np.array_equal(setup.start, x_ref) else x_ref
    report = mark_fits(solve(setup.start, targets.values, False, first), ctx.arm, targets, formulation, setup.noise)
    for attempt in range(setup.restarts):
        status = np.array(report.status)
        solved = np.isin(status, SOLVED)
        retry = np.flatnonzero(~solved)
        if retry.size == 0:
            break
        if attempt == 0 and solved.any():
            starts = nearest_solutions(targets.values, report.x, solved, retry, targets.kind == "pose")
        else:
            starts = ctx.arm.sample_configurations(retry.size, ctx.rng(100 + attempt))
        again = solve(starts, targets.values[retry], False, x_ref)
        keep_better(report, retry, mark_fits(again, ctx.arm, targets.subset(retry), formulation, setup.noise))
    return report


def rms_distances(arm: ArmModel, targets: Targets, formulation: Formulation, X: np.ndarray) -> np.ndarray:
    """``(N,)`` RMS of the unweighted distances [m] of solutions ``X`` to their targets: the tip distance
    (position), the RMS of the tip distance and ``L`` times the angle error (pose), or
    :meth:`~optikin.ik.points.PointSet.rms_distance` (points)."""
    if targets.kind == "points":
        assert formulation.points is not None
        return formulation.points.rms_distance(arm, X, targets.values, formulation.orientation_length)
    position_error, angle_error = tip_errors(arm, targets, X)
    if angle_error is None:
        return position_error
    return np.sqrt(0.5 * (position_error**2 + (formulation.orientation_length * angle_error) ** 2))


def mark_fits(
    report: SolutionBatch, arm: ArmModel, targets: Targets, formulation: Formulation, noise: float | None
) -> SolutionBatch:
    """Without ``noise``, ``report`` unchanged. With it the problem is a minimisation of ``||r||``
    (:attr:`~optikin.ik.formulation.Formulation.exact` is False), and a sample at a minimum (``ok``) is
    ``ok`` when ``||r|| <= tolerance``, ``fit`` when its :func:`rms_distances` is at most ``noise``, and
    ``unreachable`` beyond, its message stating the distance."""
    if noise is None or targets.kind == "legs":
        return report
    minima = np.flatnonzero((np.array(report.status) == "ok") & (report.residual > formulation.tolerance))
    if minima.size == 0:
        return report
    rms = rms_distances(arm, targets.subset(minima), formulation, report.x[minima])
    for i, distance in zip(minima, rms):
        if distance <= noise:
            report.status[i] = "fit"
            report.messages[i] = f"least-squares fit: RMS distance {distance * 1e3:.3g} mm, within the noise"
        else:
            report.status[i] = "unreachable"
            report.messages[i] = (
                f"RMS distance {distance * 1e3:.3g} mm at the minimum exceeds the noise {noise * 1e3:.3g} mm"
            )
    return report


def keep_better(report: SolutionBatch, retry: np.ndarray, again: SolutionBatch) -> None:
    """Fold the retries ``again`` of samples ``retry`` into ``report``: iterations and time add up, the point
    is replaced when the retry is ``ok`` or has a residual no larger."""
    for j, i in enumerate(retry):
        better = again.status[j] in SOLVED or (
            np.isfinite(again.residual[j]) and not again.residual[j] >= report.residual[i]
        )
        report.iterations[i] += again.iterations[j]
        report.seconds[i] += again.seconds[j]
        if better:
            report.x[i], report.status[i] = again.x[j], again.status[j]
            report.residual[i], report.messages[i] = again.residual[j], again.messages[j]


def nearest_solutions(
    values: np.ndarray, X: np.ndarray, solved: np.ndarray, retry: np.ndarray, dual_quaternions: bool = False
) -> np.ndarray:
    """For each sample in ``retry``, the solution of the solved target nearest to its own target.

    With ``dual_quaternions`` (pose targets), ``Q`` and ``-Q`` are the same pose: the distance takes the
    nearer sign.
    """
    candidates = np.flatnonzero(solved)
    a, b = values[retry][:, None, :], values[candidates][None, :, :]
    distance = np.linalg.norm(a - b, axis=2)
    if dual_quaternions:
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
    lies within Table I. Point targets: the distance of every point ``(N, k)`` [m], the angle errors of
    directions and orientations ``(N, k)`` [rad] where measured, the RMS distance of
    :func:`rms_distances` and the weighted distance from rest. Tip targets: the tip error [m] (and
    angle error [rad] for poses) by ``fk_dq``, the weighted distance from rest; on a CBHA also the
    smallest leg margin to Table I [m], the deviation from the elongation distribution [m] and the six
    tube lengths [m] (section, tube), the
    output of seed 004's inverse model.
    """
    if targets.kind == "legs":
        if not isinstance(arm, CBHAArm):
            raise ValueError(f"leg-length targets need a CBHA arm, not {arm.name}")
        leg_error, within = leg_checks(arm, targets.values, X)
        return {"leg_error": leg_error, "within_table_i": within}
    if targets.kind == "points":
        assert formulation.points is not None
        errors = formulation.points.errors(arm, X, targets.values)
        checks = {
            "point_error": errors["position"],
            "rms_distance": rms_distances(arm, targets, formulation, X),
            "rest_distance": rest_distances(arm, formulation, X),
        }
        if np.isfinite(errors["angle"]).any():
            checks["point_angle_error"] = errors["angle"]
        return checks
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
def load_targets(ctx: ProblemContext, setup: IkSetup) -> Targets:
    """The targets of ``ctx``'s data source for ``setup.target`` (with the measured points for ``points``)."""
    assert ctx.data_source is not None
    load = ctx.data_source.load
    if setup.target != "points":
        return load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path, kind=setup.target)
    if "points" not in inspect.signature(load).parameters:
        raise ctx.error("data.source", f"source {ctx.spec.data.source!r} does not provide measured-point targets")
    return load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path, kind="points", points=setup.formulation.points)


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
    the tip positions ``(N, 3)`` [m] of the solver's configurations (the start where one is not finite).
    ``not_applicable``: the methods that cannot solve the formulation (not run, listed with the reason)."""

    setup: IkSetup
    targets: Targets
    runs: list[MethodRun]
    solution_tips: np.ndarray | None = None
    not_applicable: list[Method] = field(default_factory=list)

    @property
    def main(self) -> MethodRun:
        return self.runs[0]


def solve(ctx: ProblemContext, split: Callable[[int, Solve], Solve] | None = None) -> IkOutcome:
    """Check the options, load the targets, and solve them with every method (module docstring).

    ``split(index, solve)``, when given, replaces the batch solver of method ``index`` of
    :func:`methods_of` (:mod:`optikin.problems.ik.chunks`: the batch in pieces on worker processes).
    """
    setup = setup_of(ctx)
    assert ctx.data_source is not None
    targets = load_targets(ctx, setup)
    methods = methods_of(ctx, setup, targets)
    if methods[0].not_applicable:
        raise ctx.error("solver", f"{methods[0].name} cannot solve this formulation: {methods[0].not_applicable}")
    runs = []
    skipped = [m for m in methods if m.not_applicable]
    applicable = [(index, m) for index, m in enumerate(methods) if not m.not_applicable]
    with ctx.progress.task(f"ik: {len(targets)} targets x {len(applicable)} methods", total=len(applicable)) as advance:
        for index, method in applicable:
            solve_batch = solver_of(method.adapter, method.problem)
            solve_batch(setup.start, targets.values[:1], False, None)  # build (and compile) before timing
            if split is not None:
                solve_batch = split(index, solve_batch)
            started = time.perf_counter()
            x_ref = reference_of(method.formulation, method.problem)
            report = solve_targets(solve_batch, targets, setup, method.formulation, ctx, x_ref)
            wall = time.perf_counter() - started
            runs.append(MethodRun(method, report, answer_checks(ctx.arm, targets, method.formulation, report.x), wall))
            advance()
    outcome = IkOutcome(setup, targets, runs, not_applicable=skipped)
    if targets.kind == "legs":
        X = outcome.main.report.x
        outcome.solution_tips = ctx.arm.evaluate("fk_position", np.where(np.isfinite(X), X, setup.start))
    return outcome
