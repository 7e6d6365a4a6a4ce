"""Human-readable tables of Results and of the named problems and solvers (rich)."""

from __future__ import annotations

import io
import re
import shutil
from typing import TYPE_CHECKING, Sequence

from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from optikin.errors import UnknownNameError
from optikin.tables import comparison_rows, compact_columns, flatten, format_value

if TYPE_CHECKING:
    from optikin.results import Result


METRIC_LINES = 12
"""Metric lines a result prints before the comparison (all of them with ``verbose``)."""

SHORT_NAME_LENGTH = 14
"""Longest method name the compact comparison prints; longer ones are abbreviated, with a legend."""

PIPED_WIDTH = 80
"""Columns of a result printed to a pipe or a file (``COLUMNS`` overrides)."""


def wide_console() -> Console:
    """A console as wide as the terminal, or 160 columns when output is not a terminal."""
    return Console(width=shutil.get_terminal_size((160, 24)).columns)


def result_console(wide: bool = False) -> Console:
    """The console a result prints to: the terminal's width, :data:`PIPED_WIDTH` columns when piped
    (``COLUMNS`` overrides both); ``wide`` never folds a line (every column of the comparison)."""
    width = shutil.get_terminal_size((PIPED_WIDTH, 24)).columns
    return Console(width=100_000 if wide else width, soft_wrap=wide)


def print_result(result: Result, console: Console | None = None, wide: bool = False, verbose: bool = False) -> None:
    """Headline (with the size setting of a kind that has one), each missed criterion with its reason, the
    criteria met, whether the verdict is the one the problem file expects, metrics, the comparison, notes.

    Parameters
    ----------
    result:
        The solved problem.
    console:
        Where to print; :func:`result_console` when None. The compact comparison fits its width
        without breaking a word: methods under short names (a legend line gives the full ones, ``*``
        marks the problem's own solver), the kind's headline columns from the left as far as they fit
        (the others named in a line below), then the statuses.
    wide:
        Every column of the comparison, full method names and roles (the result folder's
        ``comparison.csv`` and ``.md`` always hold them).
    verbose:
        Every metric; otherwise the first :data:`METRIC_LINES` (all are in ``result.json``).
    """
    console = console or result_console(wide)
    counts = ", ".join(f"{k}: {v}" for k, v in result.status_counts().items())
    setting = f", setting {escape(result.setting)}" if result.setting is not None else ""
    console.print(
        f"[bold]{escape(result.problem)}[/bold] ({escape(result.kind)}, solver {escape(str(result.solver))}{setting}): "
        f"{result.samples} samples, {escape(counts)}"
    )
    reasons = missed_reasons(result)
    for name in [name for name, ok in result.criteria.items() if not ok]:
        reason = f": {escape(reasons[name])}" if name in reasons else ""
        console.print(f"criterion {escape(name)} [red]not met[/red]{reason}")
    met = [escape(name) for name, ok in result.criteria.items() if ok]
    if met:
        console.print(f"criteria met: {', '.join(met)}")
    if result.expect is not None:
        console.print(escape(expected_line(result)))
    if result.metrics:
        _print_metrics(result, console, wide or verbose)
    if result.comparison:
        (_print_wide_comparison if wide else _print_compact_comparison)(result, console)
    shown = {f"{CRITERION_NOTE.format(name)}{reason}" for name, reason in reasons.items()}
    for note in result.notes:
        if note not in shown:
            console.print(f"note: {escape(note)}")


CRITERION_NOTE = "criterion {} not met: "
"""How a kind's note on a missed criterion begins (the reason follows); :func:`print_result` shows the reason
beside the criterion rather than among the notes."""


def missed_reasons(result: Result) -> dict[str, str]:
    """The reason of every missed criterion of ``result`` that a note gives (:data:`CRITERION_NOTE`), by name."""
    reasons = {}
    for name, ok in result.criteria.items():
        prefix = CRITERION_NOTE.format(name)
        reason = next((note[len(prefix) :] for note in result.notes if note.startswith(prefix)), None)
        if not ok and reason is not None:
            reasons[name] = reason
    return reasons


def expected_line(result: Result) -> str:
    """One line saying whether the run's exit status is the one the problem file's ``expect`` states, and why.

    ``expected: exit 1 because ...`` when it is (the exit status stays 1: a missed criterion is still missed);
    ``unexpected: exit 0, the problem file expects exit 1 because ...`` when it is not.
    """
    expect = result.expect or {}
    because = f" because {expect['because']}" if expect.get("because") else ""
    if result.as_expected:
        return f"expected: exit {result.exit_status}{because}"
    return f"unexpected: exit {result.exit_status}, the problem file expects exit {expect.get('exit')}{because}"


def _print_metrics(result: Result, console: Console, every: bool) -> None:
    flat = list(flatten(result.metrics).items())
    shown = flat if every else flat[:METRIC_LINES]
    table = Table(title="metrics", show_header=False, box=box.SIMPLE)
    table.add_column(overflow="fold")
    table.add_column(overflow="fold")
    for k, v in shown:
        table.add_row(escape(k), escape(format_value(v)))
    console.print(table)
    if len(shown) < len(flat):
        console.print(f"{len(flat) - len(shown)} more metrics in result.json (all: --verbose)")


def _print_wide_comparison(result: Result, console: Console) -> None:
    columns, cells = comparison_rows(result.comparison)
    table = Table(title="comparison (same run)")
    for i, column in enumerate(columns):
        table.add_column(escape(column), justify="left" if i < 2 else "right", no_wrap=True)
    for row in cells:
        table.add_row(*(escape(c) for c in row))
    console.print(table)


def _print_compact_comparison(result: Result, console: Console) -> None:
    columns, cells = comparison_rows(result.comparison)
    metrics = compact_columns(columns, headline_of(result.kind))
    reasons = _not_applicable(columns, cells)
    names = short_names([row[0] for row in cells])
    labels = [names[row[0]] + ("*" if row[1] == "solver" else "") for row in cells]
    shown = list(metrics)
    table = _compact_table(columns, cells, labels, shown)
    while shown and not _fits_whole_words(table, console.width):
        shown.pop(-2 if len(shown) > 1 and shown[-1] == "statuses" else -1)
        table = _compact_table(columns, cells, labels, shown)
    console.print(table)
    legend = [f"{short} = {full}" for full, short in names.items() if short != full]
    solver = any(row[1] == "solver" for row in cells)
    if legend or solver:
        console.print(escape("; ".join(legend + (["* the problem's solver"] if solver else []))))
    hidden = [c for c in metrics if c not in shown]
    if hidden:
        console.print(escape(f"not shown at {console.width} columns: {', '.join(hidden)} (--wide or comparison.md)"))
    for method, reason in reasons.items():
        console.print(f"not applicable: {escape(names[method])}: {escape(reason)}")


def _compact_table(columns: list[str], cells: list[list[str]], labels: list[str], shown: list[str]) -> Table:
    where = [columns.index(c) for c in shown]
    table = Table(title="comparison (same run)", box=box.SIMPLE_HEAD)
    for header, texts in [("method", labels), *((c, [row[i] for row in cells]) for c, i in zip(shown, where))]:
        longest = max(len(word) for text in (header, *texts) for word in text.split() or [""])
        table.add_column(escape(header), justify="left" if header == "method" else "right", min_width=longest)
    for label, row in zip(labels, cells):
        table.add_row(escape(label), *(escape(row[i]) for i in where))
    return table


def _fits_whole_words(table: Table, width: int) -> bool:
    """Whether ``table`` printed at ``width`` columns stays within them and keeps every word whole."""
    probe = Console(width=width, file=io.StringIO(), color_system=None)
    probe.print(table)
    printed = probe.file.getvalue()  # type: ignore[attr-defined]
    words = set(printed.split())
    texts = [Text.from_markup(str(c.header)).plain for c in table.columns]
    texts += [Text.from_markup(str(cell)).plain for c in table.columns for cell in c.cells]
    return all(len(line) <= width for line in printed.splitlines()) and all(
        word in words for text in texts for word in text.split()
    )


def _not_applicable(columns: list[str], cells: list[list[str]]) -> dict[str, str]:
    """The reason of every method that was not applicable, by method; its statuses say so."""
    if "not applicable" not in columns:
        return {}
    why = columns.index("not applicable")
    status = columns.index("statuses") if "statuses" in columns else None
    reasons = {}
    for row in cells:
        if row[why]:
            reasons[row[0]] = row[why]
            if status is not None:
                row[status] = "not applicable"
    return reasons


def short_names(methods: Sequence[str], length: int = SHORT_NAME_LENGTH) -> dict[str, str]:
    """A unique name of at most ``length`` characters for each method, by full name.

    A name that fits is kept; a longer one becomes the part before its parenthesis
    (``qp (daqp-active-set)`` -> ``qp``) when that fits and is free, else its initials, the
    parenthesis's initials joined with a dash (``mrac (seed gains)`` -> ``mrac-sg`` beside ``mrac``,
    ``damped least squares`` -> ``dls``, ``pseudo-inverse (saturated)`` -> ``pi-s`` beside
    ``pseudo-inverse``), numbered when still taken.

    >>> short_names(["mrac", "mrac (seed gains)", "damped least squares"])
    {'mrac': 'mrac', 'mrac (seed gains)': 'mrac-sg', 'damped least squares': 'dls'}
    >>> short_names(["pseudo-inverse", "pseudo-inverse (saturated)"])["pseudo-inverse (saturated)"]
    'pi-s'
    """
    taken = {m for m in methods if len(m) <= length}
    names: dict[str, str] = {}
    for method in methods:
        if method in names:
            continue
        if len(method) <= length:
            names[method] = method
            continue
        base, _, rest = method.partition(" (")
        base, inside = base.strip(), rest.rstrip(")").strip()
        candidates = [base] if len(base) <= length else []
        stem = base if len(base) <= length else _initials(base)
        if inside:
            candidates += [f"{stem}-{_initials(inside)}", f"{_initials(base)}-{_initials(inside)}"]
        candidates += [stem, _initials(method)]
        short = next((c for c in candidates if c and len(c) <= length and c not in taken), None)
        if short is None:
            root = candidates[-1][: length - 2]
            short = next(f"{root}{i}" for i in range(2, 100) if f"{root}{i}" not in taken)
        taken.add(short)
        names[method] = short
    return names


def _initials(text: str) -> str:
    return "".join(word[0] for word in re.findall(r"[A-Za-z0-9]+", text)).lower()


def headline_of(kind: str) -> tuple[str, ...]:
    """The :attr:`~optikin.problems.ProblemKind.headline` columns of a registered kind (none if unknown)."""
    from optikin.problems import load_kind

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
