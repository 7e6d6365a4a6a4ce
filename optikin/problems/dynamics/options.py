"""The ``options`` of a ``dynamics`` problem file: the time step, the scheme, damping and the fixed loads."""

from __future__ import annotations

from pydantic import Field, StrictBool, StrictFloat, StrictInt, field_validator

from optikin.codegen import CompilerFlag
from optikin.options import Options

Vector3 = tuple[StrictFloat, StrictFloat, StrictFloat]


class DampingOptions(Options):
    """Kelvin-Voigt damping (one viscosity for every segment) and quadratic air drag."""

    viscosity: StrictFloat = Field(
        0.0, ge=0, description="Kelvin-Voigt viscosity eta [Pa s]: B = (eta / E) K, each mode decays at eta w^2 / (2 E)"
    )
    drag: Vector3 = Field((0.0, 0.0, 0.0), description="air-drag coefficients C, material frame [N s^2 / m^3]")


class DynamicsKindOptions(Options):
    """``options:`` of kind ``dynamics``."""

    dt: StrictFloat = Field(0.002, gt=0, description="time step [s]")
    alpha: StrictFloat = Field(
        0.0, ge=-0.5, le=0.0, description="BDF-alpha parameter: 0 = BDF2 (damps high modes), -0.5 = trapezoidal"
    )
    damping: DampingOptions = Field(default_factory=DampingOptions, description="damping and drag")
    gravity: StrictBool = Field(True, description="the arm's gravity acts")
    payload: StrictFloat = Field(
        0.0, ge=0, description="mass at the tip, a point mass with its weight and inertia [kg]"
    )
    distributed_force: Vector3 = Field((0.0, 0.0, 0.0), description="uniform distributed force [N/m], base frame")
    tip_couple: Vector3 = Field((0.0, 0.0, 0.0), description="couple at the tip, base frame [N m]")
    tolerance: StrictFloat = Field(1e-9, gt=0, description="largest residual of a time step's BVP")
    max_iterations: StrictInt = Field(25, ge=1, description="Newton iterations per time step")
    compiled: StrictBool = Field(True, description="Newton on the C-compiled shape (else CasADi's VM)")
    flags: tuple[CompilerFlag, ...] = Field(("-O3",), description="compiler flags of the compiled shape")
    pressure_time_constant: StrictFloat | list[StrictFloat] | None = Field(
        None,
        description="first-order lag of the chamber pressures [s], one for all or one per chamber; None: none",
    )

    @field_validator("pressure_time_constant")
    @classmethod
    def _positive(cls, value: float | list[float] | None) -> float | list[float] | None:
        values = [] if value is None else value if isinstance(value, list) else [value]
        for i, tau in enumerate(values):
            if not tau > 0:
                raise ValueError(f"entry {i} is {tau} s: a time constant must be > 0 (non-physical otherwise)")
        return value
