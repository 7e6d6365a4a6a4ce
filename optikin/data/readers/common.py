"""What every reader of :mod:`optikin.data.readers` shares: its params, units resolution and the source loader.

A source of family ``recordings`` reads ``data.params.file`` (relative to the problem
file; :mod:`optikin.data.files`) in the declared ``frame`` and ``units`` (:class:`RecordingParams`), converts it
once (:func:`optikin.data.recording.to_base_frame`), notes its gaps, NaN cells and
label swaps (:func:`optikin.data.recording.inspect_frames`), keeps the selected
markers and bodies and, unless ``drop_incomplete: false``, drops the frames where one
of them is missing (each with a ``dropped`` note). With ``data.samples`` in the
problem file only the first that many frames are kept.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable, TypeVar

import numpy as np
from pydantic import Field

from optikin.data.configurations import first_rows
from optikin.data.csvread import check_coordinates
from optikin.data.files import FileParams
from optikin.data.recording import FrameOptions, Recording, Units, inspect_frames, to_base_frame
from optikin.errors import InputDataError
from optikin.spec import DataSpec

FAMILY = "recordings"
"""The data family of the readers' sources."""

QUATERNION_TOLERANCE = 1e-3
"""| |q| - 1 | a file's quaternion may have; it is then normalised."""

UNIT_NAMES: dict[str, Units] = {
    "m": "m",
    "meters": "m",
    "metres": "m",
    "cm": "cm",
    "centimeters": "cm",
    "centimetres": "cm",
    "mm": "mm",
    "millimeters": "mm",
    "millimetres": "mm",
}
"""A file's own name of its length unit (case-insensitive) -> :data:`~optikin.data.recording.Units`."""


class RecordingParams(FileParams):
    """``data.params`` shared by every source of family ``recordings``."""

    file: str = Field(min_length=1, description="the recording, relative to the problem file's folder")
    frame: FrameOptions = Field(default_factory=FrameOptions, description="axes of the file's frame")
    units: Units | None = Field(
        None,
        description="length unit of the file's positions; default: the unit the file declares (Motive, C3D), "
        "else metres; a file declaring another unit is refused",
    )
    markers: tuple[str, ...] | None = Field(None, description="the markers to keep (default: all)")
    bodies: tuple[str, ...] | None = Field(None, description="the rigid bodies to keep (default: all)")
    drop_incomplete: bool = Field(
        True, description="drop (with a note) each frame where a kept marker or body is missing or swapped"
    )


def resolve_units(declared: str | None, requested: Units | None, source: str, field: str) -> Units:
    """The length unit to read a file in.

    Parameters
    ----------
    declared:
        What the file says (``Millimeters``, ``mm``), or None when it says nothing.
    requested:
        What the problem file says (``units``), or None.
    source, field:
        The file and the header field holding ``declared``, for the error.

    Raises
    ------
    InputDataError
        If the file declares a unit optikin does not know, or one other than ``requested``.
    """
    if declared is None or not declared.strip():
        return requested or "m"
    unit = UNIT_NAMES.get(declared.strip().lower())
    if unit is None:
        raise InputDataError(
            f"unknown length unit {declared.strip()[:20]!r} (known: {', '.join(sorted(set(UNIT_NAMES)))})",
            source=source,
            field=field,
        )
    if requested is not None and requested != unit:
        raise InputDataError(
            f"the file declares its lengths in {declared.strip()!r}, the problem file says units: {requested}",
            source=source,
            field=field,
        )
    return unit


def normalised_quaternions(
    q: np.ndarray, source: str, field: str, where: Callable[[int], tuple[int, str]]
) -> np.ndarray:
    """``q`` ``(T, 4)`` with each non-NaN row normalised; a row off unit length by more than
    :data:`QUATERNION_TOLERANCE` raises, naming ``source``, ``field`` and the row.

    ``where(row) -> (sample, message suffix)`` names the row in the error.
    """
    with np.errstate(over="ignore", invalid="ignore"):  # a huge cell gives an infinite norm, refused below
        norm = np.linalg.norm(q, axis=1)
        bad = np.flatnonzero(~np.isnan(norm) & ~(np.abs(norm - 1.0) <= QUATERNION_TOLERANCE))
    if bad.size:
        i = int(bad[0])
        sample, suffix = where(i)
        raise InputDataError(
            f"norm {norm[i]:.9g}: not a unit quaternion, not 1 to within {QUATERNION_TOLERANCE:g}{suffix}",
            source=source,
            sample=sample,
            field=field,
        )
    return q / norm[:, None]


def finish(raw: Recording, frame: FrameOptions, units: Units, numbered: bool, declared: str | None = None) -> Recording:
    """``raw`` (file frame and units) converted to SI and the base frame, with its frame notes.

    ``declared`` is the file's own statement of its length unit (Motive's ``Length Units``, C3D's
    ``POINT:UNITS``), for the hint of the error.

    Raises
    ------
    InputDataError
        Naming the marker or rigid body (``markers.NAME``, ``bodies.NAME``) and the frame of the first position
        beyond :data:`~optikin.data.csvread.MAX_COORDINATE`, with a unit hint (``set data.params.units: mm``).
    """
    recording = to_base_frame(raw, frame, units)
    tracks = [(f"markers.{n}", p) for n, p in recording.markers.items()]
    tracks += [(f"bodies.{n}", b.positions) for n, b in recording.bodies.items()]
    for field, positions in tracks:

        def where(i: int, k: int, field: str = field) -> tuple[int, str, str]:
            return i, field, f" (frame {i})"

        check_coordinates(positions, recording.source, units, where, "data.params.units", declared)
    check_not_metres(tracks, recording.source, units, declared)
    return inspect_frames(recording, numbered)


MIN_LARGEST_COORDINATE = 0.01
"""Smallest largest-magnitude position [m] of a recording read in millimetres or centimetres: a continuum arm's
markers lie centimetres from the origin at least, so a recording all within 1 cm of it holds metres."""


def check_not_metres(tracks: list[tuple[str, np.ndarray]], source: str, units: Units, declared: str | None) -> None:
    """Refuse a recording read in ``mm`` or ``cm`` whose every position lies within
    :data:`MIN_LARGEST_COORDINATE` of the origin: its values look like metres.

    Raises
    ------
    InputDataError
        Naming the file and the unit (the file's declaration, ``declared``, or ``data.params.units``).
    """
    values = [np.abs(p[np.isfinite(p)]) for _, p in tracks]
    found = [v for v in values if v.size]
    if units == "m" or not found:
        return
    largest = max(float(v.max()) for v in found)
    if largest >= MIN_LARGEST_COORDINATE:
        return
    hint = (
        f"though the file declares {declared.strip()[:20]!r}" if declared else f"set data.params.units: m, not {units}"
    )
    raise InputDataError(
        f"every position lies within {largest:.3g} m of the origin, read in {units}: values look like metres, {hint}",
        source=source,
        field="units",
    )


def select(recording: Recording, params: RecordingParams) -> Recording:
    """The markers ``params.markers`` and bodies ``params.bodies`` of ``recording`` (all when None).

    Raises
    ------
    InputDataError
        Naming the file and the first marker or body it lacks (``field``: ``markers.NAME``).
    """
    for kind, names, have in (
        ("marker", params.markers, recording.markers),
        ("rigid body", params.bodies, recording.bodies),
    ):
        missing = [n for n in names or () if n not in have]
        if missing:
            shown = ", ".join(sorted(have)[:8]) or "none"
            raise InputDataError(
                f"no {kind} {missing[0]!r} in the file; it has: {shown}",
                source=recording.source,
                field=f"{'markers' if kind == 'marker' else 'bodies'}.{missing[0]}",
            )
    markers = recording.markers if params.markers is None else {n: recording.markers[n] for n in params.markers}
    bodies = recording.bodies if params.bodies is None else {n: recording.bodies[n] for n in params.bodies}
    return replace(recording, markers=markers, bodies=bodies)


P = TypeVar("P", bound=RecordingParams)


def load_recording(read: Callable[[Path, P], Recording], data: DataSpec, params: P, path: Path) -> Recording:
    """The loader of a ``recordings`` source: ``read(file, params)``, then the steps of the module docstring."""
    recording = select(read(params.resolve(path), params), params)
    if params.drop_incomplete:
        recording = recording.drop_incomplete()
    keep, _ = first_rows(data, len(recording))
    return recording.take(np.arange(keep)) if keep < len(recording) else recording
