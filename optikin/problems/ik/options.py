"""The ``options`` of an ``ik`` problem file: the formulation of the targets, its variants, starts and restarts.

:class:`FormulationOptions` are the fields a variant may change (how the targets
are matched and the redundancy resolved); :class:`IkOptions` adds what every row
of the comparison shares (the target kind, the start, the restarts) and the
``variants``. Checks that need the arm (vector lengths, bounds, CBHA-only
choices) are made when the run starts (:func:`optikin.problems.ik.run.setup_of`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, StrictFloat, StrictInt, field_validator
from pydantic_core import PydanticCustomError

from optikin.data.targets import TargetKind
from optikin.options import Options

Redundancy = Literal["rest", "previous", "minimum_norm", "penalty"]
PenaltyReading = Literal["configuration", "position"]
Elongation = Literal["free", "distributed", "affine"]
Positive = Annotated[StrictFloat, Field(gt=0)]
PointComponent = Literal["position", "direction", "orientation"]


class PointOptions(Options):
    """One measured point of ``target: points`` (:mod:`optikin.ik.points`)."""

    section: StrictInt = Field(ge=1, description="the section it lies on, from 1 at the base")
    at: StrictFloat = Field(
        1.0, gt=0.0, le=1.0, description="fraction of that section's arc length (1: the section's end)"
    )
    offset: tuple[StrictFloat, StrictFloat, StrictFloat] = Field(
        (0.0, 0.0, 0.0), description="offset from the backbone in the backbone frame there [m] (a marker on a disk)"
    )
    measure: list[PointComponent] = Field(
        ["position"],
        min_length=1,
        description="what is measured there: position (x, y, z), direction (the frame's z axis, no twist), "
        "orientation (a unit quaternion)",
    )
    weight: Positive = Field(1.0, description="weight of its residual rows (a pure number)")

    @field_validator("measure")
    @classmethod
    def _one_rotation(cls, measure: list[str]) -> list[str]:
        if len(set(measure)) != len(measure):
            raise ValueError(f"each component once, got {measure}")
        if "direction" in measure and "orientation" in measure:
            raise ValueError("direction or orientation, not both: the orientation includes the direction")
        return measure


class FormulationOptions(Options):
    """How the targets are matched and the redundancy resolved; every field may be set by a variant."""

    redundancy: Redundancy = Field(
        "rest",
        description="which solution of a redundant problem: closest to rest, closest to the previous "
        "solution, reached by minimum-norm corrections, or the penalty of seed 004 eq. (11)",
    )
    penalty: StrictFloat = Field(
        1e-6, gt=0, description="lambda of eq. (11): m^2 on the configuration, a pure number on the position"
    )
    penalty_on: PenaltyReading = Field(
        "configuration", description="what eq. (11) penalises: the weighted distance to rest, or the tip position"
    )
    elongation: Elongation = Field(
        "free",
        description="CBHA only: the elongation distribution of seed 004 "
        "section IV (distributed or affine reading), or none",
    )
    rest: list[StrictFloat] | None = Field(
        None,
        description="rest configuration (units of the arm's variables); "
        "default straight at nominal lengths, else mid-range",
    )
    weights: list[Positive] | None = Field(
        None,
        description="diagonal W of ||W (q - q_ref)|| (1/units of each variable); default the inverse ranges "
        "(1 for a fixed variable, lower = upper)",
    )
    tolerance: StrictFloat = Field(1e-10, gt=0, description="||r|| counted as solved [m]")
    orientation_length: StrictFloat | None = Field(
        None, gt=0, description="pose targets: length L scaling the orientation rows [m]; default the arm's reach bound"
    )


class IkOptions(FormulationOptions):
    """``options`` of kind ``ik`` (module docstring of :mod:`optikin.problems.ik`)."""

    target: TargetKind = Field(
        "position",
        description="tip position, tip pose (unit dual quaternion), measured points along the arm (points) "
        "or, on a CBHA, the 48 leg lengths",
    )
    points: dict[str, PointOptions] | None = Field(
        None, description="target points only: name -> the measured point (its section, where, offset, components)"
    )
    noise: StrictFloat | Literal["calibrated"] | None = Field(
        None,
        description="measurement noise level [m]: a least-squares minimum whose RMS point distance is at most "
        "this is a fit, beyond it unreachable; calibrated: the noise_level of the calibrated arm file the "
        "problem's arm: includes (what the calibration leaves on 95 % of its held-out postures); null: targets "
        "are exact (noise-free)",
    )
    start: Literal["rest"] | list[StrictFloat] = Field(
        "rest",
        description="start configuration of independent targets and of a trajectory's first one: "
        "'rest' or a configuration (units of the arm's variables)",
    )
    restarts: StrictInt = Field(
        6,
        ge=0,
        description="retries of a target not solved (count): from the nearest "
        "solved target's solution, then from random configurations",
    )
    variants: dict[str, FormulationOptions] = Field(
        default_factory=dict,
        description="label -> formulation options over these: the problem's solver on "
        "other formulations of the same targets",
    )

    @field_validator("noise")
    @classmethod
    def _positive_noise(cls, value: float | str | None) -> float | str | None:
        if isinstance(value, float) and not value > 0:
            raise ValueError(f"noise must be positive, got {value}")
        return value

    @field_validator("start", mode="wrap")
    @classmethod
    def _rest_or_configuration(cls, value: Any, handler: Any) -> Any:
        try:
            return handler(value)
        except ValueError:
            raise PydanticCustomError(
                "start", "expected 'rest' or a configuration (a list of numbers), got {value}", {"value": repr(value)}
            ) from None
