"""Problem kind ``actuation``: marker positions from motor inputs, by physics and by learned regressors.

From a recording of steady-state postures (the markers of the three end disks of a tendon-driven trunk and its
six motor inputs) every method learns the map inputs -> markers on each training fold and predicts the held-out
fold:

``physics`` (the kind's own)
    a Kirchhoff rod per section driven by its tendons, with gravity on the rod and a tip payload
    (:mod:`optikin.calibration.actuation`); the parameters a lab calibrates (bending stiffness per section, an
    offset per motor, the payload mass, the section lengths, the base pose, the markers' offsets from their
    disks) fitted on the training postures only;
baselines ``knn``, ``mlp``, ``gp``
    scikit-learn regressors (k nearest neighbours, a multilayer perceptron, a Gaussian process) of standardised
    inputs to standardised marker coordinates, fixed settings, seeded.

A learning curve: every method at each share of ``options.fractions`` of every training fold (the same, nested,
postures for all), scored on the held-out fold over every posture. The motor inputs are read as commanded
tensions [N] (a per-motor offset fitted); displacement-commanded motors are not modelled.

Problem file::

    kind: actuation
    data: {source: tendon_lab, seed: 3, samples: 729}
    baselines: [knn, mlp, gp]
    options: {postures: 200, folds: 4, fractions: [0.1, 0.25, 0.5, 1.0]}

Options: :class:`~optikin.problems.actuation.options.ActuationOptions`. The Result is described in
:mod:`optikin.problems.actuation.report`, the figures in :mod:`optikin.problems.actuation.figures`.
"""

from __future__ import annotations

import optikin.data.readers  # noqa: F401 - registers the lab-format sources of data family "recordings"
import optikin.simulate.tendon_lab  # noqa: F401 - registers source "tendon_lab" of data family "recordings"
from optikin.calibration.synthetic import FAMILY
from optikin.problems import ProblemContext, ProblemKind, baselines_of, figures_of, register_kind
from optikin.problems.actuation.options import ActuationOptions
from optikin.problems.actuation.report import result_of
from optikin.problems.actuation.run import baselines, solve
from optikin.results import Result

__all__ = ["ActuationOptions", "run"]


def run(ctx: ProblemContext) -> Result:
    """Train every method on every share of every training fold and score it held out."""
    return result_of(ctx, solve(ctx))


register_kind(
    ProblemKind(
        name="actuation",
        summary="marker positions from motor inputs: a fitted tendon-rod physics model against learned regressors",
        run=run,
        backend_families=(),
        default_solver=None,
        baselines=baselines_of(*baselines()),
        options=ActuationOptions,
        data_family=FAMILY,
        figures=figures_of("optikin.problems.actuation.figures"),
        arm_optional=True,
    )
)
