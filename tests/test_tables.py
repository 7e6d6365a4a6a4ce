"""Comparison tables: every column in the result folder, a compact table that fits 80 columns, mappings
as sub-rows."""

from __future__ import annotations

import csv
import io

from rich.console import Console

from optikin.report import print_result
from optikin.results import MethodRow, Result, write_result
from optikin.tables import compact_columns, comparison_rows, flatten

ROWS = [
    MethodRow(
        "gauss-newton",
        "solver",
        {
            "formulation": "rest",
            "success [%]": 99.5,
            "median tip error [m]": 1.2e-14,
            "median time per solve [us]": 110.0,
            "per section": {"s1": 0.1, "s2": {"a": 1, "b": 2}},
            "statuses": "ok: 995, unreachable: 5",
        },
    ),
    MethodRow("newton", "baseline", {"formulation": "rest", "not applicable": "rank-deficient " * 8}),
]


def result() -> Result:
    return Result(
        problem="table-test",
        kind="ik",
        solver="gauss-newton",
        title="t",
        arm={},
        status=["ok"],
        metrics={"nested": {"x": 1.5, "y": [1, 2]}},
        comparison=ROWS,
    )


def test_mappings_are_flattened_into_dotted_columns():
    assert flatten({"a": 1, "b": {"c": 2, "d": {"e": 3}}}) == {"a": 1, "b.c": 2, "b.d.e": 3}
    columns, cells = comparison_rows(ROWS)
    assert "per section.s2.b" in columns
    assert cells[1][columns.index("success [%]")] == ""


def test_the_compact_table_picks_success_error_time_and_statuses():
    columns, _ = comparison_rows(ROWS)
    assert compact_columns(columns) == [
        "success [%]",
        "median tip error [m]",
        "median time per solve [us]",
        "statuses",
    ]


def test_the_printed_result_fits_80_columns_and_names_what_was_not_applicable():
    out = io.StringIO()
    print_result(result(), Console(file=out, width=80))
    text = out.getvalue()
    assert max(len(line) for line in text.splitlines()) <= 80
    assert "nested.x" in text and "not applicable: newton: rank-deficient" in text
    assert "{" not in text  # no raw Python dicts


def test_the_result_folder_holds_every_column(tmp_path):
    folder = write_result(result(), tmp_path, figures=False)
    with open(folder / "comparison.csv", newline="") as handle:
        table = list(csv.reader(handle))
    columns, _ = comparison_rows(ROWS)
    assert table[0] == columns and len(table) == 3
    markdown = (folder / "comparison.md").read_text().splitlines()
    assert markdown[0].startswith("| method | role |") and len(markdown) == 4
