"""Result and sweep folders that are not what optikin wrote, and bad ``--dask`` addresses: exit 2, one line.

Each case used to end with exit 3 (an internal error: ``BadZipFile``, ``AttributeError``,
``IsADirectoryError``, a 30 s Dask connection timeout) or with exit 0 and nothing done (``plot`` and
``view`` on a folder without arrays, ``view`` of a result naming an unknown kind).
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.cli import EXIT_BAD_INPUT, EXIT_OK, main

SMALL = ["--set", "data.samples=4", "--set", "baselines=[]", "--no-figures"]


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    """A real result folder of a small IK run (kind ik, which draws figures)."""
    out = tmp_path_factory.mktemp("written")
    assert main(["solve", "cc-ik-position", *SMALL, "--out", str(out)]) == EXIT_OK
    return out / "cc-ik-position"


def copy_of(written: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "result"
    shutil.copytree(written, folder)
    return folder


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("optikin: error: "), err
    return err[0]


@pytest.mark.parametrize("command", ["plot", "view"])
def test_the_written_result_is_drawn_and_shown(written, tmp_path, command):
    folder = copy_of(written, tmp_path)
    assert main([command, str(folder)]) == EXIT_OK
    assert (folder / "view.html").is_file() if command == "view" else (folder / "targets.png").is_file()


def _object_arrays(npz: Path) -> None:
    np.savez(npz, targets=np.array([{"x": 1}, None], dtype=object))


def _truncated(npz: Path) -> None:
    npz.write_bytes(npz.read_bytes()[:300])


def _not_a_zip(npz: Path) -> None:
    npz.write_bytes(b"hello, not an archive\n")


def _wrong_shape(npz: Path) -> None:
    with np.load(npz) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["targets"] = np.zeros((2, 7, 5))
    np.savez(npz, **arrays)


def _removed(npz: Path) -> None:
    npz.unlink()


def _a_folder(npz: Path) -> None:
    npz.unlink()
    npz.mkdir()


DAMAGE = {
    "object arrays": (_object_arrays, "object arrays"),
    "truncated": (_truncated, "not an .npz archive"),
    "not a zip": (_not_a_zip, "not an .npz archive"),
    "wrong shape": (_wrong_shape, "'targets' has shape [2, 7, 5]; result.json records [4, 3]"),
    "missing": (_removed, "arrays.npz is missing"),
    "a folder": (_a_folder, "is not a file"),
}


@pytest.mark.parametrize("command", ["plot", "view"])
@pytest.mark.parametrize("damage", list(DAMAGE))
def test_damaged_arrays_exit_2_naming_the_file(written, tmp_path, capsys, monkeypatch, command, damage):
    import pickle

    folder = copy_of(written, tmp_path)
    spoil, expected = DAMAGE[damage]
    spoil(folder / "arrays.npz")
    unpickled = []
    monkeypatch.setattr(pickle, "loads", lambda *a, **k: unpickled.append(a))
    capsys.readouterr()
    assert main([command, str(folder)]) == EXIT_BAD_INPUT
    line = one_error_line(capsys)
    assert str(folder) in line and expected in line, line
    assert not unpickled
    assert not (folder / "view.html").exists()


@pytest.mark.parametrize("command", ["plot", "view"])
@pytest.mark.parametrize("kind", ["evil", "../../os", "os", "__init__", 3, None])
def test_an_unregistered_kind_exits_2_before_any_import(written, tmp_path, capsys, monkeypatch, command, kind):
    import importlib

    folder = copy_of(written, tmp_path)
    summary = json.loads((folder / "result.json").read_text())
    summary["kind"] = kind
    (folder / "result.json").write_text(json.dumps(summary))
    imported: list[str] = []
    real = importlib.import_module
    monkeypatch.setattr(importlib, "import_module", lambda name, *a: imported.append(name) or real(name, *a))
    capsys.readouterr()
    assert main([command, str(folder)]) == EXIT_BAD_INPUT
    line = one_error_line(capsys)
    assert "result.json: kind: unknown problem kind" in line, line
    assert [name for name in imported if name.startswith("optikin.problems.")] == []


@pytest.mark.parametrize("command", ["plot", "view"])
def test_a_result_without_arrays_exits_2(written, tmp_path, capsys, command):
    folder = copy_of(written, tmp_path)
    (folder / "arrays.npz").unlink()
    summary = json.loads((folder / "result.json").read_text())
    summary["arrays"] = {}
    (folder / "result.json").write_text(json.dumps(summary))
    capsys.readouterr()
    assert main([command, str(folder)]) == EXIT_BAD_INPUT
    assert "holds no arrays" in one_error_line(capsys)


def test_figures_that_cannot_be_drawn_from_the_arrays_exit_2(written, tmp_path, capsys):
    folder = copy_of(written, tmp_path)
    summary = json.loads((folder / "result.json").read_text())
    with np.load(folder / "arrays.npz") as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["time_gauss-newton"] = np.zeros(0)  # recorded as such too: only the figures can tell
    summary["arrays"]["time_gauss-newton"] = [0]
    np.savez(folder / "arrays.npz", **arrays)
    (folder / "result.json").write_text(json.dumps(summary))
    capsys.readouterr()
    assert main(["plot", str(folder)]) == EXIT_BAD_INPUT
    line = one_error_line(capsys)
    assert f"{folder / 'arrays.npz'}:" in line and "figure" in line, line
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == []


# --- sweep folders ---------------------------------------------------------------------------------------------


@pytest.fixture
def sweep(tmp_path) -> Path:
    path = tmp_path / "mini.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "mini",
                "title": "three small IK cells",
                "problem": "cc-ik-position",
                "set": {"data.samples": 3, "baselines": []},
                "axes": {"data.seed": [0, 1, 2]},
                "metrics": ["success [%]"],
            }
        )
    )
    return path


def _cell_list(folder: Path) -> None:
    (folder / "cells").mkdir(parents=True)
    (folder / "cells" / "0123456789abcdef.json").write_text("[1, 2, 3]")


def _cell_not_json(folder: Path) -> None:
    (folder / "cells").mkdir(parents=True)
    (folder / "cells" / "0123456789abcdef.json").write_text('{"status": "do')


def _cell_folder(folder: Path) -> None:
    (folder / "cells" / "0123456789abcdef.json").mkdir(parents=True)


def _cells_file(folder: Path) -> None:
    folder.mkdir(parents=True)
    (folder / "cells").write_text("")


def _table_folder(folder: Path) -> None:
    (folder / "table.csv").mkdir(parents=True)


def _table_json_folder(folder: Path) -> None:
    (folder / "table.json").mkdir(parents=True)


def _running_file(folder: Path) -> None:
    folder.mkdir(parents=True)
    (folder / "running").write_text("")


def _sweep_folder_file(folder: Path) -> None:
    folder.parent.mkdir(parents=True)
    folder.write_text("")


SWEEP_DAMAGE = {
    "a cell holding a list": (_cell_list, "cells/0123456789abcdef.json: not a cell record"),
    "a cell not JSON": (_cell_not_json, "cells/0123456789abcdef.json: not a cell record: not JSON"),
    "a cell path that is a folder": (_cell_folder, "cells/0123456789abcdef.json: is not a file"),
    "cells/ a file": (_cells_file, "mini/cells: is not a folder"),
    "table.csv a folder": (_table_folder, "mini/table.csv: is not a file"),
    "table.json a folder": (_table_json_folder, "mini/table.json: is not a file"),
    "running/ a file": (_running_file, "mini/running: is not a folder"),
    "the sweep folder a file": (_sweep_folder_file, "mini: is not a folder"),
}


@pytest.mark.parametrize("damage", list(SWEEP_DAMAGE))
def test_a_sweep_folder_in_the_way_exits_2_before_any_cell(sweep, tmp_path, capsys, damage):
    out = tmp_path / "out"
    spoil, expected = SWEEP_DAMAGE[damage]
    spoil(out / "mini")
    capsys.readouterr()
    assert main(["sweep", str(sweep), "--out", str(out), "--no-figures", "--json"]) == EXIT_BAD_INPUT
    line = one_error_line(capsys)
    assert expected in line, line
    assert not (out / "mini" / "cells").is_dir() or damage.startswith("a cell")


# --- --dask ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("address", [";touch x", "tcp://host", "tcp://$(id):1", "local:0", "localhost:99999"])
@pytest.mark.parametrize("command", ["solve", "sweep"])
def test_a_malformed_dask_address_exits_2_naming_it(sweep, tmp_path, capsys, monkeypatch, address, command):
    monkeypatch.chdir(tmp_path)
    target = "cc-ik-position" if command == "solve" else str(sweep)
    capsys.readouterr()
    assert main([command, target, "--dask", address, "--out", str(tmp_path / "out")]) == EXIT_BAD_INPUT
    line = one_error_line(capsys)
    assert "--dask: expected local:N" in line and repr(address) in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mini.yaml"]


@pytest.mark.parametrize("command", ["solve", "sweep"])
def test_no_scheduler_at_the_address_exits_2_after_one_short_try(sweep, tmp_path, capsys, command):
    pytest.importorskip("distributed")
    from optikin.sweep.run import DASK_TIMEOUT

    target = ["solve", "cc-ik-position", *SMALL[:4]] if command == "solve" else ["sweep", str(sweep)]
    capsys.readouterr()
    started = time.monotonic()
    code = main([*target, "--dask", "tcp://127.0.0.1:1", "--out", str(tmp_path / "out")])
    elapsed = time.monotonic() - started
    assert code == EXIT_BAD_INPUT
    line = one_error_line(capsys)
    assert "--dask: no Dask scheduler answered at tcp://127.0.0.1:1" in line, line
    assert elapsed < DASK_TIMEOUT + 3, elapsed
    assert not (tmp_path / "out" / "cc-ik-position").exists()
