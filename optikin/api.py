"""Short Python entry points to the main jobs, for use without a problem file.

>>> import numpy as np
>>> import optikin
>>> from optikin.arms import ConstantCurvatureArm
>>> arm = ConstantCurvatureArm(section_lengths=(0.1, 0.1, 0.1), length_range=(1.0, 1.0))
>>> q = np.array([0.1, 0.5, 0.2, 0.1, -0.4, 1.0, 0.1, 0.3, -2.0])
>>> disks = {"d1": {"section": 1}, "d2": {"section": 2}, "d3": {"section": 3}}
>>> measured = optikin.api.point_set(disks).forward(arm, q[None])[0]  # the three disk centres, (9,) [m]
>>> solution = optikin.solve_ik(arm, measured, points=disks)
>>> solution.status, bool(solution.rms_distance < 1e-12)
('ok', True)
>>> noisy = measured + np.random.default_rng(0).normal(0.0, 3e-4, 9)  # 0.3 mm motion-capture noise
>>> optikin.solve_ik(arm, noisy, points=disks, noise=1e-3).status
'fit'

A backbone between two poses, here a quarter circle of radius 0.2 m (tangent ``+z`` at the base, ``+x`` at
the tip; poses as 4x4 transforms or unit dual quaternions):

>>> base = np.eye(4)
>>> tip = np.array([[0.0, 0, 1, 0.2], [0, 1, 0, 0], [-1, 0, 0, 0.2], [0, 0, 0, 1]])  # z_tip = +x
>>> backbone = optikin.reconstruct_backbone(base, tip, length=np.pi / 10)
>>> backbone.status, round(backbone.arc_length, 6), backbone.points.shape
('ok', 0.314159, (21, 3))

Closed-loop tracking of a minimum-jerk path through two configurations (the problem files' ``waypoints``):

>>> cc2 = ConstantCurvatureArm()
>>> run = optikin.track(cc2, {"waypoints": [[0.18, 0.3, 0.0, 0.18, 0.3, 0.0], [0.17, 0.6, 0.4, 0.18, 0.5, 1.0]],
...                           "task": "position", "rate": 200, "segment_time": 1.0, "hold": 0.5})
>>> run.statuses.count("ok") == len(run.t), bool(run.error[-1] < 1e-5)
(True, True)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Mapping

import numpy as np

from optikin.algebra import dq_rotation, dq_translation, quat_rotate
from optikin.arms.base import ArmModel
from optikin.baselines.pseudo_inverse import DampedLeastSquaresController, PseudoInverseController
from optikin.checks import (
    MAX_MAGNITUDE,
    ParameterError,
    check_configuration,
    check_dual_quaternion,
    check_finite,
    check_magnitude,
    check_numbers,
    check_parameter,
    check_rotation_matrix,
)
from optikin.control.base import Controller
from optikin.control.mpc import MPCController
from optikin.control.qp import QPController
from optikin.control.reference import Reference, minimum_jerk_path, reference_from_configurations
from optikin.control.simulate import TrackingRun, simulate
from optikin.control.task import task_dimension
from optikin.curves import EnergySettings, PHQuintic, ShapeData, ShapeEnergyModel, arc_length_estimate
from optikin.curves.min_energy import ShapeSolution
from optikin.data.references import WaypointParams
from optikin.data.targets import Targets, reach_bound
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.points import COMPONENTS, MeasuredPoint, PointSet
from optikin.physics.comparison import ph_points_at_fractions
from optikin.options import validate_options
from optikin.problems.ik.run import mark_fits, rms_distances
from optikin.solvers import load_preset
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter
from optikin.status import Status

logger = logging.getLogger(__name__)


def _arm(arm: object) -> ArmModel:
    """``arm`` itself, or a :class:`TypeError` naming the argument."""
    if not isinstance(arm, ArmModel):
        raise TypeError(
            f"arm: expected an ArmModel (e.g. optikin.arms.ConstantCurvatureArm()), got {type(arm).__name__}"
        )
    return arm


def _count(value: object, name: str, minimum: int) -> int:
    """An integer argument of at least ``minimum``, or a :class:`TypeError` / :class:`ValueError` naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__} {value!r}")
    if value < minimum:
        raise ValueError(f"{name}: must be at least {minimum}, got {value}")
    return int(value)


def _number(value: object, name: str, positive: bool = False) -> float:
    """A finite number argument (``positive``: above zero; else at least zero), naming it when it is not."""
    number = float(check_parameter(value, name, positive=positive, scalar=True))
    if not positive and number < 0:
        raise ParameterError(name, f"must not be negative, got {number:g}")
    return number


@dataclass(frozen=True)
class IkSolution:
    """The answer of :func:`solve_ik`.

    Attributes
    ----------
    configuration:
        ``(n_config,)`` in the arm's variables (SI units).
    status:
        ``ok`` (residual within the tolerance), ``fit`` (a least-squares minimum within ``noise``),
        ``unreachable``, ``not_converged``, ``failed`` or ``timeout``.
    residual:
        ``||r||`` at the answer [m].
    rms_distance:
        RMS distance of the measured points (or the tip) to the answer [m].
    iterations, seconds:
        What the solve took.
    message:
        Why, for a sample that is not ``ok``.
    problem:
        The least-squares problem that was solved (inspectable: residual Function, bounds).
    """

    configuration: np.ndarray
    status: str
    residual: float
    rms_distance: float
    iterations: int
    seconds: float
    message: str
    problem: LeastSquaresProblem


def point_set(points: Mapping[str, Mapping[str, Any]] | PointSet) -> PointSet:
    """A :class:`~optikin.ik.points.PointSet` from ``{name: {section, at, offset, measure, weight}}``
    (sections from 1, as in problem files), or the set itself."""
    if isinstance(points, PointSet):
        return points
    if not isinstance(points, Mapping):
        raise TypeError(
            f"points: expected a mapping {{name: {{section, at, offset, measure, weight}}}}, got {points!r}"
        )
    made = []
    for name, p in points.items():
        if not isinstance(p, Mapping) or "section" not in p:
            raise ValueError(f"points.{name}: expected a mapping with a section (from 1), got {p!r}")
        measure = tuple(p.get("measure", ("position",)))
        offset = check_finite(
            check_numbers(p.get("offset", (0.0, 0.0, 0.0)), f"points.{name}.offset"), f"points.{name}.offset"
        )
        if offset.shape != (3,):
            raise ValueError(f"points.{name}.offset: expected 3 numbers [m], got {offset.tolist()}")
        made.append(
            MeasuredPoint(
                name=name,
                section=_count(p["section"], f"points.{name}.section", 1) - 1,
                fraction=_number(p.get("at", 1.0), f"points.{name}.at", positive=True),
                offset=(float(offset[0]), float(offset[1]), float(offset[2])),
                components=tuple(c for c in COMPONENTS if c in measure),
                weight=_number(p.get("weight", 1.0), f"points.{name}.weight", positive=True),
            )
        )
    return PointSet(tuple(made))


def solve_ik(
    arm: ArmModel,
    target: np.ndarray,
    *,
    points: Mapping[str, Mapping[str, Any]] | PointSet | None = None,
    start: np.ndarray | None = None,
    preset: str = "gauss-newton",
    noise: float | None = None,
    tolerance: float = 1e-10,
) -> IkSolution:
    """Inverse kinematics of one target, as the ``ik`` kind solves it (:mod:`optikin.problems.ik`).

    Parameters
    ----------
    arm:
        The arm.
    target:
        A tip position ``(3,)`` [m], a tip pose as a unit dual quaternion ``(8,)``, or with ``points``
        the stacked measurements ``(D,)`` of :meth:`optikin.ik.points.PointSet.columns`.
    points:
        The measured points (``{name: {section, at, offset, measure, weight}}``, sections from 1).
    start:
        Start configuration; default the arm's rest (straight at nominal lengths for a CC arm).
    preset:
        A ``nonlinear`` solver preset (name or path).
    noise:
        Measurement noise level [m]: the target is fitted, a minimum within it is ``fit``.
    tolerance:
        ``||r||`` [m] counted as solved exactly.

    Returns
    -------
    IkSolution

    Raises
    ------
    TypeError
        ``arm`` not an arm, or an argument that is not numbers, naming it.
    ValueError
        A target of the wrong size, not finite, beyond :data:`optikin.checks.MAX_MAGNITUDE` m or (a pose)
        not a unit dual quaternion; a ``start`` that is not a plausible configuration; a ``noise`` or
        ``tolerance`` that is not a finite number of the right sign; naming the argument.
    """
    arm = _arm(arm)
    target = check_magnitude(check_finite(check_numbers(target, "target"), "target"), "target", MAX_MAGNITUDE, "m")
    target = target.ravel()
    kind = "points" if points is not None else {3: "position", 8: "pose"}.get(target.size)
    if kind is None:
        raise ValueError(f"target must be a position (3) or a dual quaternion (8), got {target.size} values")
    if kind == "pose":
        check_dual_quaternion(target, name="target")
    noise = None if noise is None else _number(noise, "noise")
    tolerance = _number(tolerance, "tolerance", positive=True)
    measured = point_set(points) if points is not None else None
    if measured is not None:
        measured.check(arm)
        if target.size != measured.size:
            raise ValueError(f"the points {measured.columns()} need {measured.size} values, got {target.size}")
    span = arm.upper - arm.lower
    formulation = Formulation(
        target=kind,
        redundancy="rest",
        rest=rest_configuration(arm),
        weights=1.0 / np.where(span > 0, span, 1.0),
        tolerance=tolerance,
        orientation_length=reach_bound(arm) if kind != "position" else 1.0,
        points=measured,
        noise=noise,
    )
    problem = build_problem(arm, formulation)
    assert isinstance(problem, LeastSquaresProblem)
    loaded = load_preset(preset)
    if loaded.backend.family != "nonlinear":
        raise ValueError(f"preset {preset!r} is of family {loaded.backend.family}, not nonlinear")
    adapter: NonlinearAdapter = loaded.build()
    x0 = formulation.rest if start is None else check_configuration(arm, start, "start", within="plausible")
    targets = Targets(kind, target[None], np.full((1, arm.n_config), np.nan), np.ones(1, bool), points=measured)
    batch = mark_fits(
        adapter.solve_many(problem, x0, target[None], x_ref=formulation.rest), arm, targets, formulation, noise
    )
    x = np.asarray(batch.x[0], dtype=float)
    rms = float(rms_distances(arm, targets, formulation, x[None])[0])
    return IkSolution(
        x,
        batch.status[0],
        float(batch.residual[0]),
        rms,
        int(batch.iterations[0]),
        float(batch.seconds[0]),
        batch.messages[0],
        problem,
    )


@dataclass(frozen=True)
class Backbone:
    """The answer of :func:`reconstruct_backbone`.

    Attributes
    ----------
    curve:
        The PH quintic ``r(t)``, ``t`` in ``[0, 1]`` from base to tip (numpy coefficients; points,
        frames, curvature, torsion, arc length).
    points:
        ``(samples, 3)`` points of the curve at equal fractions of its arc length, base first [m].
    energy:
        Bending energy ``int kappa^2 ds`` (plus the twist term, if weighted) [1/m].
    arc_length:
        Length of the curve [m].
    status:
        ``ok``, ``not_converged`` or ``failed``.
    message:
        Why, when not ``ok``.
    solution:
        The solver's answer (free angles and end speeds, iterations, notes).
    """

    curve: PHQuintic
    points: np.ndarray
    energy: float
    arc_length: float
    status: str
    message: str
    solution: ShapeSolution


def _end(pose: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and backbone tangent (the frame's z axis) of a unit dual quaternion ``(8,)`` or a 4x4 transform."""
    x = check_magnitude(check_finite(check_numbers(pose, name), name), name, MAX_MAGNITUDE, "m")
    if x.shape == (4, 4):
        R = check_rotation_matrix(x[:3, :3], f"{name}[:3, :3]")
        return x[:3, 3], R[:, 2]
    if x.shape == (8,):
        check_dual_quaternion(x, name=name)
        return dq_translation(x, check=False), quat_rotate(dq_rotation(x), np.array([0.0, 0.0, 1.0]), check=False)
    raise ValueError(f"{name} must be a unit dual quaternion (8,) or a 4x4 transform, got shape {x.shape}")


@lru_cache(maxsize=4)
def _shape_model(twist_weight: float) -> ShapeEnergyModel:
    return ShapeEnergyModel(EnergySettings(twist_weight=twist_weight), free_speeds=True)


def reconstruct_backbone(
    base_pose: np.ndarray,
    tip_pose: np.ndarray,
    *,
    length: float | None = None,
    samples: int = 21,
    twist_weight: float = 0.0,
) -> Backbone:
    """The minimum-energy spatial PH quintic between two poses (Singh et al. 2018, section II.A).

    The backbone leaves the base point along the base frame's z axis and reaches the tip point along the
    tip frame's z axis; among the PH quintics that do (a two-parameter family, with the end speeds free),
    the one of least bending energy whose arc length is ``length`` is taken
    (:class:`optikin.curves.ShapeEnergyModel` with ``free_speeds=True``, Newton's method).

    Parameters
    ----------
    base_pose, tip_pose:
        End frames in one common frame: unit dual quaternions ``(8,)`` (``(Q_r, Q_d)``, translation in
        metres) or homogeneous transforms ``(4, 4)``.
    length:
        Backbone length [m], longer than the distance of the end points; default the circular arc's
        (:func:`optikin.curves.arc_length_estimate`).
    samples:
        Number of points returned in :attr:`Backbone.points`.
    twist_weight:
        Weight of ``int tau^2 ds`` in the energy (0: bending only).

    Returns
    -------
    Backbone

    Raises
    ------
    TypeError
        An argument that is not numbers (or ``samples`` not an integer), naming it.
    ValueError
        A pose of the wrong shape, not finite or not a rigid transform; ``samples`` below 2, a
        ``length`` or ``twist_weight`` that is not a finite number of the right sign; naming the argument.
    optikin.errors.InputDataError
        ``length`` not longer than the chord (naming the field).
    """
    p0, t0 = _end(base_pose, "base_pose")
    p1, t1 = _end(tip_pose, "tip_pose")
    samples = _count(samples, "samples", 2)
    twist_weight = _number(twist_weight, "twist_weight")
    if length is not None:
        length = _number(length, "length", positive=True)
    if length is None:
        length = float(arc_length_estimate(p0, t0, p1, t1))
    data = ShapeData.checked(p0, t0, p1, t1, length=length, source="reconstruct_backbone")
    model = _shape_model(float(twist_weight))
    solution = model.solve_newton(data)
    curve = model.curve(solution, data)
    logger.debug("backbone of length %.6g m: %s in %d iterations", length, solution.status, solution.iterations)
    return Backbone(
        curve,
        ph_points_at_fractions(curve, np.linspace(0.0, 1.0, samples)),
        solution.energy,
        float(curve.arc_length()),
        solution.status,
        solution.message,
        solution,
    )


@dataclass(frozen=True)
class Tracking:
    """The answer of :func:`track`: one closed-loop run, ``N`` control steps.

    Attributes
    ----------
    t:
        ``(N,)`` control instants [s].
    q:
        ``(N, n_config)`` configuration of the arm at each instant (SI units).
    tip:
        ``(N, 3)`` tip position [m], base frame.
    error:
        ``(N,)`` distance of the tip from the reference position [m].
    orientation_error:
        ``(N,)`` angle between the tip and reference orientations [rad]; ``None`` for a position task.
    statuses:
        Per step ``ok``, or ``fallback (...): reason`` when the controller's solver failed.
    controller:
        The controller's name.
    run:
        The full record (commanded rates, limit excess, step times; ``run.metrics()``).
    """

    t: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    error: np.ndarray
    orientation_error: np.ndarray | None
    statuses: list[str]
    controller: str
    run: TrackingRun


def _reference(
    arm: ArmModel, reference: Reference | Mapping[str, Any] | np.ndarray, rate: float
) -> tuple[Reference, np.ndarray | None]:
    """The reference and, for waypoints, the start configuration."""
    if isinstance(reference, Reference):
        return reference, None
    if isinstance(reference, Mapping):
        params = validate_options(WaypointParams, dict(reference), "track", "reference")
        W = np.asarray(params.waypoints, dtype=float)
        if W.ndim != 2 or W.shape[1] != arm.n_config:
            raise ValueError(f"waypoints need rows of {arm.n_config} values ({', '.join(arm.config_names)})")
        t, Q, Qdot = minimum_jerk_path(W, params.segment_time, params.rate, params.hold)
        return reference_from_configurations(arm, t, Q, Qdot, params.task), W[0]
    value = check_magnitude(
        check_finite(check_numbers(reference, "reference"), "reference"), "reference", MAX_MAGNITUDE, "m"
    )
    task = {3: "position", 8: "pose"}.get(value.shape[-1]) if value.ndim == 2 else None
    if task is None:
        raise ValueError(f"a reference array must be (N, 3) positions or (N, 8) dual quaternions, got {value.shape}")
    t = np.arange(len(value)) / rate
    return Reference(t, value, np.gradient(value, t, axis=0), task), None  # type: ignore[arg-type]


def track(
    arm: ArmModel,
    reference: Reference | Mapping[str, Any] | np.ndarray,
    controller: str | Controller = "qp",
    *,
    start: np.ndarray | None = None,
    rate: float = 500.0,
    preset: str = "qp-active-set",
    gain: float = 10.0,
    damping: float = 1e-4,
    horizon: int = 20,
) -> Tracking:
    """Track a tip reference in closed loop, as the ``tracking`` kind does (:mod:`optikin.control`).

    The controller's model is the arm itself and the plant is exact (no mismatch, disturbance or noise:
    :func:`optikin.control.simulate.simulate` with its default plant).

    Parameters
    ----------
    arm:
        The arm.
    reference:
        The tip reference: a :class:`~optikin.control.reference.Reference`; a mapping of a problem file's
        ``waypoints`` source (``{"waypoints": (K, n_config), "segment_time": s, "hold": s, "task":
        "pose" | "position", "rate": Hz}``: the forward kinematics of a minimum-jerk path through them); or
        an array of tip positions ``(N, 3)`` [m] or tip dual quaternions ``(N, 8)`` sampled at ``rate``
        (rates by central differences).
    controller:
        ``qp`` (the bounded QP of :class:`~optikin.control.qp.QPController`), ``mpc`` (the sparse-QP MPC of
        :class:`~optikin.control.mpc.MPCController` over ``horizon`` steps, previewing the reference),
        ``damped_least_squares``, ``pseudo_inverse``, or a ready :class:`~optikin.control.base.Controller` at
        the reference's period.
    start:
        Configuration ``(n_config,)`` at ``t = 0``; default the first waypoint, else the inverse kinematics of
        the first reference sample (:func:`solve_ik`).
    rate:
        Sample rate of an array reference [Hz].
    preset:
        The ``qp`` solver preset of the ``qp`` controller (default: DAQP's active set, warm-started, exact;
        ``qp-osqp`` for ADMM).
    gain, damping:
        Feedback gain ``K`` [1/s] and damping ``lambda`` of the built controllers (``lambda`` is the MPC's
        effort weight: with ``horizon = 1`` the MPC is the QP step).
    horizon:
        The MPC's horizon [steps].

    Returns
    -------
    Tracking

    Raises
    ------
    optikin.errors.SpecError
        A waypoint mapping its model refuses (naming ``reference.<field>``).
    TypeError
        ``arm`` not an arm, an argument that is not numbers or ``horizon`` not an integer, naming it.
    ValueError
        An unknown controller, a preset not of family ``qp``, a reference array of the wrong shape or not
        finite, waypoints of the wrong length, a first reference sample that no configuration reaches, a
        ``start`` that is not a plausible configuration, or a ``rate``, ``gain``, ``damping`` or ``horizon``
        out of range, naming the argument.
    """
    arm = _arm(arm)
    rate, gain, damping = _number(rate, "rate", positive=True), _number(gain, "gain"), _number(damping, "damping")
    horizon = _count(horizon, "horizon", 1)
    if start is not None:
        start = check_configuration(arm, start, "start", within="plausible")
    ref, first = _reference(arm, reference, rate)
    if start is None:
        if first is None:
            solution = solve_ik(arm, ref.value[0])
            if solution.status != Status.OK:
                raise ValueError(f"the first reference sample is not reachable ({solution.message})")
            first = solution.configuration
        start = first
    dt, task, m = ref.dt, ref.task, task_dimension(ref.task)
    if isinstance(controller, Controller):
        made = controller
    elif controller == "qp":
        loaded = load_preset(preset)
        if loaded.backend.family != "qp":
            raise ValueError(f"preset {preset!r} is of family {loaded.backend.family}, not qp")
        made = QPController(arm, dt, task, gain, damping, solver=loaded.build().create(arm.n_config, m))
    elif controller == "mpc":
        made = MPCController(arm, dt, task, gain, damping, horizon=horizon, preview=ref)
    elif controller == "damped_least_squares":
        made = DampedLeastSquaresController(arm, dt, task, gain, damping)
    elif controller == "pseudo_inverse":
        made = PseudoInverseController(arm, dt, task, gain)
    else:
        raise ValueError(f"unknown controller {controller!r}; known: qp, mpc, damped_least_squares, pseudo_inverse")
    run = simulate(made, ref, np.asarray(start, dtype=float))
    logger.debug("tracked %d steps with %s", len(ref.t), made.name)
    return Tracking(ref.t, run.q, run.position, run.position_error, run.orientation_error, run.status, made.name, run)
