"""The printed result fits the terminal: 60, 80 and 120 columns for every kind, no word broken.

Each kind's compact comparison is printed with the long method names the kinds use, its own
headline columns and values of every magnitude; every line must fit and every word of every
header and cell that is shown must appear whole. One real solve is checked the same way.
"""

from __future__ import annotations

import io
import re

import pytest
from rich.console import Console

from optikin.problems import PROBLEM_KINDS, load_kinds
from optikin.report import print_result, short_names
from optikin.results import MethodRow, Result

WIDTHS = (60, 80, 120)

METHODS = (
    ("qp (daqp-active-set)", "solver"),
    ("mrac", "baseline"),
    ("mrac (seed gains)", "baseline"),
    ("pseudo-inverse", "baseline"),
    ("damped least squares", "baseline"),
    ("gauss-newton-compiled", "baseline"),
    ("hybrid network (Fig. 7 database, seed-raw)", "baseline"),
    ("newton", "variant"),
)
VALUES = (2.249, 9.842e-05, 1511, 1.212e04, 0.0007958, 100.0, True, 1.5e-14)
GENERIC = ("success [%]", "median tip error [m]", "median time per solve [us]")


def kinds() -> list[str]:
    load_kinds()
    return PROBLEM_KINDS.names()


def result_of(kind: str) -> Result:
    headline = PROBLEM_KINDS.get(kind).headline or GENERIC
    rows = []
    for i, (method, role) in enumerate(METHODS):
        metrics: dict[str, object] = {c: VALUES[(i + j) % len(VALUES)] for j, c in enumerate(headline)}
        metrics["statuses"] = "ok: 17, not_converged: 3" if i % 2 else "ok: 20"
        rows.append(MethodRow(method, role, metrics))
    rows[-1].metrics["not applicable"] = "the Hessian of a rank-deficient formulation is singular at every root"
    return Result(
        problem=f"{kind}-width",
        kind=kind,
        solver="qp",
        title="t",
        arm={},
        status=["ok"] * 3,
        metrics={f"metric number {i} [mm]": float(i) for i in range(20)},
        comparison=rows,
    )


def printed(result: Result, width: int, **flags: bool) -> str:
    out = io.StringIO()
    print_result(result, Console(file=out, width=width, color_system=None), **flags)
    return out.getvalue()


def table_lines(text: str) -> list[str]:
    """The lines of the comparison table, from its title to the blank line closing it."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if "comparison" in line)
    end = next(i for i in range(start + 3, len(lines)) if not lines[i].strip())
    return lines[start:end]


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("kind", kinds())
def test_every_kind_fits_the_width_with_whole_words(kind, width):
    result = result_of(kind)
    text = printed(result, width)
    assert max(len(line) for line in text.splitlines()) <= width
    table = " ".join(table_lines(text))
    words = set(table.split())
    names = short_names([row.method for row in result.comparison])
    for short in names.values():
        assert all(w in words or w + "*" in words for w in short.split()), (short, table)
    headline = PROBLEM_KINDS.get(kind).headline or GENERIC
    shown = [c for c in (*headline, "statuses") if all(w in words for w in c.split())]
    assert shown, f"no metric column shown at {width} columns"
    hidden = [c for c in headline if c not in shown]
    if hidden:
        assert "not shown at" in text and all(c.split()[0] in text for c in hidden)
    for row in result.comparison:
        for column in shown:
            value = row.metrics.get(column)
            if column in row.metrics and row.method != METHODS[-1][0]:
                assert all(w in words for w in str(value).split()) or isinstance(value, float)


@pytest.mark.parametrize("kind", kinds())
def test_the_first_headline_column_is_shown_at_80(kind):
    headline = PROBLEM_KINDS.get(kind).headline or GENERIC
    table = " ".join(table_lines(printed(result_of(kind), 80)))
    assert all(word in table.split() for word in headline[0].split())


def test_abbreviations_have_a_legend_and_the_solver_a_mark():
    raw = printed(result_of("tracking"), 80)
    text = " ".join(raw.split())
    assert "qp = qp (daqp-active-set)" in text
    assert "dls = damped least squares" in text
    assert "mrac-sg = mrac (seed gains)" in text
    assert re.search(r"^\s*qp\*\s", raw, re.M)
    assert "not applicable: newton: the Hessian" in text


def test_short_names_are_unique_and_short():
    methods = [m for m, _ in METHODS] + ["damped least-squares", "dls", "quite a long method name (variant a)"]
    names = short_names(methods)
    assert len(set(names.values())) == len(methods)
    assert all(len(n) <= 14 for n in names.values())
    assert names["mrac"] == "mrac" and names["pseudo-inverse"] == "pseudo-inverse"
    saturated = short_names(["pseudo-inverse", "pseudo-inverse (saturated)", "damped least squares (saturated)"])
    assert saturated == {
        "pseudo-inverse": "pseudo-inverse",
        "pseudo-inverse (saturated)": "pi-s",
        "damped least squares (saturated)": "dls-s",
    }


def test_metrics_are_cut_at_twelve_lines_unless_verbose():
    result = result_of("ik")
    short, full = printed(result, 80), printed(result, 80, verbose=True)
    assert "metric number 11 [mm]" in short and "metric number 12 [mm]" not in short
    assert "8 more metrics in result.json" in short
    assert "metric number 19 [mm]" in full and "more metrics" not in full


def test_wide_shows_every_column_and_full_names():
    text = printed(result_of("tracking"), 100_000, wide=True)
    assert "damped least squares" in text and "role" in text
    assert all(len(line) < 1_000 for line in text.splitlines())


def test_a_real_solve_fits_80_columns(capsys, monkeypatch, tmp_path):
    from optikin.cli import main

    monkeypatch.setenv("COLUMNS", "80")
    rc = main(["solve", "cc-ik-position", "--set", "data.samples=6", "--no-figures", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert max(len(line) for line in out.splitlines() if not line.startswith("written to")) <= 80
    assert "gnc = gauss-newton-compiled" in " ".join(out.split())
