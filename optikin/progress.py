"""Progress reporting for long runs: a rich progress bar on a terminal, silence otherwise."""

from __future__ import annotations

import sys
from contextlib import contextmanager
from typing import Any, Iterator

from optikin.interrupt import check_interrupted


class Progress:
    """Reports progress of named tasks; ``enabled=False`` (or no terminal) makes it silent."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled and sys.stderr.isatty()

    @contextmanager
    def task(self, description: str, total: int) -> Iterator["_Advance"]:
        """Context manager of one task of ``total`` steps; yields ``advance(n=1)``."""
        if not self.enabled:
            yield _Advance(None, None)
            return
        from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeRemainingColumn
        from rich.progress import Progress as RichProgress

        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
        with RichProgress(*columns, transient=True) as bar:
            yield _Advance(bar, bar.add_task(description, total=total))


class _Advance:
    def __init__(self, bar: Any, task_id: Any) -> None:
        self._bar, self._task = bar, task_id

    def __call__(self, n: int = 1) -> None:
        check_interrupted()
        if self._bar is not None:
            self._bar.advance(self._task, n)


SILENT = Progress(enabled=False)
