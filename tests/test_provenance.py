"""Results record what they solved and where; ``--set`` overrides fields; unknown names get a suggestion."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from optikin.cli import main
from optikin.errors import SpecError, UnknownNameError
from optikin.runner import solve
from optikin.spec import parse_override, resolve


def test_a_result_records_the_validated_problem_the_versions_and_the_machine(tmp_path):
    result, written = solve("cc-two-section-fk", out=tmp_path, figures=False, overrides=[("data.samples", 7)])
    assert written is not None
    provenance = json.loads((written / "result.json").read_text())["provenance"]
    assert provenance["problem"]["spec"]["data"]["samples"] == 7
    assert provenance["problem"]["file"].endswith("cc-two-section-fk.yaml")
    assert provenance["preset"]["spec"]["name"] == result.solver
    assert provenance["versions"]["casadi"] and provenance["versions"]["numpy"]
    assert provenance["machine"]["cores"] >= 1 and provenance["wall seconds"] > 0
    assert result.samples == 7


def test_set_overrides_are_validated_like_the_file(tmp_path, capsys):
    code = main(["solve", "cc-two-section-fk", "--out", str(tmp_path), "--no-figures", "--set", "data.seedd=3"])
    assert code == 2
    assert "data.seedd: unknown field" in capsys.readouterr().err
    code = main(["solve", "cc-two-section-fk", "--out", str(tmp_path), "--no-figures", "--set", "data.samples=-1"])
    assert code == 2
    assert "data.samples" in capsys.readouterr().err


@pytest.mark.parametrize("text", ["data.seed", "=3", "data..seed=1", "data.seed=[1"])
def test_malformed_overrides_are_refused(text):
    with pytest.raises(SpecError):
        parse_override(text)


def test_override_values_are_yaml():
    assert parse_override("options.noise=0.001") == ("options.noise", 0.001)
    assert parse_override("baselines=[lm, trf]") == ("baselines", ["lm", "trf"])


def test_an_unknown_name_suggests_the_nearest_known_one():
    with pytest.raises(UnknownNameError) as info:
        resolve("cc-ik-pos", "problems")
    assert info.value.suggestion == "cc-ik-pose"
    assert "did you mean 'cc-ik-pose'?" in str(info.value)


def test_a_name_far_from_every_known_one_gets_no_suggestion():
    with pytest.raises(UnknownNameError) as info:
        resolve("zzzzzzzz", "problems")
    assert info.value.suggestion is None


def test_result_json_of_a_written_run_is_valid_json(tmp_path):
    _, written = solve("cc-two-section-fk", out=tmp_path, figures=False, overrides=[("data.samples", 3)])
    assert isinstance(json.loads(Path(written, "result.json").read_text())["provenance"]["started"], str)
