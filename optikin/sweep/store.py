"""The results folder of a sweep: one file per finished cell, the merged table and the figures.

``OUT/<sweep name>/``:

* ``cells/KEY.json``: one finished cell (done or failed), written to a temporary file in the same folder
  and renamed into place (``os.replace``), so a crash, a SIGKILL or Ctrl-C never leaves half a cell and
  never loses a finished one;
* ``running/KEY.PID``: a marker a worker holds while it runs a cell; one whose process is gone counts a
  try of that cell that died;
* ``table.csv``, ``table.json``: one row per cell in sweep order (axes, status, collected metrics);
* ``figures/METRIC--vs--AXIS.png``: each metric against each swept axis, the median over the seeds
  (axes whose field ends in ``seed``) with their min-max band, one line per value of the other axes.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import secrets
from pathlib import Path
from typing import Any

from optikin.results import process_alive
from optikin.sweep.spec import Cell, SweepSpec

TIMING = re.compile(r"time|elapsed|\[(s|ms|us)\]")
"""Column names that hold timings: left out when two runs' tables are compared."""


def cells_dir(folder: Path) -> Path:
    return folder / "cells"


def markers_dir(folder: Path) -> Path:
    return folder / "running"


def write_cell(folder: Path, record: dict[str, Any]) -> Path:
    """Write one finished cell atomically (temporary file + ``os.replace``); returns its path."""
    target = cells_dir(folder) / f"{record['key']}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = target.parent / f".{record['key']}.tmp-{os.getpid()}-{secrets.token_hex(4)}"
    with open(staging, "w", encoding="utf-8") as stream:
        json.dump(record, stream, indent=1, allow_nan=False, default=str)
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(staging, target)
    return target


def read_cells(folder: Path) -> dict[str, dict[str, Any]]:
    """The finished cells of a folder by key (an unreadable file is skipped: that cell runs again)."""
    records = {}
    for path in sorted(cells_dir(folder).glob("*.json")):
        try:
            records[path.stem] = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
    return records


def dead_tries(folder: Path) -> dict[str, int]:
    """Keys of cells whose worker died in them (a marker whose process is gone), with how many times;
    those markers are removed."""
    counts: dict[str, int] = {}
    for marker in markers_dir(folder).glob("*.*"):
        key, _, pid = marker.name.partition(".")
        if pid.isdigit() and not process_alive(int(pid)):
            counts[key] = counts.get(key, 0) + 1
            marker.unlink(missing_ok=True)
    return counts


def table_rows(cells: list[Cell], records: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per cell, in sweep order: index, key, the axes, status, tries, succeeded, the collected
    metrics (columns in order of first appearance), reason, elapsed time."""
    value_columns: list[str] = []
    for cell in cells:
        for name in records.get(cell.key, {}).get("values", {}):
            if name not in value_columns:
                value_columns.append(name)
    rows = []
    for cell in cells:
        record = records.get(cell.key, {})
        row: dict[str, Any] = {"index": cell.index, "key": cell.key}
        row |= {field: value for field, value in cell.axes}
        row |= {"status": record.get("status", "missing"), "tries": record.get("tries")}
        row["succeeded"] = record.get("succeeded")
        values = record.get("values", {})
        row |= {name: values.get(name) for name in value_columns}
        row |= {"reason": record.get("reason", ""), "elapsed [s]": record.get("elapsed [s]")}
        rows.append(row)
    return rows


def _csv_value(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return repr(value) if isinstance(value, float) else str(value)


def write_table(folder: Path, spec: SweepSpec, rows: list[dict[str, Any]]) -> tuple[Path, Path]:
    """``table.csv`` and ``table.json`` (rows, the axes, the timing columns), each written atomically."""
    columns = list(rows[0]) if rows else []
    csv_path, json_path = folder / "table.csv", folder / "table.json"
    staging = folder / f".table.csv.tmp-{os.getpid()}"
    with open(staging, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_csv_value(row[c]) for c in columns])
    os.replace(staging, csv_path)
    document = {
        "sweep": spec.name,
        "title": spec.title,
        "axes": list(spec.axes),
        "timing_columns": [c for c in columns if TIMING.search(c)],
        "rows": rows,
    }
    staging = folder / f".table.json.tmp-{os.getpid()}"
    staging.write_text(json.dumps(document, indent=1, default=str), encoding="utf-8")
    os.replace(staging, json_path)
    return csv_path, json_path


def comparable(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows without their timing columns (:data:`TIMING`) and without which worker ran them."""
    return [{k: v for k, v in row.items() if not TIMING.search(k)} for row in rows]


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "metric"


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def write_figures(folder: Path, spec: SweepSpec, rows: list[dict[str, Any]]) -> list[Path]:
    """Each numeric metric against each swept axis: median over the seed axes, min-max band, one line
    per combination of the other axes. Returns the files drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    axes = list(spec.axes)
    seeds = [a for a in axes if a.endswith("seed")]
    plotted = [a for a in axes if a not in seeds] or axes
    fixed = {"index", "key", "status", "tries", "succeeded", "reason", *axes}
    metrics = [c for c in (rows[0] if rows else {}) if c not in fixed and not TIMING.search(c)]
    metrics = [m for m in metrics if any(_number(r[m]) is not None for r in rows)]
    out = folder / "figures"
    out.mkdir(exist_ok=True)
    drawn = []
    for metric in metrics:
        for axis in plotted:
            others = [a for a in plotted if a != axis]
            xs = list(dict.fromkeys(json.dumps(r[axis], default=str) for r in rows))
            numeric = all(_number(json.loads(x)) is not None for x in xs)
            positions = [float(json.loads(x)) for x in xs] if numeric else list(range(len(xs)))
            groups = list(dict.fromkeys(json.dumps([r[a] for a in others], default=str) for r in rows))
            fig, ax = plt.subplots(figsize=(6.4, 4.0))
            for group in groups[:8]:
                med, low, high = [], [], []
                for x in xs:
                    ys = [
                        _number(r[metric])
                        for r in rows
                        if json.dumps(r[axis], default=str) == x
                        and json.dumps([r[a] for a in others], default=str) == group
                    ]
                    finite = [y for y in ys if y is not None]
                    med.append(float(np.median(finite)) if finite else math.nan)
                    low.append(min(finite) if finite else math.nan)
                    high.append(max(finite) if finite else math.nan)
                label = ", ".join(f"{a}={v}" for a, v in zip(others, json.loads(group))) or metric
                (line,) = ax.plot(positions, med, marker="o", label=label)
                if seeds:
                    ax.fill_between(positions, low, high, color=line.get_color(), alpha=0.2)
            if numeric and min(positions) > 0 and max(positions) / min(positions) >= 10:
                ax.set_xscale("log")
            if not numeric:
                ax.set_xticks(positions, [str(json.loads(x)) for x in xs], rotation=20)
            ax.set_xlabel(axis)
            ax.set_ylabel(metric)
            spread = f"; median and min-max over {', '.join(seeds)}" if seeds else ""
            ax.set_title(f"{spec.name}{spread}", fontsize=9)
            if len(groups) > 1 or others:
                ax.legend(fontsize=7)
            fig.tight_layout()
            path = out / f"{_slug(metric)}--vs--{_slug(axis)}.png"
            fig.savefig(path, dpi=90)
            plt.close(fig)
            drawn.append(path)
    return drawn
