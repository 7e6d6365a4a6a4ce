"""The ``fk`` kind as a package: typed options, its four configuration sources, the three evaluation
backends' preset options, the baselines and the figure builder."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.errors import SpecError
from optikin.problems import load_kinds
from optikin.problems.fk import numpy_tip_dq
from optikin.problems.fk import figures as fk_figures
from optikin.problems.fk.figures import figures
from optikin.registry import PROBLEM_KINDS
from optikin.results import read_result
from optikin.runner import prepare, solve

TYPO = "colour"


def problem_file(tmp_path: Path, data: dict | None = None, **fields) -> Path:
    """A small fk problem (two-section CC arm, 6 random samples) with ``fields`` replaced."""
    spec = {
        "name": "small-fk",
        "title": "a small fk problem",
        "kind": "fk",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": {"source": "random", "seed": 3, "samples": 6, **(data or {})},
        "baselines": ["numpy"],
        **fields,
    }
    path = tmp_path / "problems" / "small-fk.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(spec))
    return path


def preset_file(tmp_path: Path, name: str, backend: str, options: dict) -> Path:
    path = tmp_path / "solvers" / f"{name}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump({"name": name, "backend": backend, "options": options}))
    return path


def error_of(problem: Path, solver: str | None = None) -> SpecError:
    with pytest.raises(SpecError) as err:
        solve(str(problem), solver=solver)
    return err.value


# --------------------------------------------------------------------------- option typos


def test_fk_options_typo_is_named(tmp_path):
    err = error_of(problem_file(tmp_path, options={"x": 1}))
    assert err.field == "options.x" and "unknown field" in str(err)


@pytest.mark.parametrize(
    "source, params",
    [
        ("random", {}),
        ("trajectory", {"rate": 50.0}),
        ("sweep", {"variable": "theta1"}),
        ("csv", {"file": "q.csv"}),
    ],
)
def test_data_params_typo_of_each_source_is_named(tmp_path, source, params):
    err = error_of(problem_file(tmp_path, data={"source": source, "params": {**params, TYPO: 1}}))
    assert err.field == f"data.params.{TYPO}" and "unknown field" in str(err)


@pytest.mark.parametrize(
    "backend, options",
    [
        ("casadi_map", {}),
        ("casadi_call", {}),
        ("casadi_compiled", {"flags": ["-O2"]}),
    ],
)
def test_preset_options_typo_of_each_backend_is_named(tmp_path, backend, options):
    preset = preset_file(tmp_path, "typo", backend, {**options, TYPO: 1})
    err = error_of(problem_file(tmp_path), solver=str(preset))
    assert err.field == f"options.{TYPO}" and "unknown field" in str(err) and err.path == str(preset)


@pytest.mark.parametrize(
    "data, field",
    [
        ({"source": "trajectory", "params": {"rate": 0.0}}, "data.params.rate"),
        ({"source": "trajectory", "params": {"rate": "fast"}}, "data.params.rate"),
        ({"source": "trajectory", "params": {"amplitude": 1.5}}, "data.params.amplitude"),
        ({"source": "trajectory", "params": {"amplitude": -0.1}}, "data.params.amplitude"),
        ({"source": "trajectory", "params": {"frequency": [0.4, 0.1]}}, "data.params.frequency"),
        ({"source": "trajectory", "params": {"frequency": [-0.1, 0.1]}}, "data.params.frequency"),
        ({"source": "trajectory", "params": {"frequency": [0.1]}}, "data.params.frequency.1"),
        ({"source": "sweep", "params": {"variable": "elbow"}}, "data.params.variable"),
        ({"source": "sweep", "params": {"fixed": {"elbow": 0.1}}}, "data.params.fixed.elbow"),
        ({"source": "sweep", "params": {"fixed": {"theta1": "up"}}}, "data.params.fixed.theta1"),
        ({"source": "csv"}, "data.params.file"),
        ({"source": "csv", "params": {"file": ""}}, "data.params.file"),
    ],
)
def test_bad_data_params_are_named(tmp_path, data, field):
    assert error_of(problem_file(tmp_path, data=data)).field == field


def test_kind_declares_its_models(monkeypatch):
    load_kinds()
    kind = PROBLEM_KINDS.get("fk")
    assert kind.options is not None and kind.data_family == "configurations"
    calls = []
    monkeypatch.setattr(fk_figures, "figures", lambda arrays, summary: calls.append((arrays, summary)) or {})
    arrays, summary = {"q": np.zeros((1, 6))}, {"kind": "fk"}
    assert kind.figures(arrays, summary) == {}  # the kind draws with optikin.problems.fk.figures.figures
    assert calls == [(arrays, summary)]


# --------------------------------------------------------------------------- sources and baselines


def test_sweep_moves_one_variable_and_holds_the_others(tmp_path):
    problem = problem_file(
        tmp_path, data={"source": "sweep", "samples": 5, "params": {"variable": "theta2", "fixed": {"phi1": 0.5}}}
    )
    _, ctx = prepare(str(problem))
    Q, t = ctx.load_data()
    arm, j = ctx.arm, ctx.arm.config_names.index("theta2")
    assert t is None and Q.shape == (5, arm.n_config)
    np.testing.assert_allclose(Q[:, j], np.linspace(arm.lower[j], arm.upper[j], 5))
    assert np.all(Q[:, arm.config_names.index("phi1")] == 0.5)


def test_trajectory_is_sampled_at_the_rate(tmp_path):
    problem = problem_file(tmp_path, data={"source": "trajectory", "samples": 7, "params": {"rate": 20}})
    _, ctx = prepare(str(problem))
    Q, t = ctx.load_data()
    np.testing.assert_allclose(t, np.arange(7) / 20.0)
    mid, half = 0.5 * (ctx.arm.lower + ctx.arm.upper), 0.5 * (ctx.arm.upper - ctx.arm.lower)
    assert np.all(np.abs(Q - mid) <= 0.8 * half + 1e-15)


def test_csv_rows_are_read_relative_to_the_problem_file(tmp_path):
    problem = problem_file(tmp_path, data={"source": "csv", "samples": 2, "params": {"file": "q.csv"}})
    (problem.parent / "q.csv").write_text(
        textwrap.dedent("""\
        t,S1,theta1,phi1,S2,theta2,phi2
        0.0,0.18,0.1,0.2,0.18,0.3,0.4
        0.5,0.18,0.2,0.2,0.18,0.3,0.4
        1.0,0.18,0.3,0.2,0.18,0.3,0.4
        """)
    )
    result, _ = solve(str(problem))
    np.testing.assert_array_equal(result.arrays["t"], [0.0, 0.5])
    assert result.arrays["configurations"].shape == (2, 6) and result.succeeded


def test_results_agree_with_numpy_and_an_evaluation_preset_baseline(tmp_path):
    result, _ = solve(str(problem_file(tmp_path, baselines=["numpy", "casadi-call"])))
    rows = {row.method: row for row in result.comparison}
    assert list(rows) == ["casadi-map", "numpy", "casadi-call"]
    assert rows["casadi-call"].role == "baseline"
    assert all(row.metrics["max |tip - numpy| [mm]"] < 1e-9 for row in rows.values())
    np.testing.assert_allclose(
        result.arrays["tip_dq"], numpy_tip_dq(_arm(), result.arrays["configurations"]), atol=1e-12
    )
    assert result.succeeded and set(result.arrays) == {
        "configurations",
        "tip_dq",
        "tip_position",
        "section_dq",
        "backbone",
    }


def _arm():
    from optikin.arms.constant_curvature import ConstantCurvatureArm

    return ConstantCurvatureArm(section_lengths=(0.18, 0.18))


# --------------------------------------------------------------------------- figures


@pytest.mark.parametrize("source", ["random", "trajectory"])
def test_figure_builder_redraws_the_written_figures(tmp_path, source):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    _, folder = solve(str(problem_file(tmp_path, data={"source": source})), out=tmp_path / "out")
    written = sorted(p.stem for p in folder.glob("*.png"))
    assert written == ["backbones", "tip"]
    summary, arrays = read_result(folder)
    drawers = figures(arrays, summary)
    assert sorted(drawers) == written
    for name, draw in drawers.items():
        draw(tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 1000


def test_figures_missing_their_arrays_are_left_out():
    assert figures({}, {"problem": "p"}) == {}
    assert list(figures({"tip_position": np.zeros((2, 3))}, {"problem": "p"})) == ["tip"]
