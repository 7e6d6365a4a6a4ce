"""Options of kind ``ph_chain``: those of every PH kind (the arm links) and the rope's end speeds."""

from __future__ import annotations

from pydantic import Field

from optikin.problems.ph_shared import PHOptions


class PHChainOptions(PHOptions):
    """Options of ``ph_chain`` (besides :class:`~optikin.problems.ph_shared.PHOptions`, which set the arm links)."""

    rope_free_speeds: bool = Field(
        True, strict=True, description="rope: end speeds free and arc length held to the rope length"
    )
