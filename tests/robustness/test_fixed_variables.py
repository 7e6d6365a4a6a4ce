"""Fixed variables (``lower = upper``, e.g. inextensible sections) are removed from the solve by every backend.

The reference is the same arm with a tiny positive length range (1e-9 of the nominal
length each way), solved by IPOPT, and the tip recomputed by forward kinematics.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import yaml

from optikin.arms import ConstantCurvatureArm
from optikin.cli import main
from optikin.ik.formulation import Formulation, build_problem
from optikin.problems.ik.run import default_weights
from optikin.solvers import build_preset
from optikin.solvers.nonlinear import LeastSquaresProblem

PRESETS = ["gauss-newton", "gauss-newton-compiled", "newton", "ipopt", "sqpmethod", "lm", "trf"]
FIXED = ConstantCurvatureArm(length_range=(1.0, 1.0))
TINY = ConstantCurvatureArm(length_range=(1.0 - 1e-9, 1.0 + 1e-9))
START = np.array([0.18, 0.6, 0.0, 0.18, 0.6, 1.57])
CONFIGURATIONS = START + np.array(
    [[0, 0.1, 0.2, 0, -0.1, 0.1], [0, -0.3, 0.1, 0, 0.2, -0.2], [0, 0.2, -0.3, 0, 0.3, 0.3]]
)
TARGETS = FIXED.evaluate("fk_position", CONFIGURATIONS)


def problem(arm: ConstantCurvatureArm, redundancy: str) -> LeastSquaresProblem:
    formulation = Formulation("position", redundancy, arm.straight_configuration(), default_weights(arm), 1e-10)
    built = build_problem(arm, formulation)
    assert isinstance(built, LeastSquaresProblem)
    return built


@pytest.fixture(scope="module")
def reference() -> np.ndarray:
    """Closest to the start in the weighted norm, on the arm with a tiny length range (IPOPT)."""
    batch = build_preset("ipopt").solve_many(problem(TINY, "rest"), START, TARGETS, x_ref=START)
    assert batch.status == ["ok"] * len(TARGETS)
    return batch.x


@pytest.mark.parametrize("name", PRESETS)
def test_inextensible_sections_solve_with_every_preset(name, reference):
    adapter = build_preset(name)
    # ipopt, sqpmethod and newton solve "closest to x_ref"; the others make minimum-norm corrections
    redundancy = "rest" if name in ("ipopt", "sqpmethod", "newton") else "minimum_norm"
    fixed = problem(FIXED, redundancy)
    batch = adapter.solve_many(fixed, START, TARGETS, x_ref=START)
    assert batch.status == ["ok"] * len(TARGETS), batch.messages
    singles = [adapter.solve(fixed, START, p, START) for p in TARGETS]
    assert [s.status for s in singles] == ["ok"] * len(TARGETS)
    for X in (batch.x, np.array([s.x for s in singles])):
        np.testing.assert_array_equal(X[:, [0, 3]], 0.18)  # the lengths are not moved
        tips = FIXED.evaluate("fk_position", X)
        assert np.linalg.norm(tips - TARGETS, axis=1).max() <= 1e-10
        assert np.all(fixed.classify_many(X, TARGETS)[0] == np.array(["ok"] * len(TARGETS)))
    if redundancy == "rest":
        np.testing.assert_allclose(batch.x, reference, atol=1e-8)
    elif name != "trf":  # trf's reflections at the tiny bounds take another path to another solution
        np.testing.assert_allclose(batch.x, adapter.solve_many(problem(TINY, redundancy), START, TARGETS).x, atol=1e-8)


def test_a_point_at_a_fixed_bound_classifies_ok():
    fixed = problem(FIXED, "minimum_norm")
    status, residual, message = fixed.classify(CONFIGURATIONS[0], TARGETS[0], 0.0, 1.0)
    assert (status, message) == ("ok", "")
    moved = CONFIGURATIONS[0] + [1e-3, 0, 0, 0, 0, 0]
    assert fixed.classify(moved, TARGETS[0], 0.0, 1.0)[2] == "S1 = 0.181 outside its bounds"


@pytest.mark.parametrize("name", ["gauss-newton", "lm", "ipopt"])
def test_every_variable_fixed_is_classified_without_a_solve(name):
    x, p = ca.SX.sym("x"), ca.SX.sym("p")
    line = LeastSquaresProblem(ca.Function("line", [x, p], [x - p]), [2.0], [2.0], [False])
    batch = build_preset(name).solve_many(line, [0.0], [[2.0], [3.0]])
    # x = 2 misses the target 3 and cannot move: a stationary point within the bounds
    assert batch.status == ["ok", "unreachable"]
    np.testing.assert_array_equal(batch.x, [[2.0], [2.0]])


def test_default_weights_of_a_fixed_variable():
    np.testing.assert_allclose(default_weights(FIXED), [1.0, 3 / (4 * np.pi), 1 / (2 * np.pi)] * 2)


def test_an_ik_problem_file_with_inextensible_sections_and_no_weights_runs(tmp_path):
    spec = {
        "name": "inextensible",
        "title": "inextensible sections",
        "description": "length_range (1, 1), default weights",
        "kind": "ik",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18], "length_range": [1.0, 1.0]}},
        "data": {"source": "random", "seed": 4, "samples": 8},
        "solver": "gauss-newton",
        "baselines": ["newton", "ipopt", "lm", "trf"],
        "options": {"target": "position", "redundancy": "minimum_norm", "start": START.tolist()},
    }
    path = tmp_path / "inextensible.yaml"
    path.write_text(yaml.safe_dump(spec))
    assert main(["solve", str(path), "--no-figures", "--out", str(tmp_path / "out")]) == 0
