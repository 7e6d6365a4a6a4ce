"""The PH kinds as packages: typed options, their data sources' params, the ph backends' preset options,
and the figure builders (a written result is redrawn from its arrays and summary alone)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.errors import SpecError
from optikin.problems import load_kinds
from optikin.problems.ph_shared import problem_variant, recording_of
from optikin.registry import PROBLEM_KINDS
from optikin.results import read_result
from optikin.runner import solve

TYPO = "colour"
PROBLEMS = {"ph_shape": "cbha-ph-shape", "ph_ik": "cbha-ph-ik", "ph_chain": "cbha-rope-chain"}


def small(tmp_path: Path, problem: str, samples: int = 2, **changes) -> Path:
    return problem_variant(problem, tmp_path / "problems", samples=samples, baselines=[], **changes)


def with_data(path: Path, source: str, params: dict) -> Path:
    raw = yaml.safe_load(path.read_text())
    raw["data"]["source"], raw["data"]["params"] = source, params
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def error_of(problem: Path, solver: str | None = None) -> SpecError:
    with pytest.raises(SpecError) as err:
        solve(str(problem), solver=solver)
    return err.value


@pytest.mark.parametrize("problem", sorted(PROBLEMS.values()))
def test_options_typo_is_named(tmp_path, problem):
    err = error_of(small(tmp_path, problem, options={TYPO: 1}))
    assert err.field == f"options.{TYPO}" and "unknown field" in str(err)


@pytest.mark.parametrize(
    "problem, source, params",
    [
        ("cbha-ph-shape", "synthetic", {"noise": 0.0}),
        ("cbha-ph-shape", "csv", {"file": "recorded.csv"}),
        ("cbha-ph-ik", "csv", {"file": "recorded.csv", "intermediate": [5, 9, 13]}),
        ("cbha-rope-chain", "synthetic", {"rope_length": 0.6}),
    ],
)
def test_data_params_typo_of_each_source_is_named(tmp_path, problem, source, params):
    err = error_of(with_data(small(tmp_path, problem), source, {**params, TYPO: 1}))
    assert err.field == f"data.params.{TYPO}" and "unknown field" in str(err)


@pytest.mark.parametrize(
    "backend, options",
    [
        ("ph_newton", {"compile": False}),
        ("ph_ipopt", {"warm_start": False}),
        ("ph_grid", {"n": 16}),
    ],
)
def test_preset_options_typo_of_each_backend_is_named(tmp_path, backend, options):
    preset = tmp_path / "solvers" / "typo.yaml"
    preset.parent.mkdir(parents=True)
    preset.write_text(yaml.safe_dump({"name": "typo", "backend": backend, "options": {**options, TYPO: 1}}))
    err = error_of(small(tmp_path, "cbha-ph-shape"), solver=str(preset))
    assert err.field == f"options.{TYPO}" and "unknown field" in str(err) and err.path == str(preset)


@pytest.mark.parametrize(
    "problem, options, data, field",
    [
        ("cbha-ph-shape", {"length": "guess"}, None, "options.length"),
        ("cbha-ph-shape", {"length": -0.3}, None, "options.length"),
        ("cbha-ph-shape", {"nodes": 1}, None, "options.nodes"),
        ("cbha-ph-shape", {"free_speeds": "yes"}, None, "options.free_speeds"),
        ("cbha-ph-shape", {"twist_weight": -1.0}, None, "options.twist_weight"),
        ("cbha-ph-ik", {"frame": "frenet"}, None, "options.frame"),
        ("cbha-ph-ik", {"tube_radius": [0.04]}, None, "options.tube_radius.1"),
        ("cbha-ph-ik", {"tube_radius": 0.04}, None, "options.tube_radius"),
        ("cbha-ph-ik", {"tube_radius": [0.04, -0.03]}, None, "options.tube_radius.1"),
        ("cbha-rope-chain", {"rope_free_speeds": 1}, None, "options.rope_free_speeds"),
        ("cbha-ph-shape", {}, ("synthetic", {"amplitude": 1.5}), "data.params.amplitude"),
        ("cbha-ph-shape", {}, ("synthetic", {"frequency": [0.4, 0.1]}), "data.params.frequency"),
        ("cbha-ph-shape", {}, ("csv", {}), "data.params.file"),
        ("cbha-rope-chain", {}, ("synthetic", {"rope_length": 0.0}), "data.params.rope_length"),
        ("cbha-rope-chain", {}, ("csv", {"file": "x.csv"}), "data.source"),
    ],
)
def test_bad_values_are_named(tmp_path, problem, options, data, field):
    path = small(tmp_path, problem, options=options)
    if data is not None:
        with_data(path, *data)
    assert error_of(path).field == field


def test_kinds_declare_their_models():
    load_kinds()
    for kind, family in (("ph_shape", "markers"), ("ph_ik", "markers"), ("ph_chain", "rope_chains")):
        registered = PROBLEM_KINDS.get(kind)
        assert registered.options is not None and registered.data_family == family
        assert registered.figures is not None


@pytest.mark.parametrize("kind", sorted(PROBLEMS))
def test_figure_builder_redraws_the_written_figures(tmp_path, kind):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    load_kinds()
    _, folder = solve(str(small(tmp_path, PROBLEMS[kind])), out=tmp_path / "out")
    written = sorted(p.stem for p in folder.glob("*.png"))
    assert written == (["errors", "times"] if kind == "ph_ik" else ["errors", "shapes", "times"])
    summary, arrays = read_result(folder)
    drawers = PROBLEM_KINDS.get(kind).figures(arrays, summary)
    assert sorted(drawers) == written
    for name, draw in drawers.items():
        draw(tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 1000


def test_figures_missing_their_arrays_are_left_out():
    load_kinds()
    for kind in PROBLEMS:
        assert PROBLEM_KINDS.get(kind).figures({}, {"problem": "p"}) == {}
    shape = PROBLEM_KINDS.get("ph_shape").figures
    assert list(shape({"seconds_ph-newton": np.ones(3)}, {"problem": "p"})) == ["times"]


def test_cosserat_wrench_baseline_reports_its_row(tmp_path):
    """The rod fits of a Cosserat-rod recording lie near its truth backbone (the data source's own equilibria)."""
    load_kinds()
    problem = problem_variant("cbha-ph-shape-cosserat", tmp_path / "problems", samples=3, baselines=["cosserat-wrench"])
    result, _ = solve(str(problem), out=tmp_path / "out")
    rows = {row.method: row.metrics for row in result.comparison}
    row = rows["cosserat-wrench"]
    assert row["ok"] == "3/3" and row["failed fits"] == 0
    per_marker = np.asarray(row["mean distance per marker [mm]"])
    assert per_marker.shape == (3,) and np.all(np.isfinite(per_marker))
    assert np.isfinite(row["mean marker distance [mm]"]) and row["median time per sample [us]"] > 0
    # a stretched, coiled rod under hundreds of newtons also reaches the tip pose, about 90 mm off the arm
    assert row["truth backbone: largest node distance [mm]"] < 10.0


def test_the_base_pose_is_each_postures_own_unless_the_problem_fixes_it(tmp_path):
    """Without ``fixed_base`` every posture keeps its measured base pose; ``fixed_base: true`` (the shipped
    file's) uses their mean for all."""
    path = small(tmp_path / "own", "cbha-ph-shape", samples=3)
    raw = yaml.safe_load(path.read_text())
    del raw["options"]["fixed_base"]
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    recording = recording_of("cbha-ph-shape", 3)
    own, _ = solve(str(path))
    np.testing.assert_array_equal(own.arrays["base_position"], recording.base_position)
    fixed, _ = solve(str(small(tmp_path / "fixed", "cbha-ph-shape", samples=3)))
    mean = np.tile(recording.base_position.mean(axis=0), (3, 1))
    np.testing.assert_allclose(fixed.arrays["base_position"], mean, atol=1e-15)
    assert np.ptp(recording.base_position, axis=0).max() > 1e-4  # the noise the mean removes
