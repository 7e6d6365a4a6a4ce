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

A recorded signal is raised by :func:`check_interrupted`, which the sample loops,
the chunked batches of :class:`optikin.batch.BatchFunction` and
:class:`optikin.progress.Progress` call between CasADi calls, or by a re-check
every :data:`RECHECK` seconds (a one-shot ``SIGALRM`` timer) once the stack has
left those calls. A CasADi call therefore delays the stop by at most its own
duration, which is why long batches run in chunks. A second signal while one is
recorded ends the process at once by that signal's default action (nothing is
cleaned up).
"""

from __future__ import annotations

import importlib.util
import os
import signal
import threading
import warnings
from contextlib import contextmanager
from pathlib import Path
from types import CodeType, FrameType
from typing import Any, Callable, Iterator, Literal, TypeVar

SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a run."""
RECHECK = 0.05
"""Seconds between re-checks of a recorded signal."""
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
        raise KeyboardInterrupt


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


def _on_recheck(signum: int, frame: FrameType | None) -> None:
    if _pending is None:
        return
    where = _inside(frame)
    if where is None:
        check_interrupted()
    signal.setitimer(signal.ITIMER_REAL, RECHECK)
    if where == "catching":
        raise KeyboardInterrupt


@contextmanager
def deferred_interrupts() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise ``KeyboardInterrupt`` as the module docstring
    describes; the previous handlers (SIGALRM's too) are restored on exit.

    A signal still recorded when the block ends is raised then. Outside the main thread, or
    nested in another such block, the block runs with the handlers as they are.
    """
    global _active, _pending
    if _active or threading.current_thread() is not threading.main_thread():
        yield
        return
    handlers = {s: signal.getsignal(s) for s in (*SIGNALS, signal.SIGALRM)}
    _active, _pending = True, None
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
        for s, handler in handlers.items():
            signal.signal(s, handler)
        _active, _pending = False, None
