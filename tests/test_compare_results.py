"""tools/compare_results.py: shipped problems solved again give the same results to the bit, and a changed
array, metric or status is reported under its problem and key."""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CHEAP = ["cc-two-section-fk", "cc-ik-pose"]
"""Two of the tool's problems that solve in well under a second each."""


@pytest.fixture(scope="module")
def tool() -> ModuleType:
    """tools/compare_results.py as a module."""
    spec = importlib.util.spec_from_file_location("compare_results", ROOT / "tools" / "compare_results.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def reference(tool: ModuleType, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("reference")
    tool.write(out, CHEAP)
    return out


def _copy(reference: Path, tmp_path: Path) -> Path:
    other = tmp_path / "other"
    shutil.copytree(reference, other)
    return other


def test_solving_again_gives_the_same_results(tool, reference, capsys):
    assert tool.main([str(reference), "--problems", *CHEAP]) == 0
    assert capsys.readouterr().out.splitlines() == [f"{name}: identical" for name in CHEAP]


def test_one_changed_entry_of_an_array_is_reported_under_its_problem_and_name(tool, reference, tmp_path, capsys):
    other = _copy(reference, tmp_path)
    path = other / "cc-ik-pose" / "arrays.npz"
    with np.load(path) as data:
        arrays = {key: data[key] for key in data.files}
    name = next(key for key, value in arrays.items() if value.dtype.kind == "f" and not tool.is_timing(key))
    arrays[name].flat[0] = np.nextafter(arrays[name].flat[0], np.inf)
    np.savez_compressed(path, **arrays)
    assert tool.main([str(reference), "--against", str(other), "--problems", *CHEAP]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "cc-two-section-fk: identical"
    assert out[1:] == ["cc-ik-pose: 1 difference(s)", f"  arrays.npz {name}: 1 of {arrays[name].size} entries differ"]


def test_a_changed_metric_and_status_count_are_reported_and_timings_are_not(tool, reference, tmp_path):
    other = _copy(reference, tmp_path)
    path = other / "cc-two-section-fk" / "result.json"
    data = json.loads(path.read_text())
    data["timings"] = {"total": -1.0}
    data["provenance"] = {}
    data["status_counts"] = {"ok": data["samples"] - 1, "failed": 1}
    row = data["comparison"][0]
    metric = next(key for key, value in row["metrics"].items() if isinstance(value, float) and not tool.is_timing(key))
    row["metrics"][metric] += 1.0
    timed = next(key for key in row["metrics"] if tool.is_timing(key))
    row["metrics"][timed] = -1.0
    path.write_text(json.dumps(data))
    found = tool.compare(reference, other, CHEAP)
    assert found["cc-ik-pose"] == []
    samples = data["samples"]
    assert sorted(found["cc-two-section-fk"]) == sorted(
        [
            "result.json status_counts.failed: new (1)",
            f"result.json status_counts.ok: {samples} -> {samples - 1}",
            f"result.json comparison[{row['method']}].metrics.{metric}: "
            f"{row['metrics'][metric] - 1.0!r} -> {row['metrics'][metric]!r}",
        ]
    )


def test_timing_keys_are_told_from_the_others(tool):
    timed = ["time_lm", "ik_seconds_hybrid", "median time per sample [us]", "calibration time [s]", "solve_ms"]
    kept = ["residual_lm", "mean distance per marker [mm]", "status_counts", "samples", "iterations"]
    assert [tool.is_timing(key) for key in timed + kept] == [True] * len(timed) + [False] * len(kept)


def test_a_missing_result_is_a_difference(tool, reference, tmp_path):
    other = _copy(reference, tmp_path)
    shutil.rmtree(other / "cc-ik-pose")
    assert tool.compare(reference, other, CHEAP)["cc-ik-pose"] == [f"{other / 'cc-ik-pose'}: no result"]


def test_the_checkouts_folder_in_a_note_is_no_difference_and_another_file_is(tool, reference, tmp_path):
    other = _copy(reference, tmp_path)
    path = other / "cc-ik-pose" / "result.json"
    data = json.loads(path.read_text())
    data["notes"] = [*data["notes"], "read /somewhere/else/problems/cc-ik-pose.yaml"]
    path.write_text(json.dumps(data))
    mine = tmp_path / "mine"
    shutil.copytree(reference, mine)
    want = json.loads((mine / "cc-ik-pose" / "result.json").read_text())
    want["notes"] = [*want["notes"], f"read {ROOT}/problems/cc-ik-pose.yaml"]
    (mine / "cc-ik-pose" / "result.json").write_text(json.dumps(want))
    assert tool.compare(mine, other, ["cc-ik-pose"])["cc-ik-pose"] == []
    data["notes"][-1] = "read /somewhere/else/problems/cc-ik-position.yaml"
    path.write_text(json.dumps(data))
    assert len(tool.compare(mine, other, ["cc-ik-pose"])["cc-ik-pose"]) == 1
