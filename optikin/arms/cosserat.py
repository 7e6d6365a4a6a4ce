"""A continuum arm as a static Cosserat rod (:mod:`optikin.physics`), built from a problem file's ``arm.params``.

``arm: {type: cosserat, params: {...}}`` describes the rod (one material for the
whole arm), its segments (lengths and sections), its tendons (offset, angle,
routing and the segment whose end disk each ends at) and its pneumatic chambers
(offset, angle, area and the segment they lie in), validated by
:class:`CosseratParams`. :class:`CosseratArm` builds the
:class:`~optikin.physics.RodArm` from them.

Its "configuration" is the actuation, one value per actuator in the order of
:attr:`optikin.physics.RodArm.actuator_names` (per segment its tendons, then its
chambers): tendon tensions [N] within ``[0, max_tension]`` and chamber gauge
pressures [Pa] within ``pressure_range``. The shape is not a function of the
actuation alone but the equilibrium of every load (gravity, payload, tip
wrench), solved by the ``statics`` kind (:mod:`optikin.problems.statics`); the
kinematic Functions of :class:`~optikin.arms.base.ArmModel` (``fk_dq``, ...) are
therefore not offered and raise a :class:`~optikin.errors.SolverError` naming
the kind to use.

Defaults and their sources
--------------------------
``poisson_ratio = 0.5``
    Incompressible material (``G = E / 3``): the soft-robot convention; give the
    metal's value for a metal backbone (nitinol about 0.33).
``density = 0``, ``gravity = (0, 0, -9.81)``
    A massless rod unless a density is given; gravity along ``-z`` of the base frame,
    i.e. the base clamped pointing up (standard gravity 9.81 m/s^2).
``model = "cosserat"``
    Shear and extension included (Rucker & Webster, IEEE T-RO 27(6), 2011, eqs. 1-7).
``max_tension = 10 N``
    The upper actuation bound of a tendon: the order of the tensions Rao et al.
    (Frontiers in Robotics and AI 7, 2021) apply to their two-segment prototype.
``pressure_range = [0, 1e5] Pa``
    0 to 1 bar gauge.
``steps_per_segment = 50``
    RK4 steps per segment of the shooting grid (and backbone points per segment).
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field, StrictFloat, StrictInt, ValidationError, field_validator

from optikin.arms.base import ArmModel
from optikin.checks import ParameterError
from optikin.errors import SolverError
from optikin.options import Options, error_message, field_path
from optikin.physics import Chamber, Rod, RodArm, Segment, Tendon

Vector3 = tuple[StrictFloat, StrictFloat, StrictFloat]


class SegmentParams(Options):
    """One segment: its length and cross-section."""

    length: StrictFloat = Field(gt=0, le=100.0, description="length of the segment [m], at most 100 m")
    radius: StrictFloat = Field(
        gt=0, le=1.0, description="radius of the solid circular backbone (A, I, J) [m], at most 1 m"
    )
    outer_radius: StrictFloat | None = Field(
        None,
        gt=0,
        le=1.0,
        description="radius actuators must stay inside (spacer disks of a tendon robot) [m]; default: radius",
    )

    @field_validator("outer_radius")
    @classmethod
    def _outside_the_backbone(cls, value: float | None, info: Any) -> float | None:
        radius = info.data.get("radius")
        if value is not None and radius is not None and value < radius:
            raise ValueError(f"{value} m is inside the backbone radius {radius} m")
        return value

    @property
    def section_radius(self) -> float:
        """The radius actuators must stay strictly inside [m]."""
        return float(self.radius if self.outer_radius is None else self.outer_radius)


class TendonParams(Options):
    """One tendon, from the base to the end disk of segment ``segment``."""

    offset: StrictFloat = Field(gt=0, description="distance from the backbone [m], inside every section it passes")
    angle: StrictFloat = Field(0.0, description="angle in the cross-section from d1 at s = 0 [rad]")
    helix_rate: StrictFloat = Field(0.0, description="turn of the routing per unit arc length [rad/m]; 0 = straight")
    segment: StrictInt = Field(0, ge=0, description="index of the segment at whose end disk the tendon ends")
    max_tension: StrictFloat = Field(10.0, gt=0, description="upper bound of the tension [N]")


class ChamberParams(Options):
    """One pressurised chamber along segment ``segment``."""

    offset: StrictFloat = Field(ge=0, description="distance of the chamber axis from the backbone [m]")
    angle: StrictFloat = Field(0.0, description="angle in the cross-section from d1 [rad]")
    area: StrictFloat = Field(gt=0, description="pressurised cross-section area [m^2]")
    segment: StrictInt = Field(0, ge=0, description="index of the segment the chamber lies in")
    pressure_range: tuple[StrictFloat, StrictFloat] = Field(
        (0.0, 1e5), description="[low, high] gauge pressure bounds [Pa], low <= high"
    )

    @field_validator("pressure_range")
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not value[0] <= value[1]:
            raise ValueError(f"expected [low, high] with low <= high, got {list(value)}")
        return value


class CosseratParams(Options):
    """``arm.params`` of ``arm.type: cosserat`` (module docstring for the defaults and their sources)."""

    youngs_modulus: StrictFloat = Field(gt=0, description="Young's modulus E [Pa]")
    poisson_ratio: StrictFloat = Field(0.5, gt=-1, le=0.5, description="nu, G = E / (2 (1 + nu)) [-]")
    density: StrictFloat = Field(0.0, ge=0, description="mass density of the rod [kg/m^3]")
    gravity: Vector3 = Field((0.0, 0.0, -9.81), description="gravitational acceleration, base frame [m/s^2]")
    model: Literal["cosserat", "kirchhoff"] = Field(
        "cosserat", description="'cosserat' (shear-extensible) or 'kirchhoff' (inextensible, unshearable)"
    )
    segments: tuple[SegmentParams, ...] = Field(min_length=1, description="the segments, base first")
    tendons: tuple[TendonParams, ...] = Field((), description="the tendons")
    chambers: tuple[ChamberParams, ...] = Field((), description="the pressurised chambers")
    steps_per_segment: StrictInt = Field(50, ge=1, le=10_000, description="RK4 steps (backbone points) per segment")


def _parameter_error(exc: ValidationError) -> ParameterError:
    """The first error of ``exc`` as a :class:`ParameterError` naming the dotted field."""
    errors = exc.errors()
    first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    return ParameterError(field_path(first["loc"]) or "params", error_message(first))


class CosseratArm(ArmModel):
    """A rod arm whose configuration is its actuation (tensions [N], then pressures [Pa], per segment).

    Parameters
    ----------
    youngs_modulus, poisson_ratio, density, gravity, model, segments, tendons, chambers, steps_per_segment
        The fields of :class:`CosseratParams` (SI units); ``segments``, ``tendons`` and
        ``chambers`` are lists of mappings of :class:`SegmentParams`, :class:`TendonParams`
        and :class:`ChamberParams`.
    name : str
        Identifier in reports.

    Attributes
    ----------
    params : CosseratParams
        The validated parameters.
    rod_arm : optikin.physics.RodArm
        The physical arm.

    Raises
    ------
    optikin.checks.ParameterError
        Naming the field (``segments.0.radius``, ``tendons.1.offset``, ``chambers.0.segment``):
        a value that is not a finite number, ``E <= 0``, a radius ``<= 0``, a tendon or chamber
        not strictly inside the section of every segment it runs through, a segment index
        past the last segment, a pressure range not ``low <= high``.
    """

    def __init__(
        self,
        youngs_modulus: float,
        segments: list[dict[str, Any]],
        poisson_ratio: float = 0.5,
        density: float = 0.0,
        gravity: tuple[float, float, float] = (0.0, 0.0, -9.81),
        model: str = "cosserat",
        tendons: list[dict[str, Any]] | None = None,
        chambers: list[dict[str, Any]] | None = None,
        steps_per_segment: int = 50,
        name: str = "cosserat",
    ) -> None:
        try:
            params = CosseratParams(
                youngs_modulus=youngs_modulus,
                poisson_ratio=poisson_ratio,
                density=density,
                gravity=gravity,
                model=model,
                segments=segments,
                tendons=tendons or (),
                chambers=chambers or (),
                steps_per_segment=steps_per_segment,
            )
        except ValidationError as exc:
            raise _parameter_error(exc) from None
        self.params = params
        self._check_actuators(params)
        rods = [
            Rod(
                length=s.length,
                area=np.pi * s.radius**2,
                second_moment=np.pi * s.radius**4 / 4,
                polar_moment=np.pi * s.radius**4 / 2,
                outer_radius=s.section_radius,
                youngs_modulus=params.youngs_modulus,
                poisson_ratio=params.poisson_ratio,
                density=params.density,
                gravity=params.gravity,
                model=params.model,
            )
            for s in params.segments
        ]
        names: list[str] = []
        lower: list[float] = []
        upper: list[float] = []
        built = []
        for k, rod in enumerate(rods):
            ends = [(i, t) for i, t in enumerate(params.tendons) if t.segment == k]
            inside = [(i, c) for i, c in enumerate(params.chambers) if c.segment == k]
            built.append(
                Segment(
                    rod=rod,
                    tendons=tuple(Tendon(offset=t.offset, angle=t.angle, helix_rate=t.helix_rate) for _, t in ends),
                    chambers=tuple(Chamber(offset=c.offset, angle=c.angle, area=c.area) for _, c in inside),
                )
            )
            for i, t in ends:
                names.append(f"tendons.{i}")
                lower.append(0.0)
                upper.append(t.max_tension)
            for i, c in inside:
                names.append(f"chambers.{i}")
                lower.append(c.pressure_range[0])
                upper.append(c.pressure_range[1])
        self.rod_arm = RodArm(segments=tuple(built))
        self.steps_per_segment = params.steps_per_segment
        super().__init__(
            name, tuple(names), np.array(lower), np.array(upper), backbone_points_per_section=params.steps_per_segment
        )

    @staticmethod
    def _check_actuators(params: CosseratParams) -> None:
        """Segment indices exist; every actuator lies strictly inside each section it runs through."""
        n = len(params.segments)
        placed = [("tendons", i, t.segment, t.offset) for i, t in enumerate(params.tendons)]
        placed += [("chambers", i, c.segment, c.offset) for i, c in enumerate(params.chambers)]
        for what, i, segment, offset in placed:
            if segment >= n:
                raise ParameterError(f"{what}.{i}.segment", f"segment {segment} does not exist (0..{n - 1})")
            passes = range(segment + 1) if what == "tendons" else (segment,)
            for k in passes:
                radius = params.segments[k].section_radius
                if offset >= radius:
                    raise ParameterError(
                        f"{what}.{i}.offset", f"{offset} m is not inside the section radius {radius} m of segment {k}"
                    )

    @property
    def n_sections(self) -> int:
        """Number of segments."""
        return len(self.params.segments)

    @property
    def tendon_mask(self) -> np.ndarray:
        """``(n_config,)`` True for a tendon tension, False for a chamber pressure."""
        return np.array([n.startswith("tendons.") for n in self.config_names])

    def section_frames(self, q: Any) -> list[tuple[Any, Any]]:
        """Not offered: the shape is an equilibrium of every load (module docstring).

        Raises
        ------
        optikin.errors.SolverError
            Always, naming the ``statics`` kind.
        """
        raise SolverError(f"{self.name}: a Cosserat arm's shape is the equilibrium of its loads; use kind statics")

    def backbone_points(self, q: Any, points_per_section: int) -> Any:
        """Not offered (see :meth:`section_frames`).

        Raises
        ------
        optikin.errors.SolverError
            Always, naming the ``statics`` kind.
        """
        raise SolverError(f"{self.name}: a Cosserat arm's shape is the equilibrium of its loads; use kind statics")

    def describe(self) -> dict[str, Any]:
        """Bounds (:meth:`ArmModel.describe`), the parameters and each segment's stiffness ``E I`` [N m^2]."""
        out = super().describe()
        out["params"] = self.params.model_dump(mode="json")
        out["bending_stiffness"] = [s.rod.EI for s in self.rod_arm.segments]
        out["length"] = self.rod_arm.length
        return out
