"""The short Python entry points: the module's example runs, and bad calls say what is wrong."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

import optikin
import optikin.api
from optikin.arms import ConstantCurvatureArm


def test_the_docstring_example_runs():
    result = doctest.testmod(optikin.api, raise_on_error=False)
    assert result.attempted >= 8 and result.failed == 0


def test_tip_position_ik_reaches_a_reachable_target():
    arm = ConstantCurvatureArm()
    q = np.array([0.18, 0.7, 0.4, 0.17, -0.5, 2.0])
    tip = arm.evaluate("fk_position", q[None])[0]
    solution = optikin.solve_ik(arm, tip)
    assert solution.status == "ok"
    assert np.linalg.norm(arm.evaluate("fk_position", solution.configuration[None])[0] - tip) < 1e-9


def test_a_target_of_the_wrong_size_is_refused():
    arm = ConstantCurvatureArm()
    with pytest.raises(ValueError, match="position \\(3\\) or a dual quaternion \\(8\\)"):
        optikin.solve_ik(arm, np.zeros(5))
    with pytest.raises(ValueError, match="need 6 values"):
        optikin.solve_ik(arm, np.zeros(5), points={"a": {"section": 1}, "b": {"section": 2}})


def test_a_preset_of_another_family_is_refused():
    with pytest.raises(ValueError, match="not nonlinear"):
        optikin.solve_ik(ConstantCurvatureArm(), np.array([0.0, 0.0, 0.3]), preset="qp-osqp")
