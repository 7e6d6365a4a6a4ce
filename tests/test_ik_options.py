"""Typed options of kind ``ik``, of its target sources and of the ``nonlinear`` presets; the ik figure builder.

A typo in any section of a problem file or a preset is a :class:`SpecError` naming the
dotted field ("unknown field"), raised by :func:`optikin.runner.solve` before anything is
solved; the figures of a written result are redrawn from its arrays and summary alone.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from optikin.errors import SpecError
from optikin.problems.ik.figures import figures
from optikin.problems.ik.options import FormulationOptions, IkOptions
from optikin.results import read_result
from optikin.runner import solve
from optikin.spec import available

HOME = [0.18, 0.6, 0.0, 0.18, 0.6, 1.5707963267948966]
PRESETS = ("gauss-newton", "gauss-newton-compiled", "newton", "ipopt", "sqpmethod", "lm", "trf")


def write_problem(tmp_path: Path, name: str = "small", **fields) -> Path:
    spec: dict[str, Any] = {
        "name": name,
        "title": "test",
        "kind": "ik",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": {"source": "random", "seed": 1, "samples": 4},
        "solver": "gauss-newton",
        "options": {"target": "position", "redundancy": "minimum_norm", "start": HOME, "restarts": 1},
    }
    for key, value in fields.items():
        spec[key] = spec[key] | value if isinstance(value, dict) and key in ("data", "options") else value
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def unknown_field(path: Path, solver: str | None = None) -> SpecError:
    with pytest.raises(SpecError) as info:
        solve(str(path), solver=solver, figures=False)
    assert "unknown field" in str(info.value), str(info.value)
    return info.value


def test_options_defaults_are_the_documented_ones():
    o = IkOptions()
    assert (o.target, o.redundancy, o.rest, o.weights, o.start, o.restarts, o.tolerance) == (
        "position",
        "rest",
        None,
        None,
        "rest",
        6,
        1e-10,
    )
    assert (o.orientation_length, o.penalty, o.penalty_on, o.elongation, o.variants) == (
        None,
        1e-6,
        "configuration",
        "free",
        {},
    )
    assert set(FormulationOptions.model_fields) < set(IkOptions.model_fields)


@pytest.mark.parametrize(
    "options, field",
    [
        ({"targett": "position"}, "options.targett"),
        ({"restart": 1}, "options.restart"),
        ({"variants": {"v": {"redundancyy": "penalty"}}}, "options.variants.v.redundancyy"),
        ({"variants": {"v": {"start": "rest"}}}, "options.variants.v.start"),
    ],
)
def test_a_typo_in_the_options_names_the_field(tmp_path, options, field):
    assert unknown_field(write_problem(tmp_path, options=options)).field == field


@pytest.mark.parametrize(
    "data, field",
    [
        ({"source": "random", "params": {"unreachabel": 3}}, "data.params.unreachabel"),
        ({"source": "trajectory", "params": {"ratee": 50.0}}, "data.params.ratee"),
        ({"source": "csv", "params": {"file": "targets.csv", "trajectoryy": True}}, "data.params.trajectoryy"),
    ],
)
def test_a_typo_in_the_params_of_each_target_source_names_the_field(tmp_path, data, field):
    (tmp_path / "targets.csv").write_text("x,y,z\n0.0,0.0,0.36\n")
    assert unknown_field(write_problem(tmp_path, data=data)).field == field


@pytest.mark.parametrize(
    "options, field",
    [
        ({"unreachable": -1}, "data.params.unreachable"),
        ({"unreachable": True}, "data.params.unreachable"),
        ({"margin": [0.9, 1.2]}, "data.params.margin"),
    ],
)
def test_bad_random_params_name_the_field(tmp_path, options, field):
    with pytest.raises(SpecError) as info:
        solve(str(write_problem(tmp_path, data={"params": options})), figures=False)
    assert info.value.field == field


def test_a_csv_source_needs_its_file(tmp_path):
    with pytest.raises(SpecError) as info:
        solve(str(write_problem(tmp_path, data={"source": "csv", "params": {}})), figures=False)
    assert info.value.field == "data.params.file"


@pytest.mark.parametrize("preset", PRESETS)
def test_a_typo_in_each_nonlinear_preset_names_the_field(tmp_path, preset):
    spec = yaml.safe_load(Path(available("solvers")[preset]).read_text())
    spec["name"] = f"typo-{preset}"
    spec["options"] = dict(spec.get("options") or {}) | {"tolerancee": 1.0}
    path = tmp_path / f"typo-{preset}.yaml"
    path.write_text(yaml.safe_dump(spec))
    error = unknown_field(write_problem(tmp_path), solver=str(path))
    assert error.field == "options.tolerancee"
    assert str(path) in str(error)


@pytest.mark.parametrize("preset", ("ipopt", "sqpmethod"))
def test_a_typo_in_a_plugin_setting_names_the_setting(tmp_path, preset):
    spec = yaml.safe_load(Path(available("solvers")[preset]).read_text())
    spec["name"] = f"typo-{preset}"
    spec["options"]["settings"]["hessian_approximationn"] = "exact"
    path = tmp_path / f"typo-{preset}.yaml"
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(SpecError) as info:
        solve(str(write_problem(tmp_path)), solver=str(path), figures=False)
    assert info.value.field == "options.settings.hessian_approximationn"


@pytest.mark.parametrize(
    "fields, expected",
    [
        ({"baselines": ["lm"]}, {"targets", "comparison"}),
        (
            {"data": {"source": "trajectory", "samples": 20}, "options": {"redundancy": "previous"}},
            {"targets", "trajectory", "comparison"},
        ),
        (
            {
                "arm": {"type": "cbha"},
                "data": {"samples": 2},
                "options": {"target": "legs", "start": "rest", "redundancy": "rest", "tolerance": 1e-12},
            },
            {"targets"},
        ),
    ],
)
def test_the_figures_are_redrawn_from_the_written_result(tmp_path, fields, expected):
    result, folder = solve(str(write_problem(tmp_path, **fields)), out=tmp_path / "out", figures=True)
    assert folder is not None
    summary, arrays = read_result(folder)
    assert {Path(f).stem for f in summary["figures"]} == expected
    drawers = figures(arrays, summary)
    assert set(drawers) == expected
    for name, draw in drawers.items():
        draw(tmp_path / f"{name}.png")
        assert (tmp_path / f"{name}.png").stat().st_size > 0
