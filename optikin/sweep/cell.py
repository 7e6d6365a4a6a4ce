"""One sweep cell, run in a worker process: :func:`optikin.runner.solve` of the overridden problem.

The cell is plain data (:class:`~optikin.sweep.spec.Cell`); the worker builds the arm and the solver's
CasADi Functions itself from the problem file, so no CasADi object crosses a process boundary. A worker
keeps its imports (CasADi, scipy, the kinds and backends) from one cell to the next, which is where most
of a cold cell's time goes, and its arms (:func:`cached_arm`): the cells of a sweep over seeds, noise or
solvers share one arm and its CasADi Functions, built by the first of them.
"""

from __future__ import annotations

import ctypes
import json
import os
import signal
import threading
import time
from collections import OrderedDict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from optikin.sweep.spec import Cell

if TYPE_CHECKING:
    from optikin.arms.base import ArmModel

KEPT_ARMS = 8
"""Arms a worker process keeps (the most recently used)."""
PARENT_POLL = 0.5
"""Seconds between a worker's looks at whether the process that started it is still there."""
_PR_SET_PDEATHSIG = 1  # Linux prctl option: the signal this process gets when its parent thread ends

_ARMS: OrderedDict[str, "ArmModel"] = OrderedDict()


def watch_parent(parent: int) -> None:
    """A joblib (loky) worker's initializer: end this worker when process ``parent``, which started it, is gone.

    On Linux the kernel sends this process SIGKILL when its parent ends (``prctl(PR_SET_PDEATHSIG)``), even
    during a long CasADi call; everywhere, a daemon thread looks every :data:`PARENT_POLL` seconds whether the
    parent is still ``parent`` (a process whose parent dies is handed to another, even while the dead one is
    not yet reaped) and ends this process with ``os._exit`` if not. So a killed ``optikin sweep`` or
    ``optikin solve --jobs`` leaves no workers behind.
    """
    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="optikin-parent-watch", daemon=True).start()


def worker_pool(jobs: int, ordered: bool = True) -> Any:
    """A joblib ``Parallel`` of ``jobs`` loky workers that end with this process (:func:`watch_parent`),
    returning a list in order (``ordered``) or a generator in the order the tasks finish."""
    from joblib import Parallel
    from joblib._parallel_backends import LokyBackend

    backend = LokyBackend(initializer=watch_parent, initargs=(os.getpid(),))
    return Parallel(n_jobs=jobs, backend=backend, return_as="list" if ordered else "generator_unordered")


def cached_arm(arm_type: str, params: dict[str, Any], path: str | Path = "<arm>") -> "ArmModel":
    """:func:`optikin.arms.build_arm`, once per process for each arm: keyed by the canonical JSON of
    ``{type, params}``, so every cell with the same arm reuses it with the CasADi Functions built on it.

    An arm is read-only once built (its Functions are cached properties of its parameters), so cells
    sharing it get the answers of a fresh one. A spec error is raised again for every cell that has it.
    """
    from optikin.arms import build_arm

    key = json.dumps({"type": arm_type, "params": params}, sort_keys=True, default=repr)
    if key not in _ARMS:
        _ARMS[key] = build_arm(arm_type, params, path)
        while len(_ARMS) > KEPT_ARMS:
            _ARMS.popitem(last=False)
    _ARMS.move_to_end(key)
    return _ARMS[key]


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
        result, _ = solve(
            cell.problem, solver=solver, out=None, figures=False, overrides=list(cell.overrides), arms=cached_arm
        )
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
