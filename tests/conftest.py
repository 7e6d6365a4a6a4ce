"""Fixtures shared by the test files: the arm most tests use, shipped problems solved once per session with
``overrides`` (:func:`optikin.runner.solve`), and changed copies of a shipped problem's YAML for the changes
``overrides`` cannot make."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

import pytest
import yaml

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.results import Result
from optikin.runner import solve
from optikin.spec import load_problem

Overrides = Sequence[tuple[str, Any]]


@pytest.fixture(scope="session")
def cc_arm() -> ConstantCurvatureArm:
    """The default two-section constant-curvature arm (its CasADi Functions built once per session)."""
    return ConstantCurvatureArm()


def write_variant(directory: Path, name: str, change: Callable[[dict[str, Any]], None]) -> Path:
    """A copy of shipped problem ``name`` in ``directory`` with ``change(data)`` applied to its YAML; a data file
    given by a relative path is pointed at the shipped one."""
    _, path = load_problem(name)
    data = yaml.safe_load(path.read_text())
    change(data)
    params = data.get("data", {}).get("params", {})
    if isinstance(params.get("file"), str):
        params["file"] = str((path.parent / params["file"]).resolve())
    out = directory / f"{name}.yaml"
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


@pytest.fixture
def problem_variant(tmp_path: Path) -> Callable[[str, Callable[[dict[str, Any]], None]], Path]:
    """``problem_variant(name, change)``: :func:`write_variant` in the test's own folder (for changes
    ``overrides`` cannot make: removing a field, a malformed value the schema refuses)."""
    return lambda name, change: write_variant(tmp_path, name, change)


@pytest.fixture(scope="session")
def solved() -> Callable[..., Result]:
    """``solved(name, overrides)``: the Result of shipped problem ``name`` solved with ``overrides`` and no
    figures, solved once per session for each distinct ``(name, overrides)`` (read it, do not change it)."""
    cache: dict[tuple[str, str], Result] = {}

    def run(name: str, overrides: Overrides = ()) -> Result:
        key = (name, repr(list(overrides)))
        if key not in cache:
            cache[key] = solve(name, figures=False, overrides=list(overrides))[0]
        return cache[key]

    return run
