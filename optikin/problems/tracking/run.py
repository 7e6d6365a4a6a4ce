"""The ``tracking`` run: the reference from the data source, the start, the plant, the controllers, the closed loops."""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.baselines.mrac import MRACController, SeedGainMRACController
from optikin.baselines.pseudo_inverse import DampedLeastSquaresController, PseudoInverseController
from optikin.control.base import Controller
from optikin.control.limits import RateBounds
from optikin.control.mpc import MPCController
from optikin.control.mpc_nlp import NonlinearMPCController
from optikin.control.obstacles import BarrierRows, Obstacle
from optikin.control.qp import QPController
from optikin.control.reference import Reference
from optikin.control.rod_plant import PneumaticRod, RodPlantSimulator
from optikin.control.simulate import Plant, TrackingRun, simulate
from optikin.control.task import Task, task_dimension
from optikin.data.references import TrackingReference
from optikin.problems import Baseline, ProblemContext, baselines_of
from optikin.problems.tracking.options import (
    CosseratPlantOptions,
    ObstacleOptions,
    PlantOptions,
    ToleranceOptions,
    TrackingOptions,
)
from optikin.solvers.base import QPBackend
from optikin.solvers.qp.common import StepSolverFactory

if TYPE_CHECKING:
    from optikin.solvers import LoadedPreset


@dataclass(frozen=True)
class ControllerSetup:
    """What every controller of a run is built from (:attr:`optikin.problems.Baseline.build`'s ``setup``).

    Attributes
    ----------
    options:
        ``options:`` of the file.
    dt, task:
        The control period [s] and the task the reference states.
    barrier:
        The QP's backbone barrier rows; ``None`` without obstacles.
    reference:
        The reference (the MPC's preview).
    """

    options: TrackingOptions
    dt: float
    task: Task
    barrier: BarrierRows | None = None
    reference: Reference | None = None

    def limits(self, ctx: ProblemContext) -> RateBounds:
        """The QP's box: its rate limits, limit margin and limit gain (:class:`optikin.control.limits.RateBounds`)."""
        o = self.options
        return RateBounds(ctx.arm, self.dt, o.rate_limits, o.limit_margin, gain=o.limit_gain, compiled=o.compiled)


def _mrac(ctx: ProblemContext, setup: ControllerSetup) -> Controller:
    o = setup.options
    mrac = o.mrac.model_dump() | {"gain": o.gain if o.mrac.gain is None else o.mrac.gain}
    return MRACController(ctx.arm, setup.dt, setup.task, **mrac, compiled=o.compiled)


def _mrac_seed(ctx: ProblemContext, setup: ControllerSetup) -> Controller:
    o = setup.options
    seed = o.mrac.model_dump(exclude={"gain"})
    return SeedGainMRACController(ctx.arm, setup.dt, setup.task, **seed, compiled=o.compiled)


def _pseudo_inverse(ctx: ProblemContext, setup: ControllerSetup) -> Controller:
    o = setup.options
    return PseudoInverseController(ctx.arm, setup.dt, setup.task, o.gain, compiled=o.compiled)


def _damped_least_squares(ctx: ProblemContext, setup: ControllerSetup) -> Controller:
    o = setup.options
    return DampedLeastSquaresController(ctx.arm, setup.dt, setup.task, o.gain, o.damping, compiled=o.compiled)


def _mpc(ctx: ProblemContext, setup: ControllerSetup, name: str) -> Controller:
    """The MPC baseline ``name`` of ``options.mpc``; a bad horizon or weight is an error naming ``options.mpc``."""
    o, m = setup.options, setup.options.mpc
    dt, task, barrier, reference = setup.dt, setup.task, setup.barrier, setup.reference
    rows = None
    if barrier is not None:
        rows = BarrierRows(
            ctx.arm,
            barrier.dt,
            barrier.distances.obstacles,
            barrier.margin,
            barrier.gamma,
            barrier.points_per_obstacle,
            barrier.distances.points_per_section,
            compiled=barrier.distances.compiled,
        )
    horizon: dict[str, Any] = dict(
        horizon=m.horizon,
        rate_limits=o.rate_limits,
        margin=o.limit_margin,
        limit_gain=o.limit_gain,
        barrier=rows,
        preview=reference if m.preview else None,
        compiled=o.compiled,
    )
    weight = o.damping if m.effort_weight is None else m.effort_weight
    try:
        if name == "mpc_ipopt" or m.solver == "ipopt":
            return NonlinearMPCController(
                ctx.arm, dt, task, o.gain, weight, tolerance=m.ipopt_tolerance, max_iter=m.ipopt_max_iter, **horizon
            )
        return MPCController(
            ctx.arm,
            dt,
            task,
            o.gain,
            weight,
            eps_abs=m.eps,
            eps_rel=m.eps,
            rho=m.rho,
            max_iter=m.max_iter,
            polishing=m.polishing,
            **horizon,
        )
    except ValueError as exc:
        raise ctx.error("options.mpc", str(exc)) from None


def _saturated(build: Callable[[ProblemContext, ControllerSetup], Controller]) -> Callable[..., Controller]:
    """``build``'s controller with its commands clipped into the QP's box (:meth:`Controller.saturate_at`)."""

    def saturated(ctx: ProblemContext, setup: ControllerSetup) -> Controller:
        controller = build(ctx, setup)
        controller.saturate_at(setup.limits(ctx))
        return controller

    return saturated


UNLIMITED: tuple[tuple[str, str, Callable[[ProblemContext, ControllerSetup], Controller]], ...] = (
    ("mrac", MRACController.name, _mrac),
    ("mrac_seed", SeedGainMRACController.name, _mrac_seed),
    ("pseudo_inverse", PseudoInverseController.name, _pseudo_inverse),
    ("damped_least_squares", DampedLeastSquaresController.name, _damped_least_squares),
)
"""The baselines that know no limits: name, row label, builder; each is also a ``<name>_saturated`` baseline."""

MPC_NAMES = ("mpc", "mpc_ipopt")
"""The baselines that are MPC controllers (held to the no-penetration criterion like the QP)."""

BASELINES: dict[str, Baseline[ControllerSetup, Controller]] = baselines_of(
    *(Baseline(name, title, build=build) for name, title, build in UNLIMITED),
    *(Baseline(f"{name}_saturated", f"{title} (saturated)", build=_saturated(b)) for name, title, b in UNLIMITED),
    Baseline("mpc", MPCController.name, "solver", partial(_mpc, name="mpc")),
    Baseline("mpc_ipopt", NonlinearMPCController.name, build=partial(_mpc, name="mpc_ipopt")),
)
"""The kind's own baselines: ``baselines:`` name -> :class:`~optikin.problems.Baseline` (its ``title``, the name of
its controller, labels its rows and curves; ``mpc`` with ``options.mpc.solver: ipopt`` is ``mpc (ipopt)``).

``<name>_saturated`` is baseline ``<name>`` with its commands clipped into the QP's box (the rate limits and the
configuration limits after the step, with ``options.limit_margin`` and ``options.limit_gain``), so that it too stays
inside the limits. ``mpc`` and ``mpc_ipopt`` are the MPC of ``options.mpc`` (:mod:`optikin.control.mpc`), with the
QP's gain, limits and obstacles: ``mpc`` by ``options.mpc.solver``, ``mpc_ipopt`` the IPOPT reference.
"""


def preset_baseline(name: str, preset: LoadedPreset) -> Baseline[ControllerSetup, Controller]:
    """A ``qp`` preset listed in ``baselines``: the QP controller with that preset's step solver, labelled ``name``."""

    def build(ctx: ProblemContext, setup: ControllerSetup) -> Controller:
        controller = _qp(ctx, setup, preset.build(), f"baselines.{ctx.spec.baselines.index(name)}")
        controller.name = name
        return controller

    return Baseline(name, name, build=build, preset=preset)


@dataclass
class TrackingOutcome:
    """The closed-loop runs of one problem.

    Attributes
    ----------
    reference:
        The tip reference every controller tracked.
    runs:
        ``"qp"`` and every baseline's name -> its run, in that order.
    wall:
        Seconds each run took, per name.
    tolerance:
        The convergence check of ``options.tolerance``.
    settle_after:
        When the plant's disturbance ends [s] (settling times are counted from it); ``None`` without one.
    obstacles:
        The distances of every run's backbone samples, ``None`` without obstacles.
    """

    reference: Reference
    runs: dict[str, TrackingRun]
    wall: dict[str, float]
    tolerance: ToleranceOptions
    settle_after: float | None = None
    obstacles: ObstacleOutcome | None = None


@dataclass
class ObstacleOutcome:
    """Backbone clearances along every run of a problem with obstacles.

    Attributes
    ----------
    barrier:
        The QP's barrier rows (obstacles, margin, sampling).
    distances:
        Per run name, ``(N, n_obstacles, K)`` signed distances of every backbone sample of the plant [m].
    reference_distance:
        ``(N,)`` the least signed distance of the reference tip position to any obstacle [m].
    """

    barrier: BarrierRows
    distances: dict[str, np.ndarray]
    reference_distance: np.ndarray


def run(ctx: ProblemContext) -> TrackingOutcome:
    """Load the reference, build the plant and the controllers from ``ctx``, and run every closed loop."""
    if "samples" in ctx.spec.data.model_fields_set:
        raise ctx.error("data.samples", "not used by tracking: the run length follows from the path and rate")
    source: TrackingReference = ctx.load_data()
    options: TrackingOptions = ctx.options
    q0 = _start(ctx, options, source.start)
    plant = _plant(ctx, options.plant)
    reference = source.reference
    barrier = _barrier(ctx, options, plant, q0, reference)
    controllers = _controllers(ctx, options, reference.dt, reference.task, barrier, reference)
    runs: dict[str, TrackingRun] = {}
    wall: dict[str, float] = {}
    with ctx.progress.task(
        f"tracking: {len(controllers)} controllers x {len(reference.t)} steps", total=len(controllers)
    ) as advance:
        for name, controller in controllers.items():
            start = time.perf_counter()
            runs[name] = simulate(controller, reference, q0, plant, seed=ctx.spec.data.seed)
            wall[name] = time.perf_counter() - start
            advance()
    off = plant.disturbance_window[1]
    settle_after = off if plant.disturbance is not None and off <= reference.t[-1] else None
    obstacles = None
    if barrier is not None:
        factors = plant.length_factors(ctx.arm)
        distances = {name: barrier.distances.sampled(r.q * factors, r.t) for name, r in runs.items()}
        tip = reference.position
        ref = np.min([ob.distances(tip.T, reference.t) for ob in barrier.distances.obstacles], axis=0)
        obstacles = ObstacleOutcome(barrier, distances, ref)
    return TrackingOutcome(reference, runs, wall, options.tolerance, settle_after, obstacles)


def _vector(
    ctx: ProblemContext, value: float | list[float], n: int, field: str, allow_scalar: bool = False
) -> np.ndarray:
    """``value`` as ``n`` numbers (a scalar repeated where allowed); otherwise an error naming ``field``."""
    v = np.asarray(value, dtype=float)
    if allow_scalar and v.ndim == 0:
        v = np.full(n, float(v))
    if v.shape != (n,):
        raise ctx.error(field, f"expected {n} numbers{' or one' if allow_scalar else ''}, got {value!r}")
    return v


def _start(ctx: ProblemContext, options: TrackingOptions, path_start: np.ndarray) -> np.ndarray:
    """The initial configuration: ``options.start`` (else the reference's start) plus ``options.start_offset``."""
    n = ctx.arm.n_config
    q0 = path_start if options.start is None else _vector(ctx, options.start, n, "options.start")
    if options.start_offset is not None:
        q0 = q0 + _vector(ctx, options.start_offset, n, "options.start_offset")
    return q0


def _plant(ctx: ProblemContext, options: PlantOptions) -> Plant:
    """The simulated plant of ``options.plant``, its vectors checked against the arm."""
    n = ctx.arm.n_config
    disturbance = None
    if options.disturbance is not None:
        disturbance = tuple(_vector(ctx, options.disturbance, n, "options.plant.disturbance"))
    noise = tuple(_vector(ctx, options.configuration_noise, n, "options.plant.configuration_noise", allow_scalar=True))
    scale = options.length_scale
    plant = Plant(
        rod=_rod_plant(ctx, options.physics),
        length_scale=tuple(scale) if isinstance(scale, list) else scale,
        disturbance=disturbance,
        disturbance_window=options.disturbance_window or (0.0, np.inf),
        configuration_noise=noise,
        tip_position_noise=options.tip_position_noise,
        tip_angle_noise=options.tip_angle_noise,
        feedback=options.feedback,
    )
    try:
        plant.length_factors(ctx.arm)
    except ValueError as exc:
        raise ctx.error("options.plant.length_scale", str(exc)) from None
    return plant


def _rod_plant(ctx: ProblemContext, options: CosseratPlantOptions | None) -> RodPlantSimulator | None:
    """The Cosserat rod plant of ``options.plant.physics`` (built once, shared by every controller's run)."""
    if options is None:
        return None
    arm = ctx.arm
    if not isinstance(arm, ConstantCurvatureArm):
        raise ctx.error("options.plant.physics", "a Cosserat plant needs a constant_curvature arm as the model")
    m = arm.n_sections
    rest = options.rest_length
    if rest is None:
        rest = [float(arm.lower[3 * k]) for k in range(m)]
    for name, value in (("radius", options.radius), ("chamber_offset", options.chamber_offset), ("rest_length", rest)):
        if len(value) != m:
            raise ctx.error(f"options.plant.physics.{name}", f"expected {m} values (one per section), got {value!r}")
    for k, (radius, offset) in enumerate(zip(options.radius, options.chamber_offset)):
        if offset >= radius:
            raise ctx.error(
                "options.plant.physics.chamber_offset",
                f"section {k + 1}: {offset} m is not inside the radius {radius} m",
            )
    rod = PneumaticRod(
        youngs_modulus=options.youngs_modulus,
        poisson_ratio=options.poisson_ratio,
        density=options.density,
        radius=tuple(options.radius),
        chamber_offset=tuple(options.chamber_offset),
        chamber_area=options.chamber_area,
        rest_length=tuple(rest),
        gravity=options.gravity_vector if options.gravity else (0.0, 0.0, 0.0),
        payload=options.payload,
        steps_per_segment=options.steps_per_segment,
        compiled=options.compiled,
    )
    return RodPlantSimulator(arm, rod)


SHAPE_FIELDS = {
    "sphere": ("center", "radius"),
    "capsule": ("a", "b", "radius"),
    "box": ("center", "half_extents"),
    "halfspace": ("point", "normal"),
}
"""The geometry fields each obstacle shape needs."""


def obstacle_from_options(ctx: ProblemContext, i: int, options: ObstacleOptions) -> Obstacle:
    """``options.obstacles.i`` as an :class:`Obstacle`; a missing or foreign field is an error naming it."""
    where = f"options.obstacles.{i}"
    needed = SHAPE_FIELDS[options.type]
    given = {name: getattr(options, name) for name in ("center", "radius", "a", "b", "half_extents", "point", "normal")}
    for name, value in given.items():
        if value is None and name in needed:
            raise ctx.error(f"{where}.{name}", f"required for a {options.type}")
        if value is not None and name not in needed:
            raise ctx.error(f"{where}.{name}", f"not a field of a {options.type} (it takes {', '.join(needed)})")
    try:
        return Obstacle(
            options.type,
            path=None if options.path is None else tuple(options.path),
            **{name: value for name, value in given.items() if value is not None},
        )
    except ValueError as exc:
        raise ctx.error(f"{where}.{'path' if 'path' in str(exc) else needed[-1]}", str(exc)) from None


def _barrier(
    ctx: ProblemContext, options: TrackingOptions, plant: Plant, q0: np.ndarray, reference: Reference
) -> BarrierRows | None:
    """The QP's backbone barrier of ``options.obstacles``; an obstacle holding the base or the start is an error."""
    if not options.obstacles:
        return None
    if plant.rod is not None:
        raise ctx.error("options.obstacles", "obstacles need the kinematic plant (the rod plant has no backbone here)")
    obstacles = [obstacle_from_options(ctx, i, ob) for i, ob in enumerate(options.obstacles)]
    o = options.barrier
    try:
        barrier = BarrierRows(
            ctx.arm,
            reference.dt,
            obstacles,
            o.margin,
            o.gamma,
            o.points_per_obstacle,
            o.points_per_section,
            compiled=options.compiled,
        )
    except ValueError as exc:
        raise ctx.error("options.barrier", str(exc)) from None
    points = np.asarray(barrier.distances.points_at(q0 * plant.length_factors(ctx.arm)))
    for i, ob in enumerate(obstacles):
        near_base = min(float(ob.distances(points[:, :1], t)[0]) for t in _path_times(ob, reference))
        if near_base < o.margin:
            raise ctx.error(
                f"options.obstacles.{i}",
                f"contains the arm's base or comes within the margin of it ({near_base * 1e3:.3g} mm, margin "
                f"{o.margin * 1e3:.3g} mm): no command can keep the barrier",
            )
        start = ob.distances(points, 0.0)
        if start.min() < o.margin:
            j = int(np.argmin(start))
            raise ctx.error(
                f"options.obstacles.{i}",
                f"contains the start configuration's backbone or lies within the margin of it: sample {j} of "
                f"{points.shape[1]} at {start[j] * 1e3:.3g} mm (margin {o.margin * 1e3:.3g} mm)",
            )
    return barrier


def _path_times(ob: Obstacle, reference: Reference) -> np.ndarray:
    """The instants at which a moving obstacle's offset is checked: the control instants and its path's corners."""
    if ob.path is None:
        return np.zeros(1)
    return np.concatenate([reference.t, [row[0] for row in ob.path]])


def _controllers(
    ctx: ProblemContext,
    options: TrackingOptions,
    dt: float,
    task: Task,
    barrier: BarrierRows | None = None,
    reference: Reference | None = None,
) -> dict[str, Controller]:
    """The QP controller (the preset's step solver, with the barrier's rows) and every baseline, by name.

    The MPC baselines get barrier rows of their own (same obstacles and settings; each keeps its
    own clock) and ``reference`` as their preview when ``options.mpc.preview``.
    """
    setup = ControllerSetup(options, dt, task, barrier, reference)
    try:
        controllers = {"qp": _qp(ctx, setup, ctx.backend(QPBackend), "solver")}
        for baseline in ctx.baselines:
            controllers[baseline.name] = baseline.method(ctx, setup)
    except ValueError as exc:
        raise ctx.error("options", str(exc)) from None
    return controllers


def _qp(ctx: ProblemContext, setup: ControllerSetup, factory: Any, field: str) -> Controller:
    """The QP controller with ``factory``'s step solver (a ``qp`` backend's; with the barrier's rows); a factory
    taking no rows where obstacles need them is an error naming ``field``."""
    arm, o, barrier = ctx.arm, setup.options, setup.barrier
    if not isinstance(factory, QPBackend):
        raise ctx.error(field, f"{type(factory).__name__} is not a qp backend")
    if barrier is None:
        solver = factory.create(arm.n_config, task_dimension(setup.task))
    elif isinstance(factory, StepSolverFactory):
        solver = factory.create(arm.n_config, task_dimension(setup.task), rows=barrier.rows)
    else:
        raise ctx.error(field, f"{type(factory).__name__} takes no inequality rows; obstacles need a qp backend")
    return QPController(
        arm,
        setup.dt,
        setup.task,
        o.gain,
        o.damping,
        solver=solver,
        rate_limits=o.rate_limits,
        margin=o.limit_margin,
        limit_gain=o.limit_gain,
        fallback=o.fallback,
        compiled=o.compiled,
        barrier=barrier,
    )
