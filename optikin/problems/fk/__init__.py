"""Problem kind ``fk``: an arm's forward kinematics over a configuration sweep or trajectory.

Evaluates the tip pose (dual quaternion), the end pose of every section and
the backbone for every sample with the chosen evaluation backend
(:mod:`optikin.solvers.evaluation`), checks the result (finite, unit dual
quaternions to 1e-9), and compares it in the same run with the baselines: the
``numpy`` baseline evaluates the same formulas on vectorised numpy arrays
instead of CasADi; an evaluation preset named as a baseline runs on the same
configurations. Figures: the backbones in 3-D and the tip over time.

Problem file::

    kind: fk
    arm: {type: constant_curvature, params: {...}}
    data:
      source: trajectory    # random | trajectory | sweep | csv (optikin.data.configurations)
      seed: 2020
      samples: 1000
      params: {rate: 100.0, amplitude: 0.8, frequency: [0.1, 0.4]}
    solver: casadi-map      # casadi-map | casadi-call | casadi-compiled
    baselines: [numpy]

Options (``options:``): none; any field there is an error.

Arrays: ``configurations``, ``tip_dq``, ``tip_position``, ``section_dq``,
``backbone`` and, for a trajectory, ``t``.

With ``optikin solve NAME --jobs N`` (or ``--dask``) the configurations are evaluated in pieces on worker
processes, with the single-process run's per-sample arrays (:mod:`optikin.problems.fk.chunks`).
"""

from __future__ import annotations

import optikin.data.configurations  # noqa: F401 - registers the sources of data family "configurations"
from optikin.problems import Baseline, ProblemContext, ProblemKind, baselines_of, figures_of, preset_row, register_kind
from optikin.problems.fk.chunks import run_chunked
from optikin.problems.fk.options import FkOptions
from optikin.problems.fk.report import report
from optikin.problems.fk.run import FkOutcome, numpy_tip_dq, run
from optikin.results import Result

__all__ = ["FkOptions", "FkOutcome", "numpy_tip_dq", "solve"]


def solve(ctx: ProblemContext) -> Result:
    """Run an ``fk`` problem and report it."""
    return report(ctx, run(ctx))


register_kind(
    ProblemKind(
        name="fk",
        summary="forward kinematics over a configuration sweep or trajectory",
        run=solve,
        backend_families=("evaluation",),
        default_solver="casadi-map",
        baselines=baselines_of(Baseline("numpy", "numpy")),
        preset_baseline=preset_row,
        options=FkOptions,
        data_family="configurations",
        figures=figures_of("optikin.problems.fk.figures"),
        run_chunked=run_chunked,
    )
)
