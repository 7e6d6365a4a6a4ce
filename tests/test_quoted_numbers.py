"""Numbers quoted in BENCHMARKS.md are reproduced by the command quoted beside them.

A small curated table of deterministic (non-timing) results of problems that run in well under a
minute: each entry names the problem, the overrides of the quoted command (none: the shipped file),
the text of BENCHMARKS.md that holds the quote, the quoted cell, and where the run's result keeps
the numbers. Each number is compared at the precision it is quoted with (the digits shown), so a
change that moves a quoted figure fails here until BENCHMARKS.md is updated.

The quoted commands themselves are checked too: every ``optikin solve NAME`` in BENCHMARKS.md and
README.md names a shipped problem (and every ``optikin solve PATH`` into a folder of the repository a file
that exists).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from optikin.results import Result
from optikin.runner import solve
from optikin.spec import available

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "BENCHMARKS.md"
README = ROOT / "README.md"

Values = Callable[[Result], list[float]]


def _floats(value: Any) -> list[float]:
    return [float(x) for x in np.ravel(np.asarray(value, dtype=float))]


def metric(key: str, *fields: str) -> Values:
    """The numbers of ``result.metrics[key]`` (an entry of it when ``fields`` name some)."""

    def values(result: Result) -> list[float]:
        value = result.metrics[key]
        if fields:
            return [float(value[f]) for f in fields]
        return _floats(value)

    return values


def _row(result: Result, method: str) -> dict[str, Any]:
    rows = [row for row in result.comparison if row.method == method]
    assert len(rows) == 1, f"{result.problem}: comparison rows named {method!r}: {len(rows)}"
    return rows[0].metrics


def cells(method: str, *keys: str) -> Values:
    """The comparison row ``method``'s metrics ``keys``, in order."""
    return lambda result: [float(_row(result, method)[k]) for k in keys]


def span(methods: tuple[str, ...], key: str) -> Values:
    """``min-max`` of one metric over several comparison rows (a range quoted for a group of methods)."""

    def values(result: Result) -> list[float]:
        column = [float(_row(result, m)[key]) for m in methods]
        return [min(column), max(column)]

    return values


SATURATED = ("mrac (saturated)", "pseudo-inverse (saturated)", "damped least squares (saturated)")


@dataclass(frozen=True)
class Quote:
    problem: str
    row: str
    """Text of BENCHMARKS.md (one table row or sentence, verbatim) that holds the quoted cell."""
    quoted: str
    """The quoted cell as printed, e.g. ``3.73 / 3.76 / 1.44`` or ``46.92-47.05``."""
    values: Values
    overrides: tuple[tuple[str, Any], ...] = ()
    """The ``--set`` overrides of the quoted command (none when it runs the shipped file)."""

    @property
    def id(self) -> str:
        return f"{self.problem}:{self.quoted}"


QUOTES = [
    Quote(
        "track-nominal",
        "| track-nominal (CC plant) | MRAC / pseudo-inverse / DLS, saturated | 46.92-47.05 |",
        "46.92-47.05",
        span(SATURATED, "rms [mm]"),
    ),
    Quote(
        "track-nominal",
        "| track-nominal (CC plant) | MRAC / pseudo-inverse / DLS, saturated | 46.92-47.05 | 52.45-52.84 (stuck",
        "52.45-52.84",
        span(SATURATED, "final [mm]"),
    ),
    Quote(
        "cbha-ph-shape",
        "| shape, one quintic: marker 1 / 2 / 3 mean [mm] | 3.73 / 3.76 / 1.44 (`cbha-ph-shape`, 100) |",
        "3.73 / 3.76 / 1.44",
        metric("mean distance per marker [mm]"),
    ),
    Quote(
        "cbha-ph-shape",
        "| shape: backbone, mean of largest / largest distance [mm] | 4.71 / 9.54 |",
        "4.71 / 9.54",
        lambda r: [
            float(r.metrics["model backbone: mean of the largest vertebra distance [mm]"]),
            float(r.metrics["model backbone: largest vertebra distance [mm]"]),
        ],
    ),
    Quote(
        "trunk-calibrate",
        "| `trunk-calibrate` (669) | 0.213 mm median marker error over the 649 kept | **0.369 / 0.782 / 208.1 mm**",
        "0.369 / 0.782 / 208.1",
        metric("held-out largest-marker error per posture, 669 of 669 postures (kfold) [mm]", "median", "p95", "max"),
    ),
    Quote(
        "track-nominal-cosserat",
        "| nominal-cosserat | **QP** | **10.71** | 5.20 / 0.114 | **0** | no |",
        "10.71** | 5.20 / 0.114 | **0",
        cells("qp (daqp-active-set)", "rms [mm]", "final [mm]", "final [deg]", "outside limits"),
    ),
    Quote(
        "track-nominal-cosserat",
        "| nominal-cosserat | MRAC / pseudo-inverse / DLS, saturated | 34.35-34.51 | 28.56-28.76 | 0 |",
        "34.35-34.51",
        span(SATURATED, "rms [mm]"),
    ),
    Quote(
        "dmp-imu-dualquat",
        "| seed (Q_r and Q_d DMPs) | 66.84 / 37.14 [66.84 / 37.14], 24.40 at t = 0 | 102.29 [102.29] | 182.97 [182.97] "
        "| 30.59 / 16.11 [30.58 / 16.10] |",
        "30.59 / 16.11 [30.58 / 16.10]",
        cells(
            "dmp seed (cvxpy)",
            "reproduction position max [mm]",
            "reproduction position rms [mm]",
            "structural bound position max [mm]",
            "structural bound position rms [mm]",
        ),
    ),
    Quote(
        "dmp-imu-dualquat",
        "| dual-quaternion DMP | 0.346 | 0.346 | 0.346 | 1.333 | 1.333 | 1.333 |",
        "1.333",
        cells("dmp dual-quaternion (cvxpy)", "reproduction position max [mm]"),
    ),
    Quote(
        "dmp-imu-dualquat",
        "| position + quaternion DMP | 0.542 | 0.542 | 0.542 | 1.338 | 1.338 | 1.338 |",
        "1.338",
        cells("dmp cartesian (cvxpy)", "reproduction position max [mm]"),
    ),
]

NUMBER = re.compile(r"\d+(?:\.\d+)?")


def _digits(quoted: str) -> list[str]:
    return NUMBER.findall(quoted)


def _shown(value: float, like: str) -> str:
    """``value`` printed with as many decimals as the quoted number ``like``."""
    decimals = len(like.partition(".")[2])
    return f"{value:.{decimals}f}"


@functools.cache
def _run(problem: str, overrides: tuple[tuple[str, Any], ...]) -> Result:
    result, _ = solve(problem, figures=False, overrides=overrides)
    return result


@pytest.mark.parametrize("quote", QUOTES, ids=lambda q: q.id)
def test_quote_is_in_benchmarks(quote: Quote) -> None:
    text = BENCHMARKS.read_text(encoding="utf-8")
    assert quote.row in text, f"{quote.problem}: the quoted text is no longer in BENCHMARKS.md: {quote.row!r}"
    assert quote.quoted in quote.row
    assert quote.problem in available("problems")


@pytest.mark.slow
@pytest.mark.parametrize("quote", QUOTES, ids=lambda q: q.id)
def test_quoted_number_reproduces(quote: Quote) -> None:
    result = _run(quote.problem, quote.overrides)
    got = quote.values(result)
    quoted = _digits(quote.quoted)
    assert len(got) == len(quoted), f"{quote.id}: {len(got)} values for {len(quoted)} quoted numbers"
    shown = [_shown(v, q) for v, q in zip(got, quoted)]
    assert shown == quoted, f"{quote.problem}: BENCHMARKS.md quotes {quote.quoted!r}, the run gives {got}"


SOLVE = re.compile(r"optikin solve ([a-z0-9][a-z0-9-]*)(?!\.ya?ml)(?![\w/<-])")
SOLVE_PATH = re.compile(r"optikin solve ([\w./-]+\.ya?ml)")


@pytest.mark.parametrize("doc", [BENCHMARKS, README], ids=lambda p: p.name)
def test_quoted_solve_commands_name_problems(doc: Path) -> None:
    text = doc.read_text(encoding="utf-8")
    names = SOLVE.findall(text)
    assert names, f"no `optikin solve NAME` found in {doc.name}: the pattern no longer matches the file"
    unknown = sorted(set(names) - set(available("problems")))
    assert not unknown, f"{doc.name} quotes `optikin solve` for problems that do not exist: {unknown}"
    # a path under a folder of the repository must exist; others (``my-examples/``) are made by the reader
    paths = {p for p in SOLVE_PATH.findall(text) if (ROOT / p.split("/")[0]).is_dir()}
    missing = sorted(p for p in paths if not (ROOT / p).is_file())
    assert not missing, f"{doc.name} quotes `optikin solve` on files that do not exist: {missing}"


def test_solve_pattern_rejects_unknown_names() -> None:
    known = set(available("problems"))
    found = SOLVE.findall("`optikin solve no-such-problem --out DIR`, `optikin solve track-nominal`")
    assert found == ["no-such-problem", "track-nominal"]
    assert set(found) - known == {"no-such-problem"}
    assert SOLVE.findall("optikin solve problems/cbha-nn-<f>.yaml, optikin solve NAME, optikin solve --jobs") == []
