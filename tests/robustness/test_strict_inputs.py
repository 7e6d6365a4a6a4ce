"""Numbers mean what they say: strict YAML and strict types in problem files, bounds, and file sources.

Every case is a copy of a shipped problem with one thing changed, checked through the command
line (``optikin show`` or ``solve``): exit 2 and one line naming the file and the field at fault.
"""

from __future__ import annotations

import warnings
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
        ("cc-two-section-fk", ("arm", "params", "theta_max"), [1.0, 2.0], "arm.params.theta_max", "one number"),
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
    assert "data.params.waypoints.0.1: theta1 = 5 is too far outside the arm's limits [-2.0944, 2.0944]: " in err
    assert "a waypoint may lie in [-3.14159, 3.14159]" in err
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- file sources

SHIPPED = Path(load_problem("trunk-ik")[1]).parent
RECORDINGS = SHIPPED / "data" / "recordings"


def with_file(tmp_path: Path, name: str, content: str | bytes, **params: Any) -> Path:
    """The shipped problem ``name`` reading ``content`` (written as ``data.csv``), ``params`` set in ``data.params``."""
    data_path = tmp_path / "data.csv"
    data_path.write_bytes(content if isinstance(content, bytes) else content.encode())

    def edit(data: dict[str, Any]) -> None:
        data["data"]["params"].update(file=str(data_path), **params)
        data["data"]["samples"] = 3

    return copied(tmp_path, name, edit)


def rewritten(path: Path, change: Callable[[int, str, str], str]) -> str:
    """The CSV file ``path`` with each cell of data row ``i`` under header name ``h`` replaced by
    ``change(i, h, cell)``."""
    header, *rows = path.read_text().splitlines()
    names = header.split(",")
    out = [header]
    for i, row in enumerate(rows):
        out.append(",".join(change(i, h, c) for h, c in zip(names, row.split(","))))
    return "\n".join(out) + "\n"


def solve_refused(capsys: pytest.CaptureFixture[str], problem: Path, tmp_path: Path) -> str:
    err = refused(capsys, "solve", str(problem), "--out", str(tmp_path / "out"))
    assert not (tmp_path / "out").exists()
    return err


def test_a_duplicate_column_name_is_refused_naming_both_columns(tmp_path, capsys):
    header, *rows = (SHIPPED / "trunk-markers.csv").read_text().splitlines()
    content = "\n".join([header.replace("m2_x", "m1_x"), *rows]) + "\n"
    err = solve_refused(capsys, with_file(tmp_path, "trunk-ph-shape", content), tmp_path)
    assert "column 'm1_x' appears twice in the header: columns 16 and 19" in err


def test_marker_positions_in_millimetres_read_as_metres_get_a_unit_hint(tmp_path, capsys):
    content = rewritten(SHIPPED / "trunk-markers.csv", lambda i, h, c: str(float(c) * 1e3) if h[-2:] in XYZ else c)
    err = solve_refused(capsys, with_file(tmp_path, "trunk-ph-shape", content), tmp_path)
    assert "sample 0: base_x: coordinate 30.0809 m is beyond 10 m" in err
    assert "values look like millimetres: set data.params.units: mm" in err


def test_marker_positions_in_millimetres_are_read_with_units_mm(tmp_path):
    content = rewritten(SHIPPED / "trunk-markers.csv", lambda i, h, c: str(float(c) * 1e3) if h[-2:] in XYZ else c)
    problem = with_file(tmp_path, "trunk-ph-shape", content, units="mm")
    assert main(["solve", str(problem), "--out", str(tmp_path / "out")]) == 0


XYZ = ("_x", "_y", "_z")


def test_a_tip_at_the_base_is_refused_naming_the_row(tmp_path, capsys):
    header = (SHIPPED / "trunk-markers.csv").read_text().splitlines()[0].split(",")
    rows = [r.split(",") for r in (SHIPPED / "trunk-markers.csv").read_text().splitlines()[1:]]
    for c in "xyz":
        rows[2][header.index(f"tip_{c}")] = rows[2][header.index(f"base_{c}")]
    content = "\n".join([",".join(header), *(",".join(r) for r in rows)]) + "\n"
    err = solve_refused(capsys, with_file(tmp_path, "trunk-ph-shape", content), tmp_path)
    assert "sample 2: tip_x: the tip's position is the base's (0 m apart)" in err and "(line 4)" in err


def test_targets_in_millimetres_get_a_unit_hint(tmp_path, capsys):
    content = rewritten(SHIPPED / "trunk-points.csv", lambda i, h, c: str(float(c) * 1e3))
    err = solve_refused(capsys, with_file(tmp_path, "trunk-ik", content), tmp_path)
    assert "disk1_x: coordinate 65.6658 m is beyond 10 m" in err and "set data.params.units: mm" in err


def test_a_target_at_1e200_is_refused_without_a_warning(tmp_path, capsys):
    content = rewritten(SHIPPED / "trunk-points.csv", lambda i, h, c: "1e200" if (i, h) == (1, "disk2_y") else c)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        err = solve_refused(capsys, with_file(tmp_path, "trunk-ik", content), tmp_path)
    assert "sample 1: disk2_y: coordinate 1e+200 m is beyond 10 m" in err


@pytest.mark.parametrize("value", ["1e150", "1e299"])
def test_demonstration_positions_far_beyond_any_arm_are_refused(tmp_path, capsys, value):
    _, path = load_problem("examples/dmp-my-demo.yaml")
    demo = path.parent / "data" / "demo-pose.csv"
    content = rewritten(demo, lambda i, h, c: value if (i, h) == (5, "x") else c)
    data_path = tmp_path / "demo.csv"
    data_path.write_text(content)
    problem = copied(tmp_path, "examples/dmp-my-demo.yaml", setter("data", "params", "file", value=str(data_path)))
    err = solve_refused(capsys, problem, tmp_path)
    assert f"sample 5: x: coordinate {float(value):g} m is beyond 10 m" in err


def motive_problem(tmp_path: Path, text: str) -> Path:
    return with_file(tmp_path, "trunk-calibrate-motive", text)


def test_a_motive_cell_of_1e300_is_refused_naming_the_marker_and_frame(tmp_path, capsys):
    lines = (RECORDINGS / "trunk_motive_faults.csv").read_text().splitlines()
    cells = lines[9].split(",")
    cells[6] = "1e300"  # the x of rigid body disk1's position
    lines[9] = ",".join(cells)
    err = solve_refused(capsys, motive_problem(tmp_path, "\n".join(lines) + "\n"), tmp_path)
    assert "bodies.disk1: coordinate" in err and "is beyond 10 m" in err and "(frame 1)" in err


def test_a_motive_file_declaring_metres_for_millimetres_says_so(tmp_path, capsys):
    text = (
        (RECORDINGS / "trunk_motive_faults.csv").read_text().replace("Length Units,Millimeters", "Length Units,Meters")
    )
    err = solve_refused(capsys, motive_problem(tmp_path, text), tmp_path)
    assert "values look like millimetres, though the file declares 'Meters'" in err


def test_a_data_file_that_is_a_symlink_loop_is_refused(tmp_path, capsys):
    (tmp_path / "a.csv").symlink_to(tmp_path / "b.csv")
    (tmp_path / "b.csv").symlink_to(tmp_path / "a.csv")
    problem = copied(tmp_path, "trunk-ik", setter("data", "params", "file", value=str(tmp_path / "a.csv")))
    err = solve_refused(capsys, problem, tmp_path)
    assert "data.params.file:" in err and "is a loop of symbolic links" in err


@pytest.mark.parametrize("fraction", [0.5, 0.3, 0.05])
def test_a_c3d_file_cut_short_is_reported_as_truncated(tmp_path, capsys, fraction):
    pytest.importorskip("ezc3d")
    from optikin.data.readers import read_c3d
    from optikin.errors import InputDataError

    raw = (RECORDINGS / "trunk.c3d").read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(raw[: int(len(raw) * fraction)])
    with pytest.raises(InputDataError, match="truncated: the header declares 40 frames"):
        read_c3d(cut)


EXAMPLE_DATA = SHIPPED.parent / "examples" / "data"


def test_a_configuration_file_with_two_s1_columns_is_refused(tmp_path, capsys):
    header, *rows = (EXAMPLE_DATA / "configurations.csv").read_text().splitlines()
    content = "\n".join([header + ",S1", *(row + ",0.2" for row in rows)]) + "\n"
    (tmp_path / "two-s1.csv").write_text(content)
    data = {"source": "csv", "params": {"file": str(tmp_path / "two-s1.csv")}}
    problem = copied(tmp_path, "cc-two-section-fk", setter("data", value=data))
    assert "column 'S1' appears twice in the header: columns 1 and 7" in solve_refused(capsys, problem, tmp_path)


def test_cbha_markers_in_millimetres_get_a_unit_hint(tmp_path, capsys):
    content = rewritten(EXAMPLE_DATA / "markers.csv", lambda i, h, c: str(float(c) * 1e3) if h[-2:] in XYZ else c)

    def edit(data: dict[str, Any]) -> None:
        data["data"] = {"source": "csv", "params": {"file": str(tmp_path / "mm.csv")}}
        data["baselines"] = []

    (tmp_path / "mm.csv").write_text(content)
    err = solve_refused(capsys, copied(tmp_path, "cbha-ph-shape", edit), tmp_path)
    assert "is beyond 10 m" in err and "values look like millimetres: set data.params.units: mm" in err


def test_a_motive_rotation_cell_of_1e300_is_refused_without_a_warning(tmp_path, capsys):
    lines = (RECORDINGS / "trunk_motive_faults.csv").read_text().splitlines()
    cells = lines[9].split(",")
    cells[2] = "1e300"  # the x of rigid body disk1's quaternion
    lines[9] = ",".join(cells)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        err = solve_refused(capsys, motive_problem(tmp_path, "\n".join(lines) + "\n"), tmp_path)
    assert "sample 1: disk1 Rotation: norm inf: not a unit quaternion" in err


def test_a_motive_file_declaring_millimetres_for_metres_says_so(tmp_path, capsys):
    lines = (RECORDINGS / "trunk_motive_faults.csv").read_text().splitlines()
    kinds = lines[6].split(",")
    for i in range(8, len(lines)):
        cells = lines[i].split(",")
        lines[i] = ",".join(
            repr(float(c) / 1e3) if k >= 2 and kinds[k] == "Position" and c else c for k, c in enumerate(cells)
        )
    err = solve_refused(capsys, motive_problem(tmp_path, "\n".join(lines) + "\n"), tmp_path)
    assert "values look like metres, though the file declares 'Millimeters'" in err
