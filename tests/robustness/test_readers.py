"""The CSV readers of the data sources: how many rows a file source reads, what a reader rejects and how it says so.

A file source reads every row unless ``data.samples`` is given; fewer samples than rows is
said in a note. A reader names the file, the row (``sample``, counted from 0 over the data
rows, and the line of the file) and the column of a bad cell, shows at most a short escaped
excerpt of what it found, and refuses binary, non-UTF-8 and very large files.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import ast
import os
import re

import numpy as np
import pytest
import yaml

from optikin.cli import EXIT_BAD_INPUT, main
from optikin.data.csvread import EXCERPT_LENGTH, MAX_BYTES, excerpt
from optikin.data.targets import read_target_csv
from optikin.data.configurations import read_configuration_csv
from optikin.data.demonstrations import read_csv as read_demonstration_csv
from optikin.data.markers import CsvMarkerParams, csv_source, read_marker_csv
from optikin.errors import InputDataError, SpecError
from optikin.runner import prepare, solve
from optikin.spec import DataSpec

CONFIG_HEADER = "t,S1,theta1,phi1,S2,theta2,phi2"


def config_rows(n: int) -> list[str]:
    """``n`` admissible configurations of the two-section arm, 10 ms apart."""
    return [f"{0.01 * i:.2f},0.18,{0.1 + 0.002 * i:.3f},0.2,0.18,0.3,1.0" for i in range(n)]


def write_csv(path: Path, header: str, rows: list[str]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


MARKER_HEADER = (
    ["t"]
    + [f"{b}_{c}" for b in ("base", "tip") for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    + ["m1_x", "m1_y", "m1_z"]
)


def marker_rows(n: int) -> list[str]:
    """``n`` postures of a straight arm 0.2 m long, base and tip frames aligned, 0.1 s apart."""
    return [f"{0.1 * i:.1f},0,0,0,1,0,0,0,0,0,0.2,1,0,0,0,0,0,0.1" for i in range(n)]


def fk_problem(tmp_path: Path, data: dict[str, Any]) -> Path:
    spec = {
        "name": "csv-fk",
        "title": "fk from a CSV file",
        "kind": "fk",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": data,
    }
    path = tmp_path / "problems" / "csv-fk.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(spec))
    return path


def ik_problem(tmp_path: Path, data: dict[str, Any], target: str = "position") -> Path:
    spec = {
        "name": "csv-ik",
        "title": "ik from a CSV file",
        "kind": "ik",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": data,
        "solver": "gauss-newton",
        "options": {"target": target, "redundancy": "minimum_norm", "restarts": 0},
    }
    path = tmp_path / "problems" / "csv-ik.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(spec))
    return path


def target_rows(n: int) -> list[str]:
    """``n`` tip positions on a small circle inside the workspace of the two-section arm [m]."""
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return [f"{0.05 * np.cos(a):.6f},{0.05 * np.sin(a):.6f},0.33" for a in angle]


# --------------------------------------------------------------------------- 1. rows read by a file source


def test_fk_csv_without_samples_reads_every_row(tmp_path):
    write_csv(tmp_path / "problems" / "q.csv", CONFIG_HEADER, config_rows(250))
    result, _ = solve(str(fk_problem(tmp_path, {"source": "csv", "params": {"file": "q.csv"}})), figures=False)
    assert result.samples == 250
    np.testing.assert_allclose(result.arrays["t"], 0.01 * np.arange(250), atol=1e-12)
    assert not any("skipped" in note for note in result.notes)


def test_fk_csv_with_fewer_samples_says_how_many_rows_were_skipped(tmp_path):
    write_csv(tmp_path / "problems" / "q.csv", CONFIG_HEADER, config_rows(250))
    problem = fk_problem(tmp_path, {"source": "csv", "samples": 100, "params": {"file": "q.csv"}})
    result, _ = solve(str(problem), figures=False)
    assert result.samples == 100
    assert "150 rows of q.csv skipped (data.samples)" in result.notes


def test_fk_csv_with_as_many_samples_as_rows_has_no_note(tmp_path):
    write_csv(tmp_path / "problems" / "q.csv", CONFIG_HEADER, config_rows(7))
    problem = fk_problem(tmp_path, {"source": "csv", "samples": 7, "params": {"file": "q.csv"}})
    result, _ = solve(str(problem), figures=False)
    assert result.samples == 7 and not any("skipped" in note for note in result.notes)


def test_ik_csv_without_samples_reads_every_row(tmp_path):
    write_csv(tmp_path / "problems" / "p.csv", "x,y,z", target_rows(250))
    _, ctx = prepare(str(ik_problem(tmp_path, {"source": "csv", "params": {"file": "p.csv"}})))
    assert ctx.data_source is not None
    targets = ctx.data_source.load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path, kind="position")
    assert len(targets) == 250 and targets.skipped_rows == 0


def test_ik_csv_with_fewer_samples_says_how_many_rows_were_skipped(tmp_path):
    write_csv(tmp_path / "problems" / "p.csv", "x,y,z", target_rows(12))
    problem = ik_problem(tmp_path, {"source": "csv", "samples": 5, "params": {"file": "p.csv"}})
    result, _ = solve(str(problem), figures=False)
    assert result.samples == 5
    assert "7 rows of p.csv skipped (data.samples)" in result.notes


def test_marker_csv_without_samples_reads_every_row(tmp_path):
    write_csv(tmp_path / "rec.csv", ",".join(MARKER_HEADER), marker_rows(130))
    params = CsvMarkerParams(file="rec.csv")
    recording = csv_source(None, DataSpec(source="csv"), params, tmp_path / "problem.yaml")
    assert len(recording) == 130 and recording.skipped_rows == 0
    recording = csv_source(None, DataSpec(source="csv", samples=30), params, tmp_path / "problem.yaml")
    assert len(recording) == 30 and recording.skipped_rows == 100


# --------------------------------------------------------------------------- 2. cells rejected at read time

POSE_HEADER = "x,y,z,qw,qx,qy,qz"
POSE = "0.05,0,0.33,1,0,0,0"


def load_targets(tmp_path: Path, header: str, rows: list[str], target: str = "position"):
    write_csv(tmp_path / "problems" / "p.csv", header, rows)
    _, ctx = prepare(str(ik_problem(tmp_path, {"source": "csv", "params": {"file": "p.csv"}}, target)))
    assert ctx.data_source is not None
    return ctx.data_source.load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path, kind=target)


@pytest.mark.parametrize("cell", ["nan", "inf", "-inf", "NaN", "1e999"])
def test_a_non_finite_target_cell_names_file_row_line_and_column(tmp_path, cell):
    rows = ["0.05,0,0.33", "0.04,0.01,0.33", f"0.03,{cell},0.33"]
    with pytest.raises(InputDataError, match=r"p\.csv: sample 2: y: .* is not a finite number \(line 4\)"):
        load_targets(tmp_path, "x,y,z", rows)


@pytest.mark.parametrize(
    "quaternion, norm",
    [("nan,0,0,0", "nan"), ("1.1,0,0,0", "1.1"), ("0.5,0.5,0.5,0.5000001", None), ("0,0,0,0", "0")],
)
def test_a_nan_or_non_unit_target_quaternion_is_refused(tmp_path, quaternion, norm):
    rows = [POSE, f"0.05,0,0.33,{quaternion}"]
    if norm is None:  # within 1e-6 of unit length: accepted
        assert len(load_targets(tmp_path, POSE_HEADER, rows, "pose")) == 2
        return
    with pytest.raises(InputDataError, match=r"p\.csv: sample 1: .*(finite|not a unit quaternion).*\(line 3\)"):
        load_targets(tmp_path, POSE_HEADER, rows, "pose")


def test_a_non_finite_target_quaternion_exits_2_naming_file_line_and_column(tmp_path, capsys):
    write_csv(tmp_path / "problems" / "p.csv", POSE_HEADER, [POSE, "0.05,0,0.33,nan,0,0,0"])
    problem = ik_problem(tmp_path, {"source": "csv", "params": {"file": "p.csv"}}, "pose")
    assert main(["solve", str(problem), "--out", str(tmp_path / "out"), "--no-figures"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "p.csv: sample 1: qw:" in err and "(line 3)" in err


@pytest.mark.parametrize(
    "times, line",
    [(["0", "nan", "0.2"], 3), (["0", "0.1", "0.05"], 4), (["0", "0.1", "0.1"], 4), (["inf", "1", "2"], 2)],
)
def test_configuration_times_must_be_finite_and_increase(tmp_path, times, line):
    rows = [f"{t},0.18,0.1,0.2,0.18,0.3,1.0" for t in times]
    path = write_csv(tmp_path / "q.csv", CONFIG_HEADER, rows)
    with pytest.raises(InputDataError, match=rf"q\.csv: sample {line - 2}: t: .*\(line {line}\)"):
        read_configuration_csv(path, ("S1", "theta1", "phi1", "S2", "theta2", "phi2"))


def test_configuration_times_are_checked_on_the_line_they_are_on(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text(CONFIG_HEADER + "\n0,0.18,0.1,0.2,0.18,0.3,1.0\n\n0.1,0.18,0.1,0.2,0.18,0.3,1.0\nnan,0,0,0,0,0,0\n")
    with pytest.raises(InputDataError, match=r"sample 2: t: 'nan' is not a finite number \(line 5\)"):
        read_configuration_csv(path, ("S1", "theta1", "phi1", "S2", "theta2", "phi2"))


@pytest.mark.parametrize("times, line", [(["0", "nan"], 3), (["0.2", "0.1"], 3), (["-inf", "0"], 2)])
def test_marker_times_must_be_finite_and_increase(tmp_path, times, line):
    rows = [f"{t},0,0,0,1,0,0,0,0,0,0.2,1,0,0,0,0,0,0.1" for t in times]
    path = write_csv(tmp_path / "rec.csv", ",".join(MARKER_HEADER), rows)
    with pytest.raises(InputDataError, match=rf"rec\.csv: sample {line - 2}: t: .*\(line {line}\)"):
        read_marker_csv(path)


def test_a_nan_marker_quaternion_is_refused(tmp_path):
    rows = marker_rows(2)
    rows[1] = rows[1].replace(",1,0,0,0,0,0,0.1", ",nan,0,0,0,0,0,0.1")
    with pytest.raises(InputDataError, match=r"sample 1: tip_qw: 'nan' is not a finite number \(line 3\)"):
        read_marker_csv(write_csv(tmp_path / "rec.csv", ",".join(MARKER_HEADER), rows))


def test_demonstration_errors_give_the_line(tmp_path):
    rows = ["0,0,0,0,1,0,0,0", "0.1,0,0,0,1,0,0,0", "0.2,0,inf,0,1,0,0,0"]
    path = write_csv(tmp_path / "demo.csv", "t,x,y,z,qw,qx,qy,qz", rows)
    with pytest.raises(InputDataError, match=r"demo\.csv: sample 2: y: inf is not a finite number \(line 4\)"):
        read_demonstration_csv(path)


def test_leg_length_targets_cannot_come_from_a_csv_file(tmp_path):
    write_csv(tmp_path / "problems" / "p.csv", "x,y,z", target_rows(3))
    spec = {
        "name": "legs-csv",
        "title": "leg targets from a CSV file",
        "kind": "ik",
        "arm": {"type": "cbha"},
        "data": {"source": "csv", "params": {"file": "p.csv"}},
        "solver": "gauss-newton",
        "options": {"target": "legs", "redundancy": "minimum_norm", "restarts": 0},
    }
    path = tmp_path / "problems" / "legs-csv.yaml"
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(SpecError, match="leg-length targets cannot be read from a CSV file") as info:
        solve(str(path), figures=False)
    assert info.value.field == "data.source"


# --------------------------------------------------------------------------- 3. what an error shows of a file

CONFIG_NAMES = ("S1", "theta1", "phi1", "S2", "theta2", "phi2")
SECRET = "hunter2-do-not-print-me"

READERS = {
    "configurations": lambda path: read_configuration_csv(path, CONFIG_NAMES),
    "targets": lambda path: read_target_csv(path, "pose"),
    "markers": read_marker_csv,
    "demonstrations": read_demonstration_csv,
}


def shown_excerpts(message: str) -> list[str]:
    """The quoted excerpts of a message."""
    return re.findall(r"'(?:[^'\\]|\\.)*'(?:\.\.\.)?", message)


@pytest.mark.parametrize("reader", READERS)
def test_a_missing_column_shows_no_more_than_a_few_short_header_names(tmp_path, reader):
    names = [f"TOKEN_{k}={SECRET}" for k in range(30)]
    path = tmp_path / "env.csv"
    path.write_text(",".join(names) + "\n" + ",".join("1" for _ in names) + "\n")
    with pytest.raises(InputDataError, match="missing column") as info:
        READERS[reader](path)
    message = str(info.value)
    assert SECRET not in message and "TOKEN_4" not in message
    assert all(len(e) <= EXCERPT_LENGTH for e in shown_excerpts(message))


@pytest.mark.parametrize("reader", READERS)
def test_proc_self_environ_is_refused_without_printing_it(reader):
    environ = Path("/proc/self/environ")
    if not environ.exists():
        pytest.skip("no /proc")
    with pytest.raises(InputDataError) as info:
        READERS[reader](environ)
    message = str(info.value)
    entries = [e.decode(errors="replace") for e in environ.read_bytes().split(b"\0")]
    assert not [e for e in entries if len(e) > EXCERPT_LENGTH and e[:EXCERPT_LENGTH] in message]


@pytest.mark.parametrize("cell", ["x" * 5000, "\x1b[31mred\x1b[0m and more text", SECRET * 3, "\u202eevil"])
def test_a_bad_cell_is_shown_as_a_short_escaped_excerpt(tmp_path, cell):
    path = write_csv(tmp_path / "q.csv", CONFIG_HEADER, config_rows(2) + [f'0.5,0.18,"{cell}",0,0.18,0,0'])
    with pytest.raises(InputDataError, match=r"q\.csv: sample 2: theta1: .* is not a number \(line 4\)") as info:
        read_configuration_csv(path, CONFIG_NAMES)
    message = str(info.value)
    assert "\x1b" not in message and "\u202e" not in message and SECRET * 2 not in message
    [shown] = shown_excerpts(message)
    assert len(shown) <= EXCERPT_LENGTH


@pytest.mark.parametrize(
    "text, limit",
    [("abc", 20), ("x" * 100, 20), ("\x00" * 30, 20), ("é" * 40, 12), ("'\"" * 20, 10), ("", 20)],
)
def test_excerpt_is_an_escaped_prefix_no_longer_than_its_limit(text, limit):
    shown = excerpt(text, limit)
    assert len(shown) <= limit
    body = shown[:-3] if shown.endswith("...") else shown
    assert text.startswith(ast.literal_eval(body))  # a repr: evaluates back to a prefix of the text


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize(
    "content, match",
    [
        (b"t,x,y\n0,\x00\x01\x02,1\n", "NUL bytes"),
        (b"t,S1\n0,\xff\xfe\n", r"not a UTF-8 text file: byte 0xff on line 2"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "NUL bytes"),
    ],
)
def test_binary_and_non_utf8_files_are_input_errors(tmp_path, reader, content, match):
    path = tmp_path / "data.csv"
    path.write_bytes(content)
    with pytest.raises(InputDataError, match=match) as info:
        READERS[reader](path)
    assert str(path) in str(info.value)


def test_a_binary_file_exits_2(tmp_path, capsys):
    (tmp_path / "problems").mkdir()
    (tmp_path / "problems" / "q.csv").write_bytes(b"\x7fELF\x02\x01\x01\x00\x00\x00")
    problem = fk_problem(tmp_path, {"source": "csv", "params": {"file": "q.csv"}})
    assert main(["solve", str(problem), "--out", str(tmp_path / "out"), "--no-figures"]) == EXIT_BAD_INPUT
    assert "q.csv: not a CSV text file" in capsys.readouterr().err


def test_a_very_large_file_is_refused_before_reading(tmp_path):
    path = tmp_path / "huge.csv"
    with open(path, "wb") as fh:  # sparse: no disk space used
        fh.write((CONFIG_HEADER + "\n").encode())
        fh.truncate(MAX_BYTES + 1)
    with pytest.raises(InputDataError, match=r"huge\.csv: cannot read: .*larger than the 200 MiB"):
        read_configuration_csv(path, CONFIG_NAMES)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes")
def test_a_named_pipe_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "pipe.csv")
    with pytest.raises(InputDataError, match="not a regular file"):
        read_configuration_csv(tmp_path / "pipe.csv", CONFIG_NAMES)


def test_a_short_row_and_an_overlong_cell_name_their_line(tmp_path):
    path = write_csv(tmp_path / "q.csv", CONFIG_HEADER, config_rows(1) + ["0.1,0.18,0.1"])
    with pytest.raises(InputDataError, match=r"sample 1: phi1: a missing cell: the row has 3 of .* \(line 3\)"):
        read_configuration_csv(path, CONFIG_NAMES)
    path = write_csv(tmp_path / "q.csv", CONFIG_HEADER, config_rows(1) + ["1" * 200_000])
    with pytest.raises(InputDataError, match=r"q\.csv: malformed CSV on line 3: field larger than field limit"):
        read_configuration_csv(path, CONFIG_NAMES)


def test_ph_shape_csv_with_fewer_samples_says_how_many_rows_were_skipped(tmp_path):
    write_csv(tmp_path / "rec.csv", ",".join(MARKER_HEADER), marker_rows(130))
    spec = {
        "name": "rec-shape",
        "title": "markers from a file",
        "kind": "ph_shape",
        "arm": {"type": "cbha"},
        "data": {"source": "csv", "samples": 30, "params": {"file": "rec.csv"}},
        "solver": "ph-newton",
        "options": {"length": "arc"},
    }
    problem = tmp_path / "rec-shape.yaml"
    problem.write_text(yaml.safe_dump(spec))
    result, _ = solve(str(problem))
    assert result.samples == 30 and "100 rows of rec.csv skipped (data.samples)" in result.notes
