"""Symbolic arm models and the factory that builds them from a problem file's ``arm`` section."""

from __future__ import annotations

import inspect
from pathlib import Path

from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm, CBHAGeometry
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.errors import SpecError
from optikin.registry import ARMS

ARMS.register("constant_curvature")(ConstantCurvatureArm)
ARMS.register("cbha")(CBHAArm)

__all__ = ["ArmModel", "CBHAArm", "CBHAGeometry", "ConstantCurvatureArm", "build_arm"]


def build_arm(arm_type: str, params: dict, path: str | Path = "<arm>") -> ArmModel:
    """Build the registered arm ``arm_type`` with ``params``; bad names or values name the field."""
    try:
        factory = ARMS.get(arm_type)
    except Exception as exc:
        raise SpecError(path, "arm.type", str(exc)) from None
    accepted = inspect.signature(factory).parameters
    for key in params:
        if key not in accepted or key == "self":
            known = ", ".join(p for p in accepted if p != "self")
            raise SpecError(path, f"arm.params.{key}", f"unknown parameter of {arm_type}; known: {known}")
    try:
        return factory(**params)
    except (TypeError, ValueError) as exc:
        raise SpecError(path, "arm.params", str(exc)) from None
