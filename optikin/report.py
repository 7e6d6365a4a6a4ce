"""Human-readable tables of Results and of the named problems and solvers (rich)."""

from __future__ import annotations

import shutil
from typing import Sequence

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from optikin.errors import UnknownNameError
from optikin.problems import load_kind
from optikin.results import Result
from optikin.tables import comparison_rows, compact_columns, flatten, format_value


def wide_console() -> Console:
    """A console as wide as the terminal, or 160 columns when output is not a terminal."""
    return Console(width=shutil.get_terminal_size((160, 24)).columns)


def print_result(result: Result, console: Console | None = None, wide: bool = False) -> None:
    """Status counts, the run's criteria (met or not), metrics, and the comparison of methods as tables.

    The comparison shows method, role, success, the first error and the first time (and the statuses);
    ``wide`` shows every column (the result folder's ``comparison.csv`` and ``.md`` always hold them).
    Metrics holding a mapping are printed as sub-rows ``name.key``.
    """
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
        for k, v in flatten(result.metrics).items():
            table.add_row(escape(k), escape(format_value(v)))
        console.print(table)
    if result.comparison:
        columns, cells = comparison_rows(result.comparison)
        shown = columns[2:] if wide else compact_columns(columns, headline_of(result.kind))
        where = [columns.index(c) for c in ("method", "role", *shown)]
        title = "comparison (same run)" + ("" if wide else "; every column: --wide or comparison.md")
        table = Table(title=title)
        for i in where:
            table.add_column(escape(columns[i]), justify="left" if i < 2 else "right", overflow="fold")
        reasons = {}
        if not wide and "not applicable" in columns:
            status, why = columns.index("statuses") if "statuses" in columns else None, columns.index("not applicable")
            for row in cells:
                if row[why]:
                    reasons[row[0]] = row[why]
                    if status is not None:
                        row[status] = "not applicable"
        for row in cells:
            table.add_row(*(escape(row[i]) for i in where))
        console.print(table)
        for method, reason in reasons.items():
            console.print(f"not applicable: {escape(method)}: {escape(reason)}")
    for note in result.notes:
        console.print(f"note: {escape(note)}")


def headline_of(kind: str) -> tuple[str, ...]:
    """The :attr:`~optikin.problems.ProblemKind.headline` columns of a registered kind (none if unknown)."""
    try:
        return load_kind(kind).headline
    except UnknownNameError:
        return ()


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
