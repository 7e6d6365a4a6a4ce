"""Symbolic arm models and the factory that builds them from a problem file's ``arm`` section.

* :class:`ConstantCurvatureArm`: ``m`` constant-curvature sections, ``(S, theta, phi)`` each
  (Seleem et al. 2020).
* :class:`CBHAArm`: the Compact Bionic Handling Assistant as 16 parallel platforms,
  ``(Z, theta, psi)`` each (Lakhal et al. 2016).

Configurations, frames and layouts: ``docs/conventions.md``.
"""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any, cast

from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm, CBHAGeometry
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.arms.cosserat import CosseratArm
from optikin.checks import ParameterError
from optikin.errors import SpecError
from optikin.registry import ARMS

ARMS.register("constant_curvature")(ConstantCurvatureArm)
ARMS.register("cbha")(CBHAArm)
ARMS.register("cosserat")(CosseratArm)

__all__ = ["ArmModel", "CBHAArm", "CBHAGeometry", "ConstantCurvatureArm", "build_arm"]


def build_arm(arm_type: str, params: dict[str, Any], path: str | Path = "<arm>") -> ArmModel:
    """Build the registered arm ``arm_type`` from a problem file's ``arm`` section.

    Parameters
    ----------
    arm_type : str
        A name registered in :data:`optikin.registry.ARMS` (``constant_curvature``, ``cbha``).
    params : dict
        Keyword arguments of the arm's constructor (SI units).
    path : str or pathlib.Path
        The problem file, for error messages.

    Returns
    -------
    ArmModel
        The arm.

    Raises
    ------
    optikin.errors.SpecError
        Naming ``arm.type`` for an unknown arm, ``arm.params.<name>`` for an unknown
        parameter or a value the constructor rejects (``arm.params.section_lengths.0: not a
        finite number``; :class:`optikin.checks.ParameterError`), ``arm.params`` for any other
        value it rejects.
    """
    try:
        factory = ARMS.get(arm_type)
    except Exception as exc:
        raise SpecError(str(path), "arm.type", str(exc)) from None
    accepted = inspect.signature(factory).parameters
    for key in params:
        if key not in accepted or key == "self":
            known = ", ".join(p for p in accepted if p != "self")
            raise SpecError(str(path), f"arm.params.{key}", f"unknown parameter of {arm_type}; known: {known}")
    try:
        return cast(ArmModel, factory(**params))
    except ParameterError as exc:
        raise SpecError(str(path), f"arm.params.{exc.field}", exc.message) from None
    except (TypeError, ValueError) as exc:
        raise SpecError(str(path), "arm.params", str(exc)) from None
