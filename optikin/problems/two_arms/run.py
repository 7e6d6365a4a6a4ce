"""The ``two_arms`` run: both arms placed, the reference, the joint QP and its baselines, the closed loops."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from optikin.control.limits import RateBounds
from optikin.control.self_collision import PlacedArm, TwoTubes, collision_density, rotation_from_quaternion
from optikin.control.two_arm import (
    Rope,
    RopeTubes,
    TwoArmController,
    TwoArmModel,
    TwoArmPseudoInverse,
    TwoArmQP,
    TwoArmReference,
    TwoArmRun,
    TwoArmTask,
    rope_samples,
    simulate_two_arms,
)
from optikin.control.two_arm_obstacles import TwoArmObstacleRows
from optikin.curves.catenary_sensitivity import CatenarySensitivity
from optikin.errors import InputDataError
from optikin.problems import Baseline, ProblemContext, baselines_of
from optikin.problems.tracking.run import obstacle_from_options
from optikin.problems.two_arms.options import TwoArmOptions
from optikin.problems.two_arms.references import RopeLoop, TipPaths
from optikin.solvers.qp.common import StepSolverFactory

if TYPE_CHECKING:
    from optikin.solvers import LoadedPreset


@dataclass(frozen=True)
class JointSetup:
    """What every controller of a run is built from (:attr:`optikin.problems.Baseline.build`'s ``setup``).

    Attributes
    ----------
    options:
        ``options:`` of the file.
    plant:
        Both arms placed, the task (and the rope).
    tubes, rope_tubes, obstacle_rows:
        The joint QP's collision rows (tubes, rope off the tubes, obstacles; the latter two may be ``None``).
    dt:
        The control period [s].
    q0:
        The start of both arms, the posture term's ``q_nom``.
    """

    options: TwoArmOptions
    plant: TwoArmModel
    tubes: TwoTubes
    rope_tubes: RopeTubes | None
    obstacle_rows: TwoArmObstacleRows | None
    dt: float
    q0: np.ndarray

    def joint(self, factory: StepSolverFactory, with_rows: bool = True) -> TwoArmQP:
        """The joint QP with ``factory``'s step solver; ``with_rows=False``: without any collision rows."""
        o = self.options
        return TwoArmQP(
            self.plant,
            self.dt,
            o.gain,
            factory=factory,
            damping=o.damping,
            posture=self.q0,
            posture_weight=o.posture_weight,
            posture_gain=o.posture_gain,
            rate_limits=o.rate_limits,
            limit_margin=o.limit_margin,
            tubes=self.tubes if with_rows else None,
            rope_tubes=self.rope_tubes if with_rows else None,
            obstacle_rows=self.obstacle_rows if with_rows else None,
            gamma=o.collision.gamma,
            margin=o.collision.margin,
        )

    def limits(self) -> list[RateBounds]:
        """The joint QP's boxes, one per arm (its rate limits and limit margin)."""
        o = self.options
        return [RateBounds(placed.arm, self.dt, o.rate_limits, o.limit_margin) for placed in self.plant.arms]


def _step_solvers(ctx: ProblemContext, adapter: object, field: str) -> StepSolverFactory:
    """``adapter`` as a ``qp`` factory taking inequality rows; another is an error naming ``field``."""
    if not isinstance(adapter, StepSolverFactory):
        raise ctx.error(field, f"{type(adapter).__name__} takes no inequality rows; two_arms needs a qp backend")
    return adapter


def _no_collision_rows(ctx: ProblemContext, setup: JointSetup) -> TwoArmController:
    return setup.joint(_step_solvers(ctx, ctx.adapter, "solver"), with_rows=False)


def _pseudo_inverse(ctx: ProblemContext, setup: JointSetup) -> TwoArmController:
    return TwoArmPseudoInverse(setup.plant, setup.dt, setup.options.gain)


def _pseudo_inverse_saturated(ctx: ProblemContext, setup: JointSetup) -> TwoArmController:
    return TwoArmPseudoInverse(setup.plant, setup.dt, setup.options.gain, limits=setup.limits())


BASELINES: dict[str, Baseline[JointSetup, TwoArmController]] = baselines_of(
    Baseline("no_collision_rows", "joint QP without collision rows", build=_no_collision_rows),
    Baseline("pseudo_inverse", TwoArmPseudoInverse.name, build=_pseudo_inverse),
    Baseline("pseudo_inverse_saturated", f"{TwoArmPseudoInverse.name} (saturated)", build=_pseudo_inverse_saturated),
)
"""The kind's own baselines: ``no_collision_rows``, the same joint QP without the self-collision, rope and obstacle
rows; ``pseudo_inverse``, the pseudo-inverse (per arm for tips, of the rope Jacobian for the rope), no limits;
``pseudo_inverse_saturated``, the same with its command clipped into the joint QP's boxes (rate limits, and the
configuration limits after the step)."""


def preset_baseline(name: str, preset: LoadedPreset) -> Baseline[JointSetup, TwoArmController]:
    """A ``qp`` preset listed in ``baselines``: the joint QP with that preset's step solver, labelled ``name``."""

    def build(ctx: ProblemContext, setup: JointSetup) -> TwoArmController:
        controller = setup.joint(_step_solvers(ctx, preset.build(), f"baselines.{ctx.spec.baselines.index(name)}"))
        controller.name = name
        return controller

    return Baseline(name, name, build=build, preset=preset)


@dataclass
class TwoArmOutcome:
    """The closed-loop runs of one problem.

    Attributes
    ----------
    reference:
        The task reference every controller tracked.
    model:
        The plant: both arms placed, the task (and the rope).
    tubes:
        The two tubes' clearance (the QP's collision rows).
    runs, wall:
        ``"qp"`` and every baseline's name -> its run, and the seconds it took.
    clearances:
        Per run name, the least sampled clearance between the tubes at every step ``(N,)`` [m].
    obstacles:
        The obstacle rows (their bodies and sampling), ``None`` without obstacles.
    obstacle_clearances:
        Per run name, the least clearance of each body to any obstacle at every step ``(N, bodies)`` [m].
    """

    reference: TwoArmReference
    model: TwoArmModel
    tubes: TwoTubes
    runs: dict[str, TwoArmRun]
    wall: dict[str, float]
    clearances: dict[str, np.ndarray]
    obstacles: TwoArmObstacleRows | None = None
    obstacle_clearances: dict[str, np.ndarray] | None = None


@dataclass
class TwoArmSetup:
    """Everything a run is made of, built and checked from the problem file.

    Attributes
    ----------
    reference, q0:
        The task reference and the start of both arms ``(n_1 + n_2,)``.
    plant:
        Both arms placed, the task (and the rope).
    tubes:
        The self-collision rows of the joint QP.
    controllers:
        ``"qp"`` and every baseline's name -> its controller.
    rope_tubes:
        The rows keeping the rope off the tubes (rope task with ``collision.rope_pairs``), or ``None``.
    obstacle_rows:
        The rows keeping both tubes and the rope off ``options.obstacles``, or ``None``.
    """

    reference: TwoArmReference
    q0: np.ndarray
    plant: TwoArmModel
    tubes: TwoTubes
    controllers: dict[str, TwoArmController]
    rope_tubes: RopeTubes | None = None
    obstacle_rows: TwoArmObstacleRows | None = None


def setup(ctx: ProblemContext) -> TwoArmSetup:
    """Place the arms, load the reference, build the controllers from ``ctx``; bad input is a SpecError naming it."""
    if "samples" in ctx.spec.data.model_fields_set:
        raise ctx.error("data.samples", "not used by two_arms: the run length follows from the path and rate")
    options: TwoArmOptions = ctx.options
    source = ctx.load_data()
    task: TwoArmTask = "rope" if isinstance(source, RopeLoop) else "tips"
    dt = float(source.t[1] - source.t[0])
    arms = _placed(ctx, options)
    rope = _rope(ctx, options, task)
    q0 = _start(ctx, options, source)
    plant = TwoArmModel(arms, task, rope)
    _check_start(ctx, options, plant, q0)
    reference = _reference(plant, source, q0)
    c = options.collision
    try:
        tubes = TwoTubes(arms[0], arms[1], c.margin, c.gamma, dt, c.pairs)
    except ValueError as exc:
        raise ctx.error("options.collision", str(exc)) from None
    rope_tubes = None
    if rope is not None and rope.samples is not None:
        try:
            rope_tubes = RopeTubes(plant, c.rope_margin, c.gamma, dt, c.rope_pairs)
        except ValueError as exc:
            raise ctx.error("options.collision", str(exc)) from None
    obstacle_rows = _obstacle_rows(ctx, options, plant, q0, reference)
    controllers = _controllers(ctx, options, plant, tubes, rope_tubes, obstacle_rows, dt, q0)
    return TwoArmSetup(reference, q0, plant, tubes, controllers, rope_tubes, obstacle_rows)


def run(ctx: ProblemContext) -> TwoArmOutcome:
    """Build the problem (:func:`setup`) and run every closed loop."""
    built = setup(ctx)
    reference, plant, tubes, q0 = built.reference, built.plant, built.tubes, built.q0
    runs: dict[str, TwoArmRun] = {}
    wall: dict[str, float] = {}
    with ctx.progress.task(
        f"two arms: {len(built.controllers)} controllers x {len(reference.t)} steps", total=len(built.controllers)
    ) as advance:
        for name, controller in built.controllers.items():
            start = time.perf_counter()
            runs[name] = simulate_two_arms(controller, reference, q0, plant)
            wall[name] = time.perf_counter() - start
            advance()
    n1 = plant.n1
    clearances = {name: tubes.clearances(r.q[:, :n1], r.q[:, n1:]) for name, r in runs.items()}
    rows = built.obstacle_rows
    near = None if rows is None else {name: _obstacle_clearances(rows, plant, r) for name, r in runs.items()}
    return TwoArmOutcome(reference, plant, tubes, runs, wall, clearances, rows, near)


def _obstacle_clearances(rows: TwoArmObstacleRows, plant: TwoArmModel, tracked: TwoArmRun) -> np.ndarray:
    """The least clearance of each body to any obstacle along a run, ``(N, bodies)`` [m] (NaN where the rope
    could not hang)."""
    out = np.full((len(tracked.t), len(rows.bodies)), np.nan)
    for k, (q, t) in enumerate(zip(tracked.q, tracked.t)):
        try:
            plant.evaluate(q)
        except InputDataError:
            continue
        out[k] = rows.least(float(t))
    return out


def _obstacle_rows(
    ctx: ProblemContext, options: TwoArmOptions, plant: TwoArmModel, q0: np.ndarray, reference: TwoArmReference
) -> TwoArmObstacleRows | None:
    """The obstacle rows; an obstacle within the margin of a base or of the start's bodies is an error naming it."""
    if not options.obstacles:
        return None
    c = options.collision
    obstacles = [obstacle_from_options(ctx, i, ob) for i, ob in enumerate(options.obstacles)]
    try:
        rows = TwoArmObstacleRows(plant, obstacles, c.obstacle_margin, c.gamma, reference.dt, c.points_per_obstacle)
    except ValueError as exc:
        raise ctx.error("options.collision", str(exc)) from None
    plant.evaluate(q0)
    times = np.unique(np.r_[reference.t, [row[0] for ob in obstacles if ob.path is not None for row in ob.path]])
    for i, ob in enumerate(obstacles):
        bases = np.array([placed.base for placed in plant.arms]).T
        for t in times if ob.path is not None else [0.0]:
            near = float(ob.distances(bases, float(t)).min()) - max(placed.radius for placed in plant.arms)
            if near < c.obstacle_margin:
                raise ctx.error(
                    f"options.obstacles.{i}",
                    f"comes within the margin of an arm's base ({near * 1e3:.3g} mm at t = {t:.3g} s, margin "
                    f"{c.obstacle_margin * 1e3:.3g} mm): no command can keep the barrier",
                )
    least = rows.least(0.0)
    if least.min() < c.obstacle_margin:
        body = rows.bodies[int(np.argmin(least))]
        raise ctx.error(
            "options.obstacles",
            f"the start's {body} lies {least.min() * 1e3:.3g} mm from an obstacle, within the margin "
            f"({c.obstacle_margin * 1e3:.3g} mm)",
        )
    return rows


def _placed(ctx: ProblemContext, options: TwoArmOptions) -> tuple[PlacedArm, PlacedArm]:
    """Both arms in the shared frame; bases whose tubes overlap (within the margin) are an error naming the base."""
    arm, c = ctx.arm, options.collision
    try:
        density = collision_density(arm, c.margin) if c.points_per_section is None else c.points_per_section
    except ValueError as exc:
        raise ctx.error("arm", str(exc)) from None
    first, second = (
        PlacedArm(arm, np.array(p.base), rotation_from_quaternion(p.orientation), p.radius, density, options.compiled)
        for p in options.arms
    )
    apart = float(np.linalg.norm(first.base - second.base))
    needed = first.radius + second.radius + c.margin
    if apart < needed:
        raise ctx.error(
            "options.arms.1.base",
            f"the bases are {apart * 1e3:.3g} mm apart: the tubes (radii {first.radius * 1e3:.3g} and "
            f"{second.radius * 1e3:.3g} mm) overlap or come within the margin ({c.margin * 1e3:.3g} mm) of each other "
            f"there, where no command moves them",
        )
    return first, second


def _rope(ctx: ProblemContext, options: TwoArmOptions, task: TwoArmTask) -> Rope | None:
    if task == "tips":
        if options.rope is not None:
            raise ctx.error("options.rope", "the tips task (data.source tip_waypoints) holds no rope")
        return None
    r = options.rope
    if r is None:
        raise ctx.error("options.rope", "the rope task (data.source rope_loop) needs the rope: {length: ...}")
    if not r.slack < r.length:
        raise ctx.error("options.rope.slack", f"{r.slack} m leaves no rope of length {r.length} m")
    try:
        sensitivity = CatenarySensitivity(r.length, r.mass_per_length, r.gravity, options.compiled, str(ctx.path))
    except InputDataError as exc:
        raise ctx.error(f"options.rope.{exc.field}", str(exc)) from None
    c = options.collision
    samples = None
    if c.rope_pairs:
        try:
            samples = rope_samples(sensitivity, c.rope_exclusion, c.rope_margin, options.compiled)
        except ValueError as exc:
            raise ctx.error("options.collision.rope_exclusion", str(exc)) from None
    return Rope(sensitivity, r.slack, r.floor, samples, c.rope_exclusion)


def _start(ctx: ProblemContext, options: TwoArmOptions, source: RopeLoop | TipPaths) -> np.ndarray:
    n = ctx.arm.n_config
    parts = []
    for k, placement in enumerate(options.arms):
        if placement.start is None:
            if isinstance(source, RopeLoop):
                raise ctx.error(f"options.arms.{k}.start", "the rope task needs each arm's start configuration")
            parts.append(source.configurations[k][0])
            continue
        if len(placement.start) != n:
            raise ctx.error(f"options.arms.{k}.start", f"expected {n} numbers ({ctx.arm.name}), got {placement.start}")
        parts.append(np.asarray(placement.start, dtype=float))
    return np.concatenate(parts)


def _check_start(ctx: ProblemContext, options: TwoArmOptions, plant: TwoArmModel, q0: np.ndarray) -> None:
    """The start: inside the limits, tubes clear of each other, the rope longer than its grips' distance."""
    for k, (placed, part) in enumerate(zip(plant.arms, plant.split(q0))):
        outside = (part < placed.arm.lower - 1e-12) | (part > placed.arm.upper + 1e-12)
        outside &= ~placed.arm.periodic
        if outside.any():
            names = [placed.arm.config_names[i] for i in np.flatnonzero(outside)]
            raise ctx.error(f"options.arms.{k}.start", f"outside the arm's limits in {', '.join(names)}")
    first, second = plant.arms
    tubes = TwoTubes(first, second, options.collision.margin, 1.0, 1.0)
    first.evaluate(plant.split(q0)[0])
    second.evaluate(plant.split(q0)[1])
    least = float(tubes.clearance_matrix(first.P, second.P).min())
    if least < options.collision.margin:
        raise ctx.error(
            "options.arms",
            f"the start configurations' tubes are {least * 1e3:.3g} mm apart, within the margin "
            f"({options.collision.margin * 1e3:.3g} mm): the barrier cannot hold there",
        )
    if plant.rope is not None:
        rope = plant.rope
        grips = float(np.linalg.norm(second.tip - first.tip))
        if not grips < rope.sensitivity.length - rope.slack:
            raise ctx.error(
                "options.rope.length",
                f"rope of length {rope.sensitivity.length:.6g} m is not longer than the distance between the grips "
                f"at the start, {grips:.6g} m, by the slack {rope.slack:.3g} m: it cannot hang",
            )
        try:
            plant.evaluate(q0)
        except InputDataError as exc:
            raise ctx.error(f"options.rope.{exc.field}", str(exc)) from None
        if rope.floor is not None and float(rope.sensitivity.up @ plant.x) < rope.floor + options.collision.margin:
            raise ctx.error("options.rope.floor", "the start's lowest point lies below the floor or within the margin")
        if rope.samples is not None:
            clearance = RopeTubes(plant, options.collision.rope_margin, 1.0, 1.0).clearance()
            if clearance < options.collision.rope_margin:
                raise ctx.error(
                    "options.arms",
                    f"at the start the rope comes {clearance * 1e3:.3g} mm from a tube, within "
                    f"collision.rope_margin ({options.collision.rope_margin * 1e3:.3g} mm)",
                )


def _reference(plant: TwoArmModel, source: RopeLoop | TipPaths, q0: np.ndarray) -> TwoArmReference:
    """The task reference in the shared frame: the loop about its centre, or both tips' forward kinematics."""
    if isinstance(source, RopeLoop):
        plant.evaluate(q0)
        center = plant.x.copy() if source.center is None else np.asarray(source.center, dtype=float)
        return TwoArmReference(source.t, center + source.offset, source.rate, "rope")
    value, rate = [], []
    for placed, Q, Qdot in zip(plant.arms, source.configurations, source.rates):
        tips, rates = np.empty((len(Q), 3)), np.empty((len(Q), 3))
        for k, (q, qdot) in enumerate(zip(Q, Qdot)):
            placed.evaluate(q)
            tips[k], rates[k] = placed.tip, placed.tip_jacobian @ qdot
        value.append(tips)
        rate.append(rates)
    return TwoArmReference(source.t, np.hstack(value), np.hstack(rate), "tips")


def _controllers(
    ctx: ProblemContext,
    options: TwoArmOptions,
    plant: TwoArmModel,
    tubes: TwoTubes,
    rope_tubes: RopeTubes | None,
    obstacle_rows: TwoArmObstacleRows | None,
    dt: float,
    q0: np.ndarray,
) -> dict[str, TwoArmController]:
    """The joint QP (the preset's step solver, with the collision rows) and every baseline, by name."""
    setup = JointSetup(options, plant, tubes, rope_tubes, obstacle_rows, dt, q0)
    try:
        controllers: dict[str, TwoArmController] = {"qp": setup.joint(_step_solvers(ctx, ctx.adapter, "solver"))}
        for baseline in ctx.baselines:
            controllers[baseline.name] = baseline.method(ctx, setup)
    except ValueError as exc:
        raise ctx.error("options", str(exc)) from None
    return controllers
