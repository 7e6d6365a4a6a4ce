"""Learn the demonstration with every variant, roll the DMPs out, tune the gains: the ``dmp`` kind's run.

:func:`solve` returns a :class:`DmpOutcome`; :mod:`optikin.problems.dmp.report`
turns it into the result.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from optikin.algebra import quat_exp, quat_multiply, rpy_from_quat
from optikin.data import demonstrations as sources
from optikin.dmp import DMP, Fit, Gains, Rollout, UnitQuaternion
from optikin.dmp.tuning import TuningProblem, TuningResult, tune_genetic, tune_gradient, tune_multistart, tuning_problem
from optikin.errors import InputDataError, OptikinError, SpecError
from optikin.problems import ProblemContext
from optikin.problems.dmp.options import Coupling, DmpOptions, Tuning
from optikin.problems.dmp.variants import (
    MM,
    MRAD,
    make_dmp,
    pose_errors,
    rollout_status,
    structural_bound,
    unit_error,
    variant_data,
    variant_pose,
)

Goal = tuple[float, np.ndarray, np.ndarray]
"""``(time [s], position (3,) [m], unit quaternion (4,))`` of a new goal."""


@dataclass(frozen=True)
class Reproduction:
    """One variant learned by one regression method and rolled out over the demonstration.

    ``errors``: per-sample errors against the demonstration (``position`` [m],
    ``orientation`` [rad]); ``truth_errors``: against the recording's noise-free
    motion (IMU recordings, solver rows only); ``unit_error``: largest departure
    from unit norm (solver rows only); ``bound``: the radius a ``seed`` variant keeps [m] and the least
    position error it implies per sample [m] (:func:`~optikin.problems.dmp.variants.structural_bound`).
    """

    variant: str
    method: str
    role: str
    fit: Fit
    rollout: Rollout
    errors: dict[str, np.ndarray]
    truth_errors: dict[str, np.ndarray] | None = None
    unit_error: float | None = None
    bound: tuple[float, np.ndarray] | None = None


@dataclass(frozen=True)
class GoalSwitchRun:
    """A roll-out through the goal switches: states ``(K+1, size)``, final errors to the last goal [m | rad]."""

    variant: str
    y: np.ndarray
    final: dict[str, float]
    status: str


@dataclass(frozen=True)
class PerturbationRun:
    """A roll-out under the disturbance (``label``: ``plain`` or a coupling), its deviation from the same
    DMP's undisturbed roll-out per sample [m | rad], and the phase at the end with and without the push."""

    variant: str
    label: str
    y: np.ndarray
    deviation: dict[str, np.ndarray]
    phase_end: float
    calm_phase_end: float
    status: str


@dataclass(frozen=True)
class TuningOutcome:
    """The gains tuned on one target (a variant, or a term ``Q_r`` / ``Q_d`` of the seed's DMP), by IPOPT, the
    multi-start L-BFGS-B (with a budget) and (when a baseline) the genetic algorithm, one result per seed; and
    eq. (29) at the reference gains of the options."""

    variant: str
    names: tuple[str, ...]
    results: list[TuningResult]
    seeds: list[int] = field(default_factory=list)
    reference: dict[str, float] = field(default_factory=dict)
    reference_error: float | None = None


@dataclass
class DmpOutcome:
    """Everything the run produced, for :func:`optikin.problems.dmp.report.result`."""

    demo: sources.PoseDemonstration
    recording: sources.Recording
    method: str
    reproductions: list[Reproduction] = field(default_factory=list)
    goal_switches: list[GoalSwitchRun] = field(default_factory=list)
    perturbations: list[PerturbationRun] = field(default_factory=list)
    tuning: list[TuningOutcome] = field(default_factory=list)


@dataclass(frozen=True)
class Learner:
    """Builds the DMPs of the run and fits them to the demonstration, naming the file on a failed fit."""

    demo: sources.PoseDemonstration
    options: DmpOptions
    gains: Gains
    source: str
    path: Path

    def dmp(self, variant: str, gains: Gains | None = None, phase_stopping: str = "tracking") -> DMP:
        return make_dmp(
            variant,
            self.options.n_basis,
            self.gains if gains is None else gains,
            smoothing=self.options.smoothing,
            phase_stopping=phase_stopping,
        )

    def fit(self, dmp: DMP, variant: str, method: str) -> Fit:
        """Learn the demonstration in the variant's layout with ``method`` (ridge and bound as the options say)."""
        regression = self.options.regression
        kwargs: dict[str, Any] = {}
        if method != "lwr":
            kwargs["ridge"] = regression.ridge
        if method == "cvxpy" and regression.bound is not None:
            kwargs.update(lower=-regression.bound, upper=regression.bound)
        Y = variant_data(variant, self.demo.position, self.demo.quaternion)
        try:
            return dmp.imitate(self.demo.t, Y, method=method, source=self.source, **kwargs)
        except InputDataError:
            raise
        except OptikinError as exc:
            raise SpecError(str(self.path), "options.regression", str(exc)) from None

    def reproduce(
        self, variant: str, method: str, role: str, truth: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[DMP, Reproduction]:
        """A new DMP of ``variant`` fitted by ``method`` and rolled out over the demonstration."""
        dmp = self.dmp(variant)
        fit = self.fit(dmp, variant, method)
        out = dmp.rollout()
        errors = pose_errors(variant, out.y, self.demo.position, self.demo.quaternion)
        bound = structural_bound(variant, out.y, self.demo.position)
        if role == "baseline":
            return dmp, Reproduction(variant, method, role, fit, out, errors, bound=bound)
        truth_errors = None if truth is None else pose_errors(variant, out.y, *truth)
        unit = unit_error(variant, out.y)
        return dmp, Reproduction(variant, method, role, fit, out, errors, truth_errors, unit, bound)


def solve(ctx: ProblemContext) -> DmpOutcome:
    """Load the demonstration (positions from ``options.origin_shift``), learn it with every variant and run every
    scenario the options ask for."""
    options: DmpOptions = ctx.options
    recording = ctx.load_data()
    shift = np.asarray(options.origin_shift, dtype=float)
    demo = sources.pose_demonstration(recording)
    demo = replace(demo, position=demo.position - shift)
    learner = Learner(demo, options, options.gains.gains(), f"{ctx.path.name}: data ({ctx.spec.data.source})", ctx.path)
    method = options.regression.method
    outcome = DmpOutcome(demo, recording, method)
    truth = true_motion(ctx, recording)
    if truth is not None:
        truth = (truth[0] - shift, truth[1])
    models: dict[str, DMP] = {}
    with ctx.progress.task(f"dmp: {len(options.variants)} variants", total=len(options.variants)) as advance:
        for variant in options.variants:
            models[variant], reproduction = learner.reproduce(variant, method, "solver", truth)
            outcome.reproductions.append(reproduction)
            advance()
    first = options.variants[0]
    for baseline in ctx.spec.baselines:  # the regression methods compared on the first variant
        if baseline in ("lstsq", "lwr") and baseline != method:
            outcome.reproductions.append(learner.reproduce(first, baseline, "baseline")[1])
    goals = goal_switches(ctx, options, demo)
    final_rpy = np.unwrap(rpy_from_quat(demo.quaternion, check=False), axis=0)[-1]
    if goals:
        outcome.goal_switches = [
            switch_goals(variant, dmp, goals, final_rpy, options) for variant, dmp in models.items()
        ]
    if options.disturbance is not None:
        outcome.perturbations = perturbations(ctx, learner, models)
    if options.tuning is not None:
        outcome.tuning = tune(ctx, learner, options.tuning, goals, final_rpy)
    return outcome


def true_motion(ctx: ProblemContext, recording: sources.Recording) -> tuple[np.ndarray, np.ndarray] | None:
    """The noise-free tip motion of an IMU recording (forward kinematics of its true configurations)."""
    if not isinstance(recording, sources.InterfaceRecording):
        return None
    quaternion, position = ctx.arm.section_frames(recording.configuration)[-1]
    sign = np.where(np.sum(quaternion * recording.demonstration.quaternion, axis=1) < 0, -1.0, 1.0)
    return position, quaternion * sign[:, None]


def goal_switches(ctx: ProblemContext, options: DmpOptions, demo: sources.PoseDemonstration) -> list[Goal]:
    """The new goals of ``options.goal_switches``, each relative to the goal before it."""
    tau = float(demo.t[-1] - demo.t[0])
    goals, position, quaternion = [], demo.position[-1], demo.quaternion[-1]
    for i, switch in enumerate(options.goal_switches):
        if not switch.time <= 3 * tau:
            raise ctx.error(f"options.goal_switches.{i}.time", f"must be within 0 .. {3 * tau:.3g} s")
        position = position + np.asarray(switch.translate)
        quaternion = quat_multiply(quat_exp(0.5 * np.asarray(switch.rotate)), quaternion)
        goals.append((switch.time, position, quaternion))
    return goals


def switch_goals(
    variant: str, dmp: DMP, goals: list[Goal], final_rpy: np.ndarray, options: DmpOptions
) -> GoalSwitchRun:
    """Roll ``dmp`` out for ``settle x tau`` through the goal switches; converged within the tolerance?"""
    switches = [(when, variant_data(variant, p, q, final_rpy)) for when, p, q in goals]
    out = dmp.rollout(duration=options.settle * dmp.tau, goal_switches=switches)
    _, p_goal, q_goal = goals[-1]
    final = {k: float(v[0]) for k, v in pose_errors(variant, out.y[-1:], p_goal, q_goal).items()}
    tolerance = options.tolerance
    converged = (
        final.get("position", 0.0) * MM <= tolerance.position_mm
        and final.get("orientation", 0.0) * MRAD <= tolerance.orientation_mrad
    )
    state = rollout_status(out.y, unit_error(variant, out.y))
    return GoalSwitchRun(variant, out.y, final, state if state != "ok" or converged else "not_converged")


def step_force(options: DmpOptions, dim: int) -> Callable[[np.ndarray], np.ndarray]:
    """The disturbance's step as a function of the times ``(K,) -> (K, dim)``: a force on eq. (17) or an output
    displacement (``options.disturbance.kind``, :meth:`optikin.dmp.DMP.rollout`'s ``disturbance`` or ``offset``)."""
    d = options.disturbance
    assert d is not None

    def force(t: np.ndarray) -> np.ndarray:
        out = np.zeros((t.size, dim))
        out[(t >= d.start) & (t < d.stop), d.component] = d.amplitude
        return out

    return force


def perturbations(ctx: ProblemContext, learner: Learner, models: dict[str, DMP]) -> list[PerturbationRun]:
    """Every variant, plain and under each coupling, pushed by the disturbance."""
    options = learner.options
    assert options.disturbance is not None
    runs: list[PerturbationRun] = []
    for variant, model in models.items():
        dim = model.space.dim
        if not options.disturbance.component < dim:
            raise ctx.error("options.disturbance.component", f"must be in 0 .. {dim - 1} for {variant}")
        push = step_force(options, dim)
        couplings: list[tuple[str, Coupling | None]] = [("plain", None), *options.couplings.items()]
        runs += [perturb(learner, variant, label, coupling, push) for label, coupling in couplings]
    return runs


def perturb(
    learner: Learner, variant: str, label: str, coupling: Coupling | None, push: Callable[[np.ndarray], np.ndarray]
) -> PerturbationRun:
    """A new DMP of ``variant`` (coupled to the demonstration as learned, eq. 27, unless plain), rolled out with
    and without the push; the deviation is the push's effect on the same DMP."""
    if coupling is None:
        dmp = learner.dmp(variant)
    else:
        gains = learner.gains.with_values(alpha_s=coupling.alpha_s, alpha=coupling.alpha)
        dmp = learner.dmp(variant, gains, coupling.phase_stopping)
    learner.fit(dmp, variant, learner.options.regression.method)
    reference = None if coupling is None else dmp.learned.Y  # smoothed if asked
    calm = dmp.rollout(reference=reference)
    assert learner.options.disturbance is not None
    if learner.options.disturbance.kind == "output":
        out = dmp.rollout(offset=push, reference=reference)
    else:
        out = dmp.rollout(disturbance=push, reference=reference)
    p_calm, q_calm = variant_pose(variant, calm.y)
    return PerturbationRun(
        variant,
        label,
        out.y,
        pose_errors(variant, out.y, p_calm, q_calm),
        float(out.phase[-1]),
        float(calm.phase[-1]),
        rollout_status(out.y, unit_error(variant, out.y)),
    )


def tune(
    ctx: ProblemContext, learner: Learner, tuning: Tuning, goals: list[Goal], final_rpy: np.ndarray
) -> list[TuningOutcome]:
    """Tune the gains of ``tuning.variant`` (or of the seed's DMP on each of ``tuning.terms``)."""
    variant = tuning.variant or learner.options.variants[0]
    demo = learner.demo
    targets: list[tuple[str, DMP, np.ndarray, dict[str, Any]]] = []
    if tuning.terms:
        if tuning.scenario == "goal":
            raise ctx.error("options.tuning.terms", "the seed's terms are tuned on the reproduction scenario only")
        for term in tuning.terms:
            part = slice(0, 4) if term == "Q_r" else slice(4, 8)
            dmp = DMP(UnitQuaternion(), learner.options.n_basis, learner.gains, smoothing=learner.options.smoothing)
            targets.append((term, dmp, demo.dual_quaternion[:, part], {}))
    else:
        extra: dict[str, Any] = {}
        if tuning.scenario == "goal":
            if not goals:
                raise ctx.error("options.tuning.scenario", "the goal scenario needs options.goal_switches")
            when, p, q = goals[0]
            extra = {"new_goal": variant_data(variant, p, q, final_rpy), "switch_time": when}
        targets.append((variant, learner.dmp(variant), variant_data(variant, demo.position, demo.quaternion), extra))
    unknown = sorted(set(tuning.reference) - {label for label, *_ in targets})
    if unknown:
        raise ctx.error("options.tuning.reference", f"no tuned target {unknown[0]!r}; the targets are tuned ones")
    return [tune_target(ctx, tuning, label, dmp, demo.t, Y, extra) for label, dmp, Y, extra in targets]


def tuned_names(tuning: Tuning, dim: int) -> tuple[str, ...]:
    """The gains tuned, ``beta_g0`` expanded to ``beta_g0[0] .. beta_g0[dim-1]`` with ``goal_diagonal``."""
    names: list[str] = []
    for n in tuning.gains:
        names += [f"beta_g0[{i}]" for i in range(dim)] if n == "beta_g0" and tuning.goal_diagonal else [n]
    return tuple(names)


def tune_target(
    ctx: ProblemContext,
    tuning: Tuning,
    label: str,
    dmp: DMP,
    t: np.ndarray,
    Y: np.ndarray,
    extra: dict[str, Any],
) -> TuningOutcome:
    """IPOPT, then (with a budget) the multi-start L-BFGS-B and (as a baseline) the GA on IPOPT's evaluation count,
    ``tuning.seeds`` times each."""
    names = tuned_names(tuning, dmp.space.dim)
    try:
        problem = tuning_problem(dmp, t, Y, names, scenario=tuning.scenario, **extra)
    except InputDataError as exc:
        raise ctx.error("options.tuning.gains", str(exc).removeprefix("tuning.gains: ")) from None
    seed = ctx.spec.data.seed
    seeds = [seed + k for k in range(tuning.seeds)]
    genetic = "genetic" in ctx.spec.baselines
    steps = 1 + (len(seeds) if tuning.budget is not None else 0) + (len(seeds) if genetic else 0)
    with ctx.progress.task(f"dmp: tuning {', '.join(names)} of {label}", total=steps) as advance:
        ipopt = tune_gradient(
            problem,
            max_iterations=tuning.max_iterations,
            screen=tuning.screen,
            starts=tuning.starts,
            seed=seed,
            budget=tuning.budget,
        )
        advance()
        results = [ipopt]
        budget = None if tuning.budget is None else ipopt.evaluations
        if budget is not None:
            for s in seeds:
                results.append(tune_multistart(problem, budget=budget, screen=tuning.screen, seed=s))
                advance()
        if genetic:
            for s in seeds:
                results.append(
                    tune_genetic(
                        problem, population=tuning.population, generations=tuning.generations, seed=s, budget=budget
                    )
                )
                advance()
    reference: dict[str, float] = {str(k): v for k, v in tuning.reference.get(label, {}).items()}
    return TuningOutcome(label, names, results, seeds, reference, reference_error(problem, reference))


def reference_error(problem: TuningProblem, reference: dict[str, float]) -> float | None:
    """Eq. (29) at the tuned gains set to ``reference`` (the others at their starting values); ``None`` if empty."""
    if not reference:
        return None
    values = np.array([reference.get(n, v) for n, v in zip(problem.names, problem.initial)])
    return problem.error(values)
