"""Options of kind ``ph_ik``: those of every PH kind, the frame and the tube radii."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, PositiveFloat, StrictBool

from optikin.problems.ph_shared import PHOptions


class PHIkOptions(PHOptions):
    """Options of ``ph_ik`` (besides :class:`~optikin.problems.ph_shared.PHOptions`)."""

    frame: Literal["rmf", "euler_rodrigues"] = Field(
        "rmf", description="the frame that carries the tubes: rotation-minimising or Euler-Rodrigues"
    )
    tube_radius: tuple[PositiveFloat, PositiveFloat] | None = Field(
        None,
        description="[base, tip] offset radius of the tubes [m]; default: the CBHA's r_max, r_min "
        "(required for another arm)",
    )
    coverage: StrictBool = Field(
        False,
        description="redraw the hybrid networks' training database to report how far the recording's tips lie "
        "from its training tips (fairness manifest; 30-50 s per store, then cached)",
    )
