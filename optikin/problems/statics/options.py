"""The ``options`` of a ``statics`` problem file: the mode, the loads, the shooting and collocation settings."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, StrictBool, StrictFloat, StrictInt

from optikin.codegen import CompilerFlag
from optikin.options import Options

Vector3 = tuple[StrictFloat, StrictFloat, StrictFloat]


class LoadOptions(Options):
    """The external loads, the same for every sample."""

    gravity: StrictBool = Field(True, description="the arm's gravity acts (on the rod and the payload)")
    payload: StrictFloat = Field(0.0, ge=0, description="mass hanging at the tip [kg]; its weight is mass x gravity")
    tip_force: Vector3 = Field((0.0, 0.0, 0.0), description="force at the tip, base frame [N]")
    tip_couple: Vector3 = Field((0.0, 0.0, 0.0), description="couple at the tip, base frame [N m]")


class StaticsOptions(Options):
    """``options:`` of kind ``statics``."""

    mode: Literal["forward", "inverse"] = Field(
        "forward", description="forward: actuation -> equilibrium shape; inverse: tip target -> actuation"
    )
    loads: LoadOptions = Field(default_factory=LoadOptions, description="external loads")
    compiled: StrictBool = Field(True, description="the shooting Newton on C-compiled Functions (else CasADi's VM)")
    flags: tuple[CompilerFlag, ...] = Field(("-O3",), description="compiler flags of the compiled Functions")
    tolerance: StrictFloat = Field(
        1e-10, gt=0, description="largest tip residual of an equilibrium, ||(N(L) - F, M(L) - C)|| [N, N m]"
    )
    collocation_intervals: StrictInt = Field(
        25, ge=1, description="baseline collocation: Gauss-Legendre intervals per segment"
    )
    collocation_degree: StrictInt = Field(3, ge=1, le=9, description="baseline collocation: points per interval")
    target: Literal["position", "pose"] = Field("position", description="inverse: match the tip position or pose")
    target_tolerance: StrictFloat = Field(1e-9, gt=0, description="inverse: ||r|| counted as solved [m]")
    orientation_length: StrictFloat | None = Field(
        None, gt=0, description="inverse, pose targets: length scaling the orientation error [m]; default arm length"
    )
    start: Literal["middle", "lower"] | list[StrictFloat] = Field(
        "middle", description="inverse: start of the first solve: mid-range, the lower bounds, or an actuation"
    )
