"""Pneumatic chambers along a rod: pressure times area as an axial force at an offset.

A chamber (a tube of the CBHA: three per section at 120 degrees) of cross-section
area ``a`` runs along its segment at the offset ``r`` from the backbone, closed by the
segment's two disks. Its gauge pressure ``P`` pushes the end disk distally and the
start disk proximally with ``P a``; here that force acts along the backbone tangent
``d3`` at the chamber's offset. Inside the segment the section then carries, with
the rod's own elastic wrench ``n, m``, the chamber's axial force:

    N = n - P a d3,    M = m + (R r) x (-P a d3),

and ``N, M`` obey the rod equations with the external loads only: a chamber is a
"pushing tendon" of tension ``-P a`` whose direction is the backbone's. The
pressure thus stretches the rod (``E A``) and bends it away from the chamber: a
straight rod with one pressurised chamber, no other load, takes the curvature
``P a r / (E I)``; equal pressures in three chambers at 120 degrees give a pure
extension ``3 P a / (E A)``.

Assumptions: the chamber wall has no stiffness of its own (it is part of the rod's
``E A``, ``E I``), its area does not change with pressure or strain, the chamber axis
stays parallel to the backbone tangent (exact without shear), and the pressure is
uniform along the chamber.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from pydantic import Field

from optikin.options import Options

CBHA_ANGLES = (0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0)
"""The three tubes of a CBHA section, 120 degrees apart [rad]."""


class Chamber(Options):
    """A pressurised chamber parallel to the backbone at ``offset (cos angle, sin angle, 0)`` (material frame)."""

    offset: float = Field(ge=0, description="distance of the chamber axis from the backbone [m], inside the section")
    angle: float = Field(0.0, description="angle of the chamber in the cross-section, from d1 [rad]")
    area: float = Field(gt=0, description="pressurised cross-section area a of the chamber [m^2]")


def chamber_offset(chamber: Chamber) -> ca.DM:
    """The chamber axis in the material frame, ``3 x 1`` [m]."""
    return chamber.offset * ca.DM([np.cos(chamber.angle), np.sin(chamber.angle), 0.0])


def cbha_chambers(offset: float, area: float, phase: float = 0.0) -> tuple[Chamber, Chamber, Chamber]:
    """Three chambers 120 degrees apart, as in a section of the CBHA.

    Parameters
    ----------
    offset : float
        Distance of each chamber from the backbone [m].
    area : float
        Pressurised area of each [m^2].
    phase : float
        Angle of the first from ``d1`` [rad].

    Returns
    -------
    tuple of Chamber
    """
    return tuple(Chamber(offset=offset, angle=phase + a, area=area) for a in CBHA_ANGLES)  # type: ignore[return-value]
