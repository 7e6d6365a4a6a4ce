"""``optikin sweep``: sweep files, cells, the results store, resume, faults, engines agreeing."""

from __future__ import annotations

import itertools
import logging
import json
import os
import signal
import threading
import time
from pathlib import Path

import pytest
import yaml

from optikin.cli import main
from optikin.errors import SpecError
from optikin.runner import solve
from optikin.sweep import expand, load_sweep, parse_range, run_sweep
from optikin.sweep.store import comparable, markers_dir

METRICS = ["success [%]", "median tip error [m]", "median time per solve [us]"]


def _write(folder: Path, name: str = "mini", **fields) -> Path:
    content = {
        "name": name,
        "title": "test sweep",
        "problem": "cc-ik-position",
        "set": {"data.samples": 4, "baselines": []},
        "axes": {"data.seed": "range(2)", "solver": ["gauss-newton", "newton"]},
        "metrics": METRICS,
    } | fields
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(content, sort_keys=False))
    return path


@pytest.mark.parametrize("text", ["range(5)", "range(2, 9)", "range(2, 9, 3)", "range(10, 0, -4)", " range( 0 ,3 ) "])
def test_range_is_pythons(text):
    args = [int(a) for a in text.strip()[len("range(") : -1].split(",")]
    assert parse_range(text) == list(range(*args))


@pytest.mark.parametrize("text", ["range()", "range(a)", "range(1.5)", "__import__('os')", "range(1,2,3,4)"])
def test_non_ranges_are_not_evaluated(text):
    assert parse_range(text) is None


def test_sweep_file_errors_name_the_field(tmp_path):
    with pytest.raises(SpecError, match="axes.*range"):
        load_sweep(str(_write(tmp_path, axes={"data.seed": "range(x)"})))
    with pytest.raises(SpecError, match="combine"):
        load_sweep(str(_write(tmp_path, combine="cross")))
    with pytest.raises(SpecError, match="metricz: unknown field"):
        load_sweep(str(_write(tmp_path, metricz=["x"])))
    with pytest.raises(SpecError, match="zip needs axes of equal length"):
        load_sweep(str(_write(tmp_path, combine="zip", axes={"data.seed": "range(3)", "solver": ["lm"]})))
    with pytest.raises(SpecError, match="name"):
        load_sweep(str(_write(tmp_path, name="other").rename(tmp_path / "renamed.yaml")))
    assert main(["sweep", str(_write(tmp_path, retries=-1)), "--out", str(tmp_path / "o")]) == 2


def test_product_and_zip_cells(tmp_path):
    spec, path = load_sweep(str(_write(tmp_path, axes={"data.seed": "range(3)", "solver": ["a", "b", "c"]})))
    cells = expand(spec, path)
    assert [c.axes for c in cells] == [
        (("data.seed", s), ("solver", v)) for s, v in itertools.product(range(3), ["a", "b", "c"])
    ]
    assert len({c.key for c in cells}) == 9
    spec, path = load_sweep(
        str(_write(tmp_path, combine="zip", axes={"data.seed": "range(3)", "solver": ["a", "b", "c"]}))
    )
    assert [dict(c.axes) for c in expand(spec, path)] == [
        {"data.seed": s, "solver": v} for s, v in zip(range(3), "abc")
    ]


def test_a_piped_sweep_logs_its_progress(tmp_path, caplog):
    with caplog.at_level(logging.INFO, logger="optikin.progress"):
        report = run_sweep(str(_write(tmp_path)), out=tmp_path / "out", jobs=1, figures=False, progress=True)
    lines = [r.getMessage() for r in caplog.records if r.name == "optikin.progress"]
    assert report.ran == 4
    assert lines[0].endswith(": 0 done, 0 failed, 0 running: started, 4 cells")
    # a line for each of the first three cells (each passes another tenth of 4), the fourth in the closing line
    assert [line.split(": ")[-1].split(" (")[0] for line in lines[1:-1]] == ["1/4", "2/4", "3/4"]
    assert ": 4 done, 0 failed, 0 running: done, 4/4 in " in lines[-1]


def test_cell_equals_solve_and_resume_runs_only_missing_cells(tmp_path):
    path = _write(tmp_path)
    out = tmp_path / "out"
    report = run_sweep(str(path), out=out, jobs=1, figures=False, progress=False)
    assert (report.cells, report.ran, report.failed) == (4, 4, 0)
    cell = report.rows[3]
    assert (cell["data.seed"], cell["solver"]) == (1, "newton")
    alone, _ = solve(
        "cc-ik-position",
        overrides=[("data.samples", 4), ("baselines", []), ("data.seed", 1), ("solver", "newton")],
        figures=False,
    )
    row = alone.summary()["comparison"][0]
    assert row["method"] == "newton"
    for name in METRICS[:2]:
        assert cell[f"solver: {name}"] == row["metrics"][name]
    stored = json.loads((report.folder / "cells" / f"{cell['key']}.json").read_text())
    assert stored["summary"]["status_counts"] == alone.summary()["status_counts"]

    # an interrupted sweep: two finished cells are missing; the rerun runs those two only
    for row in report.rows[:2]:
        (report.folder / "cells" / f"{row['key']}.json").unlink()
    again = run_sweep(str(path), out=out, jobs=1, figures=False, progress=False)
    assert (again.ran, again.skipped) == (2, 2)
    assert comparable(again.rows) == comparable(report.rows)
    # a changed axis value is a changed cell; the others are kept
    changed = _write(tmp_path, axes={"data.seed": [1, 5], "solver": ["gauss-newton", "newton"]})
    third = run_sweep(str(changed), out=out, jobs=1, figures=True, progress=False)
    assert (third.ran, third.skipped) == (2, 2)
    assert third.figures and all(p.stat().st_size > 0 for p in third.figures)
    table = (third.folder / "table.csv").read_text().splitlines()
    assert len(table) == 5 and table[0].startswith("index,key,data.seed,solver,status")


def test_a_bad_cell_fails_alone_with_its_message(tmp_path, capsys):
    path = _write(tmp_path, axes={"data.samples": [3, 0]})
    code = main(["sweep", str(path), "--out", str(tmp_path / "out"), "--no-figures"])
    assert code == 1
    rows = json.loads((tmp_path / "out" / "mini" / "table.json").read_text())["rows"]
    assert [r["status"] for r in rows] == ["done", "failed"]
    assert "data.samples" in rows[1]["reason"] and "greater than or equal to 1" in rows[1]["reason"]
    assert "cell 1 failed" in capsys.readouterr().out


def _kill_first_worker(folder: Path, killed: list[int]) -> None:
    """SIGKILL the first worker seen running a cell (its marker names it), once."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not killed:
        for marker in markers_dir(folder).glob("*.*"):
            pid = int(marker.name.partition(".")[2])
            if pid != os.getpid():
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
        time.sleep(0.01)


@pytest.mark.slow
@pytest.mark.parametrize("engine", [{"jobs": 2}, {"dask": "local:2"}], ids=["joblib", "dask"])
def test_killed_worker_cell_is_retried_and_sweep_completes(tmp_path, engine):
    if "dask" in engine:
        pytest.importorskip("distributed")
    path = _write(tmp_path, name="killed")
    out = tmp_path / "out"
    killed: list[int] = []
    watcher = threading.Thread(target=_kill_first_worker, args=(out / "killed", killed))
    watcher.start()
    report = run_sweep(str(path), out=out, figures=False, progress=False, **engine)
    watcher.join()
    assert killed, "no worker was seen running a cell"
    assert (report.cells, report.failed) == (4, 0)
    assert len(list((out / "killed" / "cells").glob("*.json"))) == 4
    assert max(r["tries"] for r in report.rows) >= 2
    reference = run_sweep(str(path), out=tmp_path / "ref", jobs=1, figures=False, progress=False)
    assert comparable(report.rows) == [
        r | {"tries": c["tries"]} for r, c in zip(comparable(reference.rows), report.rows)
    ]


@pytest.mark.slow
def test_engines_give_identical_tables(tmp_path):
    pytest.importorskip("distributed")
    path = _write(tmp_path)
    tables = [
        comparable(run_sweep(str(path), out=tmp_path / name, figures=False, progress=False, **engine).rows)
        for name, engine in [("j1", {"jobs": 1}), ("j2", {"jobs": 2}), ("dask", {"dask": "local:2"})]
    ]
    assert tables[0] == tables[1] == tables[2]
    assert all(r["status"] == "done" for r in tables[0])


@pytest.mark.parametrize("name", ["ph-noise", "ik-robustness", "nn-database"])
def test_shipped_sweeps_validate_every_cell(name):
    from optikin.spec import load_problem

    spec, path = load_sweep(name)
    cells = expand(spec, path)
    assert len(cells) <= 12
    for cell in cells:
        problem, _ = load_problem(cell.problem, cell.overrides)
        for field, value in cell.axes:
            node = problem.model_dump()
            for part in field.split("."):
                node = node[part]
            assert node == value
