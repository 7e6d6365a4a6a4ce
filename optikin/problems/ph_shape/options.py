"""Options of kind ``ph_shape``: those every PH kind takes, and the rod of the ``cosserat-wrench`` baseline."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from optikin.data.cosserat_markers import CosseratMarkerParams
from optikin.options import Options
from optikin.problems.ph_shared import PHOptions

_SOURCE = CosseratMarkerParams.model_fields
"""The ``cosserat`` marker source's parameters: the baseline's rod defaults to that arm's stiffness and mass."""


class CosseratWrenchOptions(Options):
    """The rod of the ``cosserat-wrench`` baseline (:mod:`optikin.problems.ph_shape.wrench`).

    One uniform Cosserat rod, unactuated, clamped at the measured base pose; the
    defaults are the stiffnesses, mass per length and gravity of the ``cosserat``
    marker source (:class:`~optikin.data.cosserat_markers.CosseratMarkerParams`).
    """

    EA: float = Field(_SOURCE["axial_stiffness"].default, gt=0, description="axial stiffness E A [N]")
    EI: float = Field(_SOURCE["bending_stiffness"].default, gt=0, description="bending stiffness E I [N m^2]")
    GA: float = Field(_SOURCE["shear_stiffness"].default, gt=0, description="shear stiffness G A [N]")
    GJ: float = Field(_SOURCE["torsion_stiffness"].default, gt=0, description="torsion stiffness G J [N m^2]")
    mass_per_length: float = Field(
        _SOURCE["mass_per_length"].default, ge=0, description="mass per reference length [kg/m]"
    )
    gravity: tuple[float, float, float] = Field(
        _SOURCE["gravity"].default, description="gravitational acceleration in the world frame [m/s^2]"
    )
    steps: int = Field(48, ge=1, le=2000, strict=True, description="RK4 steps along the rod [-]")


class PHShapeOptions(PHOptions):
    """Options of ``ph_shape`` (:class:`~optikin.problems.ph_shared.PHOptions`, ``tip``, ``c1_joint`` and
    ``cosserat_wrench``)."""

    tip: Literal["recorded", "circle"] = Field(
        "recorded",
        description="the tip orientation: recorded (the data's), or circle: the tangent of the circle through "
        "the last three points of (base, markers, tip), each marker also scored on the backbone whose tangent "
        "did not use it (optikin.data.markers.estimated_tip)",
    )

    c1_joint: bool = Field(
        False,
        strict=True,
        description="also rebuild each backbone as two PH quintics joined at the end of section 1 with C1 "
        "continuity (seed 002 eqs. 15-18), the joint pose from the tube markers there (given speeds)",
    )
    cosserat_wrench: CosseratWrenchOptions = Field(
        default_factory=CosseratWrenchOptions, description="the rod of baseline cosserat-wrench"
    )
