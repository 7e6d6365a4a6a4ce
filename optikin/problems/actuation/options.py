"""The ``options`` of an ``actuation`` problem file: the channels, the folds, the learning curve, the physics fit."""

from __future__ import annotations

from pydantic import Field, StrictFloat, StrictInt, field_validator

from optikin.options import Options


class ActuationOptions(Options):
    """``options:`` of kind ``actuation``."""

    markers: list[str] = Field(
        ["disk1", "disk2", "disk3"], min_length=3, max_length=3, description="the marker of each section's end disk"
    )
    motors: list[str] = Field(
        [f"motor{j}" for j in range(1, 7)],
        min_length=6,
        max_length=6,
        description="the recording's channels of motors 1-6: tendons of section 1, 1, 2, 2, 3, 3 [N]",
    )
    postures: StrictInt | None = Field(
        None, ge=20, description="a seeded subset of this many postures of the recording; None: every posture"
    )
    folds: StrictInt = Field(4, ge=2, le=20, description="shuffled folds of the held-out test")
    fractions: list[StrictFloat] = Field(
        [0.1, 0.25, 0.5, 1.0], min_length=1, description="shares of each training fold of the learning curve"
    )
    section_lengths: list[StrictFloat] = Field(
        [0.1, 0.1, 0.1], min_length=3, max_length=3, description="nominal section lengths, the physics fit's start [m]"
    )
    length_range: tuple[StrictFloat, StrictFloat] = Field(
        (0.7, 1.3), description="bounds of the fitted section lengths relative to the nominal"
    )
    stiffness: StrictFloat = Field(0.01, gt=0, description="start of each section's bending stiffness EI [N m^2]")
    payload: StrictFloat = Field(0.1, ge=0, description="start of the payload mass [kg]")
    tendon_offset: StrictFloat = Field(0.012, gt=0, description="distance of the tendons from the backbone [m] (held)")
    linear_density: StrictFloat = Field(0.0099, ge=0, description="backbone mass per length [kg/m] (held)")
    steps: StrictInt = Field(4, ge=2, le=50, description="integration steps per section of the rod")
    max_evaluations: StrictInt = Field(20, ge=2, description="residual evaluations of each physics fit at most")
    loss_scale: StrictFloat = Field(
        0.003, gt=0, description="marker error beyond which the physics fit's soft-L1 loss is robust [m]"
    )

    @field_validator("fractions")
    @classmethod
    def _fractions(cls, value: list[float]) -> list[float]:
        if any(not 0 < f <= 1 for f in value) or sorted(value) != value or len(set(value)) != len(value):
            raise ValueError(f"expected increasing shares in (0, 1], got {value}")
        return value
