"""``arm: FILE`` includes the arm section another file holds (the calibrated arm a calibrate run writes);
arm names must be identifiers."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from optikin.errors import SpecError
from optikin.runner import solve
from optikin.spec import load_problem

PROBLEM = {
    "name": "included",
    "title": "t",
    "kind": "fk",
    "arm": "arm.yaml",
    "data": {"source": "random", "samples": 4},
}


def write(tmp_path: Path, arm_file: object, problem: dict | None = None) -> Path:
    if arm_file is not None:
        (tmp_path / "arm.yaml").write_text(yaml.safe_dump(arm_file))
    path = tmp_path / "included.yaml"
    path.write_text(yaml.safe_dump(problem or PROBLEM))
    return path


def test_the_arm_section_is_read_from_the_named_file(tmp_path):
    arm = {"type": "constant_curvature", "params": {"section_lengths": [0.1, 0.2]}}
    spec, _ = load_problem(str(write(tmp_path, {"arm": arm, "calibration": {"base_position": [0, 0, 0]}})))
    assert spec.arm is not None and spec.arm.params["section_lengths"] == [0.1, 0.2]
    result, _ = solve(str(tmp_path / "included.yaml"), figures=False)
    assert result.arm["section_lengths"] == [0.1, 0.2]


def test_the_shipped_trunk_problems_include_the_calibrated_arm():
    spec, _ = load_problem("trunk-ik")
    assert spec.arm is not None and spec.arm.params["name"] == "trunk_calibrated"


@pytest.mark.parametrize(
    ("arm_file", "message"),
    [(None, "no such file"), ({"calibration": {}}, "has no arm: mapping"), ({"arm": "other.yaml"}, "has no arm:")],
)
def test_a_bad_include_names_the_arm_field(tmp_path, arm_file, message):
    with pytest.raises(SpecError) as info:
        load_problem(str(write(tmp_path, arm_file)))
    assert info.value.field == "arm" and message in str(info.value)


def test_an_arm_name_that_is_not_an_identifier_is_a_field_error(tmp_path):
    problem = PROBLEM | {"arm": {"type": "constant_curvature", "params": {"name": "trunk-calibrated"}}}
    with pytest.raises(SpecError) as info:
        solve(str(write(tmp_path, None, problem)), figures=False)
    assert info.value.field == "arm.params.name"
