"""Problem files without ``arm:``: the shape kinds run on data that carry the end poses; other kinds, and
sources that need an arm, name the missing ``arm`` field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.errors import SpecError
from optikin.runner import solve

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"


def without_arm(tmp_path: Path, name: str, **changes) -> Path:
    spec = yaml.safe_load((PROBLEMS / f"{name}.yaml").read_text())
    spec.pop("arm")
    spec["name"] = f"{name}-no-arm"
    for key, value in changes.items():
        spec[key] = spec[key] | value if isinstance(value, dict) else value
    path = tmp_path / f"{name}-no-arm.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_a_shape_problem_on_recorded_end_poses_needs_no_arm(tmp_path):
    data = {"source": "csv", "samples": 10, "params": {"file": str(PROBLEMS / "trunk-markers.csv")}}
    with_arm, _ = solve("trunk-ph-shape", figures=False, overrides=[("data.samples", 10)])
    result, _ = solve(str(without_arm(tmp_path, "trunk-ph-shape", data=data)), figures=False)
    assert result.arm == {}
    assert result.status == with_arm.status
    assert np.array_equal(result.residuals, with_arm.residuals)  # the arm's geometry was never used


def test_a_kind_that_needs_an_arm_names_the_missing_field(tmp_path):
    with pytest.raises(SpecError) as info:
        solve(str(without_arm(tmp_path, "cc-two-section-fk")), figures=False)
    assert info.value.field == "arm" and "needs an arm" in str(info.value)


def test_a_source_that_records_an_arm_names_the_missing_field(tmp_path):
    with pytest.raises(SpecError) as info:
        solve(str(without_arm(tmp_path, "cbha-ph-shape", data={"samples": 3})), figures=False)
    assert info.value.field == "arm"
