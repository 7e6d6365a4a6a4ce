"""OptiTrack Motive CSV export (format versions 1.2x, header included).

The layout Motive writes (its "Data Export: CSV" documentation)::

    Format Version,1.25,Take Name,trunk,...,Rotation Type,Quaternion,Length Units,Millimeters,...
    <blank line>
    ,Type,Rigid Body,Rigid Body,...,Marker,Marker,Marker,...
    ,Name,disk1,disk1,...,disk1:Marker1,disk1:Marker1,disk1:Marker1,...
    ,ID,1,1,...,1:1,1:1,1:1,...
    ,Parent,...                      (1.25; absent from older versions)
    ,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error,Position,...
    Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,X,Y,Z,...
    0,0.000000,...

* the first row holds ``key,value`` pairs; ``Length Units`` gives the unit (checked
  against the problem file's ``units``), ``Rotation Type`` must be ``Quaternion`` when
  rigid bodies are exported (Euler exports are refused: export quaternions);
* the ``Type``/``Name``/``ID``/``Parent`` rows label the columns from the third on
  (a ``TimeCode`` column, with an empty type, may follow the time); the row with an
  empty first and second cell gives each column's component (``Rotation``,
  ``Position``, ``Mean Marker Error``, ``Marker Quality``), the ``Frame`` row its axis;
* ``Marker`` columns become :attr:`Recording.markers` (``Position X, Y, Z``); unlabelled
  markers (Motive names them ``Unlabeled N``, a different point from one take to the
  next) are skipped unless ``unlabeled`` is asked for,
  ``Rigid Body`` columns :attr:`Recording.bodies` (``Rotation X, Y, Z, W`` -> ``w, x, y, z``
  and ``Position X, Y, Z``); expected-marker columns (``Rigid Body Marker``, ``Bone
  Marker``), bones and quality columns are not read;
* an empty (or ``nan``) cell is a marker or body Motive did not see in that frame (NaN, noted);
  frame numbers must increase strictly (a jump is noted as a gap), times too.

Errors (:class:`~optikin.errors.InputDataError`) name the file, the data row (``sample``,
from 0; the message gives the line and the frame number) and the column
(``NAME Component Axis``, e.g. ``disk1 Position Y``).
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import Field

from optikin.data.csvread import excerpt, read_text
from optikin.data.readers.common import (
    FAMILY,
    RecordingParams,
    finish,
    load_recording,
    normalised_quaternions,
    resolve_units,
)
from optikin.data.recording import FrameOptions, Recording, RigidBodyTrack, Units
from optikin.data.sources import register_source
from optikin.errors import InputDataError
from optikin.spec import DataSpec

LABEL_ROWS = ("Type", "Name", "ID", "Parent")
"""Second cell of the rows that label the columns."""
POSITION = ("X", "Y", "Z")
ROTATION = ("X", "Y", "Z", "W")


@dataclass
class _Asset:
    """The columns of one marker or rigid body: ``(component, axis) -> column index``."""

    kind: str
    name: str
    columns: dict[tuple[str, str], int] = field(default_factory=dict)


def _metadata(row: list[str]) -> dict[str, str]:
    return {row[i].strip(): row[i + 1].strip() for i in range(0, len(row) - 1, 2) if row[i].strip()}


def _header(rows: list[tuple[int, list[str]]], source: str) -> tuple[dict[str, str], dict[str, list[str]], int]:
    """Metadata, the label rows (``Type``, ``Name``, ..., ``component``, ``axis``) and the first data row's index."""
    if not rows:
        raise InputDataError("empty file", source=source)
    line, first = rows[0]
    if not first or first[0].strip() != "Format Version":
        raise InputDataError(
            f"not a Motive CSV export: line {line} starts with {excerpt(first[0] if first else '')}, "
            "not 'Format Version'",
            source=source,
            field="Format Version",
        )
    labels: dict[str, list[str]] = {}
    for k in range(1, len(rows)):
        line, row = rows[k]
        head = [c.strip() for c in row[:2]] + ["", ""]
        if head[0] == "Frame":
            labels["axis"] = [c.strip() for c in row]
            missing = [n for n in ("Type", "Name") if n not in labels]
            if missing or "component" not in labels:
                what = missing[0] if missing else "component (Rotation/Position)"
                raise InputDataError(f"header row {what} missing before line {line}", source=source, field=what)
            return _metadata(first), labels, k + 1
        if head[0] == "" and head[1] in LABEL_ROWS:
            labels[head[1]] = [c.strip() for c in row]
        elif head[0] == "" and head[1] == "":
            labels["component"] = [c.strip() for c in row]
        else:
            second = row[1] if len(row) > 1 else ""
            raise InputDataError(
                f"unexpected header row on line {line}: starts with {excerpt(row[0])}, {excerpt(second)}",
                source=source,
            )
    raise InputDataError("no 'Frame,Time (Seconds),...' header row: the file ends in its header", source=source)


UNLABELED = "Unlabeled "
"""How Motive's names of unlabelled markers start."""


def _assets(labels: dict[str, list[str]], source: str, unlabeled: bool) -> tuple[list[_Asset], list[_Asset]]:
    """Markers (with ``unlabeled``, the unlabelled ones too) and rigid bodies, in column order."""
    width = max(len(v) for v in labels.values())

    def cell(row: str, j: int) -> str:
        values = labels.get(row, [])
        return values[j] if j < len(values) else ""

    found: dict[tuple[str, str], _Asset] = {}
    ids: dict[tuple[str, str], str] = {}
    for j in range(2, width):
        kind, name = cell("Type", j), cell("Name", j)
        if kind not in ("Marker", "Rigid Body") or (kind == "Marker" and name.startswith(UNLABELED) and not unlabeled):
            continue
        component, axis = cell("component", j), cell("axis", j)
        if component not in ("Position", "Rotation"):
            continue
        key = (kind, name)
        column = f"{name} {component} {axis}"
        if ids.setdefault(key, cell("ID", j)) != cell("ID", j):
            raise InputDataError(
                f"two {kind.lower()}s are named {excerpt(name)} (IDs {excerpt(ids[key])} and {excerpt(cell('ID', j))})",
                source=source,
                field=column,
            )
        asset = found.setdefault(key, _Asset(kind, name))
        if (component, axis) in asset.columns:
            raise InputDataError(f"column {column} appears twice", source=source, field=column)
        asset.columns[(component, axis)] = j
    markers: list[_Asset] = []
    bodies: list[_Asset] = []
    for asset in found.values():
        needed = [("Position", a) for a in POSITION]
        if asset.kind == "Rigid Body":
            needed += [("Rotation", a) for a in ROTATION]
        missing = [f"{asset.name} {c} {a}" for c, a in needed if (c, a) not in asset.columns]
        if missing:
            raise InputDataError(
                f"{asset.kind.lower()} {excerpt(asset.name)} lacks column {missing[0]}", source=source, field=missing[0]
            )
        (markers if asset.kind == "Marker" else bodies).append(asset)
    return markers, bodies


def _cell_error(row: list[str], cells: list[tuple[str, int]], source: str, i: int, at: str) -> InputDataError:
    """The error on the first cell of ``row`` that is missing, not a number, or infinite (or an empty time)."""
    for k, (name, j) in enumerate(cells):
        if j >= len(row):
            return InputDataError(
                f"a missing cell: the row has {len(row)} cells {at}", source=source, sample=i, field=name
            )
        text = row[j].strip()
        if not text and k > 0:
            continue
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if math.isinf(value) or (math.isnan(value) and (k == 0 or text.lower() != "nan")):
            shown = excerpt(text) if text else "an empty cell"
            return InputDataError(f"{shown} is not a finite number {at}", source=source, sample=i, field=name)
    raise AssertionError("no bad cell in a row that failed to parse")


def read_motive_csv(
    path: str | Path, frame: FrameOptions | None = None, units: Units | None = None, unlabeled: bool = False
) -> Recording:
    """Read a Motive CSV export (layout in the module docstring) into a :class:`Recording`.

    Parameters
    ----------
    path:
        The file.
    frame:
        The axes of the export (Motive's default is y-up, right-handed: ``FrameOptions(up="y")``);
        default z-up.
    units:
        The export's length unit; default its ``Length Units`` (refused when they differ).
    unlabeled:
        Also read the unlabelled markers (``Unlabeled N``).

    Returns
    -------
    Recording
        In SI and optikin's base frame; :attr:`Recording.frames` holds the ``Frame`` column;
        notes for gaps, NaN cells and label swaps.

    Raises
    ------
    InputDataError
        Naming the file, row and column: a missing or malformed header row, a cell that is
        not a number, frames or times that do not increase, a non-unit quaternion, an
        Euler rotation type, a unit other than ``units``; the refusals of
        :mod:`optikin.data.csvread` (not a regular file, too large, binary, not UTF-8).
    """
    path = Path(path)
    source = str(path)
    reader = csv.reader(io.StringIO(read_text(path, source), newline=""))
    rows: list[tuple[int, list[str]]] = []
    start = 1
    try:
        for row in reader:
            if "".join(row).strip():
                rows.append((start, row))
            start = reader.line_num + 1
    except csv.Error as exc:
        raise InputDataError(f"malformed CSV on line {start}: {exc}", source=source) from None
    metadata, labels, first_data = _header(rows, source)
    unit = resolve_units(metadata.get("Length Units"), units, source, "Length Units")
    markers, bodies = _assets(labels, source, unlabeled)
    if bodies and metadata.get("Rotation Type", "Quaternion") != "Quaternion":
        raise InputDataError(
            f"rotation type {excerpt(metadata['Rotation Type'])}: export rigid bodies with Rotation Type Quaternion",
            source=source,
            field="Rotation Type",
        )
    data = rows[first_data:]
    if not data:
        raise InputDataError("no data rows", source=source)
    columns = [(f"{a.name} {c} {x}", j) for a in markers + bodies for (c, x), j in a.columns.items()]
    values = np.full((len(data), len(columns)), np.nan)
    frames = np.zeros(len(data), dtype=np.int64)
    time = np.zeros(len(data))
    cells = [("Time (Seconds)", 1)] + columns
    picked = [j for _, j in cells]
    for i, (line, row) in enumerate(data):
        at = f"(line {line}, frame {row[0].strip()[:12]})"
        try:
            frames[i] = int(row[0])
        except ValueError:
            raise InputDataError(
                f"{excerpt(row[0].strip()) or 'an empty cell'} is not a frame number (line {line})",
                source=source,
                sample=i,
                field="Frame",
            ) from None
        try:
            parsed = [float(row[j]) if row[j].strip() else math.nan for j in picked]
            bad = not math.isfinite(parsed[0]) or any(map(math.isinf, parsed))
        except (ValueError, IndexError):
            bad = True
        if bad:
            raise _cell_error(row, cells, source, i, at)
        time[i] = parsed[0]
        values[i] = parsed[1:]
        if i and not frames[i] > frames[i - 1]:
            raise InputDataError(
                f"frame numbers must increase strictly, got {frames[i]} after {frames[i - 1]} (line {line})",
                source=source,
                sample=i,
                field="Frame",
            )
        if i and not time[i] > time[i - 1]:
            raise InputDataError(
                f"times must increase strictly, got {time[i]:.9g} after {time[i - 1]:.9g} {at}",
                source=source,
                sample=i,
                field="Time (Seconds)",
            )
    index = {name: k for k, (name, _) in enumerate(columns)}

    def block(asset: _Asset, component: str, axes: tuple[str, ...]) -> np.ndarray:
        out = values[:, [index[f"{asset.name} {component} {a}"] for a in axes]]
        out[np.isnan(out).any(axis=1)] = np.nan
        return out

    def where(row: int) -> tuple[int, str]:
        return row, f" (line {data[row][0]}, frame {frames[row]})"

    tracks: dict[str, RigidBodyTrack] = {}
    for body in bodies:
        xyzw = block(body, "Rotation", ROTATION)
        wxyz = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
        q = normalised_quaternions(wxyz, source, f"{body.name} Rotation", where)
        tracks[body.name] = RigidBodyTrack(block(body, "Position", POSITION), q)
    raw = Recording(
        time,
        markers={m.name: block(m, "Position", POSITION) for m in markers},
        bodies=tracks,
        source=source,
        frames=frames,
    )
    return finish(raw, frame or FrameOptions(), unit, numbered=True, declared=metadata.get("Length Units"))


class MotiveParams(RecordingParams):
    """``data.params`` of source ``motive`` (family ``recordings``)."""

    unlabeled: bool = Field(False, description="also read the unlabelled markers (Motive's 'Unlabeled N')")


def _read(path: Path, params: MotiveParams) -> Recording:
    return read_motive_csv(path, params.frame, params.units, params.unlabeled)


@register_source(FAMILY, "motive", "an OptiTrack Motive CSV export (markers and rigid bodies)", params=MotiveParams)
def motive_source(arm: object, data: DataSpec, params: MotiveParams, path: Path) -> Recording:
    """:func:`read_motive_csv` of ``params.file``, then the steps of :mod:`optikin.data.readers.common`."""
    return load_recording(_read, data, params, path)
