"""``optikin show`` prints no sample count or seed that a source reading a file whole would ignore."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from optikin.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def shown(capsys, name: str) -> dict:
    assert main(["show", name, "--json"]) == 0
    out = capsys.readouterr().out
    return json.loads(out[out.index("\n") + 1 :])


def test_a_file_source_shows_neither_the_default_samples_nor_the_default_seed(capsys):
    data = shown(capsys, "trunk-calibrate-motive")["data"]
    assert data["params"]["file"] and "samples" not in data and "seed" not in data


def test_a_seed_the_file_sets_is_shown(capsys):
    written = yaml.safe_load((EXAMPLES / "track-my-demo.yaml").read_text())["data"]
    data = shown(capsys, str(EXAMPLES / "track-my-demo.yaml"))["data"]
    assert data["seed"] == written["seed"] and "samples" not in data


def test_a_generated_source_shows_both(capsys):
    data = shown(capsys, "cc-ik-position")["data"]
    assert data["samples"] == 1000 and "seed" in data
