"""The options of the ``two_arms`` kind: where the arms stand, the rope, the joint QP and its collision rows.

Vectors whose length depends on the arm (``arms[k].start``) are checked against it when the
run starts, naming the field; so are the bases (overlapping tubes), the start (tubes within
the margin of each other) and the rope (not longer than the distance between the grips).
"""

from __future__ import annotations

from pydantic import Field, NonNegativeFloat, PositiveFloat, field_validator

from optikin.options import Options
from optikin.problems.tracking.options import ObstacleOptions, RateLimitKey

Vector3 = tuple[float, float, float]


class ArmPlacementOptions(Options):
    """One arm in the shared frame: its base pose, start configuration and tube radius."""

    base: Vector3 = Field(description="base position in the shared frame [m]")
    orientation: tuple[float, float, float, float] = Field(
        (1.0, 0.0, 0.0, 0.0), description="base rotation as a unit quaternion (w, x, y, z); normalised"
    )
    start: list[float] | None = Field(
        None, description="initial configuration [SI units]; null: the first waypoint (tips task), required otherwise"
    )
    radius: PositiveFloat = Field(0.015, description="radius of the arm's tube around its backbone [m]")

    @field_validator("orientation")
    @classmethod
    def _non_zero(cls, value: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        if not sum(v * v for v in value) > 1e-12:
            raise ValueError("the orientation quaternion has zero length")
        return value


class RopeOptions(Options):
    """The rope the two tips hold (:class:`optikin.curves.catenary_sensitivity.CatenarySensitivity`)."""

    length: PositiveFloat = Field(description="rope length L [m]; longer than the distance between the grips")
    mass_per_length: NonNegativeFloat = Field(0.05, description="mu [kg/m] (sets the tension, not the shape)")
    slack: PositiveFloat = Field(0.03, description="the grips stay at least this much closer than L [m]")
    floor: float | None = Field(
        None, description="height (along -gravity) the lowest point keeps above [m]; null: none"
    )
    gravity: Vector3 = Field((0.0, 0.0, -1.0), description="direction of gravity in the shared frame")


class CollisionOptions(Options):
    """The self-collision rows between the two tubes (:class:`optikin.control.self_collision.TwoTubes`)."""

    margin: PositiveFloat = Field(0.02, description="clearance every sampled pair of the two tubes keeps [m]")
    gamma: PositiveFloat = Field(20.0, description="barrier rate: d_dot >= -gamma (d - margin) [1/s]; gamma dt <= 1")
    pairs: int = Field(4, ge=1, description="pairs of samples in the QP (the nearest, one per sample of arm 1)")
    points_per_section: int | None = Field(
        None, ge=1, description="backbone samples per section; null: ceil(2 S_max / margin), spacing <= margin / 2"
    )
    rope_pairs: int = Field(2, ge=0, description="rows per arm keeping the rope's samples off its tube; 0: none")
    rope_margin: PositiveFloat = Field(0.01, description="clearance the rope's samples keep from the tubes [m]")
    rope_exclusion: PositiveFloat = Field(
        0.07, description="arc length of rope at each grip not kept off the tubes (it leaves the holding tube) [m]"
    )
    obstacle_margin: PositiveFloat = Field(
        0.01, description="clearance both tubes and the rope keep from obstacles [m]"
    )
    points_per_obstacle: int = Field(
        3, ge=1, description="samples per body (arm 1, arm 2, rope) and obstacle in the QP"
    )


class TwoArmOptions(Options):
    """Options of the ``two_arms`` kind."""

    arms: list[ArmPlacementOptions] = Field(description="the two arms (the same arm model), in the shared frame")
    rope: RopeOptions | None = Field(None, description="the rope held by the tips (the rope task needs it)")
    gain: NonNegativeFloat = Field(10.0, description="K of the task feedback [1/s]")
    damping: NonNegativeFloat = Field(1e-4, description="lambda, the weight of ||qdot||^2")
    posture_weight: NonNegativeFloat = Field(
        1e-3, description="w of the posture term ||qdot - k_p (q_start - q)||^2 (settles the free motions)"
    )
    posture_gain: NonNegativeFloat = Field(1.0, description="k_p of the posture term [1/s]")
    rate_limits: dict[RateLimitKey, PositiveFloat] | None = Field(
        None, description="rate limits by variable name or prefix (S, theta, phi) [m/s, rad/s]; null: S 0.1, theta pi"
    )
    limit_margin: NonNegativeFloat = Field(1e-9, description="distance kept from the configuration limits")
    collision: CollisionOptions = Field(default_factory=CollisionOptions, description="the self-collision rows")
    obstacles: list[ObstacleOptions] = Field(
        default_factory=list,
        description="obstacles in the shared frame kept off both tubes and the rope (the joint QP only)",
    )
    compiled: bool = Field(False, description="compile the per-step CasADi Functions with a C compiler")

    @field_validator("arms")
    @classmethod
    def _two(cls, value: list[ArmPlacementOptions]) -> list[ArmPlacementOptions]:
        if len(value) != 2:
            raise ValueError(f"exactly two arms, got {len(value)}")
        return value
