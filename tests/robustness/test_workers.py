"""Worker processes: ``--jobs`` above the CPU count is capped with one line, and workers end with their parent.

Before, ``optikin sweep ... --jobs 100000`` started hundreds of loky workers (and did not finish a
3-cell sweep in 60 s), and a sweep killed by SIGKILL left its workers running.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from optikin.cli import EXIT_OK, main

ALIVE_WITHIN = 10.0
"""Seconds after the parent's death by which no worker may be left."""


def sweep_file(folder: Path, cells: int, samples: int) -> Path:
    path = folder / "mini.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "mini",
                "title": "small IK cells",
                "problem": "cc-ik-position",
                "set": {"data.samples": samples, "baselines": []},
                "axes": {"data.seed": list(range(cells))},
                "metrics": ["success [%]"],
            }
        )
    )
    return path


def warning_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "--jobs" in line]


@pytest.fixture
def one_cpu(monkeypatch):
    """A machine of one CPU as joblib counts them: capped runs take one process, so these tests stay fast."""
    import joblib

    monkeypatch.setattr(joblib, "cpu_count", lambda *a, **k: 1)


def test_jobs_above_the_cpu_count_are_capped_with_one_line_in_a_sweep(tmp_path, capsys, one_cpu):
    sweep = sweep_file(tmp_path, cells=3, samples=3)
    capsys.readouterr()
    assert main(["sweep", str(sweep), "--jobs", "100000", "--out", str(tmp_path / "out"), "--no-figures"]) == EXIT_OK
    captured = capsys.readouterr()
    assert warning_lines(captured.err) == [
        "optikin: warning: --jobs 100000 is above this machine's CPU count (1): running 1 workers"
    ]
    assert "engine: joblib loky x1" in captured.out and "ran: 3, failed: 0" in captured.out


def test_jobs_above_the_cpu_count_are_capped_with_one_line_in_a_solve(tmp_path, capsys, one_cpu):
    args = ["solve", "cc-ik-position", "--set", "data.samples=5", "--set", "baselines=[]", "--no-figures"]
    capsys.readouterr()
    assert main([*args, "--jobs", "64", "--out", str(tmp_path)]) == EXIT_OK
    assert warning_lines(capsys.readouterr().err) == [
        "optikin: warning: --jobs 64 is above this machine's CPU count (1): running 1 workers"
    ]


def test_jobs_within_the_cpu_count_are_kept_silently(caplog):
    import joblib

    from optikin.sweep.run import check_jobs

    assert check_jobs(1) == 1
    assert check_jobs(joblib.cpu_count()) == joblib.cpu_count()
    assert check_jobs(joblib.cpu_count() + 5) == joblib.cpu_count()
    assert [r.getMessage() for r in caplog.records if "--jobs" in r.getMessage()] == [
        f"--jobs {joblib.cpu_count() + 5} is above this machine's CPU count ({joblib.cpu_count()}): "
        f"running {joblib.cpu_count()} workers"
    ]


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (psutil when installed, else /proc)."""
    try:
        import psutil
    except ImportError:
        parents: dict[int, int] = {}
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit():
                try:
                    parents[int(entry.name)] = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
                except (OSError, IndexError, ValueError):
                    continue
        found, frontier = [], [pid]
        while frontier:
            children = [c for c, p in parents.items() if p in frontier]
            found += children
            frontier = children
        return found
    return [p.pid for p in psutil.Process(pid).children(recursive=True)]


def _alive(pid: int) -> bool:
    """Running and not a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.slow
@pytest.mark.parametrize("command", ["sweep", "solve"])
def test_workers_end_when_their_parent_is_killed(tmp_path, command):
    if command == "sweep":
        args = ["sweep", str(sweep_file(tmp_path, cells=40, samples=400)), "--no-figures"]
    else:
        args = ["solve", "cc-ik-position", "--set", "data.samples=20000", "--set", "baselines=[]", "--no-figures"]
    process = subprocess.Popen(
        [sys.executable, "-m", "optikin.cli", *args, "--jobs", "2", "--out", str(tmp_path / "out")],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    workers: list[int] = []
    everything: list[int] = []
    try:
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline and process.poll() is None:
            workers = [p for p in _descendants(process.pid) if "Loky" in Path(f"/proc/{p}/cmdline").read_text()]
            if len(workers) >= 2:
                break
            time.sleep(0.2)
        assert len(workers) >= 2, "the run started no workers"
        time.sleep(2.0)  # the workers are in a cell or piece
        everything = _descendants(process.pid)
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        killed = time.monotonic()
        while time.monotonic() - killed < ALIVE_WITHIN and any(_alive(p) for p in everything):
            time.sleep(0.2)
        left = [p for p in everything if _alive(p)]
        print(f"{command}: the last of {len(everything)} processes ended {time.monotonic() - killed:.2f} s after")
    finally:
        for pid in everything + workers:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if process.poll() is None:
            process.kill()
            process.wait()
    assert left == [], f"{len(left)} of {len(everything)} processes alive {ALIVE_WITHIN} s after the parent died"
