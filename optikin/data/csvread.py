"""The one reader of numeric CSV files behind every file source (configurations, targets, markers, demonstrations).

A file is UTF-8 text (an initial byte-order mark is allowed) with a header row naming
the columns and one row per sample; blank lines are skipped, columns not asked for are
ignored, cells are decimal numbers as Python's ``float`` reads them (``1.5``,
``-2e-3``; ``nan`` and ``inf`` only where a reader allows them). A file is refused
before it is parsed when it is not a regular file, is larger than :data:`MAX_BYTES`,
holds a NUL byte (binary) or is not valid UTF-8.

Every error is an :class:`~optikin.errors.InputDataError` naming the file, the row
(``sample``: the data row counted from 0, and the 1-based ``line`` of the file in the
message) and the column. A message shows what the file holds only as a short escaped
excerpt (:func:`excerpt`, at most :data:`EXCERPT_LENGTH` characters): never a whole
line or header, so pointing a source at an unexpected file (``/proc/self/environ``, a
key file) does not print it.
"""

from __future__ import annotations

import csv
import io
import math
import os
import stat
from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from optikin.errors import InputDataError

MAX_BYTES = 200 * 1024 * 1024
"""Largest CSV file read [bytes]; a larger one is refused before reading."""
EXCERPT_LENGTH = 20
"""Most characters of a file's text an error message shows (cell or header name, escaped)."""
HEADER_NAMES_SHOWN = 4
"""Header names an error about a missing column shows."""
MAX_COORDINATE = 10.0
"""Largest magnitude of a position coordinate read from a file [m], after its declared unit is applied: no
continuum arm or its workspace reaches 10 m from the origin of the frame it is recorded in, so a larger value is
a unit error (millimetres read as metres) or a corrupt cell, refused with a unit hint."""
UNIT_METRES: dict[str, float] = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
"""Metres per length unit a file may be written in."""


def unit_hint(largest: float, unit: str, key: str = "units", declared: str | None = None) -> str:
    """``": values look like millimetres: set units: mm"`` when positions whose largest magnitude is ``largest``
    [m], read in ``unit``, come within :data:`MAX_COORDINATE` in a smaller unit; else ``""``. With ``declared``
    (the unit the file itself states) the hint says that the file's declaration is wrong instead."""
    for smaller, name in (("cm", "centimetres"), ("mm", "millimetres")):
        ratio = UNIT_METRES[unit] / UNIT_METRES[smaller]
        if ratio > 1 and largest / ratio <= MAX_COORDINATE and (smaller == "mm" or largest / ratio < 1.0):
            if declared is not None:
                return f": values look like {name}, though the file declares {excerpt(declared)}"
            return f": values look like {name}: set {key}: {smaller}"
    return ""


def check_coordinates(
    values: np.ndarray,
    source: str,
    unit: str,
    where: Callable[[int, int], tuple[int, str, str]],
    key: str = "units",
    declared: str | None = None,
) -> None:
    """Refuse a finite coordinate of ``values`` ``(rows, k)`` [m] above :data:`MAX_COORDINATE` in magnitude.

    ``where(row, column) -> (sample, field, message suffix)`` names the cell; ``unit`` is the unit the values
    were read in, ``key`` the problem file's key that sets it and ``declared`` the file's own statement of its
    unit (if any), for the hint (:func:`unit_hint`).

    Raises
    ------
    InputDataError
        Naming the file, the sample and the field of the first such cell, with the largest magnitude of all.
    """
    values = np.asarray(values, dtype=float).reshape(len(values), -1)
    with np.errstate(invalid="ignore"):
        large = np.isfinite(values) & (np.abs(values) > MAX_COORDINATE)
    if not large.any():
        return
    i, k = (int(v) for v in np.argwhere(large)[0])
    largest = float(np.max(np.abs(values[np.isfinite(values)])))
    sample, field, suffix = where(i, k)
    raise InputDataError(
        f"coordinate {values[i, k]:.6g} m is beyond {MAX_COORDINATE:g} m, the largest a continuum arm's recording "
        f"holds (largest: {largest:.6g} m){unit_hint(largest, unit, key, declared)}{suffix}",
        source=source,
        sample=sample,
        field=field,
    )


def excerpt(text: str, limit: int = EXCERPT_LENGTH) -> str:
    """``repr(text)``, cut to at most ``limit`` characters (a cut excerpt ends with ``...``).

    Escaping (``repr``) keeps control characters and terminal escapes out of messages.
    """
    shown = repr(text[: limit + 1])
    if len(shown) <= limit and len(text) <= limit:
        return shown
    keep = min(len(text), limit)
    while keep and len(repr(text[:keep])) + 3 > limit:
        keep -= 1
    return repr(text[:keep]) + "..."


def _describe(cell: str) -> str:
    return excerpt(cell.strip()) if cell.strip() else "an empty cell"


@dataclass(frozen=True)
class Table:
    """The numeric columns read from a CSV file.

    Attributes
    ----------
    source:
        The file, as errors name it.
    columns:
        The column names, in the order of ``values``.
    values:
        ``(rows, len(columns))`` floats.
    lines:
        ``(rows,)`` the 1-based line of the file each row starts on.
    header:
        Every column name of the file's header row (stripped).
    """

    source: str
    columns: tuple[str, ...]
    values: np.ndarray
    lines: np.ndarray
    header: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.values)

    def column(self, name: str) -> np.ndarray:
        """The column ``name`` ``(rows,)``."""
        return self.values[:, self.columns.index(name)]

    def stacked(self, names: Sequence[str]) -> np.ndarray:
        """The columns ``names`` side by side ``(rows, len(names))``."""
        return self.values[:, [self.columns.index(n) for n in names]]

    def error(self, message: str, row: int, column: str) -> InputDataError:
        """An :class:`InputDataError` on data row ``row`` (from 0) and ``column``; the message gets the line."""
        return InputDataError(
            f"{message} (line {int(self.lines[row])})", source=self.source, sample=int(row), field=column
        )

    def check_coordinates(self, names: Sequence[str], scale: float, unit: str, key: str = "units") -> None:
        """Refuse a coordinate of the columns ``names`` (times ``scale``, metres per unit) above
        :data:`MAX_COORDINATE` (:func:`check_coordinates`)."""
        check_coordinates(
            self.stacked(names) * scale,
            self.source,
            unit,
            lambda i, k: (i, names[k], f" (line {int(self.lines[i])})"),
            key,
        )

    def check_finite(self, names: Sequence[str]) -> None:
        """Raise on the first row (then column) of ``names`` holding NaN or an infinity."""
        block = self.stacked(names)
        bad = np.argwhere(~np.isfinite(block))
        if bad.size:
            i, k = (int(v) for v in bad[0])
            raise self.error(f"{block[i, k]} is not a finite number", i, names[k])

    def check_increasing(self, name: str = "t") -> None:
        """Raise on the first row where column ``name`` does not increase strictly (NaN included)."""
        t = self.column(name)
        if not np.isfinite(t[:1]).all():
            raise self.error(f"{t[0]} is not a finite number", 0, name)
        with np.errstate(invalid="ignore"):
            bad = np.flatnonzero(~(np.diff(t) > 0))
        if bad.size:
            k = int(bad[0]) + 1
            raise self.error(f"times must increase strictly, got {t[k]:.9g} after {t[k - 1]:.9g}", k, name)

    def check_unit_quaternions(self, names: Sequence[str], tolerance: float) -> np.ndarray:
        """The columns ``names`` (``w, x, y, z``) ``(rows, 4)``, each row of norm within ``tolerance`` of 1.

        NaN fails the check (``not |n - 1| <= tolerance``).
        """
        q = self.stacked(names)
        with np.errstate(over="ignore", invalid="ignore"):  # a huge cell gives an infinite norm, refused below
            norm = np.linalg.norm(q, axis=1)
            bad = np.flatnonzero(~(np.abs(norm - 1.0) <= tolerance))
        if bad.size:
            i = int(bad[0])
            raise self.error(
                f"norm {norm[i]:.9g}: not a unit quaternion, not 1 to within {tolerance:g}", i, ", ".join(names)
            )
        return q


def missing_columns(source: str, header: Sequence[str], names: Sequence[str], hint: str = "") -> InputDataError | None:
    """The error for the columns of ``names`` absent from ``header`` (None when all are there).

    Names the missing columns (ours) and at most :data:`HEADER_NAMES_SHOWN` header names,
    each an :func:`excerpt`.
    """
    missing = [n for n in names if n not in header]
    if not missing:
        return None
    shown = ", ".join(excerpt(h) for h in header[:HEADER_NAMES_SHOWN])
    more = ", ..." if len(header) > HEADER_NAMES_SHOWN else ""
    return InputDataError(
        f"missing column(s) {', '.join(missing)}{hint}; the header has {len(header)} column(s): {shown}{more}",
        source=source,
        field=missing[0],
    )


def check_unique(header: Sequence[str], source: str) -> None:
    """Refuse a header naming one column twice (which of the two would be read is a guess), naming both."""
    first: dict[str, int] = {}
    for k, name in enumerate(header):
        if name and name in first:
            raise InputDataError(
                f"column {excerpt(name)} appears twice in the header: columns {first[name] + 1} and {k + 1}",
                source=source,
                field=name,
            )
        first.setdefault(name, k)


def read_text(path: Path, source: str) -> str:
    """The file's text, after the checks of the module docstring."""
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise InputDataError("cannot read: not a regular file", source=source)
        if info.st_size > MAX_BYTES:
            raise InputDataError(
                f"cannot read: {info.st_size / 2**20:.0f} MiB, larger than the {MAX_BYTES // 2**20} MiB "
                "a CSV file may have",
                source=source,
            )
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise InputDataError(f"cannot read: {exc.strerror or type(exc).__name__}", source=source) from None
    if len(raw) > MAX_BYTES:
        raise InputDataError(
            f"cannot read: larger than the {MAX_BYTES // 2**20} MiB a CSV file may have", source=source
        )
    if b"\x00" in raw:
        raise InputDataError("not a CSV text file: it holds NUL bytes (a binary file?)", source=source)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputDataError(
            f"not a UTF-8 text file: byte 0x{raw[exc.start]:02x} on line {line} is not UTF-8", source=source
        ) from None


Selection = Callable[[tuple[str, ...]], tuple[Sequence[str], Sequence[str]]]
"""``header -> (columns, finite)``: the columns to read, and those of them where NaN and infinities are refused."""


def read_table(path: str | Path, select: Selection, exact: bool = False) -> Table:
    """Read the numeric columns ``select(header)`` chooses from a CSV file with a header row.

    Parameters
    ----------
    path:
        The file.
    select:
        Given the file's header (names stripped), returns the columns to read and those of
        them that must hold finite numbers; it raises (e.g. :func:`missing_columns`) when
        the header lacks what the reader needs.
    exact:
        Refuse a row with more cells than the header has names too (a decimal comma, a
        stray separator), not only one with too few.

    Returns
    -------
    Table
        The columns, their values ``(rows, columns)`` and the line of each row.

    Raises
    ------
    InputDataError
        Besides the refusals of the module docstring: an empty file, no data rows, a row
        with too few cells, a cell that is not a number (or, in a ``finite`` column, not
        a finite one), malformed CSV quoting.
    """
    path = Path(path)
    source = str(path)
    reader = csv.reader(io.StringIO(read_text(path, source), newline=""))
    start = 1
    try:
        header_row = next(reader, None)
        while header_row is not None and not header_row:
            start = reader.line_num + 1
            header_row = next(reader, None)
        if header_row is None:
            raise InputDataError("empty file", source=source)
        header = tuple(h.strip() for h in header_row)
        check_unique(header, source)
        columns, finite = select(header)
        columns = tuple(columns)
        index = [header.index(c) for c in columns]
        must_be_finite = [c in finite for c in columns]
        values, lines = array("d"), array("q")
        rows = 0
        start = reader.line_num + 1
        for row in reader:
            line, start = start, reader.line_num + 1
            if not row:
                continue
            if exact and len(row) > len(header):
                raise InputDataError(
                    f"{len(row)} cells, the header has {len(header)} names (a decimal comma?) (line {line})",
                    source=source,
                    sample=rows,
                    field=header[-1],
                )
            for j, name, finite_only in zip(index, columns, must_be_finite):
                if j >= len(row):
                    raise InputDataError(
                        f"a missing cell: the row has {len(row)} of the header's {len(header)} cells (line {line})",
                        source=source,
                        sample=rows,
                        field=name,
                    )
                cell = row[j]
                try:
                    value = float(cell)
                except ValueError:
                    value = None
                if value is None or (finite_only and not math.isfinite(value)):
                    what = "a finite number" if finite_only else "a number"
                    raise InputDataError(
                        f"{_describe(cell)} is not {what} (line {line})", source=source, sample=rows, field=name
                    )
                values.append(value)
            lines.append(line)
            rows += 1
    except csv.Error as exc:
        raise InputDataError(f"malformed CSV on line {start}: {exc}", source=source) from None
    if rows == 0:
        raise InputDataError("no data rows", source=source)
    return Table(
        source,
        columns,
        np.frombuffer(values, dtype=float).reshape(rows, len(columns)).copy(),
        np.frombuffer(lines, dtype=np.int64).copy(),
        header,
    )


def columns_of(
    source: str, names: Sequence[str], optional: Sequence[str] = (), finite: Sequence[str] = (), hint: str = ""
) -> Selection:
    """The :data:`Selection` of the columns ``names`` (all required) and of those of ``optional`` present."""

    def select(header: tuple[str, ...]) -> tuple[Sequence[str], Sequence[str]]:
        error = missing_columns(source, header, names, hint)
        if error is not None:
            raise error
        return [*names, *(c for c in optional if c in header)], finite

    return select
