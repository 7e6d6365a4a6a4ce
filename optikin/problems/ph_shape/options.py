"""Options of kind ``ph_shape``: those every PH kind takes."""

from __future__ import annotations

from optikin.problems.ph_shared import PHOptions


class PHShapeOptions(PHOptions):
    """Options of ``ph_shape`` (:class:`~optikin.problems.ph_shared.PHOptions`)."""
