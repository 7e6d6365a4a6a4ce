"""``optikin examples``: the shipped examples copied whole into a new folder, solvable from anywhere."""

from __future__ import annotations

import filecmp
from pathlib import Path

import pytest

from optikin.errors import SpecError
from optikin.examples import copy_examples, example_problems
from optikin.runner import solve

CHECKOUT_EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def same_tree(left: Path, right: Path) -> bool:
    compared = filecmp.dircmp(left, right, ignore=["__pycache__"])
    if compared.left_only or compared.right_only or compared.diff_files or compared.funny_files:
        return False
    return all(same_tree(left / sub, right / sub) for sub in compared.common_dirs)


def test_the_copy_holds_every_example_file(tmp_path):
    folder = copy_examples(tmp_path / "mine")
    assert same_tree(folder, CHECKOUT_EXAMPLES)
    assert [p.name for p in example_problems(folder)] == ["dmp-my-demo.yaml", "track-my-demo.yaml"]
    assert [p.name for p in tmp_path.iterdir()] == ["mine"]  # no staging folder left


@pytest.mark.parametrize(
    "make", [lambda p: p.mkdir(), lambda p: p.write_text("x"), lambda p: p.symlink_to(p.parent / "gone")]
)
def test_an_existing_destination_is_refused_and_left_alone(tmp_path, make):
    target = tmp_path / "taken"
    make(target)
    before = sorted(tmp_path.iterdir())
    with pytest.raises(SpecError, match="already exists"):
        copy_examples(target)
    assert sorted(tmp_path.iterdir()) == before


def test_an_empty_name_or_a_missing_parent_is_refused(tmp_path):
    with pytest.raises(SpecError, match="empty"):
        copy_examples(" ")
    with pytest.raises(SpecError, match="does not exist"):
        copy_examples(tmp_path / "no" / "such")


def test_a_copied_example_solves_from_another_folder(tmp_path, monkeypatch):
    folder = copy_examples(tmp_path / "mine")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    result, written = solve(str(folder / "dmp-my-demo.yaml"), out=elsewhere / "out", figures=False)
    assert result.samples > 0 and written.is_dir()


def test_the_command_copies_names_the_next_step_and_refuses_an_existing_folder(tmp_path, monkeypatch, capsys):
    from optikin.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "optikin-examples" / "track-my-demo.yaml").is_file()
    assert "optikin solve optikin-examples/track-my-demo.yaml" in out and "plugin" in out
    assert main(["examples"]) == 2
    assert "already exists" in capsys.readouterr().err
