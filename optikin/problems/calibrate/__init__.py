"""Problem kind ``calibrate``: the geometry of an arm from measured postures, by robust nonlinear least squares.

From ``N`` measured postures (marker positions at the section end disks of a
constant-curvature arm, NaN where a marker was not seen) it estimates, over all
postures at once, the section lengths (or, for an extensible arm, one length per
section and posture), the base pose in the recording frame and, optionally, one
offset per marker from its disk's centre (:mod:`optikin.calibration`). The
solver is Levenberg-Marquardt on the Schur complement of the shared parameters
with exact CasADi Jacobians and a robust loss (:mod:`optikin.calibration.solver`);
postures far from the model are rejected with a reason (a label swap is recognised)
and the fit repeated without them. The base is a tracked rigid body, a mount plane and exit
direction, a pose, or estimated from several starts (the best by held-out error); the section
lengths stay within the arm's ``length_range`` of the nominal. The report gives first the verdict,
``ok`` or ``not_identifiable`` (:mod:`optikin.calibration.identifiability`: the weakly determined
parameters and the options that would determine them; rc 1), then the held-out largest-marker error
per posture over every posture (least squares; the outlier rule applied inside each training fold
and reported apart), the estimates with standard deviations, the fold of every posture, and the
calibrated ``arm:`` section (:mod:`optikin.calibration.export`), written to ``options.arm_file`` when
given.

Problem file
------------
``arm``
    a ``constant_curvature`` arm: its ``section_lengths`` are the start (or, with
    ``lengths: fixed``, the values held).
``data``
    a source of family ``recordings`` (:class:`~optikin.data.recording.Recording`):
    ``synthetic`` (:mod:`optikin.calibration.synthetic`: a CC arm of known geometry
    recorded with noise and label swaps), ``cosserat`` (:mod:`optikin.calibration.cosserat_source`:
    the Cosserat-rod CBHA with markers on its tubes), ``tendon_lab`` (:mod:`optikin.simulate.tendon_lab`:
    a hanging tendon-driven Cosserat trunk with what real recordings have and the models do not) or a
    reader of lab files (:mod:`optikin.data.readers`: ``motive``, ``c3d``, ``rosbag``, ``csv``). The points
    fitted are the markers named in ``options.markers`` (markers or rigid bodies, each with the section
    whose end disk carries it), else the recording's markers, else its rigid bodies, when there is one per
    section.
``options``
    :class:`~optikin.problems.calibrate.options.CalibrateOptions`.
"""

from __future__ import annotations

import optikin.calibration.cosserat_source  # noqa: F401 - registers source "cosserat" of data family "recordings"
import optikin.calibration.synthetic  # noqa: F401 - registers source "synthetic" of data family "recordings"
import optikin.data.readers  # noqa: F401 - registers the lab-format sources of data family "recordings"
import optikin.simulate.tendon_lab  # noqa: F401 - registers source "tendon_lab" of data family "recordings"
from optikin.calibration.synthetic import FAMILY
from optikin.problems import ProblemContext, ProblemKind, figures_of, register_kind
from optikin.problems.calibrate.options import CalibrateOptions
from optikin.problems.calibrate.report import result_of
from optikin.problems.calibrate.run import solve
from optikin.results import Result

__all__ = ["CalibrateOptions", "run"]


def run(ctx: ProblemContext) -> Result:
    """Calibrate the arm on the recording and report the estimates, the errors and the held-out test."""
    return result_of(ctx, solve(ctx))


register_kind(
    ProblemKind(
        name="calibrate",
        summary="arm geometry (section lengths, base pose, marker offsets) from measured postures, robust fit",
        run=run,
        backend_families=(),
        default_solver=None,
        options=CalibrateOptions,
        data_family=FAMILY,
        figures=figures_of("optikin.problems.calibrate.figures"),
    )
)
