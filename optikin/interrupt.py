"""Stopping a run at Ctrl-C or SIGTERM within about a second, without interrupting CasADi mid-call.

Python's default SIGINT handler raises ``KeyboardInterrupt`` wherever the main
thread is, which goes wrong in two places. CasADi polls Python's signal handlers
from inside its calls (``PyErr_CheckSignals``) and then either swallows the
exception (the solve reports a failure, the run goes on and writes a full result)
or returns with it still set (``SystemError: <built-in function
_function_buffer_eval> returned a result with an exception set``); and
scikit-learn's MLP training catches ``KeyboardInterrupt``, warns "Training
interrupted by user" and carries on with the next epoch.

:func:`deferred_interrupts` replaces the SIGINT and SIGTERM handlers, for the
duration of a run, by one that looks at the Python stack when the signal arrives:

* inside a call into CasADi (a frame of CasADi's Python wrappers, or of a call site
  registered with :func:`calls_casadi`, such as the zero-copy buffer calls of
  :mod:`optikin.fastcall` and :mod:`optikin.batch`), it only records the signal;
* inside a call into a package that catches ``KeyboardInterrupt``
  (:data:`CATCHING_PACKAGES`), it records the signal and raises, which ends that
  call's work early;
* anywhere else it raises ``KeyboardInterrupt`` at once, as the default handler does.

A recorded signal is raised at the first line the program runs outside those calls:
the handler sets a trace function on the frames that called into them (``frame.f_trace``,
with ``sys.settrace`` switched on while a signal is recorded), which raises
``KeyboardInterrupt`` as soon as one of them runs its next line. A loop of back-to-back
CasADi calls from Python (a GA evaluating one mapped call per generation, a solver
stepping with compiled Functions) therefore stops after the call in progress, although a
Python signal handler only ever runs inside CasADi's Python wrappers there. The same
signal is raised by :func:`check_interrupted`, which the sample loops, the chunked batches
of :class:`optikin.batch.BatchFunction`, :class:`optikin.progress.Progress`, the training
epochs and the GA's generations call between CasADi calls, and by a re-check every
:data:`RECHECK` seconds (a one-shot ``SIGALRM`` timer). A CasADi call therefore delays the
stop by at most its own duration, which is why long batches run in chunks. A second
signal while one is recorded ends the process at once by that signal's default action
(nothing is cleaned up).

A single CasADi call can run for tens of seconds (building a large NLP, one IPOPT solve),
and no Python signal handler runs before it returns. A program (the command line)
therefore passes ``hard_stop``: a thread reads the signal numbers that the C-level handler
writes to a wakeup pipe (:func:`signal.set_wakeup_fd`) and, when the block has not ended
:data:`STOP_GRACE` seconds after a stopping signal, ends the process itself (CasADi
releases the GIL during its calls) with that message and exit status 130, having removed
the folders registered with :func:`removed_on_hard_stop` (a result's staging folder).
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import sys
import threading
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from types import CodeType, FrameType
from typing import Any, Callable, Iterator, Literal, TypeVar

SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a run."""
RECHECK = 0.05
"""Seconds between re-checks of a recorded signal."""
STOP_GRACE = 0.6
"""Seconds a program's block has, after a stopping signal, to end by itself (``hard_stop``)."""
EXIT_INTERRUPTED = 130
"""The exit status of an interrupted program."""
DEFERRING_PACKAGES = ("casadi",)
"""Packages that must not see an exception raised by a signal handler during their calls."""
CATCHING_PACKAGES = ("sklearn",)
"""Packages that catch ``KeyboardInterrupt`` during their calls and carry on."""
_CAUGHT_WARNING = "Training interrupted by user"  # scikit-learn's, when it catches one

F = TypeVar("F", bound=Callable[..., Any])


def _package_dirs(names: tuple[str, ...]) -> tuple[str, ...]:
    """The source folders (with a trailing separator) of the installed packages among ``names``."""
    dirs = []
    for name in names:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            dirs.append(str(Path(spec.origin).parent) + os.sep)
    return tuple(dirs)


_DEFERRING = _package_dirs(DEFERRING_PACKAGES)
_CATCHING = _package_dirs(CATCHING_PACKAGES)
_CALL_SITES: set[CodeType] = set()
_pending: int | None = None  # the signal recorded and not yet raised outside, if any
_active = False
_removals: list[Path] = []  # removed on a hard stop


def calls_casadi(function: F) -> F:
    """Register ``function`` as a call site into CasADi (it calls a CasADi builtin directly, not
    through CasADi's Python wrappers): a signal arriving while it runs is only recorded.
    Returns ``function`` unchanged."""
    _CALL_SITES.add(function.__code__)
    return function


def _inside(frame: FrameType | None) -> Literal["deferring", "catching"] | None:
    """Which kind of call the stack from ``frame`` (the innermost Python frame) is in, if any."""
    catching = False
    while frame is not None:
        code = frame.f_code
        if code in _CALL_SITES or code.co_filename.startswith(_DEFERRING):
            return "deferring"
        catching = catching or code.co_filename.startswith(_CATCHING)
        frame = frame.f_back
    return "catching" if catching else None


def interrupted() -> bool:
    """Whether a stopping signal is recorded and not yet raised outside the calls that delay it."""
    return _pending is not None


def check_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` if a stopping signal is recorded; call it between CasADi calls.

    Costs one global read when nothing is recorded, so it may sit in per-sample loops.
    """
    global _pending
    if _pending is not None:
        _pending = None
        signal.setitimer(signal.ITIMER_REAL, 0)
        _untrace()
        raise KeyboardInterrupt


_traced: list[FrameType] = []  # the frames given _on_line while a signal is recorded
_previous_trace: Any = None


def _trace_callers(frame: FrameType | None) -> None:
    """Make every frame of the stack from ``frame`` outside the delaying calls raise the recorded signal at
    its next line (:func:`_on_line`)."""
    global _previous_trace
    if not _traced:
        _previous_trace = sys.gettrace()
        sys.settrace(_on_call)
    while frame is not None:
        code = frame.f_code
        if code not in _CALL_SITES and not code.co_filename.startswith(_DEFERRING):
            frame.f_trace = _on_line
            frame.f_trace_lines = True
            _traced.append(frame)
        frame = frame.f_back


def _untrace() -> None:
    """Undo :func:`_trace_callers`: the frames' trace functions, and the thread's (the previous one back)."""
    global _previous_trace
    if not _traced:
        return
    for frame in _traced:
        frame.f_trace = None
    _traced.clear()
    sys.settrace(_previous_trace)
    _previous_trace = None


def _on_call(frame: FrameType, event: str, arg: Any) -> None:
    """The thread's trace function while a signal is recorded: new frames are not traced."""
    return None


def _on_line(frame: FrameType, event: str, arg: Any) -> Any:
    """A traced frame runs a line: outside every delaying call, raise the recorded signal."""
    if _pending is None:
        return None
    if event == "line" and _inside(frame) is None:
        check_interrupted()
    return _on_line


def _on_signal(signum: int, frame: FrameType | None) -> None:
    global _pending
    if _pending is not None:  # a second signal: the caller insists
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    where = _inside(frame)
    if where is None:
        raise KeyboardInterrupt
    _pending = signum
    signal.setitimer(signal.ITIMER_REAL, RECHECK)
    if where == "catching":
        raise KeyboardInterrupt
    _trace_callers(frame)


def _watch(read_end: int, message: str) -> None:
    """In a thread, reading the signal numbers that the C-level handler writes to the wakeup pipe: after a
    stopping signal, give the block :data:`STOP_GRACE` seconds to end (the signal raised and unwound); if
    it is still running then (inside one long CasADi call), remove the registered folders and end the
    process with ``message`` and :data:`EXIT_INTERRUPTED`. Returns when the pipe's write end closes."""
    stopping = {int(s) for s in SIGNALS}
    while True:
        try:
            received = os.read(read_end, 64)
        except OSError:
            return
        if not received:
            return
        if not stopping.intersection(received):
            continue
        deadline = time.monotonic() + STOP_GRACE
        while _active and time.monotonic() < deadline:
            time.sleep(0.01)
        if _active:
            for path in list(_removals):
                shutil.rmtree(path, ignore_errors=True)
            exit_now(EXIT_INTERRUPTED, message)


@contextmanager
def removed_on_hard_stop(path: Path) -> Iterator[None]:
    """Within the block, a hard stop (:func:`deferred_interrupts`' ``hard_stop``) removes the folder ``path``."""
    _removals.append(path)
    try:
        yield
    finally:
        _removals.remove(path)


def _on_recheck(signum: int, frame: FrameType | None) -> None:
    if _pending is None:
        return
    where = _inside(frame)
    if where is None:
        check_interrupted()
    signal.setitimer(signal.ITIMER_REAL, RECHECK)
    if where == "catching":
        raise KeyboardInterrupt


def exit_now(code: int, message: str = "") -> None:
    """End the process with ``code`` after flushing stdout and stderr (then writing ``message``, if any, as a
    line on stderr), without the interpreter's teardown (``os._exit``): after an interrupt, collecting the
    objects of a large run (CasADi expression graphs, trained models) can take seconds. Worker processes
    end with it (:func:`optikin.sweep.cell.watch_parent`)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    if message:
        try:
            os.write(2, f"{message}\n".encode())
        except OSError:
            pass
    os._exit(code)


@contextmanager
def deferred_interrupts(hard_stop: str | None = None) -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise ``KeyboardInterrupt`` as the module docstring
    describes; the previous handlers (SIGALRM's too) are restored on exit.

    A signal still recorded when the block ends is raised then. Outside the main thread, or
    nested in another such block, the block runs with the handlers as they are.

    Parameters
    ----------
    hard_stop:
        For a program only (it ends the process): the message printed when the block is still running
        :data:`STOP_GRACE` seconds after SIGINT or SIGTERM, before the process ends with
        :data:`EXIT_INTERRUPTED` (module docstring).
    """
    global _active, _pending
    if _active or threading.current_thread() is not threading.main_thread():
        yield
        return
    handlers = {s: signal.getsignal(s) for s in (*SIGNALS, signal.SIGALRM)}
    _active, _pending = True, None
    wakeup = None
    if hard_stop is not None:
        read_end, write_end = os.pipe()
        os.set_blocking(write_end, False)
        wakeup = (read_end, write_end, signal.set_wakeup_fd(write_end, warn_on_full_buffer=False))
        watcher = threading.Thread(target=_watch, args=(read_end, hard_stop), name="optikin-stop", daemon=True)
        watcher.start()
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=_CAUGHT_WARNING)
            for s in SIGNALS:
                signal.signal(s, _on_signal)
            signal.signal(signal.SIGALRM, _on_recheck)
            yield
            check_interrupted()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        _untrace()
        for s, handler in handlers.items():
            signal.signal(s, handler)
        _active, _pending = False, None
        if wakeup is not None:
            read_end, write_end, previous = wakeup
            signal.set_wakeup_fd(previous)
            os.close(write_end)
            watcher.join()
            os.close(read_end)
