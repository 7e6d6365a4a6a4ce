"""A tracking run states its success criterion: converged within ``options.tolerance`` by the end,
and no step on which the QP's own command kept or took the arm outside the limits. A run that
misses it exits 1, its Result does not report ``succeeded``, and a note says which criterion
failed and by how much.

Before the criterion, ``track-nominal`` started at ``[0.10, 3.1, 0.3, 0.30, 3.1, -1.0]``
ended about 450 mm / 67 degrees from the reference with every step ``ok`` and exit 0.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import yaml

from optikin.arms import build_arm
from optikin.cli import main
from optikin.problems.tracking.options import ToleranceOptions
from optikin.problems.tracking.report import success_criteria
from optikin.results import Result

REPO = Path(__file__).resolve().parents[2]
FAR_START = [0.10, 3.1, 0.3, 0.30, 3.1, -1.0]


def solve(tmp_path: Path, options: dict) -> tuple[int, dict, dict]:
    """``optikin solve`` of ``track-nominal`` with ``options`` replaced: exit status, result.json, arrays."""
    spec = yaml.safe_load((REPO / "problems" / "track-nominal.yaml").read_text())
    spec["options"] = options
    problem = tmp_path / "track-nominal.yaml"
    problem.write_text(yaml.safe_dump(spec))
    code = main(["solve", str(problem), "--no-figures", "--json", "--out", str(tmp_path / "out")])
    folder = tmp_path / "out" / "track-nominal"
    with np.load(folder / "arrays.npz") as npz:
        arrays = {k: npz[k] for k in npz.files}
    return code, json.loads((folder / "result.json").read_text()), arrays


def final_position_error_mm(spec_arm: dict, arrays: dict) -> float:
    """Mean tip distance from the reference over the last 10 % of the run, from the configurations."""
    arm = build_arm(spec_arm["type"], spec_arm["params"], "track-nominal.yaml")
    tip = arm.evaluate("fk_position", arrays["q_qp"]).reshape(-1, 3)
    distance = np.linalg.norm(tip - arrays["reference_position"], axis=1) * 1e3
    return float(distance[-int(round(0.1 * len(distance))) :].mean())


def test_far_start_misses_convergence_and_exits_1(tmp_path, capsys):
    code, summary, arrays = solve(tmp_path, {"start": FAR_START})
    assert code == 1
    assert summary["status_counts"] == {"ok": summary["samples"]}  # every step ok: the criterion decides
    assert summary["criteria"] == {"converged": False, "within limits": True}
    assert summary["succeeded"] is False
    (note,) = [n for n in summary["notes"] if n.startswith("criterion converged not met")]
    reported = float(re.search(r"final position error ([\d.e+-]+) mm", note).group(1))
    spec_arm = yaml.safe_load((REPO / "problems" / "track-nominal.yaml").read_text())["arm"]
    expected = final_position_error_mm(spec_arm, arrays)
    assert expected > 100  # far from the reference, not a tolerance matter
    assert abs(reported - expected) <= 1e-3 * expected  # the note's number, to its 4 digits
    assert "tolerance 0.05 mm" in note and "orientation error" in note


def test_shipped_start_meets_the_criterion(tmp_path):
    spec = yaml.safe_load((REPO / "problems" / "track-nominal.yaml").read_text())
    code, summary, _ = solve(tmp_path, spec["options"])
    assert code == 0
    assert summary["criteria"] == {"converged": True, "within limits": True} and summary["succeeded"]


def test_limit_criterion_names_steps_and_excess():
    metrics = {
        "position error final [mm]": 0.01,
        "orientation error final [deg]": 0.01,
        "steps the controller kept or took outside": 3,
        "max limit excess S [mm]": 2.5,
        "max limit excess theta [deg]": 0.0,
    }
    criteria, notes = success_criteria(metrics, ToleranceOptions())
    assert criteria == {"converged": True, "within limits": False}
    assert notes == [
        "criterion within limits not met: the QP's command kept or took the arm outside the "
        "configuration limits on 3 steps; farthest: S 2.5 mm"
    ]


def test_result_succeeds_only_when_every_criterion_is_met():
    def result(criteria: dict[str, bool]) -> Result:
        return Result("p", "k", None, "t", {}, ["ok", "ok"], criteria=criteria)

    assert result({}).succeeded and result({"a": True}).succeeded
    failing = result({"a": True, "b": False})
    assert not failing.succeeded
    assert failing.summary()["criteria"] == {"a": True, "b": False} and failing.summary()["succeeded"] is False
