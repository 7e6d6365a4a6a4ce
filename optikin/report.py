"""Human-readable tables of Results and of the named problems and solvers (rich)."""

from __future__ import annotations

import shutil
from typing import Any, Sequence

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from optikin.results import Result


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    return str(value)


def wide_console() -> Console:
    """A console as wide as the terminal, or 160 columns when output is not a terminal."""
    return Console(width=max(shutil.get_terminal_size((160, 24)).columns, 100))


def print_result(result: Result, console: Console | None = None) -> None:
    """Status counts, the run's criteria (met or not), metrics, and the comparison of methods as tables."""
    console = console or wide_console()
    counts = ", ".join(f"{k}: {v}" for k, v in result.status_counts().items())
    console.print(
        f"[bold]{result.problem}[/bold] ({result.kind}, solver {result.solver}): {result.samples} samples, {counts}"
    )
    if result.criteria:
        met = ", ".join(
            f"{escape(name)} " + ("[green]met[/green]" if ok else "[red]not met[/red]")
            for name, ok in result.criteria.items()
        )
        console.print(f"criteria: {met}")
    if result.metrics:
        table = Table(title="metrics", show_header=False)
        for k, v in result.metrics.items():
            table.add_row(escape(k), escape(_fmt(v)))
        console.print(table)
    if result.comparison:
        keys = list(dict.fromkeys(k for row in result.comparison for k in row.metrics))
        table = Table(title="comparison (same run)")
        table.add_column("method")
        table.add_column("role")
        for k in keys:
            table.add_column(escape(k), justify="right")
        for row in result.comparison:
            table.add_row(row.method, row.role, *(escape(_fmt(row.metrics.get(k, ""))) for k in keys))
        console.print(table)
    for note in result.notes:
        console.print(f"note: {escape(note)}")


def print_listing(
    title: str, rows: Sequence[tuple[str, ...]], columns: tuple[str, ...], console: Console | None = None
) -> None:
    """A table titled ``title`` with ``columns`` and one row per entry of ``rows`` (e.g. ``optikin list``)."""
    console = console or wide_console()
    table = Table(title=title)
    for c in columns:
        table.add_column(c)
    for r in rows:
        table.add_row(*(escape(c) for c in r))
    console.print(table)
