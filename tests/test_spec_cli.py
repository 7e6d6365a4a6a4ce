"""Problem files, solver presets and the command line: good input runs, bad input is named and exits non-zero."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from optikin.cli import EXIT_BAD_INPUT, EXIT_OK, main
from optikin.errors import SpecError, UnknownNameError
from optikin.runner import solve
from optikin.spec import available, load_problem, load_solver

GOOD_PROBLEM = """\
name: {name}
title: a small test problem
kind: fk
arm:
  type: constant_curvature
  params: {{section_lengths: [0.18, 0.18]}}
data:
  source: random
  seed: 3
  samples: 16
baselines: [numpy]
"""


def write(tmp_path: Path, name: str, text: str, folder: str = "problems") -> Path:
    path = tmp_path / folder / f"{name}.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def good(tmp_path: Path, name: str = "small", **replace: str) -> Path:
    text = GOOD_PROBLEM.format(name=name)
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    return write(tmp_path, name, text)


CHECKOUT = Path(__file__).resolve().parent.parent
SHIPPED_FILES = sorted(
    [*(CHECKOUT / "problems").glob("*.yaml"), *(CHECKOUT / "examples").glob("*.yaml")], key=lambda p: p.name
)


@pytest.mark.parametrize("path", SHIPPED_FILES, ids=lambda p: p.name)
def test_every_shipped_and_example_problem_shows(path, capsys):
    """``optikin show`` validates the whole file: its kind's options, its data source's params and its arm."""
    assert main(["show", str(path)]) == EXIT_OK, capsys.readouterr().err


@pytest.mark.parametrize("path", sorted((CHECKOUT / "solvers").glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_solver_preset_shows(path, capsys):
    assert main(["show", "--solver", str(path)]) == EXIT_OK, capsys.readouterr().err


@pytest.mark.parametrize("path", sorted((CHECKOUT / "sweeps").glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_sweep_validates(path):
    from optikin.sweep.spec import load_sweep

    spec, _ = load_sweep(str(path))
    assert spec.name == path.stem


def test_shipped_problems_and_solvers_validate():
    problems, solvers = available("problems"), available("solvers")
    assert {"cc-two-section-fk", "cbha-fk"} <= set(problems)
    for name in problems:
        spec, path = load_problem(name)
        assert spec.name == path.stem
    for name in solvers:
        spec, path = load_solver(name)
        assert spec.name == path.stem


@pytest.mark.parametrize(
    "replace, field, message",
    [
        ({"kind: fk": "kind: fk\ncolour: blue"}, "colour", "unknown field"),
        ({"title: a small test problem\n": ""}, "title", "required field is missing"),
        ({"samples: 16": "samples: -4"}, "data.samples", "greater than or equal to 1"),
        ({"seed: 3": "seed: three"}, "data.seed", "integer"),
        (
            {"params: {section_lengths: [0.18, 0.18]}": "params: {section_length: 0.18}"},
            "arm.params.section_length",
            "unknown parameter",
        ),
        ({"params: {section_lengths: [0.18, 0.18]}": "params: {theta_max: 9.0}"}, "arm.params.theta_max", "theta_max"),
        ({"type: constant_curvature": "type: octopus"}, "arm.type", "unknown arm 'octopus'"),
        ({"kind: fk": "kind: teleport"}, "kind", "unknown problem kind 'teleport'"),
        (
            {"source: random": "source: dreams"},
            "data.source",
            "unknown configurations source 'dreams'; known: csv, random, sweep, trajectory",
        ),
        (
            {"baselines: [numpy]": "baselines: [numpy, oracle]"},
            "baselines.1",
            "'oracle' is neither a baseline of kind 'fk'",
        ),
        ({"baselines: [numpy]": "baselines: [qp-osqp]"}, "baselines.0", "'qp-osqp' (qp) cannot be a baseline of kind"),
    ],
)
def test_bad_problem_fields_are_named(tmp_path, replace, field, message):
    path = good(tmp_path, **replace)
    with pytest.raises(SpecError) as info:
        solve(str(path))
    assert info.value.field == field
    assert message in str(info.value)
    assert str(path) in str(info.value)


def test_malformed_yaml_names_file_and_line(tmp_path):
    path = write(tmp_path, "broken", "name: broken\ntitle: [unclosed\nkind: fk\n")
    with pytest.raises(SpecError, match=r"broken.yaml: malformed YAML: line \d+"):
        load_problem(str(path))


def test_top_level_must_be_a_mapping(tmp_path):
    path = write(tmp_path, "listy", "- a\n- b\n")
    with pytest.raises(SpecError, match="expected a mapping"):
        load_problem(str(path))


def test_name_must_match_file(tmp_path):
    path = write(tmp_path, "one", GOOD_PROBLEM.format(name="two"))
    with pytest.raises(SpecError, match="differs from the file name"):
        load_problem(str(path))


def test_unknown_named_problem_lists_known():
    with pytest.raises(UnknownNameError, match="known: .*cc-two-section-fk"):
        load_problem("no-such-problem")


def test_solver_preset_unknown_backend_and_wrong_family(tmp_path, monkeypatch):
    write(tmp_path, "warp", "name: warp\nbackend: warp_drive\n", folder="solvers")
    write(tmp_path, "bad-limits", "name: bad-limits\nbackend: casadi_map\nlimits: {time_limit: -1}\n", folder="solvers")
    monkeypatch.setenv("OPTIKIN_PATH", str(tmp_path))
    problem = good(tmp_path)
    with pytest.raises(SpecError, match=r"warp.yaml: backend: unknown solver backend 'warp_drive'"):
        solve(str(problem), solver="warp")
    with pytest.raises(SpecError, match=r"bad-limits.yaml: limits.time_limit"):
        solve(str(problem), solver="bad-limits")


def test_csv_source_reads_named_columns_and_rejects_bad_cells(tmp_path):
    rows = ["t,S1,theta1,phi1,S2,theta2,phi2,comment"]
    rows += [f"{0.01 * i},0.18,{0.1 * i},0.2,0.18,-0.3,1.0,x" for i in range(5)]
    (tmp_path / "problems").mkdir()
    (tmp_path / "problems" / "configs.csv").write_text("\n".join(rows) + "\n")
    path = good(tmp_path, "fromcsv", **{"source: random": "source: csv\n  params: {file: configs.csv}"})
    result, _ = solve(str(path))
    assert result.samples == 5
    np.testing.assert_allclose(result.arrays["t"], 0.01 * np.arange(5))
    rows[3] = rows[3].replace("0.18,0.2", "0.18,abc", 1)
    (tmp_path / "problems" / "configs.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(Exception, match=r"configs.csv: sample 2: theta1: 'abc' is not a number"):
        solve(str(path))


def test_out_of_bounds_and_nan_configurations_name_the_sample(tmp_path):
    (tmp_path / "problems").mkdir()
    csv = tmp_path / "problems" / "q.csv"
    csv.write_text("S1,theta1,phi1,S2,theta2,phi2\n0.18,0.1,0,0.18,0.1,0\n0.18,nan,0,0.18,0.1,0\n")
    path = good(tmp_path, "nanq", **{"source: random": "source: csv\n  params: {file: q.csv}"})
    with pytest.raises(Exception, match=r"sample 1: theta1: nan is not a finite number"):
        solve(str(path))
    csv.write_text("S1,theta1,phi1,S2,theta2,phi2\n0.18,0.1,0,0.5,0.1,0\n")
    with pytest.raises(Exception, match=r"sample 0: S2: 0.5 outside the bounds"):
        solve(str(path))


def test_solve_writes_json_npz_and_figures_atomically(tmp_path):
    path = good(tmp_path)
    out = tmp_path / "out"
    result, written = solve(str(path), out=out)
    assert written == out / "small"
    summary = json.loads((written / "result.json").read_text())
    assert summary["status_counts"] == {"ok": 16}
    assert {"backbones.png", "tip.png"} <= {p.name for p in written.iterdir()}
    arrays = np.load(written / "arrays.npz")
    np.testing.assert_allclose(arrays["tip_position"], result.arrays["tip_position"])
    # A second, failing run leaves the first result intact and no staging folders behind.
    bad = good(tmp_path, "small", **{"samples: 16": "samples: 0"})
    with pytest.raises(SpecError):
        solve(str(bad), out=out)
    assert json.loads((written / "result.json").read_text())["status_counts"] == {"ok": 16}
    assert [p.name for p in out.iterdir()] == ["small"]


def test_failure_while_writing_leaves_no_partial_result(tmp_path, monkeypatch):
    from optikin import plots

    def broken_plot(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(plots, "backbones_3d", broken_plot)
    out = tmp_path / "out"
    with pytest.raises(RuntimeError, match="disk full"):
        solve(str(good(tmp_path)), out=out)
    assert list(out.iterdir()) == []


def test_cli_list_show_solve(tmp_path, capsys):
    assert main(["list", "--solvers"]) == EXIT_OK
    listing = capsys.readouterr().out
    assert "cc-two-section-fk" in listing and "casadi-map" in listing
    assert main(["show", "cc-two-section-fk", "--json"]) == EXIT_OK
    shown = capsys.readouterr().out
    assert json.loads(shown.split("\n", 1)[1])["kind"] == "fk"
    assert main(["solve", str(good(tmp_path)), "--out", str(tmp_path / "o"), "--json", "--no-figures"]) == EXIT_OK
    summary = json.loads(capsys.readouterr().out)
    assert summary["samples"] == 16
    assert not list((tmp_path / "o" / "small").glob("*.png"))


def test_cli_bad_input_exits_2_with_one_line_message(tmp_path):
    path = good(tmp_path, **{"kind: fk": "kind: teleport"})
    run = subprocess.run(
        [sys.executable, "-m", "optikin.cli", "solve", str(path), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == EXIT_BAD_INPUT
    assert run.stderr.startswith("optikin: error: ") and "kind: unknown problem kind 'teleport'" in run.stderr
    assert "Traceback" not in run.stderr
    assert not (tmp_path / "o" / "small").exists()


@pytest.mark.parametrize("name", ["cc-two-section-fk", "cbha-fk"])
def test_shipped_fk_problems_run_end_to_end(name, tmp_path):
    assert main(["solve", name, "--out", str(tmp_path)]) == EXIT_OK
    summary = json.loads((tmp_path / name / "result.json").read_text())
    assert summary["status_counts"] == {"ok": summary["samples"]}
    numpy_row = next(row for row in summary["comparison"] if row["method"] == "numpy")
    assert numpy_row["metrics"]["max |tip - numpy| [mm]"] < 1e-9
    assert {"backbones.png", "tip.png"} <= set(summary["figures"])
