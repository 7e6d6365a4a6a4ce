"""Problem kind ``ik``: inverse kinematics as root finding / bounded nonlinear least squares.

For each target the configuration ``q`` solves ``min 1/2 ||r(q, target)||^2``
within the arm's bounds (:mod:`optikin.solvers.nonlinear`), with

* ``target: position``: ``r = p(q) - p*`` (metres), the tip position of the arm's
  :meth:`~optikin.arms.base.ArmModel.section_frames`;
* ``target: pose``: ``r = (p(q) - p*, 2 L vec(q*^-1 q(q)))``, the position error
  and the unit-quaternion orientation error (Siciliano et al., Robotics, 2009,
  sec. 3.7.3), scaled by the length ``L`` (``orientation_length``, default: the
  arm's reach bound) so ``||r||`` is in metres. ``2 vec(q*^-1 q) = 2 sin(a/2) n`` is
  the rotation vector ``a n`` of the error to first order, vanishes exactly when the
  orientations agree (either quaternion sign), and is smooth everywhere: unlike the
  rotation log it has no branch at ``a = pi``, which left Gauss-Newton in spurious
  minima on more random targets. The target is a unit dual quaternion (real part
  first, ``Q = r + eps 1/2 p r``). For a two-section CC arm the 6 x 6 pose Jacobian
  has rank 5 at every configuration (torsion-free sections: the reachable poses form
  a 5-D set), so pose IK is a rank-deficient least-squares problem with a curve of
  solutions per reachable pose.
* ``target: points``: measured points along the arm (``options.points``: name -> section, ``at`` a
  fraction of its arc, ``offset`` in the backbone frame there, ``measure`` position / direction /
  orientation, ``weight``), their rows stacked as :mod:`optikin.ik.points` describes: section ends,
  markers on disks or tubes, the tip direction without its twist.
* ``target: legs`` (CBHA only): the 48 leg lengths of the 16 platforms ->
  ``(Z_k, theta_k, psi_k)``, seed 004 eqs. (7)-(9) inverted platform by platform
  (:mod:`optikin.ik.platform`); ``||r||`` in metres of leg length.

For a CBHA every leg length must also lie within Table I of seed 004: the NLP
backends impose these limits as constraints, and any backend's configuration
that breaks one is reported ``failed`` naming the leg.

With fewer target coordinates than configuration variables (tip position of a
two-section CC arm: 3 for 6) the solutions form a set, and ``redundancy``
chooses among them, in the weighted norm ``||W (q - q_ref)||`` (``weights``,
default the inverse ranges of the variables):

``rest``          closest to the rest configuration ``rest`` (default: straight
                  at nominal lengths for the CC arm, mid-range otherwise);
``previous``      closest to the previous solution along a trajectory (to the start
                  point for independent targets);
``minimum_norm``  the solution reached by weighted minimum-norm corrections from
                  the start point (the pseudo-inverse Newton-Raphson iteration);
``penalty``       seed 004 eq. (11): no exact constraint, the tip error plus
                  ``penalty`` (lambda) times a squared norm is minimised
                  (``penalty_on: configuration``, the weighted distance to ``rest``;
                  or ``position``, the tip's distance to the base, as printed);
                  see :mod:`optikin.ik.formulation`. A sample is ``ok``
                  at a stationary point of that cost; its tip error is reported
                  beside (in general larger than ``tolerance``).

Measured targets carry noise: with ``options.noise`` (metres) the targets are fitted rather than
matched, ``1/2 ||r||^2`` is minimised (the NLP backends drop the redundancy preference and the equality
constraints ``r = 0``), and a minimum is ``ok`` when ``||r|| <= tolerance``, ``fit`` when the RMS
distance of the points (:func:`optikin.problems.ik.run.rms_distances`) is at most ``noise``, else
``unreachable``. ``fit`` counts as solved (exit status 0).

On a CBHA, ``elongation: distributed`` adds the elongation distribution of seed
004 section IV (every inter-vertebra a fixed fraction of its section's tube
length, from Table I; :mod:`optikin.ik.cbha`) to any of these;
``elongation: affine`` its other reading (the elongation above Table I's minimum
shared in proportion to each inter-vertebra's range).

Backends that minimise a distance (``newton`` through the optimality system,
``ipopt``, ``sqpmethod``) do so exactly, with ``q_ref`` the rest configuration or
the start point; ``gauss_newton``, ``lm`` and ``trf`` take minimum-norm steps
from the start point, which is the rest configuration for independent targets
under ``rest``. A fit to noisy targets (``noise`` given) with at least as many rows as free
variables has the same minimiser whatever ``q_ref``, so no reference is passed there
(:func:`optikin.problems.ik.run.reference_of`): ``gauss_newton`` then solves the batch, or the
recording warm-started in order (``data.params.trajectory`` of the ``csv`` source), in generated
C (:mod:`optikin.native.ik`), about fifteen times faster per posture than its Python loop.

Problem file
------------
``data``
    a source of family ``targets`` (:mod:`optikin.data.targets`): ``random``
    (forward kinematics of random admissible configurations, optionally with targets
    outside the workspace), ``trajectory`` (a smooth motion, solved in order, each
    solve warm-started from the previous solution) or ``csv``. Independent targets
    are solved as one batch when the backend has a batched path; those not solved
    are retried ``restarts`` times, keeping the best point: first from the solution
    of the nearest solved target, then from random admissible configurations
    (seeded). Targets outside the workspace end as ``unreachable`` at the closest
    configuration the backend found, with its residual: never ``ok``.
``solver``, ``baselines``
    presets of the ``nonlinear`` family; every baseline solves the same targets in
    the same run, and so does the solver on each of the ``variants`` (other
    formulations of the same targets, e.g. the penalty of eq. (11) beside the exact
    tip with the closest-to-rest choice). The comparison rows are described in
    :mod:`optikin.problems.ik.report`, the figures in :mod:`optikin.problems.ik.figures`.
``options``
    :class:`~optikin.problems.ik.options.IkOptions`: ``target``, ``redundancy``,
    ``rest``, ``weights``, ``start`` (``rest`` or a configuration), ``restarts``
    (default 6), ``tolerance`` (``||r||`` in metres counted as solved, default
    1e-10), ``orientation_length``, ``penalty`` (lambda, default 1e-6: m^2 on the
    configuration, a pure number on the position), ``penalty_on``
    (``configuration`` or ``position``), ``elongation`` (``free``, ``distributed``
    or ``affine``), ``points`` and ``noise`` (above), ``variants`` (``{label: {option: value}}`` over the fields of
    :class:`~optikin.problems.ik.options.FormulationOptions`).

Independent targets can be split across worker processes (``optikin solve NAME --jobs N`` or ``--dask``):
the batch solves go in pieces to the workers, the retries are decided here on all samples, and every
per-sample answer equals the single-process run's (:mod:`optikin.problems.ik.chunks`).
"""

from __future__ import annotations

from optikin.data.targets import FAMILY as TARGETS
from optikin.problems import ProblemContext, ProblemKind, figures_of, preset_row, register_kind
from optikin.problems.ik.chunks import run_chunked
from optikin.problems.ik.options import FormulationOptions, IkOptions
from optikin.problems.ik.report import array_key, result_of
from optikin.problems.ik.run import solve
from optikin.results import Result
from optikin.solvers.nonlinear import FAMILY

__all__ = ["FormulationOptions", "IkOptions", "array_key", "run"]


def run(ctx: ProblemContext) -> Result:
    """Solve the targets with every method and report the comparison."""
    return result_of(ctx, solve(ctx))


register_kind(
    ProblemKind(
        name="ik",
        summary="inverse kinematics by Newton / nonlinear least squares, backends compared on the same targets",
        run=run,
        backend_families=(FAMILY,),
        preset_baseline=preset_row,
        default_solver="gauss-newton",
        options=IkOptions,
        data_family=TARGETS,
        figures=figures_of("optikin.problems.ik.figures"),
        run_chunked=run_chunked,
    )
)
