"""The results folder of a sweep: one file per finished cell, the merged table and the figures.

``OUT/<sweep name>/``:

* ``cells/KEY.json``: one finished cell (done or failed), written to a temporary file in the same folder
  and renamed into place (``os.replace``), so a crash, a SIGKILL or Ctrl-C never leaves half a cell and
  never loses a finished one;
* ``running/KEY.PID``: a marker a worker holds while it runs a cell; one whose process is gone counts a
  try of that cell that died;
* ``table.csv``, ``table.json``: one row per cell in sweep order (axes, status, collected metrics);
* ``figures/METRIC--vs--AXIS.png``: each metric against each swept axis, one line per method (the
  cell's solver and every baseline that reports the metric), the median over the seeds (axes whose
  field ends in ``seed``) with their min-max band; one panel per value of the other swept axes.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import secrets
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from optikin.errors import InputDataError
from optikin.results import OutputError, process_alive
from optikin.sweep.spec import Cell, SweepSpec

if TYPE_CHECKING:
    from matplotlib.figure import Figure

TIMING = re.compile(r"time|elapsed|\[(s|ms|us)\]")
"""Column names that hold timings: left out when two runs' tables are compared."""


def cells_dir(folder: Path) -> Path:
    return folder / "cells"


def markers_dir(folder: Path) -> Path:
    return folder / "running"


FOLDERS = ("cells", "running", "figures")
"""Entries of a sweep folder that must be folders."""
FILES = ("table.csv", "table.json")
"""Entries of a sweep folder that must be files."""


def prepare_folder(folder: Path) -> None:
    """Check a sweep folder before any cell runs, and create it with ``cells/`` and ``running/``.

    Raises
    ------
    OutputError
        Naming the entry: ``folder`` or one of :data:`FOLDERS` is not a folder, one of :data:`FILES` or a
        ``cells/*.json`` is not a file, or the folder cannot be created.
    """
    folder = Path(folder)
    for path in (folder, *(folder / n for n in FOLDERS)):
        if (path.exists() or path.is_symlink()) and not path.is_dir():
            raise OutputError(
                f"{path}: is not a folder, and the sweep needs one there; move it away or choose another --out"
            )
    for name in FILES:
        path = folder / name
        if (path.exists() or path.is_symlink()) and not path.is_file():
            raise OutputError(f"{path}: is not a file, and the sweep writes its table there; move it away")
    for path in sorted(cells_dir(folder).glob("*.json")):
        if not path.is_file():
            raise OutputError(f"{path}: is not a file, and the sweep writes a cell there; move it away")
    try:
        cells_dir(folder).mkdir(parents=True, exist_ok=True)
        markers_dir(folder).mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{folder}: cannot create the sweep folder: {exc.strerror or exc}") from None


def write_cell(folder: Path, record: dict[str, Any]) -> Path:
    """Write one finished cell atomically (temporary file + ``os.replace``); returns its path.

    Raises
    ------
    OutputError
        The cell cannot be written (naming its file); nothing half-written is left.
    """
    target = cells_dir(folder) / f"{record['key']}.json"
    staging = target.parent / f".{record['key']}.tmp-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with open(staging, "w", encoding="utf-8") as stream:
            json.dump(record, stream, indent=1, allow_nan=False, default=str)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(staging, target)
    except OSError as exc:
        staging.unlink(missing_ok=True)
        raise OutputError(f"{target}: cannot write the cell: {exc.strerror or exc}") from None
    return target


def read_cells(folder: Path) -> dict[str, dict[str, Any]]:
    """The finished cells of a folder by key.

    Raises
    ------
    InputDataError
        A ``cells/*.json`` cannot be read or is not a cell record (a JSON object with a ``status`` and, if
        any, a mapping of ``values``); removing that file runs its cell again.
    """
    records = {}
    for path in sorted(cells_dir(folder).glob("*.json")):
        again = "remove it to run that cell again"
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise InputDataError(f"cannot read the cell: {exc.strerror or exc}; {again}", source=str(path)) from None
        except ValueError as exc:
            raise InputDataError(f"not a cell record: not JSON ({exc}); {again}", source=str(path)) from None
        if (
            not isinstance(record, dict)
            or not isinstance(record.get("status"), str)
            or not isinstance(record.get("values", {}), dict)
        ):
            raise InputDataError(f"not a cell record (a JSON object with status and values); {again}", source=str(path))
        records[path.stem] = record
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
    document = {
        "sweep": spec.name,
        "title": spec.title,
        "axes": list(spec.axes),
        "timing_columns": [c for c in columns if TIMING.search(c)],
        "rows": rows,
    }
    for target in (csv_path, json_path):
        staging = folder / f".{target.name}.tmp-{os.getpid()}"
        try:
            with open(staging, "w", newline="", encoding="utf-8") as stream:
                if target == json_path:
                    stream.write(json.dumps(document, indent=1, default=str))
                else:
                    writer = csv.writer(stream)
                    writer.writerow(columns)
                    for row in rows:
                        writer.writerow([_csv_value(row[c]) for c in columns])
            os.replace(staging, target)
        except OSError as exc:
            staging.unlink(missing_ok=True)
            raise OutputError(f"{target}: cannot write the sweep's table: {exc.strerror or exc}") from None
    return csv_path, json_path


def comparable(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows without their timing columns (:data:`TIMING`) and without which worker ran them."""
    return [{k: v for k, v in row.items() if not TIMING.search(k)} for row in rows]


MAX_PANELS = 6
"""Most panels of a figure (one per combination of the other swept axes); beyond, those axes are pooled."""
DECADE = 10.0
"""An axis whose positive values span this ratio or more (a decade) is drawn on a log scale."""
LOG_Y = 30.0
"""A y axis whose positive medians span more than this ratio (about a decade and a half) is logarithmic."""
WRAP = 42
"""Characters per line of a y label (long metric names are wrapped)."""
MAX_TICKS = 8
"""A numeric axis with at most this many values gets a tick at each value (and no others)."""


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "metric"


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def _token(value: Any) -> str:
    return json.dumps(value, default=str)


@dataclass(frozen=True)
class Curve:
    """One method's line in a panel: per value of the swept axis, the median and the min-max of the metric
    over the cells that share it (the seeds, and the pooled axes); NaN where no cell has a number."""

    median: tuple[float, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]


@dataclass(frozen=True)
class FigurePlan:
    """What one figure of a sweep draws: ``metric`` against the swept ``axis``.

    ``values`` are the axis values in sweep order (x positions when all are numbers, else tick labels);
    ``panels`` holds per combination of the other swept axes (``"a=1, b=2"``; ``""`` for one panel) the
    :class:`Curve` of each method; ``pooled`` names the axes gathered with the seeds.
    """

    metric: str
    axis: str
    values: tuple[Any, ...]
    panels: tuple[tuple[str, dict[str, Curve]], ...]
    spread: tuple[str, ...]
    pooled: tuple[str, ...]


def metric_columns(metric: str, columns: list[str], solver: str) -> dict[str, str]:
    """``{method: column}`` of one collected metric: ``METHOD: metric`` columns (``solver: ...`` drawn as
    ``solver``), and the bare ``metric`` column as the solver's when no ``solver: metric`` column exists."""
    found: dict[str, str] = {}
    for column in columns:
        if column.endswith(f": {metric}"):
            method = column[: -len(metric) - 2]
            if ": " not in method:
                found[solver if method == "solver" else method] = column
    if metric in columns and solver not in found:
        found = {solver: metric} | found
    return found


def figure_plans(spec: SweepSpec, rows: list[dict[str, Any]]) -> list[FigurePlan]:
    """One :class:`FigurePlan` per (collected metric with a number, swept axis other than the seeds).

    Parameters
    ----------
    spec:
        The sweep (its axes, metrics and solver name the lines).
    rows:
        :func:`table_rows` output; cells without a number for a method are left out of its median.

    Returns
    -------
    list of FigurePlan
        In the order of ``spec.metrics`` and ``spec.axes``.
    """
    import numpy as np

    axes = list(spec.axes)
    seeds = [a for a in axes if a.endswith("seed")]
    plotted = [a for a in axes if a not in seeds] or axes
    columns = list(rows[0]) if rows else []
    solver = spec.solver or "solver"
    plans = []
    for metric in spec.metrics:
        methods = metric_columns(metric, columns, solver)
        methods = {m: c for m, c in methods.items() if any(_number(r[c]) is not None for r in rows)}
        if not methods:
            continue
        for axis in plotted:
            others = [a for a in plotted if a != axis]
            combos = list(dict.fromkeys(_token([r[a] for a in others]) for r in rows))
            pooled = others if len(combos) > MAX_PANELS else []
            split = [a for a in others if a not in pooled]
            values = list(dict.fromkeys(_token(r[axis]) for r in rows))
            panels = []
            for combo in dict.fromkeys(_token([r[a] for a in split]) for r in rows):
                members = [r for r in rows if _token([r[a] for a in split]) == combo]
                curves = {}
                for method, column in methods.items():
                    med, low, high = [], [], []
                    for value in values:
                        ys = [_number(r[column]) for r in members if _token(r[axis]) == value]
                        finite = [y for y in ys if y is not None]
                        med.append(float(np.median(finite)) if finite else math.nan)
                        low.append(min(finite) if finite else math.nan)
                        high.append(max(finite) if finite else math.nan)
                    curves[method] = Curve(tuple(med), tuple(low), tuple(high))
                label = ", ".join(f"{a}={v}" for a, v in zip(split, json.loads(combo)))
                panels.append((label, curves))
            plans.append(
                FigurePlan(
                    metric=metric,
                    axis=axis,
                    values=tuple(json.loads(v) for v in values),
                    panels=tuple(panels),
                    spread=tuple(seeds) if axis not in seeds else (),
                    pooled=tuple(pooled),
                )
            )
    return plans


def _line_styles(methods: list[str], solver: str) -> dict[str, dict[str, Any]]:
    """:func:`optikin.plots.method_styles` with a marker on every swept value (the solver's filled)."""
    from optikin.plots import method_styles

    styles = method_styles(methods, {solver: "solver"})
    for method, style in styles.items():
        style["markevery"] = None
        style.setdefault("marker", "o")
        style.setdefault("ms", 4.5)
    return styles


def draw_figure(spec: SweepSpec, plan: FigurePlan) -> Figure:
    """The figure of one :class:`FigurePlan`: a panel per combination of the other axes (shared y), in each
    one line per method (its median) with a shaded min-max band over the seeds (none for a method whose
    medians and band lie on an earlier method's, :func:`optikin.plots.coincident`), the legend outside.

    The x axis is logarithmic when the axis values are positive numbers spanning :data:`DECADE` or more;
    non-numeric values (preset names, lists) are evenly spaced tick labels. The y label is the metric's
    name with its unit; its axis is logarithmic when its positive medians span more than :data:`LOG_Y`.
    """
    import matplotlib

    matplotlib.use("Agg")
    import numpy as np
    from matplotlib.ticker import NullLocator

    from optikin.plots import coincident, labelled, legend_outside, subplots

    numeric = all(_number(v) is not None for v in plan.values)
    x = np.array([float(v) for v in plan.values]) if numeric else np.arange(len(plan.values), dtype=float)
    solver = spec.solver or "solver"
    methods = list(plan.panels[0][1]) if plan.panels else []
    styles = _line_styles(methods, solver)
    on = coincident([{m: np.array(c.median) for m, c in p.items()} for _, p in plan.panels])
    labels = labelled(methods, on)
    same_band = coincident([{m: np.array([c.median, c.low, c.high]) for m, c in p.items()} for _, p in plan.panels])
    count = len(plan.panels)
    fig, grid = subplots(1, count, figsize=(2.4 + 3.6 * count, 3.8), sharey=True)
    log_x = numeric and x.min() > 0 and x.max() / x.min() >= DECADE
    medians: list[float] = []
    for ax, (title, curves) in zip(grid[0], plan.panels):
        for method, curve in curves.items():
            ax.plot(x, curve.median, label=labels[method], **styles[method])
            medians.extend(curve.median)
            if plan.spread and method not in same_band:
                ax.fill_between(x, curve.low, curve.high, color=styles[method]["color"], alpha=0.15, lw=0)
        if log_x:
            ax.set_xscale("log")
        if not numeric or len(x) <= MAX_TICKS:
            ax.set_xticks(x, [f"{v:g}" if numeric else str(v) for v in plan.values], rotation=0 if numeric else 20)
            ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel(plan.axis)
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
    positive = [m for m in medians if m > 0]
    if positive and all(m > 0 for m in medians if math.isfinite(m)) and max(positive) / min(positive) > LOG_Y:
        grid[0, 0].set_yscale("log")
    grid[0, 0].set_ylabel(textwrap.fill(plan.metric, WRAP))
    spread = ", ".join([*plan.spread, *plan.pooled])
    legend_outside(fig, title=f"{spec.name}\nmedian" + (f", band min-max\nover {spread}" if spread else ""))
    return fig


def write_figures(folder: Path, spec: SweepSpec, rows: list[dict[str, Any]]) -> list[Path]:
    """``figures/METRIC--vs--AXIS.png`` of every :func:`figure_plans` plan (:func:`draw_figure`); returns the
    files drawn."""
    from optikin.plots import save

    out = folder / "figures"
    drawn = []
    try:
        out.mkdir(exist_ok=True)
        for plan in figure_plans(spec, rows):
            path = out / f"{_slug(plan.metric)}--vs--{_slug(plan.axis)}.png"
            save(draw_figure(spec, plan), path)
            drawn.append(path)
    except OSError as exc:
        raise OutputError(f"{out}: cannot draw the sweep's figures: {exc.strerror or exc}") from None
    return drawn
