"""The output folder: concurrent writers, interrupted writes, things in the way, unwritable or full folders."""

from __future__ import annotations

import errno
import json
import multiprocessing
import os
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from optikin.cli import EXIT_BAD_INPUT, main
from optikin.errors import OptikinError
from optikin.results import Result, read_result, redraw, write_result

NAME = "shared"
PROBLEM = """\
name: small
title: a small test problem
kind: fk
arm:
  type: constant_curvature
  params: {section_lengths: [0.18, 0.18]}
data:
  source: random
  seed: 3
  samples: 8
"""


def result(writer: int = 0, round_: int = 0, size: int = 1000) -> Result:
    """A result whose arrays and metrics both say who wrote it, so a mixed folder is detectable."""
    tag = 1000 * writer + round_
    return Result(
        problem=NAME,
        kind="fk",
        solver=None,
        title="t",
        arm={},
        status=["ok"] * 4,
        metrics={"tag": tag},
        arrays={"tag": np.full(size, float(tag))},
    )


def entries(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


def assert_complete(folder: Path) -> int:
    """The result folder holds one whole result; returns its tag."""
    summary, arrays = read_result(folder)
    assert set(arrays) == {"tag"}
    assert np.all(arrays["tag"] == summary["metrics"]["tag"])
    return int(summary["metrics"]["tag"])


def _write_many(out: str, writer: int, rounds: int, errors) -> None:
    for round_ in range(rounds):
        try:
            write_result(result(writer, round_), Path(out), figures=False)
        except Exception as exc:
            errors.put(f"{writer}/{round_}: {type(exc).__name__}: {exc}")


def test_six_processes_writing_one_result_leave_one_complete_result(tmp_path):
    context = multiprocessing.get_context("fork")
    errors = context.Queue()
    workers = [context.Process(target=_write_many, args=(str(tmp_path), w, 10, errors)) for w in range(6)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=120)
    failures = []
    while not errors.empty():
        failures.append(errors.get())
    assert [w.exitcode for w in workers] == [0] * 6
    assert failures == []
    assert entries(tmp_path) == {NAME}
    tag = assert_complete(tmp_path / NAME)
    assert tag % 1000 == 9  # the last swap is one writer's last round


def test_a_write_killed_midway_is_cleaned_up_by_the_next(tmp_path):
    script = textwrap.dedent(
        f"""
        import os, signal
        from pathlib import Path
        import numpy as np
        from optikin.results import Result, write_result

        def killed(file, **arrays):
            Path(file).write_bytes(b"PK partial")
            os.kill(os.getpid(), signal.SIGKILL)

        np.savez_compressed = killed
        r = Result(problem={NAME!r}, kind="fk", solver=None, title="t", arm={{}}, status=["ok"],
                   arrays={{"tag": np.zeros(3)}})
        write_result(r, Path({str(tmp_path)!r}), figures=False)
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == -9, done.stderr
    assert any(name.startswith(f".{NAME}-") for name in entries(tmp_path))  # what the killed write left
    write_result(result(1), tmp_path, figures=False)
    assert entries(tmp_path) == {NAME}
    assert assert_complete(tmp_path / NAME) == 1000


def test_a_live_writer_s_staging_folder_is_left_alone(tmp_path):
    live = tmp_path / f".{NAME}-tmp-{os.uname().nodename}-{os.getpid()}-0123abcd"
    live.mkdir()
    write_result(result(), tmp_path, figures=False)
    assert live.is_dir()


@pytest.mark.parametrize("what", ["file", "symlink"])
def test_a_file_or_symlink_at_the_result_path_is_named_and_kept(tmp_path, what):
    target = tmp_path / "elsewhere"
    target.mkdir()
    (target / "keep.txt").write_text("mine")
    final = tmp_path / NAME
    if what == "file":
        final.write_text("mine")
    else:
        final.symlink_to(target)
    with pytest.raises(OptikinError, match=f"{final}: is a {what}"):
        write_result(result(), tmp_path, figures=False)
    assert final.is_symlink() == (what == "symlink")
    assert (target / "keep.txt").read_text() == "mine"
    assert not any(name.startswith(f".{NAME}-") for name in entries(tmp_path))


def test_out_that_is_a_file_exits_2_naming_it(tmp_path, capsys):
    problem = tmp_path / "small.yaml"
    problem.write_text(PROBLEM)
    out = tmp_path / "results"
    out.write_text("not a folder")
    assert main(["solve", str(problem), "--out", str(out), "--no-figures"]) == EXIT_BAD_INPUT
    error = capsys.readouterr().err.strip().splitlines()
    assert error == [f"optikin: error: {out}: the output folder is not a folder"]  # refused before the run
    assert out.read_text() == "not a folder"


def test_read_only_out_exits_2_naming_it(tmp_path, capsys, monkeypatch):
    problem = tmp_path / "small.yaml"
    problem.write_text(PROBLEM)
    out = tmp_path / "results"
    out.mkdir()
    out.chmod(0o555)
    if os.geteuid() == 0:  # root writes anywhere: refuse as a read-only mount would
        real_mkdir = os.mkdir

        def read_only_mkdir(path, mode=0o777, **kwargs):
            if Path(path).parent == out:
                raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
            return real_mkdir(path, mode, **kwargs)

        monkeypatch.setattr(os, "mkdir", read_only_mkdir)
    try:  # -q: as root the refusal comes after the run, whose progress lines would precede it
        assert main(["-q", "solve", str(problem), "--out", str(out), "--no-figures"]) == EXIT_BAD_INPUT
    finally:
        out.chmod(0o755)
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and error[0].startswith(f"optikin: error: {out}: cannot write the result 'small'")
    assert entries(out) == set()


def test_an_output_folder_under_a_file_is_refused_before_the_run(tmp_path, capsys):
    problem = tmp_path / "small.yaml"
    problem.write_text(PROBLEM)
    (tmp_path / "afile").write_text("x")
    out = tmp_path / "afile" / "results"
    assert main(["solve", str(problem), "--out", str(out), "--no-figures"]) == EXIT_BAD_INPUT
    error = capsys.readouterr().err.strip().splitlines()
    assert error == [f"optikin: error: {tmp_path / 'afile'}: the output folder is not a folder"]


def test_a_full_file_system_keeps_the_previous_result_and_leaves_nothing(tmp_path, monkeypatch):
    write_result(result(1), tmp_path, figures=False)

    def full(file, **arrays):
        Path(file).write_bytes(b"PK partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(file))

    monkeypatch.setattr(np, "savez_compressed", full)
    with pytest.raises(OptikinError) as info:
        write_result(result(2), tmp_path, figures=False)
    message = str(info.value)
    assert message == f"{tmp_path}: cannot write the result {NAME!r}: No space left on device"
    assert "\n" not in message
    assert entries(tmp_path) == {NAME}
    assert assert_complete(tmp_path / NAME) == 1000


def test_folders_and_redrawn_figures_follow_the_umask(tmp_path):
    def figures(arrays, summary):
        return {"plot": lambda path: path.write_bytes(b"png")}

    previous = os.umask(0o022)
    try:
        folder = write_result(result(), tmp_path / "out", figure_builder=figures)
        (folder / "plot.png").unlink()
        redraw(folder, figures, *read_result(folder))
    finally:
        os.umask(previous)
    assert stat.S_IMODE(folder.stat().st_mode) == 0o755
    assert stat.S_IMODE((folder / "result.json").stat().st_mode) == 0o644
    assert stat.S_IMODE((folder / "plot.png").stat().st_mode) == 0o644
    assert json.loads((folder / "result.json").read_text())["figures"] == ["plot.png"]
