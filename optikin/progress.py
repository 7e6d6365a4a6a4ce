"""Progress of long runs, and the logging of the command line.

Library code reports through Python :mod:`logging`, one logger per module (``logging.getLogger(__name__)``),
never with ``print``: an application routes the records as it likes (``logging.basicConfig(level=logging.INFO)``
shows them on stderr).

:class:`Progress` reports the tasks of a run on the logger ``optikin.progress`` at level INFO, so the level
that shows or hides the other records shows or hides it too:

* on a terminal, a rich progress bar on stderr, gone when the task ends;
* otherwise (a pipe, a file, CI), one line when a task starts, one whenever it passes another tenth of its
  steps or :attr:`Progress.interval` seconds went by without a line (a background thread writes those while
  a step runs long, whenever the step lets other Python threads run), and one when it ends, e.g.
  ``optikin: ik: 1000 targets x 3 methods: 2/3 (67 %), 12.4 s, about 6.2 s left``.

The interval defaults to the environment variable ``OPTIKIN_PROGRESS_INTERVAL`` (seconds), else 5 s.

:func:`command_line_logging` is what ``optikin -v`` / ``-q`` choose: optikin's records on stderr at INFO
(progress lines, notes), DEBUG with ``--verbose``, only errors with ``--quiet`` (the command still prints its summary).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import threading
import time
from contextlib import contextmanager
from typing import Any, Iterator

from optikin.errors import SpecError
from optikin.interrupt import check_interrupted

logger = logging.getLogger(__name__)

INTERVAL_VARIABLE = "OPTIKIN_PROGRESS_INTERVAL"
"""The environment variable that sets the seconds between progress lines off a terminal."""
DEFAULT_INTERVAL = 5.0
"""Seconds between progress lines off a terminal, unless :data:`INTERVAL_VARIABLE` says otherwise."""
LINE_PARTS = 10
"""Off a terminal, a line also whenever a task passes another ``1/LINE_PARTS`` of its steps."""


def progress_interval() -> float:
    """Seconds between progress lines: ``OPTIKIN_PROGRESS_INTERVAL``, else :data:`DEFAULT_INTERVAL`.

    Raises
    ------
    SpecError
        The variable is set to something other than a positive number of seconds.
    """
    text = os.environ.get(INTERVAL_VARIABLE)
    if text is None:
        return DEFAULT_INTERVAL
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise SpecError(INTERVAL_VARIABLE, "", f"expected a positive number of seconds, got {text!r}")
    return value


class Progress:
    """Reports the progress of named tasks (module docstring); ``enabled=False`` makes it silent.

    Parameters
    ----------
    enabled:
        Report at all (the command line turns it off for ``--json``).
    interval:
        Seconds between progress lines off a terminal; default :func:`progress_interval`.
    """

    def __init__(self, enabled: bool = True, interval: float | None = None) -> None:
        self.enabled = enabled
        self.interval = progress_interval() if interval is None else float(interval)
        if not (math.isfinite(self.interval) and self.interval > 0):
            raise ValueError(f"interval must be a positive number of seconds, got {interval!r}")

    @contextmanager
    def task(self, description: str, total: int) -> Iterator["_Advance"]:
        """Context manager of one task of ``total`` steps; yields ``advance(n=1)``."""
        if not (self.enabled and logger.isEnabledFor(logging.INFO)):
            yield _Advance(None)
            return
        if sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeRemainingColumn
            from rich.progress import Progress as RichProgress

            columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
            with RichProgress(*columns, transient=True, console=Console(stderr=True)) as bar:
                task_id = bar.add_task(description, total=total)
                yield _Advance(lambda n: bar.advance(task_id, n))
            return
        lines = ProgressLines(description, total, self.interval)
        try:
            yield _Advance(lines.advance)
        except BaseException:
            lines.close(finished=False)
            raise
        lines.close(finished=True)


class _Advance:
    """``advance(n=1)``: ``n`` more steps done (and the point where an interrupt is honoured)."""

    def __init__(self, report: Any) -> None:
        self._report = report

    def __call__(self, n: int = 1) -> None:
        check_interrupted()
        if self._report is not None:
            self._report(n)


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest:02d} s"


class ProgressLines:
    """The progress lines of one task off a terminal (module docstring), with the thread that writes the
    periodic ones.

    Parameters
    ----------
    description:
        The task's name at the start of each line; a caller may change :attr:`description` between steps
        (``optikin sweep`` puts its counts of failed and running cells there).
    total:
        Steps of the whole task, those done before included.
    interval:
        Seconds between lines when no tenth of the steps was passed.
    completed:
        Steps done before this run (a resumed sweep's finished cells): counted as done, left out of the
        estimate of the time left.
    unit:
        What a step is, for the opening line.
    """

    def __init__(self, description: str, total: int, interval: float, completed: int = 0, unit: str = "steps") -> None:
        self.description, self.total, self.interval = description, max(int(total), 0), interval
        self.done = self.completed = min(max(int(completed), 0), self.total)
        self.started = self.last = time.monotonic()
        self.parts = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        before = f", {self.completed} done before" if self.completed else ""
        logger.info("%s: started, %d %s%s", description, self.total, unit, before)
        self._thread = threading.Thread(target=self._periodic, name="optikin-progress", daemon=True)
        self._thread.start()

    def _line(self, now: float) -> None:
        """One line of the current state (the caller holds the lock)."""
        elapsed = now - self.started
        fraction = self.done / self.total if self.total else 0.0
        remaining = self.total - self.completed
        ran = (self.done - self.completed) / remaining if remaining else 0.0
        left = f", about {_duration(elapsed * (1 - ran) / ran)} left" if 0 < ran < 1 else ""
        logger.info(
            "%s: %d/%d (%.0f %%), %s%s",
            self.description,
            self.done,
            self.total,
            100 * fraction,
            _duration(elapsed),
            left,
        )
        self.last = now

    def advance(self, n: int) -> None:
        """``n`` more steps done: a line if another tenth of the steps run here was passed or the interval went by."""
        with self._lock:
            self.done += n
            if self.done >= self.total:
                return  # the closing line says so
            remaining = max(self.total - self.completed, 1)
            now, parts = time.monotonic(), LINE_PARTS * (self.done - self.completed) // remaining
            if parts > self.parts or now - self.last >= self.interval:
                self.parts = parts
                self._line(now)

    def _periodic(self) -> None:
        while not self._stop.wait(max(self.last + self.interval - time.monotonic(), 0.01)):
            with self._lock:
                now = time.monotonic()
                if now - self.last >= self.interval:
                    self._line(now)

    def close(self, finished: bool) -> None:
        """Stop the periodic lines and write the closing one (``finished``: the task ran to its end)."""
        self._stop.set()
        self._thread.join()
        elapsed = _duration(time.monotonic() - self.started)
        if finished:
            logger.info("%s: done, %d/%d in %s", self.description, self.done, self.total, elapsed)
        else:
            logger.info("%s: stopped at %d/%d after %s", self.description, self.done, self.total, elapsed)


SILENT = Progress(enabled=False, interval=DEFAULT_INTERVAL)


# ---------------------------------------------------------------------------------------------- command line
class _StderrHandler(logging.StreamHandler):
    """Writes to ``sys.stderr`` as it is at each record (a rich progress bar swaps it while it is shown)."""

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr
        super().emit(record)


class _Formatter(logging.Formatter):
    """``optikin: message``; warnings and errors name their level, ``verbose`` also the logger."""

    def __init__(self, verbose: bool) -> None:
        super().__init__()
        self.verbose = verbose

    def format(self, record: logging.LogRecord) -> str:
        message = super().format(record)
        if self.verbose:
            return f"optikin: {record.levelname.lower()}: {record.name}: {message}"
        if record.levelno >= logging.WARNING:
            return f"optikin: {record.levelname.lower()}: {message}"
        return f"optikin: {message}"


@contextmanager
def command_line_logging(verbose: bool = False, quiet: bool = False) -> Iterator[None]:
    """optikin's log records on stderr while one command runs (module docstring).

    Parameters
    ----------
    verbose:
        DEBUG records too, each with its level and logger.
    quiet:
        Only errors (no progress, no warnings); ``verbose`` wins over it.
    """
    package = logging.getLogger("optikin")
    handler = _StderrHandler(sys.stderr)
    handler.setFormatter(_Formatter(verbose))
    saved = package.level
    package.setLevel(logging.DEBUG if verbose else logging.ERROR if quiet else logging.INFO)
    package.addHandler(handler)
    try:
        yield
    finally:
        package.removeHandler(handler)
        package.setLevel(saved)


def add_verbosity_arguments(parser: argparse.ArgumentParser, commands: Any) -> None:
    """``-v/--verbose`` and ``-q/--quiet`` on ``parser`` and on every subcommand of ``commands`` (its subparsers
    action), so they may come before or after the subcommand's name."""
    targets = [(parser, False)] + [(p, argparse.SUPPRESS) for p in commands.choices.values()]
    for target, default in targets:
        group = target.add_mutually_exclusive_group()
        group.add_argument("-v", "--verbose", action="store_true", default=default, help="debug logging on stderr")
        group.add_argument(
            "-q", "--quiet", action="store_true", default=default, help="no progress: only errors and the summary"
        )
