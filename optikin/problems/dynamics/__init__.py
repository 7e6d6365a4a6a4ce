"""Problem kind ``dynamics``: a Cosserat-rod arm in time, each implicit step a BVP solved by shooting.

The arm is ``arm.type: cosserat`` (:mod:`optikin.arms.cosserat`) with a density: the rod
with linear and angular momentum, Kelvin-Voigt damping and air drag, the time derivatives
replaced by BDF-alpha (Till, Aloi and Rucker, IJRR 38(6), 2019;
:mod:`optikin.physics.dynamics`). It starts at rest in the equilibrium of the initial
commands and takes ``data.samples`` steps of ``options.dt``; the actuation (tendon
tensions [N], chamber pressures [Pa]) and the tip force follow the commands of
``data.source`` (family ``actuation_commands``: ``step``, ``ramp``, ``sine``, ``csv``;
:mod:`optikin.problems.dynamics.commands`). The chamber pressures can lag their commands
(``options.pressure_time_constant``, first order); a payload (``options.payload``) is a
point mass at the tip, with its weight and inertia.

Problem file::

    kind: dynamics
    arm: {type: cosserat, params: {youngs_modulus: 1.0e+6, density: 1000.0, segments: [...], tendons: [...]}}
    data:
      source: step          # step | ramp | sine | csv
      samples: 500          # time steps
      params: {initial: [0.0], final: [0.5], tip_force_initial: [0.0, 0.0, 0.0]}
    options: {dt: 0.002, alpha: 0.0, damping: {viscosity: 1000.0}, gravity: true}

A step whose BVP does not converge stops the run: the Result is partial (its later steps
``failed``, a note naming the step, its time and its residual) and ``optikin solve`` exits
with 1. An unusable ``dt`` (too long to resolve the first bending mode, too short for a
well-conditioned shooting) or a negative viscosity is a field error before the run.
Options: :class:`~optikin.problems.dynamics.options.DynamicsKindOptions`. The Result is
described in :mod:`optikin.problems.dynamics.report`, the figures in
:mod:`optikin.problems.dynamics.figures`.
"""

from __future__ import annotations

from optikin.problems import ProblemContext, ProblemKind, figures_of, register_kind
from optikin.problems.dynamics.commands import FAMILY
from optikin.problems.dynamics.options import DampingOptions, DynamicsKindOptions
from optikin.problems.dynamics.report import result_of
from optikin.problems.dynamics.run import solve
from optikin.results import Result

__all__ = ["DampingOptions", "DynamicsKindOptions", "run"]


def run(ctx: ProblemContext) -> Result:
    """Simulate a ``dynamics`` problem and report it."""
    return result_of(ctx, solve(ctx))


register_kind(
    ProblemKind(
        name="dynamics",
        summary="Cosserat-rod dynamics: actuation and tip-force commands -> states in time (implicit BDF-alpha)",
        run=run,
        backend_families=(),
        default_solver=None,
        options=DynamicsKindOptions,
        data_family=FAMILY,
        figures=figures_of("optikin.problems.dynamics.figures"),
        headline=("step [us]", "real-time factor", "Newton iterations", "steps ok"),
    )
)
