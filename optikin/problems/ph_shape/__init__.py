"""Problem kind ``ph_shape``: CBHA backbones rebuilt from end poses, checked against markers (Singh et al. 2018, V.A).

The seed (section V.A) builds one PH quintic per posture from the tracked start and
end poses and measures how far the three intermediate markers lie from it: 1.6,
4.2 and 3.8 mm for one posture, 1.2, 3.7 and 3.1 mm on average over a
100-posture trajectory. Here each posture's backbone is the minimum-energy PH
quintic of its end poses (:mod:`optikin.problems.ph_shared` for the options and
the methods), and the distance of every intermediate marker to it is computed
(closest point, Newton-refined). On a synthetic recording the model's own
backbone (the vertebra centres) is also compared with the PH curve, noise-free:
the honest measure of how well a PH quintic can represent the vertebra model.

On a ``cosserat`` recording (:mod:`optikin.data.cosserat_markers`: a Cosserat-rod
CBHA none of the methods models, five markers on each tube at its offset) the
backbone markers are the centroids of the three tubes' markers at each
intermediate station, so they are compared with the backbone like with like; the
truth backbone (every solver node) is compared with the PH backbone, and every
tube marker with the PH tube curve at its offset (carried by the
rotation-minimising frame from the base x axis).

Problem file::

    kind: ph_shape
    arm: {type: cbha}
    data:
      source: synthetic     # synthetic | cosserat | csv | disks (family markers, optikin.data.markers)
      seed: 2018
      samples: 100
      params: {noise: 0.0003, rate: 240.0, stride: 24}
    solver: ph-newton       # any ph preset
    baselines: [ph-ipopt, ph-ipopt-cold, ph-grid, cosserat-wrench, cc-arc, cc-two-arcs]

Options: :class:`~optikin.problems.ph_shared.PHOptions` (``twist_weight``, ``nodes``,
``free_speeds``, ``length``, ``fixed_base``), ``tip``, ``c1_joint`` and ``cosserat_wrench`` (the rod of
that baseline: ``EA``, ``EI``, ``GA``, ``GJ``, ``mass_per_length``, ``gravity``, ``steps``;
defaults those of the ``cosserat`` source).

A recording with positions only (a trunk's disks: no tip orientation) gets its tip tangent from the
points alone, the tangent at the tip of the circle through the last three points of (base, markers,
tip) (:func:`optikin.data.markers.estimated_tip`): source ``disks`` (a CSV of disk centres, the base
pose from the calibrated arm file the problem includes, or given), or ``tip: circle`` on any
recording. Those points are used by the tip estimate, so each intermediate marker is also scored on
the solver's backbone whose tip tangent did not use it (the circle through the chain without that
marker): the ``held-out`` metrics (median, 95th percentile and largest distance per marker and over all
of them) and the solver row's ``held-out m<k> median`` columns. The seed's own figures (1.2, 3.7 and
3.1 mm) are printed only for a problem whose arm is the seed's CBHA.

With ``c1_joint: true`` (:mod:`optikin.problems.ph_shape.c1`, seed 002 Fig. 2, eqs. 15-18)
every method also rebuilds each backbone as two PH quintics, section 1 and section 2,
joined at the end of section 1 with C1 continuity, the joint pose the rigid body of the
three tube markers there (a ``cosserat`` recording whose stations include 1.0); its marker
and truth-backbone distances and one comparison row per method and section are reported
next to the single curve's.

Baseline ``cosserat-wrench`` (:mod:`optikin.problems.ph_shape.wrench`): the backbone
is the Cosserat rod clamped at the measured base pose whose fitted tip wrench brings
its tip to the measured tip pose, at the PH methods' backbone length.

Baseline ``cc-arc`` (:mod:`optikin.problems.ph_shape.cc`): the backbone is the
constant-curvature arc tangent to the measured base pose through the measured tip
point (closed form), measured against the markers and the truth like the PH curves;
``cc-two-arcs`` the two-section constant-curvature backbone, section 1 through the
marker at the end of section 1, section 2 from there, C1-joined, through the tip point.

Per-sample status: the solver's (``ok``, ``not_converged``, ``failed``). The
comparison has one row per method (solver and ``ph`` baselines): energy gap to
the best energy found for the sample, time per sample, mean marker distance; the
``cosserat-wrench`` row has marker (and truth-backbone) distances, time per sample
and its failed fits instead of energies; the ``cc-arc`` row the same distances, time per sample, its
tip-tangent error and arc length against the PH length (``cc-two-arcs``: its marker distance
off the joint marker, its own). Every row with a truth backbone reports the
mean and largest distance of its nodes to the method's curve.
Figures: shapes against markers in 3-D, distances per sample, time per sample.
"""

from __future__ import annotations

import optikin.data.markers  # noqa: F401 - registers the sources of data family "markers"
import optikin.data.cosserat_markers  # noqa: F401 - registers source "cosserat" of data family "markers"
from optikin.problems import Baseline, ProblemContext, ProblemKind, baselines_of, figures_of, preset_row, register_kind
from optikin.problems.ph_shape import cc
from optikin.problems.ph_shape.options import PHShapeOptions
from optikin.problems.ph_shape.report import report
from optikin.problems.ph_shape.run import ShapeOutcome, run
from optikin.problems.ph_shape.wrench import NAME
from optikin.results import Result

__all__ = ["PHShapeOptions", "ShapeOutcome", "solve"]


def solve(ctx: ProblemContext) -> Result:
    """Run a ``ph_shape`` problem and report it."""
    return report(ctx, run(ctx))


register_kind(
    ProblemKind(
        name="ph_shape",
        summary="CBHA backbones from end poses as minimum-energy PH quintics, against markers (seed 002 V.A)",
        run=solve,
        backend_families=("ph",),
        default_solver="ph-newton",
        baselines=baselines_of(*(Baseline(name, name) for name in (NAME, cc.NAME, cc.TWO_ARCS))),
        preset_baseline=preset_row,
        options=PHShapeOptions,
        data_family="markers",
        figures=figures_of("optikin.problems.ph_shape.figures"),
        headline=(
            "mean marker distance [mm]",
            "held-out marker distance median [mm]",
            "truth backbone: mean of the largest node distance [mm]",
            "median time per sample [us]",
        ),
        arm_optional=True,
    )
)
