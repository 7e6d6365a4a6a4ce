"""Progress off a terminal and logging: a piped run is not silent, ``-q`` silences it, ``-v`` adds debug records,
library records reach a user's logging, and the library itself never prints."""

from __future__ import annotations

import ast
import logging
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import optikin
from optikin.cli import main
from optikin.errors import SpecError
from optikin import progress
from optikin.progress import INTERVAL_VARIABLE, Progress, ProgressLines
from optikin.runner import solve

ROOT = Path(__file__).resolve().parent.parent
SMALL = ["solve", "cc-two-section-fk", "--no-figures", "--set", "data.samples=20"]
LINE = re.compile(r"^optikin: fk: 20 samples: (started, 3 steps|[0-3]/3 \(\d+ %\), .*|done, 3/3 in .* s)$")


def test_a_piped_run_writes_progress_lines_on_stderr(tmp_path):
    command = [sys.executable, "-m", "optikin.cli", *SMALL, "--out", str(tmp_path / "out")]
    env = dict(os.environ, **{INTERVAL_VARIABLE: "0.05"})
    piped = subprocess.run(command, env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert piped.returncode == 0, piped.stderr
    lines = [line for line in piped.stderr.splitlines() if LINE.match(line)]
    assert lines[0] == "optikin: fk: 20 samples: started, 3 steps" and lines[-1].startswith(
        "optikin: fk: 20 samples: done"
    )
    assert "1/3 (33 %)" in piped.stderr and "written to" in piped.stdout


def test_quiet_removes_the_progress_and_verbose_adds_debug_records_after_the_subcommand_too(tmp_path, capsys):
    assert main([*SMALL, "--out", str(tmp_path / "q"), "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "written to" in out  # only the summary
    assert main(["-v", *SMALL, "--out", str(tmp_path / "v")]) == 0
    err = capsys.readouterr().err
    assert "optikin: debug: optikin.runner: " in err and "optikin: info: optikin.progress: fk: 20 samples: done" in err
    assert not any(isinstance(h, logging.StreamHandler) for h in logging.getLogger("optikin").handlers)  # gone after


def test_progress_lines_every_tenth_and_every_interval_during_a_long_step(caplog):
    with caplog.at_level(logging.INFO, logger="optikin.progress"):
        with Progress(interval=60.0).task("many", total=100) as advance:
            for _ in range(100):
                advance()
    messages = [r.getMessage() for r in caplog.records]
    assert messages[0] == "many: started, 100 steps" and messages[-1].startswith("many: done, 100/100 in ")
    assert [m.split(": ")[1].split(" ")[0] for m in messages[1:-1]] == [f"{k}0/100" for k in range(1, 10)]
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="optikin.progress"):
        with Progress(interval=0.05).task("slow", total=2) as advance:
            time.sleep(0.5)  # one step that runs long: the periodic thread still writes
            advance()
    waiting = [r.getMessage() for r in caplog.records if r.getMessage().startswith("slow: 0/2 (0 %)")]
    assert len(waiting) >= 3


def test_steps_done_before_a_resumed_run_are_left_out_of_the_time_left(caplog, monkeypatch):
    now = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: now[0])
    with caplog.at_level(logging.INFO, logger="optikin.progress"):
        lines = ProgressLines("resumed", total=10, interval=60.0, completed=5, unit="cells")
        now[0] = 2.0
        lines.advance(1)  # 1 of the 5 cells run here in 2 s: 4 more to go
        now[0] = 3.0
        lines.close(finished=False)
    messages = [r.getMessage() for r in caplog.records]
    assert messages == [
        "resumed: started, 10 cells, 5 done before",
        "resumed: 6/10 (60 %), 2.0 s, about 8.0 s left",
        "resumed: stopped at 6/10 after 3.0 s",
    ]


def test_an_interrupted_task_says_where_it_stopped(caplog):
    with caplog.at_level(logging.INFO, logger="optikin.progress"), pytest.raises(RuntimeError):
        with Progress(interval=60.0).task("cut", total=4) as advance:
            advance()
            raise RuntimeError("stop")
    assert caplog.records[-1].getMessage().startswith("cut: stopped at 1/4 after ")


def test_library_records_reach_the_user_s_logging(caplog):
    with caplog.at_level(logging.DEBUG, logger="optikin"):
        result, _ = solve("cc-two-section-fk", progress=Progress(interval=60.0), overrides=[("data.samples", 20)])
        optikin.reconstruct_backbone(
            np.eye(4), np.array([[0.0, 0, 1, 0.2], [0, 1, 0, 0], [-1, 0, 0, 0.2], [0, 0, 0, 1]])
        )
    assert result.succeeded
    names = {r.name for r in caplog.records}
    assert {"optikin.progress", "optikin.runner", "optikin.api"} <= names
    assert any(
        r.getMessage() == "fk: 20 samples: done, 3/3 in " + r.getMessage().split(" in ")[-1] for r in caplog.records
    )


def test_progress_is_silent_when_its_logger_is_off_or_it_is_disabled(caplog):
    with caplog.at_level(logging.WARNING, logger="optikin"):
        with Progress(interval=60.0).task("quiet", total=2) as advance:
            advance(2)
    with caplog.at_level(logging.INFO, logger="optikin"):
        with Progress(enabled=False).task("off", total=2) as advance:
            advance(2)
    assert caplog.records == []


def test_a_bad_interval_is_refused(monkeypatch):
    monkeypatch.setenv(INTERVAL_VARIABLE, "soon")
    with pytest.raises(SpecError, match=f"{INTERVAL_VARIABLE}: expected a positive number of seconds, got 'soon'"):
        Progress()
    with pytest.raises(ValueError, match="positive number of seconds"):
        Progress(interval=0.0)


COMMAND_LINE = {"cli.py", "report.py", "bench.py", "sweep/run.py", "export/__init__.py"}
"""Modules that are the command line's own output (tables, summaries); the library below them logs."""


def test_the_library_does_not_print():
    package = ROOT / "optikin"
    printing = []
    for path in sorted(package.rglob("*.py")):
        if path.relative_to(package).as_posix() in COMMAND_LINE:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
                printing.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert printing == [], "library code logs (logging.getLogger(__name__)) instead of printing"


def test_on_a_terminal_the_bar_is_drawn_on_stderr_and_stdout_keeps_only_the_summary(tmp_path):
    import pty

    master, slave = pty.openpty()
    command = [sys.executable, "-m", "optikin.cli", *SMALL, "--out", str(tmp_path / "out")]
    env = dict(os.environ, TERM="xterm", COLUMNS="100")
    process = subprocess.Popen(command, env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=slave, text=True)
    os.close(slave)
    terminal = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        terminal += chunk
    out = process.communicate(timeout=120)[0]
    os.close(master)
    assert process.returncode == 0
    assert b"fk: 20 samples" in terminal and b"\x1b[" in terminal  # the live bar, drawn with escape codes
    assert "fk: 20 samples" not in out and "\x1b[?25l" not in out and "written to" in out


def test_quiet_keeps_errors_only_and_verbose_names_level_and_logger(capsys):
    from optikin.progress import command_line_logging

    library = logging.getLogger("optikin.somewhere")
    with command_line_logging(quiet=True):
        library.info("progress")
        library.warning("a warning")
        library.error("an error")
    assert capsys.readouterr().err == "optikin: error: an error\n"
    with command_line_logging(verbose=True):
        library.debug("detail")
    assert capsys.readouterr().err == "optikin: debug: optikin.somewhere: detail\n"
    with command_line_logging():
        library.debug("detail")
        library.warning("a warning")
    assert capsys.readouterr().err == "optikin: warning: a warning\n"
