"""Numbers mean what they say: strict YAML and strict types in problem files, bounds, and file sources.

Every case is a copy of a shipped problem with one thing changed, checked through the command
line (``optikin show`` or ``solve``): exit 2 and one line naming the file and the field at fault.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import pytest
import yaml

from optikin.cli import EXIT_BAD_INPUT, main
from optikin.spec import MAX_DEPTH, load_problem, load_yaml

Edit = Callable[[dict[str, Any]], None]


def copied(tmp_path: Path, name: str, edit: Edit | None = None, text: Callable[[str], str] | None = None) -> Path:
    """The shipped problem ``name`` written into ``tmp_path`` (its arm and data files made absolute), changed by
    ``edit`` (on the mapping) and then by ``text`` (on the YAML text)."""
    _, path = load_problem(name)
    data = yaml.safe_load(path.read_text())
    params = data.get("data", {}).get("params") or {}
    for key in ("file", "path"):
        if isinstance(params.get(key), str):
            params[key] = str((path.parent / params[key]).resolve())
    if isinstance(data.get("arm"), str):
        data["arm"] = str((path.parent / data["arm"]).resolve())
    if edit is not None:
        edit(data)
    out = tmp_path / path.name
    content = yaml.safe_dump(data, sort_keys=False)
    out.write_text(text(content) if text is not None else content)
    return out


def refused(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """The one error line of ``optikin argv`` (asserting exit 2 and a single line)."""
    assert main(list(argv)) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def setter(*keys: Any, value: Any) -> Edit:
    def edit(data: dict[str, Any]) -> None:
        node = data
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        node[keys[-1]] = value

    return edit


# --------------------------------------------------------------------------- YAML


@pytest.mark.parametrize(
    "tag", ["!!binary aGVsbG8=", "!!python/object/apply:os.getcwd []", "!custom x", "!!timestamp 2024-01-01"]
)
def test_a_tag_outside_the_core_schema_is_refused_naming_the_line(tmp_path, capsys, tag):
    problem = copied(tmp_path, "cc-two-section-fk", text=lambda t: f"{t}outputs_note: {tag}\n")
    line = len(problem.read_text().splitlines())
    err = refused(capsys, "show", str(problem))
    assert str(problem) in err and f"line {line}" in err and "not accepted" in err


def test_a_binary_title_is_refused(tmp_path, capsys):
    problem = copied(tmp_path, "cc-two-section-fk", text=lambda t: t.replace("title: ", "title: !!binary ", 1))
    assert "'!!binary' is not accepted" in refused(capsys, "show", str(problem))


@pytest.mark.parametrize(
    "text, value",
    [("1e6", 1e6), ("1.0e6", 1e6), ("-2E-3", -2e-3), (".5", 0.5), ("010", 10), ("0o10", 8), ("0x10", 16)],
)
def test_numbers_resolve_as_in_yaml_1_2(text, value):
    read = load_yaml(f"x: {text}", "test.yaml")["x"]
    assert read == value and type(read) is type(value)


@pytest.mark.parametrize("text", ["yes", "on", "1_000", "1:30", "2024-01-01", "0b101"])
def test_yaml_1_1_only_forms_are_strings(text):
    assert load_yaml(f"x: {text}", "test.yaml")["x"] == text


def test_an_exponent_without_a_sign_or_a_dot_reaches_a_strict_float_field(tmp_path):
    problem = copied(tmp_path, "track-nominal", setter("options", "damping", value=0.5))
    problem.write_text(problem.read_text().replace("damping: 0.5", "damping: 1.0e6"))
    spec, _ = load_problem(str(problem))
    assert main(["show", str(problem)]) == 0 and spec.options["damping"] == 1e6


def test_nesting_deeper_than_the_limit_in_a_set_value_is_one_line(tmp_path, capsys):
    err = refused(
        capsys, "solve", "cc-two-section-fk", "--out", str(tmp_path / "out"), "--set", "description=" + "[" * 5000
    )
    assert "--set" in err and "description" in err and f"nested too deeply (more than {MAX_DEPTH} levels)" in err
    assert not (tmp_path / "out").exists()


def test_nesting_deeper_than_the_limit_in_a_file_names_the_line(tmp_path, capsys):
    problem = copied(tmp_path, "cc-two-section-fk", text=lambda t: t + "deep: " + "[" * 5000 + "\n")
    assert f"nested too deeply (more than {MAX_DEPTH} levels)" in refused(capsys, "show", str(problem))


# --------------------------------------------------------------------------- strict types


@pytest.mark.parametrize(
    "name, keys, value, field, words",
    [
        ("cc-two-section-fk", ("data", "samples"), True, "data.samples", "expected an integer, got true"),
        ("cc-two-section-fk", ("data", "samples"), 100.0, "data.samples", "expected an integer, got 100.0"),
        (
            "cc-two-section-fk",
            ("outputs", "figures"),
            1,
            "outputs.figures",
            "expected a boolean (true or false), got 1",
        ),
        ("track-nominal", ("options", "gain"), "2.0", "options.gain", "a quoted number"),
        ("track-nominal", ("options", "damping"), "0.001", "options.damping", "a quoted number"),
        ("track-nominal", ("options", "compiled"), "true", "options.compiled", "a boolean (true or false)"),
        ("track-nominal", ("options", "plant", "tip_position_noise"), False, "options.plant.tip_position_noise", ""),
        ("cc-two-section-fk", ("arm", "params", "theta_max"), "2.0", "arm.params.theta_max", "without quotes"),
    ],
)
def test_a_value_of_the_wrong_type_is_a_field_error(tmp_path, capsys, name, keys, value, field, words):
    problem = copied(tmp_path, name, setter(*keys, value=value))
    err = refused(capsys, "show", str(problem))
    assert f"{problem}: {field}: " in err and words in err


def test_a_sexagesimal_number_is_not_read_as_an_integer(tmp_path, capsys):
    problem = copied(tmp_path, "cc-two-section-fk", text=lambda t: t.replace("samples: 1000", "samples: 16:40"))
    assert "data.samples: expected an integer, got the string '16:40'" in refused(capsys, "show", str(problem))


def test_an_unknown_rate_limit_key_is_refused(tmp_path, capsys):
    problem = copied(tmp_path, "track-nominal", setter("options", "rate_limits", value={"X": 1.0}))
    err = refused(capsys, "show", str(problem))
    assert "options.rate_limits.X: unknown variable or prefix 'X'" in err


def test_rate_limits_by_prefix_and_by_variable_are_accepted(tmp_path):
    problem = copied(tmp_path, "track-nominal", setter("options", "rate_limits", value={"S": 0.2, "theta2": 1.0}))
    assert main(["show", str(problem)]) == 0


def test_a_number_too_large_for_an_arm_parameter_is_refused(tmp_path, capsys):
    problem = copied(tmp_path, "cc-two-section-fk", setter("arm", "params", "section_lengths", value=[1e300, 0.18]))
    assert "arm.params.section_lengths.0: 1e+300 is above" in refused(capsys, "show", str(problem))


def test_an_integer_is_still_a_float(tmp_path):
    problem = copied(tmp_path, "track-nominal", setter("options", "gain", value=5))
    assert main(["show", str(problem)]) == 0


# --------------------------------------------------------------------------- physical bounds


@pytest.mark.parametrize(
    "name, keys, value, field, bound",
    [
        ("track-nominal", ("options", "plant", "tip_position_noise"), 1e300, "options.plant.tip_position_noise", "100"),
        ("track-nominal", ("options", "barrier", "margin"), 1e6, "options.barrier.margin", "100"),
        (
            "track-nominal",
            ("options", "plant", "disturbance_window"),
            [0.0, 1e300],
            "options.plant.disturbance_window.1",
            "1e+06",
        ),
        ("track-nominal", ("options", "plant", "tip_angle_noise"), 1e200, "options.plant.tip_angle_noise", "1000"),
        ("cc-two-section-fk", ("data", "params", "rate"), 1e300, "data.params.rate", "1e+06"),
    ],
)
def test_a_length_time_angle_or_rate_beyond_its_unit_bound_names_the_bound(
    tmp_path, capsys, name, keys, value, field, bound
):
    problem = copied(tmp_path, name, setter(*keys, value=value))
    err = refused(capsys, "show", str(problem))
    shown = max(value) if isinstance(value, list) else value
    assert f".yaml: {field}: expected a number less than or equal to {bound}, got {shown:g}" in err


def test_a_tracking_disturbance_window_that_ends_before_it_starts_is_refused(tmp_path, capsys):
    problem = copied(tmp_path, "track-disturbance", setter("options", "plant", "disturbance_window", value=[3.0, 2.0]))
    err = refused(capsys, "show", str(problem))
    assert "options.plant.disturbance_window: the start t_on = 3 s is not before the end t_off = 2 s" in err


def test_a_dmp_disturbance_that_stops_before_it_starts_is_refused(tmp_path, capsys):
    problem = copied(tmp_path, "dmp-perturbation", setter("options", "disturbance", "start", value=8.0))
    assert "options.disturbance: start = 8 s is not before stop = 7 s" in refused(capsys, "show", str(problem))


def test_a_waypoint_outside_the_arms_limits_names_the_entry_and_the_limits(tmp_path, capsys):
    def edit(data: dict[str, Any]) -> None:
        data["data"]["params"]["waypoints"][0][1] = 5.0

    problem = copied(tmp_path, "track-into-limits", edit)
    err = refused(capsys, "solve", str(problem), "--out", str(tmp_path / "out"))
    assert "data.params.waypoints.0.1: theta1 = 5 is outside the arm's limits [-2.0944, 2.0944]" in err
    assert not (tmp_path / "out").exists()
