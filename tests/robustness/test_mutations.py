"""Random mutations of every shipped problem file never crash optikin.

Property (hypothesis): whatever is deleted, retyped or replaced by NaN, infinity, a huge, zero or
negative number, ``optikin show`` (which validates the file and builds the arm and the solver)
exits 0 or 2, never 3; an exit 2 names the file; random bytes are refused with exit 2. For the
cheap kinds the mutated file is also solved on a few samples: the exit code is 0, 1 or 2, and the
output folder holds either one complete result or nothing.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optikin.cli import EXIT_BAD_INPUT, EXIT_INTERNAL, main
from optikin.spec import available, load_problem

SHIPPED = sorted(available("problems"))
CHEAP_KINDS = ("fk", "ik", "ph_shape", "dmp")
REPLACEMENTS: list[Any] = [
    math.nan,
    math.inf,
    -math.inf,
    1e308,
    -1.0,
    0,
    -5,
    "fast",
    "",
    None,
    True,
    [],
    [0.4, 0.1],
    {},
    {"x": 1},
    [[1, 2], [3]],
]


def paths_of(data: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path (tuple of keys and indices) into a YAML document, the document itself excluded."""
    out: list[tuple] = []
    if isinstance(data, dict):
        for key, value in data.items():
            out.append(prefix + (key,))
            out += paths_of(value, prefix + (key,))
    elif isinstance(data, list):
        for i, value in enumerate(data[:4]):
            out.append(prefix + (i,))
            out += paths_of(value, prefix + (i,))
    return out


def mutated(data: dict, path: tuple, replacement: Any, delete: bool) -> dict:
    data = copy.deepcopy(data)
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    if delete:
        del parent[path[-1]]
    else:
        parent[path[-1]] = replacement
    return data


def shipped_data(name: str) -> tuple[dict, Path]:
    _, path = load_problem(name)
    data = yaml.safe_load(path.read_text())
    if isinstance(data.get("data", {}).get("params", {}).get("file"), str):
        data["data"]["params"]["file"] = str((path.parent / data["data"]["params"]["file"]).resolve())
    return data, path


def write(folder: Path, data: dict) -> Path:
    path = folder / f"{data.get('name', 'x') if isinstance(data.get('name'), str) else 'x'}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True))
    return path


def folder_is_complete_or_empty(out: Path) -> None:
    entries = [p for p in out.iterdir()] if out.exists() else []
    for entry in entries:
        assert entry.is_dir() and not entry.name.startswith("."), f"left behind: {entry.name}"
        summary = json.loads((entry / "result.json").read_text())
        assert summary["samples"] >= 1


mutation = st.tuples(st.integers(min_value=0), st.sampled_from(REPLACEMENTS), st.booleans())


@pytest.mark.parametrize("name", SHIPPED)
@settings(max_examples=6, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(change=mutation)
def test_a_mutated_problem_is_validated_or_refused(name, change, tmp_path, capsys):
    data, _ = shipped_data(name)
    paths = paths_of(data)
    index, replacement, delete = change
    path = paths[index % len(paths)]
    problem = write(tmp_path, mutated(data, path, replacement, delete))
    code = main(["show", str(problem)])
    err = capsys.readouterr().err
    assert code in (0, EXIT_BAD_INPUT), f"{name} with {path} -> {replacement!r} (delete={delete}): {err}"
    assert code != EXIT_INTERNAL and "Traceback" not in err
    if code == EXIT_BAD_INPUT:
        assert str(problem) in err or "arm" in err, err


def cheap_shipped() -> list[str]:
    return [name for name in SHIPPED if load_problem(name)[0].kind in CHEAP_KINDS]


@pytest.mark.parametrize("name", cheap_shipped())
@settings(max_examples=3, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(change=mutation)
def test_a_mutated_cheap_problem_solves_or_is_refused_cleanly(name, change, tmp_path, capsys):
    data, _ = shipped_data(name)
    data["data"]["samples"] = min(int(data["data"].get("samples", 100)), 8)
    data.setdefault("outputs", {})["figures"] = False
    options_paths = [p for p in paths_of(data) if p[0] in ("options", "data")]
    index, replacement, delete = change
    path = options_paths[index % len(options_paths)]
    problem = write(tmp_path, mutated(data, path, replacement, delete))
    out = tmp_path / "out"
    code = main(["solve", str(problem), "--out", str(out), "--json", "--no-figures"])
    err = capsys.readouterr().err
    assert code in (0, 1, EXIT_BAD_INPUT), f"{name} with {path} -> {replacement!r} (delete={delete}): {err}"
    folder_is_complete_or_empty(out)


@settings(max_examples=20, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(blob=st.binary(min_size=1, max_size=300))
def test_random_bytes_are_refused(blob, tmp_path, capsys):
    path = tmp_path / "random.yaml"
    path.write_bytes(blob)
    code = main(["show", str(path)])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT, err
    assert str(path) in err


def test_a_demonstration_too_short_to_tune_is_a_field_error(tmp_path, capsys):
    data, _ = shipped_data("dmp-imu-dualquat")
    data["data"]["samples"] = 4  # tau / dt = 3: beta <= 0.9 tau / dt = 2.7 lies below the tuning box's lower bound
    data.setdefault("outputs", {})["figures"] = False
    problem = write(tmp_path, data)
    assert main(["solve", str(problem), "--out", str(tmp_path / "out"), "--json"]) == EXIT_BAD_INPUT
    assert "options.tuning.gains: no admissible range for gain(s) beta" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("geometry", [float("nan"), [1, 2], "big"])
def test_a_cbha_geometry_that_is_not_a_mapping_is_a_field_error(geometry, tmp_path, capsys):
    data, _ = shipped_data("cbha-fk")
    data["arm"]["params"] = {"geometry": geometry}
    problem = write(tmp_path, data)
    assert main(["show", str(problem)]) == EXIT_BAD_INPUT
    assert "arm.params.geometry: expected a mapping of CBHAGeometry fields" in capsys.readouterr().err
