"""How an ``ik`` problem's options become a least-squares problem: tip rows, redundancy, elongation distribution.

The residual ``r(q, target)`` of :class:`~optikin.solvers.nonlinear.LeastSquaresProblem`
stacks these rows, all in metres:

tip
    ``p(q) - p*``; for poses also ``2 L vec(q*^-1 q(q))`` (:func:`tip_residual`,
    described in :mod:`optikin.problems.ik`). Target ``points``: the rows of the measured
    points along the arm (:meth:`optikin.ik.points.PointSet.residual`). Target ``sections`` (not an ``ik``
    target; the Newton-Raphson comparator of :mod:`optikin.baselines.ph_comparators`): the end
    position of every section, ``p_s(q) - p_s*``, the inputs of seed 004's inverse
    model (section V: the tip and the end of the first section).
penalty (``redundancy: penalty``): seed 004 eq. (11),
    ``J = 1/2 (X_d - X)^T (X_d - X) + lambda/2 ||X||^2``, which the seed adds to the
    cost of its inverse network "to select a particular inverse solution". ``X`` is
    "the predicted position", but a cost that depends on ``q`` only through the tip
    cannot select among configurations with the same tip, so two readings are offered:

    ``penalty_on: configuration`` (default): ``X`` is what the inverse model predicts,
    the configuration; rows ``sqrt(lambda) W dist(q, q_rest)``, the weighted distance
    to the rest configuration (``dist = 2 sin((q - q_rest)/2)`` for angles that wrap).
    The distance is taken from the rest configuration because a zero configuration lies
    outside the CBHA's bounds and ``||q||`` would add metres to radians. This is
    Tikhonov regularisation of the inverse problem: a unique, smooth choice, paid for
    with a tip error that grows with ``lambda`` (in m^2, the weighted distance being a
    pure number): at an interior minimiser ``J^T e + lambda W^2 d = 0`` (``e`` the tip
    error, ``J`` its Jacobian, ``d = q - q_rest``), so ``e = -lambda (J J^T)^-1 J W^2 d``.

    ``penalty_on: position``: ``X`` is the predicted tip position, as printed; rows
    ``sqrt(lambda) p(q)`` (``lambda`` a pure number). Over reachable tips the minimum is
    ``X = X_d / (1 + lambda)``: the tip is pulled towards the base, and the redundancy
    is left as it was (every configuration with that tip is a minimiser).

    Either way the problem is a minimisation whose minimum is not zero
    (``exact=False``): a sample is ``ok`` at a stationary point of the whole cost, and
    the tip error is reported separately.
elongation distribution (``elongation: distributed`` or ``affine``, CBHA only): seed 004
    section IV, every inter-vertebra an affine function of its section's tube length,
    ``distributed`` a fixed share of the mid-range lengths, ``affine`` the elongation above
    the minimum shared in proportion to the Table I ranges; 42 rows
    ``q_{m,k}(q) - a_k - b_k L_{m,s}(q)`` (:mod:`optikin.ik.cbha`). Combined with an exact
    redundancy choice they must vanish with the tip rows; under the penalty they are
    soft, weighed in metres of leg length against the tip error.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from optikin.algebra import dq_rotation, dq_translation, quat_conjugate, quat_multiply
from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm
from optikin.ik.cbha import DISTRIBUTIONS, distribution_rows
from optikin.ik.platform import platform_problems
from optikin.ik.points import PointSet
from optikin.solvers.nonlinear import LeastSquaresProblem

REDUNDANCY_CHOICES = ("rest", "previous", "minimum_norm", "penalty")
PENALTY_READINGS = ("configuration", "position")
ELONGATIONS = ("free",) + DISTRIBUTIONS
PENALTY_STATIONARITY = 1e-9
"""``||J^T r|| / (||J||_F ||r||)`` at which a penalised (not exact) problem counts as solved."""
FIT_STATIONARITY = 1e-6
"""The same for a fit to noisy targets (``noise`` given): the minimiser then moves by about this share
of the residual, far below the noise it is compared with."""


@dataclass(frozen=True, eq=False)
class Formulation:
    """One inverse problem on an arm: what is matched and how the redundancy is resolved (module docstring)."""

    target: str
    redundancy: str
    rest: np.ndarray
    weights: np.ndarray
    tolerance: float
    orientation_length: float = 1.0
    penalty: float = 0.0
    penalty_on: str = "configuration"
    elongation: str = "free"
    points: PointSet | None = None
    noise: float | None = None

    @property
    def exact(self) -> bool:
        """Whether solutions reach ``r = 0``: every choice but the penalty, for noise-free targets. With a
        stated measurement ``noise`` the targets are fitted: the problem is the minimisation of ``||r||``."""
        return self.redundancy != "penalty" and self.noise is None

    def label(self) -> str:
        """A short description, e.g. ``penalty on configuration, lambda=1e-06; distributed``."""
        text = self.redundancy
        if self.redundancy == "penalty":
            text += f" on {self.penalty_on}, lambda={self.penalty:g}"
        if self.elongation != "free":
            text += f"; {self.elongation}"
        return text


def tip_residual(arm: ArmModel, target: str, orientation_length: float) -> ca.Function:
    """The tip residual ``r(q, target)`` of an arm, in metres.

    Parameters
    ----------
    arm:
        The arm; its :meth:`~optikin.arms.base.ArmModel.section_frames` give the section ends.
    target:
        ``position`` (target ``p*``, 3), ``pose`` (a unit dual quaternion, 8) or ``sections``
        (the end position of every section, base to tip, ``3 n_sections``).
    orientation_length:
        ``L`` [m] scaling the orientation rows ``2 L vec(q_target^-1 q_tip)`` of a pose.

    Returns
    -------
    casadi.Function
        ``(q, target) -> r``: ``p(q) - p*`` (3), ``(p(q) - p*, 2 L vec(q*^-1 q(q)))`` (6) or the
        stacked section-end errors ``(3 n_sections)``.
    """
    q = ca.SX.sym("q", arm.n_config)
    frames = arm.section_frames(q)
    quat, position = frames[-1]
    if target == "sections":
        ends = ca.SX.sym("ends", 3 * len(frames))
        r = ca.vertcat(*[pos - ends[3 * i : 3 * i + 3] for i, (_, pos) in enumerate(frames)])
        return ca.Function(f"{arm.name}_ik_sections", [q, ends], [r], ["q", "ends"], ["r"])
    if target == "position":
        p = ca.SX.sym("p", 3)
        return ca.Function(f"{arm.name}_ik_position", [q, p], [position - p], ["q", "p"], ["r"])
    p = ca.SX.sym("dq", 8)
    error = quat_multiply(quat_conjugate(dq_rotation(p)), quat)
    r = ca.vertcat(position - dq_translation(p), orientation_length * 2.0 * error[1:])
    return ca.Function(f"{arm.name}_ik_pose", [q, p], [r], ["q", "dq"], ["r"])


def rest_configuration(arm: ArmModel) -> np.ndarray:
    """Straight at nominal lengths when the arm defines it, else the middle of the bounds."""
    straight = getattr(arm, "straight_configuration", None)
    return straight() if callable(straight) else 0.5 * (arm.lower + arm.upper)


def penalty_rows(arm: ArmModel, q: ca.SX, formulation: Formulation) -> ca.SX:
    """The rows of seed 004 eq. (11) in the chosen reading (module docstring)."""
    root = np.sqrt(formulation.penalty)
    if formulation.penalty_on == "position":
        return root * arm.section_frames(q)[-1][1]
    d = q - ca.DM(formulation.rest)
    d = ca.if_else(ca.DM(arm.periodic.astype(float)), 2.0 * ca.sin(d / 2.0), d)
    return root * ca.DM(formulation.weights) * d


def build_problem(arm: ArmModel, formulation: Formulation) -> LeastSquaresProblem | list[LeastSquaresProblem]:
    """The least-squares problem of a formulation (module docstring); for CBHA leg lengths, one per platform.

    Parameters
    ----------
    arm:
        The arm; leg targets and elongation distributions need a :class:`~optikin.arms.cbha.CBHAArm`.
    formulation:
        What is matched and how the redundancy is resolved.

    Returns
    -------
    LeastSquaresProblem or list of LeastSquaresProblem
        ``r(q, target)``: the tip rows, then the distribution rows and the penalty rows when asked
        for; on a CBHA the leg lengths must stay within Table I of seed 004 (the problem's
        constraints). For leg targets, the 16 platform problems of :func:`platform_problems`.

    Raises
    ------
    ValueError
        Leg targets or an elongation distribution on an arm that is not a CBHA.
    """
    needs_cbha = formulation.target == "legs" or formulation.elongation != "free"
    if needs_cbha and not isinstance(arm, CBHAArm):
        raise ValueError(
            f"{formulation.target} targets with elongation {formulation.elongation!r} need a CBHA arm, not {arm.name}"
        )
    if formulation.target == "legs" and isinstance(arm, CBHAArm):
        return platform_problems(arm, formulation.tolerance)
    if formulation.target == "points":
        if formulation.points is None:
            raise ValueError("points targets need their PointSet")
        tip = formulation.points.residual(arm, formulation.orientation_length)
    else:
        tip = tip_residual(arm, formulation.target, formulation.orientation_length)
    q, p = ca.SX.sym("q", arm.n_config), ca.SX.sym("p", tip.size1_in(1))
    rows = [tip(q, p)]
    if formulation.elongation != "free" and isinstance(arm, CBHAArm):
        rows.append(distribution_rows(arm, q, formulation.elongation))
    if formulation.redundancy == "penalty":
        rows.append(penalty_rows(arm, q, formulation))
    name = f"{arm.name}_ik_{formulation.target}"
    residual = tip if len(rows) == 1 else ca.Function(name, [q, p], [ca.vertcat(*rows)], ["q", "p"], ["r"])
    limits: dict[str, Any] = {}
    if isinstance(arm, CBHAArm):
        lower, upper = arm.leg_limits()
        limits = {
            "constraints": arm.leg_lengths,
            "constraint_lower": lower,
            "constraint_upper": upper,
            "constraint_names": arm.leg_names,
        }
    if not formulation.exact:
        limits["stationarity_tolerance"] = PENALTY_STATIONARITY if formulation.noise is None else FIT_STATIONARITY
    return LeastSquaresProblem(
        residual,
        arm.lower,
        arm.upper,
        arm.periodic,
        tolerance=formulation.tolerance,
        weights=formulation.weights,
        exact=formulation.exact,
        name=name,
        variable_names=arm.config_names,
        **limits,
    )
