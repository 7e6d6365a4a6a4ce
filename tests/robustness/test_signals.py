"""Ctrl-C and SIGTERM stop a run within about a second: exit 130, nothing written, no traceback.

Each case starts ``python -m optikin.cli solve`` on a shipped problem made long (more
samples, no baselines), signals it after 3 s, while it is inside the call that used to
misbehave, and expects exit 130 within 2 s of the signal (the stop itself plus the
interpreter's exit), an empty output folder (no result, no hidden staging folder) and
no traceback. Before :mod:`optikin.interrupt`, the same runs ended with exit 3 on
``SystemError: <built-in function _function_buffer_eval> returned a result with an
exception set`` (IPOPT through a zero-copy buffer), exit 2 on "the mapped rootfinder
failed: KeyboardInterrupt" (a batched CasADi rootfinder), or went on training and
wrote a full result with exit 0 (scikit-learn catches ``KeyboardInterrupt``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DELAY = 3.0
"""Seconds from the start to the signal: past the imports and the setup."""
STOPPED_WITHIN = 2.0
"""Seconds from the signal to the exit."""

CASES = {
    # problem file, changes, signal
    "ipopt-buffer": ("cc-ik-pose", {"solver": "ipopt", "baselines": [], "data.samples": 3000}, signal.SIGINT),
    "mapped-rootfinder": (
        "cc-ik-position",
        {"solver": "newton", "baselines": [], "data.samples": 5000},
        signal.SIGTERM,
    ),
    "sklearn-training": ("cbha-nn-fkm", {"baselines": [], "data.samples": 200000}, signal.SIGINT),
}


def long_problem(tmp_path: Path, name: str, changes: dict) -> Path:
    """The shipped problem ``name`` with dotted ``changes``, written into ``tmp_path``."""
    spec = yaml.safe_load((REPO / "problems" / f"{name}.yaml").read_text())
    for dotted, value in changes.items():
        *parents, leaf = dotted.split(".")
        node = spec
        for key in parents:
            node = node[key]
        node[leaf] = value
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


@pytest.mark.parametrize("case", list(CASES))
def test_signal_stops_run_promptly_and_writes_nothing(tmp_path, case):
    name, changes, signum = CASES[case]
    problem = long_problem(tmp_path, name, changes)
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    process = subprocess.Popen(
        [sys.executable, "-m", "optikin.cli", "solve", str(problem), "--no-figures", "--out", str(out)],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(DELAY)
        assert process.poll() is None, f"the run ended before the signal: {process.communicate()}"
        sent = time.monotonic()
        process.send_signal(signum)
        try:
            _, stderr = process.communicate(timeout=STOPPED_WITHIN)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{signal.Signals(signum).name}: still running {STOPPED_WITHIN} s after the signal")
        waited = time.monotonic() - sent
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 130, stderr
    assert waited < STOPPED_WITHIN
    assert "interrupted; nothing was written" in stderr
    assert "SystemError" not in stderr and "Traceback" not in stderr, stderr
    assert list(out.iterdir()) == []


def test_handlers_restored_and_signal_outside_casadi_raises_at_once():
    from optikin.interrupt import deferred_interrupts

    watched = (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)
    before = [signal.getsignal(s) for s in watched]
    with pytest.raises(KeyboardInterrupt), deferred_interrupts():
        os.kill(os.getpid(), signal.SIGTERM)
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:  # plain Python: the handler raises here
            pass
    assert [signal.getsignal(s) for s in watched] == before


def _slow_mapped_function(columns: int):
    """A CasADi Function of about 20 us per column, mapped over ``columns``, and its input."""
    import casadi as ca

    x = ca.SX.sym("x", 200)
    e = x
    for _ in range(60):
        e = ca.sin(e) * ca.cos(e) + e
    return ca.Function("f", [x], [ca.sum1(e)]).map(columns, "serial"), ca.DM.ones(200, columns)


def test_a_loop_of_casadi_calls_stops_after_the_call_in_progress():
    """Back to back CasADi calls from Python: the Python handler only ever runs inside CasADi's wrappers, so
    before the frames were traced the signal waited for the end of the block (9 s of a 10 s loop)."""
    from optikin.interrupt import deferred_interrupts

    f, X = _slow_mapped_function(400)
    started = time.perf_counter()
    f(X)
    call = time.perf_counter() - started
    sent: list[float] = []

    def later() -> None:
        time.sleep(3 * call)
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=later, daemon=True).start()
    calls = 0
    with pytest.raises(KeyboardInterrupt), deferred_interrupts():
        deadline = time.monotonic() + max(10.0, 30 * call)
        while time.monotonic() < deadline:
            f(X)
            calls += 1
    waited = time.monotonic() - sent[0]
    print(f"one call {call:.2f} s; stopped {waited:.2f} s after the signal, after {calls} calls")
    assert waited < call + 1.0
    assert sys.gettrace() is None or "coverage" in type(sys.gettrace()).__module__


HARD_STOP = """
import sys
from pathlib import Path
from optikin.interrupt import deferred_interrupts, removed_on_hard_stop
sys.path.insert(0, {tests!r})
from test_signals import _slow_mapped_function
f, X = _slow_mapped_function(40000)
folder = Path({folder!r})
folder.mkdir()
print("ready", flush=True)
with deferred_interrupts(hard_stop="optikin: interrupted; nothing was written"), removed_on_hard_stop(folder):
    f(X)
print("the call returned")
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_program_inside_one_long_casadi_call_ends_within_the_grace(tmp_path, signum):
    from optikin.interrupt import STOP_GRACE

    folder = tmp_path / "staging"
    script = HARD_STOP.format(tests=str(Path(__file__).parent), folder=str(folder))
    process = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path
    )
    try:
        assert process.stdout.readline().strip() == "ready"
        time.sleep(0.5)
        sent = time.monotonic()
        process.send_signal(signum)
        out, err = process.communicate(timeout=60)
        waited = time.monotonic() - sent
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    print(f"{signal.Signals(signum).name}: ended {waited:.2f} s after the signal")
    assert process.returncode == 130, err
    assert err.strip() == "optikin: interrupted; nothing was written"
    assert "the call returned" not in out
    assert not folder.exists()
    assert waited < STOP_GRACE + 1.0


def test_a_signal_after_the_result_is_written_says_so(tmp_path, capsys, monkeypatch):
    import optikin.report
    from optikin.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(optikin.report, "print_result", interrupted)
    args = ["solve", "cc-ik-position", "--set", "data.samples=3", "--set", "baselines=[]", "--no-figures"]
    assert main([*args, "--out", str(tmp_path)]) == 130
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"optikin: interrupted; the result was written to {tmp_path / 'cc-ik-position'}"
    )
    assert (tmp_path / "cc-ik-position" / "result.json").is_file()


def test_a_build_killed_midway_leaves_nothing_the_next_build_keeps(tmp_path, monkeypatch):
    import casadi as ca

    from optikin import codegen

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    cache = codegen.cache_dir()
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = cache / f".sec_f-build-{codegen._host()}-{int(gone.stdout)}-abc123"
    live = cache / f".sec_f-build-{codegen._host()}-{os.getpid()}-abc123"
    other = cache / f".sec_f-build-elsewhere-{int(gone.stdout)}-abc123"
    for folder in (dead, live, other):
        folder.mkdir()
        (folder / "sec_f.c").write_text("half")
    x = ca.SX.sym("x", 2)
    compiled = codegen.CompiledFunction(ca.Function("sec_f", [x], [x * 2]))
    assert compiled.library.is_file()
    assert not dead.exists() and live.is_dir() and other.is_dir()
    assert sorted(p.name for p in cache.iterdir() if not p.name.startswith(".")) == sorted(
        [compiled.library.name, compiled.library.with_suffix(".json").name]
    )
