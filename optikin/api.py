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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from optikin.arms.base import ArmModel
from optikin.data.targets import Targets, reach_bound
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.points import COMPONENTS, MeasuredPoint, PointSet
from optikin.problems.ik.run import mark_fits, rms_distances
from optikin.solvers import load_preset
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter


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
    made = []
    for name, p in points.items():
        measure = tuple(p.get("measure", ("position",)))
        made.append(
            MeasuredPoint(
                name=name,
                section=int(p["section"]) - 1,
                fraction=float(p.get("at", 1.0)),
                offset=tuple(float(v) for v in p.get("offset", (0.0, 0.0, 0.0))),  # type: ignore[arg-type]
                components=tuple(c for c in COMPONENTS if c in measure),
                weight=float(p.get("weight", 1.0)),
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
    """
    target = np.asarray(target, dtype=float).ravel()
    kind = "points" if points is not None else {3: "position", 8: "pose"}.get(target.size)
    if kind is None:
        raise ValueError(f"target must be a position (3) or a dual quaternion (8), got {target.size} values")
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
    x0 = formulation.rest if start is None else np.asarray(start, dtype=float)
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
