"""Problem kind ``ph_ik``: CBHA tube lengths from the PH backbone of the end poses (Singh et al. 2018, V.B).

The seed (section V.B) computes the lengths ``L1, L2, L3`` of the CBHA's three
tubes from the PH backbone of each posture and compares them with the wire
potentiometers: Table II gives the min / max / mean absolute error per tube along
a trajectory (PH: 2.8, 2.2 and 1.0 mm on average), Table III the time per sample
(PH 0.27 ms, Newton-Raphson 233 ms, hybrid 12 ms). Here the backbone is the
minimum-energy PH quintic of the end poses (:mod:`optikin.problems.ph_shared`),
the tubes are offset curves carried by a rotation-minimising frame
(:mod:`optikin.curves.tubes`), and the reference lengths are the recording's
(``L1, L2, L3``: the vertebra model's leg sums for a synthetic recording).

The time per sample of a method is its shape solve plus one call of the tube-length
Function (CasADi, compiled when the method's preset compiles), as the seed's PH row.

Problem file: as ``ph_shape`` (data family ``markers``: ``synthetic`` or ``csv``, whose
file needs the columns ``L1, L2, L3``), ``kind: ph_ik``.

Options: :class:`~optikin.problems.ph_shared.PHOptions`, and (:class:`PHIkOptions`)::

    frame: rmf            # rmf | euler_rodrigues: the frame that carries the tubes
    tube_radius: null     # [base, tip] offset radius in metres; default: the CBHA's r_max, r_min

Baselines: any ``ph`` preset, and the comparators of Tables II-III
(:mod:`optikin.baselines.ph_comparators`): ``newton-raphson`` (Newton on the section
end positions and the elongation distribution of :mod:`optikin.ik.cbha`), ``newton-raphson-pose`` (the
same on the tip pose, the PH rows' data), ``hybrid`` and ``hybrid-coupled`` (neural
networks from the tip position). A comparator's postures that are not ``ok`` are
counted, never dropped.

The other frame's tube lengths (same curves) are reported as an extra row, to show
what the choice of frame is worth.
"""

from __future__ import annotations

import optikin.data.markers  # noqa: F401 - registers the sources of data family "markers"
import optikin.data.cosserat_markers  # noqa: F401 - registers source "cosserat" of data family "markers"
from optikin.baselines.ph_comparators import COMPARATORS
from optikin.problems import Baseline, ProblemContext, ProblemKind, baselines_of, figures_of, preset_row, register_kind
from optikin.problems.ph_ik.options import PHIkOptions
from optikin.problems.ph_ik.report import report
from optikin.problems.ph_ik.run import IkOutcome, run, tube_length_function
from optikin.results import Result

__all__ = ["IkOutcome", "PHIkOptions", "solve", "tube_length_function"]


def solve(ctx: ProblemContext) -> Result:
    """Run a ``ph_ik`` problem and report it."""
    return report(ctx, run(ctx))


register_kind(
    ProblemKind(
        name="ph_ik",
        summary="CBHA tube lengths from the PH backbone of the end poses, against the reference (seed 002 V.B)",
        run=solve,
        backend_families=("ph",),
        default_solver="ph-newton",
        baselines=baselines_of(*(Baseline(name, name) for name in COMPARATORS)),
        preset_baseline=preset_row,
        options=PHIkOptions,
        data_family="markers",
        figures=figures_of("optikin.problems.ph_ik.figures"),
    )
)
