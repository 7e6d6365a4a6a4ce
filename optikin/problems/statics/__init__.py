"""Problem kind ``statics``: Cosserat-rod equilibria of a tendon or pneumatic arm, forward and inverse.

The arm is ``arm.type: cosserat`` (:mod:`optikin.arms.cosserat`): a static Cosserat
(or Kirchhoff) rod of one or more segments with tendons and chambers
(:mod:`optikin.physics`). The loads of ``options.loads`` (gravity, a payload mass
at the tip, a tip force and couple) are the same for every sample.

``options.mode: forward``
    Each actuation sample (tendon tensions [N], chamber pressures [Pa]) -> the
    equilibrium shape, by shooting on the C-compiled path
    (:class:`optikin.physics.ShootingSolver`, ``compiled``), each solve
    warm-started from the ones before along the samples. A sample whose BVP does
    not converge is ``failed`` with its tip residual: never a silent shape.
    Baseline ``collocation``: the same equilibria by Gauss-Legendre collocation and
    IPOPT (:class:`optikin.physics.CollocationSolver`), compared in mm and in time
    per equilibrium.
``options.mode: inverse``
    Each tip target (position, or pose with ``options.target: pose``) -> an
    actuation within the bounds (tensions ``>= 0``, pressures within their range)
    whose equilibrium reaches it: the bounded least-squares problem
    ``min 1/2 ||r(a)||^2``, ``r`` the tip error of the equilibrium reached, as an
    :class:`optikin.solvers.nonlinear.LeastSquaresProblem`
    (:mod:`optikin.problems.statics.equilibrium`: the equilibrium is embedded in
    a CasADi Function, its derivatives by the implicit function theorem), so any
    ``nonlinear`` preset solves it and the others are its baselines, on the same
    targets. Along a trajectory each target starts from the previous answer. Every
    answer's equilibrium is solved again from zero load and its tip error reported.

Problem file::

    kind: statics
    arm: {type: cosserat, params: {youngs_modulus: 60.0e+9, segments: [...], tendons: [...]}}
    data:
      source: trajectory    # trajectory | random | grid | csv | target_csv (optikin.data.actuations)
      seed: 1
      samples: 100
    solver: gauss-newton    # inverse: a nonlinear preset; forward: not used (the compiled shooting is the solver)
    baselines: [collocation]  # forward: collocation; inverse: other nonlinear presets
    options: {mode: forward, loads: {gravity: true, payload: 0.0}}

Inverse targets come from the actuation sources (the tips of their equilibria, so
reachable; the generating actuations are kept for comparison), from
``target_csv``, or from ``cosserat`` (tips of the Cosserat-rod CBHA of
:mod:`optikin.data.cosserat_sensors`, a model the problem's arm need not match).
Options: :class:`~optikin.problems.statics.options.StaticsOptions`.
The Result is described in :mod:`optikin.problems.statics.report`, the figures in
:mod:`optikin.problems.statics.figures`.
"""

from __future__ import annotations

import optikin.data.cosserat_sensors  # noqa: F401 - registers source "cosserat" of data families "targets", "actuations"
from optikin.data.actuations import FAMILY as ACTUATIONS
from optikin.problems import Baseline, ProblemContext, ProblemKind, baselines_of, figures_of, preset_row, register_kind
from optikin.problems.statics.options import LoadOptions, StaticsOptions
from optikin.problems.statics.report import result_of
from optikin.problems.statics.run import COLLOCATION, solve
from optikin.results import Result
from optikin.solvers.nonlinear import FAMILY

__all__ = ["LoadOptions", "StaticsOptions", "run"]


def run(ctx: ProblemContext) -> Result:
    """Solve a ``statics`` problem and report it."""
    return result_of(ctx, solve(ctx))


register_kind(
    ProblemKind(
        name="statics",
        summary="Cosserat-rod equilibria: actuation -> shape (shooting vs collocation), tip target -> actuation",
        run=run,
        backend_families=(FAMILY,),
        default_solver="gauss-newton",
        baselines=baselines_of(Baseline(COLLOCATION, COLLOCATION)),
        preset_baseline=preset_row,
        options=StaticsOptions,
        data_family=ACTUATIONS,
        figures=figures_of("optikin.problems.statics.figures"),
    )
)
