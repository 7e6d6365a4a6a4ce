"""Running the cells of a sweep on joblib (loky worker processes) or on a Dask cluster.

The engines do the scheduling and the data transfer; optikin only hands them :func:`run_cell` and the
picklable cells, and writes each record as it comes back (:func:`optikin.sweep.store.write_cell`).

Worker deaths:

* Dask reschedules a task whose worker died; after ``distributed.scheduler.allowed-failures`` deaths it
  raises ``KilledWorker`` for it. A ``local:N`` cluster is started with that setting at the sweep's
  ``retries``; a scheduler at an address keeps its own setting.
* joblib has no retry: a worker killed mid-cell breaks the loky pool (``TerminatedWorkerError``, and loky
  ends the other workers too). The cells whose ``running/`` marker outlived its process are charged one
  try, and the Parallel call is started again on the cells not finished; a cell charged ``1 + retries``
  tries is written as failed with the reason.

``--jobs`` above the machine's CPU count is lowered to it, with a warning (:func:`check_jobs`); joblib's
workers end when the process that started them is gone, even killed by SIGKILL
(:func:`optikin.sweep.cell.watch_parent`). A scheduler address is tried once, for :data:`DASK_TIMEOUT`
seconds.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import re
import sys
import time
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

from optikin.errors import SpecError
from optikin.progress import ProgressLines, progress_interval
from optikin.sweep.cell import run_cell, worker_pool
from optikin.sweep.spec import Cell, SweepSpec, expand, load_sweep
from optikin.sweep.store import (
    dead_tries,
    markers_dir,
    prepare_folder,
    read_cells,
    table_rows,
    write_cell,
    write_figures,
    write_table,
)

Record = dict[str, Any]

DASK_ADDRESS = re.compile(
    r"(?:(?:tcp|tls|ws|wss|ucx)://)?(?:[A-Za-z0-9](?:[A-Za-z0-9.-]{0,252})|\[[0-9A-Fa-f:.]+\]):(?P<port>[0-9]{1,5})"
)
"""A Dask scheduler address: an optional protocol, a host name, IPv4 or bracketed IPv6 address, and a port."""
DASK_TIMEOUT = 3.0
"""Seconds a Dask scheduler at an address has to answer the one connection attempt."""


@dataclass
class SweepReport:
    """What one ``optikin sweep`` did."""

    folder: Path
    cells: int
    skipped: int
    ran: int
    failed: int
    unsucceeded: int
    engine: str
    seconds: float
    rows: list[dict[str, Any]] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)


class _Bar:
    """One aggregated progress report: cells done / failed / running, with the ETA.

    On a terminal a rich bar on stderr; otherwise the lines of :class:`optikin.progress.ProgressLines` on
    the ``optikin.progress`` logger, the cells finished before a resumed run counted as done.
    """

    def __init__(self, name: str, total: int, completed: int, enabled: bool) -> None:
        self.name, self.done, self.failed, self.running = name, completed, 0, 0
        self._bar: Any = None
        self._lines: ProgressLines | None = None
        if enabled and not sys.stderr.isatty():
            self._lines = ProgressLines(self._text(), total, progress_interval(), completed, unit="cells")
        elif enabled:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self._bar = Progress(
                TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn()
            )
            self._bar.start()
            self._task = self._bar.add_task(self._text(), total=total, completed=completed)

    def _text(self) -> str:
        return f"{self.name}: {self.done} done, {self.failed} failed, {self.running} running"

    def update(self, record: Record | None, running: int) -> None:
        if record is not None:
            self.done += record["status"] == "done"
            self.failed += record["status"] != "done"
        self.running = running
        if self._bar is not None:
            self._bar.update(self._task, description=self._text(), completed=self.done + self.failed)
        if self._lines is not None:
            self._lines.description = self._text()
            self._lines.advance(record is not None)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
        if self._lines is not None:
            self._lines.description = self._text()
            self._lines.close(finished=self.done + self.failed >= self._lines.total)


def _killed(cell: Cell, tries: int, reason: str) -> Record:
    return {
        "key": cell.key,
        "index": cell.index,
        "axes": dict(cell.axes),
        "overrides": [list(o) for o in cell.overrides],
        "status": "failed",
        "reason": reason,
        "tries": tries,
    }


def _joblib(cells: list[Cell], folder: Path, jobs: int, retries: int) -> Iterator[tuple[Record, int]]:
    """Records as cells finish (any order), with the number still running."""
    from joblib import delayed
    from joblib.externals.loky.process_executor import TerminatedWorkerError

    pending = {cell.key: cell for cell in cells}
    deaths: dict[str, int] = {}
    while pending:
        try:
            parallel = worker_pool(jobs, ordered=False)
            for record in parallel(delayed(run_cell)(cell) for cell in list(pending.values())):
                pending.pop(record["key"])
                record["tries"] = deaths.get(record["key"], 0) + 1
                yield record, min(jobs, len(pending))
        except TerminatedWorkerError as exc:
            time.sleep(0.2)
            charged = dead_tries(folder)
            if not charged:
                charged = {key: 1 for key in pending}
            for key, count in charged.items():
                if key not in pending:
                    continue
                deaths[key] = deaths.get(key, 0) + count
                if deaths[key] > retries:
                    reason = f"its worker died {deaths[key]} times ({str(exc).splitlines()[0]})"
                    yield _killed(pending.pop(key), deaths[key], reason), min(jobs, len(pending))


def check_jobs(jobs: int) -> int:
    """``--jobs`` counts worker processes: at least 1, and at most the CPUs this process may use.

    Returns
    -------
    int
        ``jobs``, or the CPU count when ``jobs`` is above it (logged as a warning on ``optikin.sweep``).

    Raises
    ------
    SpecError
        ``jobs`` below 1.
    """
    if jobs < 1:
        raise SpecError("--jobs", "", f"expected at least 1 worker, got {jobs}")
    from joblib import cpu_count

    cpus = max(1, cpu_count())
    if jobs > cpus:
        logging.getLogger("optikin.sweep").warning(
            "--jobs %d is above this machine's CPU count (%d): running %d workers", jobs, cpus, cpus
        )
        return cpus
    return jobs


def check_dask(address: str | None) -> None:
    """``--dask`` is ``local:N`` (N >= 1) or a scheduler address ``[PROTOCOL://]HOST:PORT`` (:data:`DASK_ADDRESS`).

    Raises
    ------
    SpecError
        Naming ``--dask`` and the address.
    """
    if address is None:
        return
    if address.startswith("local:"):
        workers = address.removeprefix("local:")
        if not workers.isdigit() or int(workers) < 1:
            raise SpecError("--dask", "", f"expected local:N with N >= 1 workers, got {address!r}")
        return
    match = DASK_ADDRESS.fullmatch(address)
    if match is None or not 1 <= int(match.group("port")) <= 65535:
        raise SpecError(
            "--dask", "", f"expected local:N or a scheduler address such as tcp://HOST:8786, got {address!r}"
        )


@contextmanager
def dask_client(address: str, retries: int) -> Iterator[Any]:
    """A ``distributed.Client`` of the scheduler at ``address``, or of a ``LocalCluster`` of N single-threaded
    worker processes for ``local:N`` (its scheduler allowing ``retries`` worker deaths per task); closed after.

    A scheduler is tried once, for :data:`DASK_TIMEOUT` seconds.

    Raises
    ------
    SpecError
        Dask is not installed, ``address`` is malformed (:func:`check_dask`), or no scheduler answers there.
    """
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise SpecError("--dask", "", 'needs Dask: pip install "optikin[dask]" (dask[distributed])') from None
    check_dask(address)
    cluster = None
    if address.startswith("local:"):
        with dask.config.set({"distributed.scheduler.allowed-failures": retries}):
            cluster = LocalCluster(
                n_workers=int(address.removeprefix("local:")),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
            )
        client = Client(cluster)
    else:
        try:
            client = Client(address, timeout=DASK_TIMEOUT)
        except (OSError, TimeoutError) as exc:
            raise SpecError(
                "--dask", "", f"no Dask scheduler answered at {address} within {DASK_TIMEOUT:g} s ({exc})"
            ) from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _dask(cells: list[Cell], folder: Path, client: Any) -> Iterator[tuple[Record, int]]:
    """Records as cells finish on the Dask cluster of ``client``."""
    from distributed import as_completed

    futures = {client.submit(run_cell, cell, key=f"optikin-cell-{cell.key}", pure=False): cell for cell in cells}
    workers_count = max(1, len(client.scheduler_info().get("workers", {})))
    remaining = len(futures)
    deaths: dict[str, int] = {}
    for future in as_completed(futures):
        remaining -= 1
        cell = futures[future]
        for key, count in dead_tries(folder).items():
            deaths[key] = deaths.get(key, 0) + count
        try:
            record = future.result()
            record["tries"] = 1 + deaths.get(cell.key, 0)
        except Exception as exc:  # noqa: BLE001 - KilledWorker and the like fail this cell alone
            record = _killed(cell, 1 + deaths.get(cell.key, 0), f"{type(exc).__name__}: {exc}")
        yield record, min(workers_count, remaining)


def run_sweep(
    name_or_path: str,
    out: Path = Path("results"),
    jobs: int = 1,
    dask: str | None = None,
    resume: bool = True,
    figures: bool = True,
    progress: bool = True,
    on_record: Callable[[Record], None] | None = None,
) -> SweepReport:
    """Run a sweep file: every cell not already in ``OUT/<name>/cells`` (with ``resume``), then the table.

    Parameters
    ----------
    name_or_path:
        A sweep name (``sweeps/NAME.yaml``) or a path to a sweep file.
    out:
        Folder that holds the sweep's folder.
    jobs:
        joblib worker processes (1 runs the cells in this process); ignored with ``dask``.
    dask:
        A Dask scheduler address, or ``local:N`` for a local cluster of N worker processes.
    resume:
        Skip the cells finished before (same key); a failed cell runs again.
    figures:
        Draw each metric against each axis.
    progress:
        Show the aggregated progress bar on a terminal.
    on_record:
        Called with each record as it is written.

    Raises
    ------
    SpecError
        On the sweep file (naming the field), ``--jobs`` or ``--dask``.
    """
    jobs = jobs if dask else check_jobs(jobs)
    check_dask(dask)
    spec, path = load_sweep(name_or_path)
    cells = expand(spec, path)
    folder = Path(out) / spec.name
    with ExitStack() as stack:
        client = stack.enter_context(dask_client(dask, spec.retries)) if dask else None
        prepare_folder(folder)
        return _run(
            spec,
            cells,
            folder,
            jobs,
            client,
            engine=f"dask {dask}" if dask else f"joblib loky x{jobs}",
            resume=resume,
            figures=figures,
            progress=progress,
            on_record=on_record,
        )


def _run(
    spec: SweepSpec,
    cells: list[Cell],
    folder: Path,
    jobs: int,
    client: Any,
    engine: str,
    resume: bool,
    figures: bool,
    progress: bool,
    on_record: Callable[[Record], None] | None,
) -> SweepReport:
    """:func:`run_sweep` in a checked ``folder``, on ``client`` (Dask) or on ``jobs`` joblib workers."""
    dead_tries(folder)
    finished = read_cells(folder) if resume else {}
    todo = [
        dataclasses.replace(c, marker_dir=str(markers_dir(folder).resolve()))
        for c in cells
        if finished.get(c.key, {}).get("status") != "done"
    ]
    started = time.perf_counter()
    bar = _Bar(spec.name, len(cells), len(cells) - len(todo), progress)
    try:
        stream = _dask(todo, folder, client) if client is not None else _joblib(todo, folder, jobs, spec.retries)
        for record, running in stream:
            write_cell(folder, record)
            bar.update(record, running)
            if on_record is not None:
                on_record(record)
    finally:
        bar.close()
    records = read_cells(folder)
    rows = table_rows(cells, records)
    write_table(folder, spec, rows)
    drawn = write_figures(folder, spec, rows) if figures and rows else []
    return SweepReport(
        folder=folder,
        cells=len(cells),
        skipped=len(cells) - len(todo),
        ran=len(todo),
        failed=sum(r["status"] != "done" for r in rows),
        unsucceeded=sum(r["status"] == "done" and not r["succeeded"] for r in rows),
        engine=engine,
        seconds=time.perf_counter() - started,
        rows=rows,
        figures=drawn,
    )


def add_arguments(parser: Any) -> None:
    """The ``optikin sweep`` arguments."""
    parser.add_argument("sweep", help="sweep name (sweeps/NAME.yaml) or path to a sweep file")
    parser.add_argument("--out", default="results", help="folder of the sweep's folder (default: ./results)")
    parser.add_argument("--jobs", type=int, default=1, help="joblib (loky) worker processes (default 1)")
    parser.add_argument(
        "--dask", metavar="ADDRESS", help="run the cells on a Dask scheduler, or local:N for a LocalCluster of N"
    )
    parser.add_argument(
        "--resume", action=argparse.BooleanOptionalAction, default=True, help="skip cells finished before"
    )
    parser.add_argument("--no-figures", action="store_true", help="skip drawing figures")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")


def main(args: Any) -> int:
    """``optikin sweep``: 0 every cell done and solved, 1 some cell failed or had failed samples, 130
    interrupted (the finished cells are kept)."""
    import json

    try:
        report = run_sweep(
            args.sweep,
            out=Path(args.out),
            jobs=args.jobs,
            dask=args.dask,
            resume=args.resume,
            figures=not args.no_figures,
            progress=not args.json,
        )
    except KeyboardInterrupt:
        spec, path = load_sweep(args.sweep)
        kept = len(read_cells(Path(args.out) / spec.name))
        print(
            f"optikin: interrupted; {kept} of {len(expand(spec, path))} cells are finished in "
            f"{Path(args.out) / spec.name} (the same command resumes)",
            file=sys.stderr,
        )
        return 130
    counts = {
        "folder": str(report.folder),
        "engine": report.engine,
        "cells": report.cells,
        "skipped": report.skipped,
        "ran": report.ran,
        "failed": report.failed,
        "with failed samples": report.unsucceeded,
        "seconds": round(report.seconds, 3),
    }
    if args.json:
        print(json.dumps(counts | {"rows": report.rows}, indent=1, default=str))
    else:
        print(", ".join(f"{k}: {v}" for k, v in counts.items()))
        for row in report.rows:
            if row["status"] != "done":
                print(f"cell {row['index']} failed: {row['reason']}")
        print(f"table: {report.folder / 'table.csv'}")
    return 0 if report.failed == 0 and report.unsucceeded == 0 else 1
