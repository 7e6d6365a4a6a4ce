"""Parameters of an elastic rod and the static Cosserat-rod equations it obeys.

The rod is parametrised by the arc length ``s`` of its straight, unstressed
reference configuration, ``0 <= s <= L``. Its state at ``s`` is

* the position ``p`` of the centre line (3) in the global frame [m];
* the orientation of the cross-section as a unit quaternion ``q`` (4), Hamilton
  ``(w, x, y, z)`` as in :mod:`optikin.algebra`, mapping the material frame
  ``(d1, d2, d3)`` (``d3`` the backbone tangent of the unstressed rod) to the global
  frame: ``R(q) = [d1 d2 d3]``;
* the internal force ``n`` and moment ``m`` (3 each) in the global frame: what the
  material at ``s+`` exerts on the material at ``s-`` [N, N m].

A quaternion rather than a rotation matrix: it is 4 numbers instead of 9, so the
shooting and collocation problems are smaller; the only drift an integrator can
cause is in its norm, which one division removes after each step (a matrix would
need an orthogonalisation); and it is the layout optikin's algebra and results
already use.

The equations are those of the static Cosserat rod (Antman, *Nonlinear Problems of
Elasticity*, ch. 8; in the notation of Rucker & Webster, IEEE T-RO 27(6), 2011, eqs. 1-7):

    p' = R v,     R' = R [u]x   (q' = q (0, u) / 2),
    n' + f = 0,   m' + p' x n + l = 0,
    m = R K_bt (u - u*),   n = R K_se (v - v*),

with ``K_bt = diag(E I, E I, G J)``, ``K_se = diag(k G A, k G A, E A)``, ``v* = (0, 0, 1)``
and ``u*`` the intrinsic curvature (zero by default). ``k`` is the shear coefficient
(Timoshenko's; 1 by default; PyElastica uses ``27/28``, its ``alpha_c`` for a solid circular
section, so ``shear_coefficient=27/28`` matches its rods). ``f`` and ``l`` are the
distributed force and moment per unit reference length: the weight ``rho A g`` plus an
optional uniform force.

Gravity is explicit: ``gravity`` defaults to zero, so a rod has no weight unless it is
given (a ``density`` alone adds none: it is the mass of the dynamics and of a weight asked
for elsewhere, e.g. ``Loads(gravity=...)``). In the Kirchhoff model the rod is inextensible and
unshearable, ``v = v*``, and ``n`` is the constraint force (it still obeys ``n' + f = 0``).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from optikin.options import Options

Vector3 = tuple[float, float, float]

E3 = np.array([0.0, 0.0, 1.0])
"""``v* = d3``: the unstressed rod is straight, unstretched and unsheared."""


class Rod(Options):
    """An elastic rod with a uniform cross-section (one segment of an arm).

    The cross-section is either solid circular (``radius``) or given by its
    area and second moments (``area``, ``second_moment``, ``polar_moment`` and
    ``outer_radius``, the radius actuators must stay inside). The shear modulus is
    required, directly or through Poisson's ratio, ``G = E / (2 (1 + nu))``: there is
    no silent default (``G = E/3`` holds only for an incompressible material, ``nu = 1/2``).

    Raises
    ------
    pydantic.ValidationError
        Naming the field, for a non-positive length, modulus, radius, area or moment,
        a negative density, a Poisson ratio outside ``(-1, 1/2]``, a shear coefficient outside ``(0, 1]``,
        neither or both of
        ``shear_modulus`` and ``poisson_ratio``, or an incomplete cross-section.
    """

    length: float = Field(gt=0, description="length L of the segment [m]")
    radius: float | None = Field(None, gt=0, description="radius of a solid circular cross-section [m]")
    area: float | None = Field(None, gt=0, description="cross-section area A [m^2] (instead of radius)")
    second_moment: float | None = Field(None, gt=0, description="second moment of area I [m^4] (instead of radius)")
    polar_moment: float | None = Field(None, gt=0, description="torsion constant J [m^4] (instead of radius)")
    outer_radius: float | None = Field(None, gt=0, description="outer radius [m] (instead of radius)")
    youngs_modulus: float = Field(gt=0, description="Young's modulus E [Pa]")
    shear_modulus: float | None = Field(None, gt=0, description="shear modulus G [Pa] (or give poisson_ratio)")
    poisson_ratio: float | None = Field(None, gt=-1, le=0.5, description="nu, for G = E / (2 (1 + nu)) [-]")
    density: float = Field(0.0, ge=0, description="mass density rho [kg/m^3]; alone it adds no weight (gravity)")
    gravity: Vector3 = Field(
        (0.0, 0.0, 0.0),
        description="gravitational acceleration g [m/s^2], global frame; default none: give (0, 0, -9.81) for "
        "the weight of a rod clamped pointing up",
    )
    shear_coefficient: float = Field(
        1.0,
        gt=0,
        le=1,
        description="k of the shear stiffness k G A [-]; 1 by default, 27/28 as PyElastica (its alpha_c)",
    )
    model: Literal["cosserat", "kirchhoff"] = Field(
        "cosserat", description="'cosserat' (shear-extensible) or 'kirchhoff' (inextensible, unshearable)"
    )
    intrinsic_curvature: Vector3 = Field((0.0, 0.0, 0.0), description="u*, in the material frame [1/m]")

    @model_validator(mode="after")
    def _complete(self) -> Rod:
        given = {k: getattr(self, k) is not None for k in ("area", "second_moment", "polar_moment", "outer_radius")}
        if self.radius is not None and any(given.values()):
            raise ValueError("radius: give either radius or area/second_moment/polar_moment/outer_radius, not both")
        if self.radius is None and not all(given.values()):
            missing = ", ".join(k for k, v in given.items() if not v)
            raise ValueError(
                f"radius: give radius, or all of area, second_moment, polar_moment, outer_radius ({missing})"
            )
        if (self.shear_modulus is None) == (self.poisson_ratio is None):
            raise ValueError("shear_modulus: give exactly one of shear_modulus and poisson_ratio")
        return self

    # ----------------------------------------------------------------- derived section properties

    @property
    def A(self) -> float:
        """Cross-section area [m^2]."""
        return float(np.pi * self.radius**2) if self.radius is not None else float(self.area)  # type: ignore[arg-type]

    @property
    def I(self) -> float:  # noqa: E743
        """Second moment of area about either principal axis [m^4]."""
        if self.radius is not None:
            return float(np.pi * self.radius**4 / 4)
        return float(self.second_moment)  # type: ignore[arg-type]

    @property
    def J(self) -> float:
        """Torsion constant [m^4] (the polar moment ``2 I`` for a solid circle)."""
        return 2.0 * self.I if self.radius is not None else float(self.polar_moment)  # type: ignore[arg-type]

    @property
    def section_radius(self) -> float:
        """The radius actuators must stay strictly inside [m]."""
        return float(self.radius if self.radius is not None else self.outer_radius)  # type: ignore[arg-type]

    @property
    def G(self) -> float:
        """Shear modulus [Pa]: given, or ``E / (2 (1 + nu))``."""
        if self.shear_modulus is not None:
            return float(self.shear_modulus)
        return float(self.youngs_modulus / (2.0 * (1.0 + float(self.poisson_ratio))))  # type: ignore[arg-type]

    @property
    def EI(self) -> float:
        """Bending stiffness [N m^2]."""
        return self.youngs_modulus * self.I

    @property
    def K_bt(self) -> np.ndarray:
        """Bending and torsion stiffness ``diag(E I, E I, G J)`` [N m^2], (3,)."""
        return np.array([self.EI, self.EI, self.G * self.J])

    @property
    def K_se(self) -> np.ndarray:
        """Shear and extension stiffness ``diag(k G A, k G A, E A)`` [N], (3,)."""
        shear = self.shear_coefficient * self.G * self.A
        return np.array([shear, shear, self.youngs_modulus * self.A])

    @property
    def weight_per_length(self) -> np.ndarray:
        """``rho A g`` [N/m], (3,), global frame."""
        return self.density * self.A * np.asarray(self.gravity, dtype=float)
