"""Problem kind ``ph_chain``: two CBHAs holding a rope, each link a PH quintic (Singh et al. 2018, IV.B, V.C).

The seed closes a kinematic chain ABCD: CBHA 1 from its base A to its tip B, a rope
hanging under its own weight from B to C, CBHA 2 from its tip C to its base D.
Each link is rebuilt by a PH quintic from the positions and orientations at its two
ends (the seed's Table I), with C0 joints (eqs. 19-22), and compared with the
tracked markers: 2.8, 8 and 3.1 mm average error for CBHA 1, the rope and CBHA 2.

Here (:func:`optikin.data.markers.synthetic_rope_chain`) both arms are the CBHA
vertebra model driven by their tubes, upright, ``base_distance`` apart and facing
each other; the rope is the exact inextensible catenary of ``rope_length`` between
the true tips; markers (0.3 mm noise) sit on each arm (end rigid bodies and three
intermediate markers) and on the rope (three intermediate markers, and one
``end_offset`` from each end, which gives the rope's end directions). The arm links
take the options of (:class:`~optikin.problems.ph_shared.PHOptions`); the rope's length is known,
so by default its end speeds are free and its arc length is held to it
(``rope_free_speeds``).

On source ``cosserat`` (:mod:`optikin.data.cosserat_rope`) both arms are the
real-size pneumatic Cosserat CBHA of :mod:`optikin.data.cosserat_markers` under
gravity, recorded like it (rigid bodies, five markers on each tube, their centroids as
the backbone markers), and the rope's weight loads their tips (the catenary's end
tensions, made consistent with the tips by fixed-point iteration); the arms' truth is
the Cosserat backbone at every solver node. Params: those of the ``cosserat`` marker
source, ``rope_length`` (0.8 m), ``base_distance`` (0.4 m), ``rope_mass_per_length``
(0.05 kg/m), ``end_offset``, ``rope_markers``, ``coupling_tolerance``, ``coupling_iterations``.

Data (family ``rope_chains``, ``data.source: synthetic``,
:class:`~optikin.data.markers.RopeChainParams`), params: ``rope_length`` (0.65 m), ``base_distance``
(0.25 m), ``end_offset`` (0.02 m), ``rope_markers`` (fractions of the rope length,
``[0.25, 0.5, 0.75]``), ``noise``, ``stride``, ``frequency``, ``amplitude`` (as the
``synthetic`` marker source). Options (:class:`PHChainOptions`): those of
:class:`~optikin.problems.ph_shared.PHOptions`, and ``rope_free_speeds`` (true).

Per-sample status: ``ok`` when the solver solved all three links. Per link and
method: energy gap, time per sample; per link: marker distances and the largest
distance of the ground truth (vertebra centres, dense catenary) to the PH curve.
"""

from __future__ import annotations

import optikin.data.markers  # noqa: F401 - registers source "synthetic" of data family "rope_chains"
import optikin.data.cosserat_rope  # noqa: F401 - registers source "cosserat" of data family "rope_chains"
from optikin.problems import ProblemContext, ProblemKind, figures_of, preset_row, register_kind
from optikin.problems.ph_chain.options import PHChainOptions
from optikin.problems.ph_chain.report import report
from optikin.problems.ph_chain.run import LINKS, ChainOutcome, run
from optikin.results import Result

__all__ = ["LINKS", "ChainOutcome", "PHChainOptions", "solve"]


def solve(ctx: ProblemContext) -> Result:
    """Run a ``ph_chain`` problem and report it."""
    return report(ctx, run(ctx))


register_kind(
    ProblemKind(
        name="ph_chain",
        summary="two CBHAs and a hanging rope, each link a PH quintic from its end poses (seed 002 IV.B, V.C)",
        run=solve,
        backend_families=("ph",),
        default_solver="ph-newton",
        preset_baseline=preset_row,
        options=PHChainOptions,
        data_family="rope_chains",
        figures=figures_of("optikin.problems.ph_chain.figures"),
        arm_optional=True,
    )
)
