"""One sweep cell, run in a worker process: :func:`optikin.runner.solve` of the overridden problem.

The cell is plain data (:class:`~optikin.sweep.spec.Cell`); the worker builds the arm and the solver's
CasADi Functions itself from the problem file, so no CasADi object crosses a process boundary. A worker
keeps its imports (CasADi, scipy, the kinds and backends) from one cell to the next, which is where most
of a cold cell's time goes.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from optikin.sweep.spec import Cell


def _marker(cell: Cell) -> Path | None:
    """``running/KEY.PID`` while the cell runs: one left behind names a worker that died in it."""
    if cell.marker_dir is None:
        return None
    path = Path(cell.marker_dir) / f"{cell.key}.{os.getpid()}"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(str(cell.index))
    except OSError:
        return None
    return path


def collect(summary: dict[str, Any], metrics: tuple[str, ...]) -> dict[str, Any]:
    """The requested metrics of a result summary: ``key`` from its ``metrics``, and from each comparison
    row that has it ``solver: key`` (the cell's solver, whichever preset an axis set) or ``METHOD: key``
    (a baseline or variant)."""
    values: dict[str, Any] = {}
    for name in metrics:
        if name in summary.get("metrics", {}):
            values[name] = summary["metrics"][name]
        for row in summary.get("comparison", []):
            if name in row["metrics"]:
                method = "solver" if row["role"] == "solver" else row["method"]
                values[f"{method}: {name}"] = row["metrics"][name]
    return values


def run_cell(cell: Cell) -> dict[str, Any]:
    """Solve one cell and return its record (JSON-ready).

    Returns
    -------
    dict
        ``key``, ``index``, ``axes`` (field -> value), ``status`` (``done``, or ``failed`` with
        ``reason``: the :class:`~optikin.errors.OptikinError` message of a bad override or file, or the
        exception of an internal error), ``succeeded`` (every sample solved), ``values`` (the collected
        metrics), ``summary`` (:meth:`optikin.results.Result.summary` without its creation time),
        ``elapsed [s]`` and ``worker`` (the process id).
    """
    from optikin.errors import OptikinError
    from optikin.runner import solve

    marker = _marker(cell)
    started = time.perf_counter()
    record: dict[str, Any] = {
        "key": cell.key,
        "index": cell.index,
        "axes": dict(cell.axes),
        "overrides": [list(o) for o in cell.overrides],
        "worker": os.getpid(),
    }
    try:
        solver = None if any(field == "solver" for field, _ in cell.overrides) else cell.solver
        result, _ = solve(cell.problem, solver=solver, out=None, figures=False, overrides=list(cell.overrides))
        summary = result.summary()
        summary.pop("created", None)
        record |= {
            "status": "done",
            "succeeded": result.succeeded,
            "values": collect(summary, cell.metrics),
            "summary": summary,
        }
    except OptikinError as exc:
        record |= {"status": "failed", "reason": str(exc)}
    except Exception as exc:  # noqa: BLE001 - an internal error fails this cell alone, with its message
        record |= {"status": "failed", "reason": f"internal error: {type(exc).__name__}: {exc}"}
    record["elapsed [s]"] = time.perf_counter() - started
    if marker is not None:
        marker.unlink(missing_ok=True)
    return record
