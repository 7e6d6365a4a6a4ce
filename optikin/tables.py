"""The comparison of a result as plain tables: all columns for the result folder, a few for a terminal.

:func:`comparison_rows` flattens every method's metrics (a metric holding a mapping becomes one
column per entry, ``name.key``); :func:`write_comparison` writes them as ``comparison.csv`` and
``comparison.md``; :func:`compact_columns` picks what fits a narrow terminal: the success share, the
first error or distance, the first time per solve, and the statuses (a method that was not applicable
says so there; its reason is printed below the table).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

if TYPE_CHECKING:
    from optikin.results import MethodRow

SUCCESS_WORDS = ("success", "converged", "solved", "ok ")
ERROR_WORDS = ("error", "distance", "residual", "rmse", "mse")
TIME_WORDS = ("time", "[us]", "[ms]", "wall")


def flatten(metrics: dict[str, Any]) -> dict[str, Any]:
    """``metrics`` with every mapping value spread into ``name.key`` entries (recursively)."""
    flat: dict[str, Any] = {}
    for key, value in metrics.items():
        if isinstance(value, dict):
            for sub, inner in flatten(value).items():
                flat[f"{key}.{sub}"] = inner
        else:
            flat[key] = value
    return flat


def format_value(value: Any) -> str:
    """A metric as text: floats to 4 significant digits, lists element by element, None as empty."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)


def comparison_rows(rows: Sequence["MethodRow"]) -> tuple[list[str], list[list[str]]]:
    """``(columns, cells)`` of the full comparison: method, role, then every flattened metric."""
    flat = [flatten(row.metrics) for row in rows]
    keys = list(dict.fromkeys(k for metrics in flat for k in metrics))
    cells = [[row.method, row.role, *(format_value(metrics.get(k)) for k in keys)] for row, metrics in zip(rows, flat)]
    return ["method", "role", *keys], cells


def compact_columns(columns: Sequence[str], headline: Sequence[str] = ()) -> list[str]:
    """The metric columns of a compact table: the kind's ``headline`` columns that are present, else
    those of the module docstring; then the statuses."""
    present = [c for c in headline if c in columns]
    if present:
        return present + (["statuses"] if "statuses" in columns and "statuses" not in present else [])
    picked: list[str] = []
    for words in (SUCCESS_WORDS, ERROR_WORDS, TIME_WORDS):
        # the first column holding the first word that any column holds (words in order of preference)
        match = next(
            (c for w in words for c in columns[2:] if w in c.lower() and c not in picked),
            None,
        )
        if match is not None:
            picked.append(match)
    if "statuses" in columns and "statuses" not in picked:
        picked.append("statuses")
    return picked


def write_comparison(rows: Sequence["MethodRow"], folder: Path) -> list[str]:
    """Write ``comparison.csv`` and ``comparison.md`` into ``folder``; returns the file names (none
    without rows)."""
    if not rows:
        return []
    columns, cells = comparison_rows(rows)
    with open(folder / "comparison.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(cells)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in cells]
    (folder / "comparison.md").write_text("\n".join(lines) + "\n")
    return ["comparison.csv", "comparison.md"]
