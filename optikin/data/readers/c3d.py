"""C3D files (the motion-capture standard, https://www.c3d.org) through ``ezc3d`` (``pip install optikin[c3d]``).

What is read:

* ``POINT`` data: one marker per ``POINT:LABELS`` entry (``POINT:LABELS2``, ... continue
  the list when it is long), in ``POINT:UNITS`` (checked against the problem file's
  ``units``), at ``POINT:RATE``; a point with a negative residual (the C3D mark of a
  point not seen) or a NaN coordinate is missing in that frame (NaN, noted);
* ``ROTATION`` data (the C3D rotation section, 4 x 4 homogeneous matrices per frame):
  one rigid body per ``ROTATION:LABELS`` entry, the translation in ``POINT:UNITS``,
  the rotation converted to a quaternion (Shepperd's method); it must be a rotation to
  within 1e-3 (``|R^T R - I|`` and ``det R > 0``);
* ``ANALOG`` data: one actuator channel per ``ANALOG:LABELS`` entry, as ezc3d returns it
  (after the file's ``SCALE``/``OFFSET``), taken as SI; at ``ANALOG:RATE`` a multiple
  ``k`` of the point rate, the first of the ``k`` samples of each frame is kept.

Frames are numbered from the header's first frame; times are ``(frame - first) / rate``.
C3D stores floats in single precision: positions round-trip to about 1e-7 of their
magnitude, not better.

Errors (:class:`~optikin.errors.InputDataError`) name the file, the frame (``sample``,
from 0, and the file's frame number in the message) and the channel (``field``: the point,
rotation or analog label).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np

from optikin.algebra import quat_from_matrix
from optikin.data.readers.common import FAMILY, RecordingParams, finish, load_recording, resolve_units
from optikin.data.recording import FrameOptions, Recording, RigidBodyTrack, Units
from optikin.data.sources import register_source
from optikin.errors import InputDataError
from optikin.spec import DataSpec

ROTATION_TOLERANCE = 1e-3
"""Largest ``|R^T R - I|`` entry (and ``|det R - 1|``) of a ROTATION matrix."""


def _declared_frames(path: Path) -> tuple[int, int] | None:
    """The frames the file's header declares (``last - first + 1``) and the byte its data starts at, read from the
    raw header (ezc3d shortens both to what a cut file holds); None when the header is not a C3D header."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
            if len(head) < 20 or head[1] != 0x50 or head[0] < 2:
                return None
            fh.seek((head[0] - 1) * 512 + 3)
            processor = fh.read(1)
    except OSError:
        return None
    order: Literal["big", "little"] = "big" if processor == b"V" else "little"  # type 86: MIPS; else Intel, DEC
    first, last, start = (int.from_bytes(head[k : k + 2], order) for k in (6, 8, 16))
    if last == 0xFFFF or last < first:  # more frames than the header holds: the count is in the parameters
        return None
    return last - first + 1, (start - 1) * 512


def _ezc3d() -> Any:
    try:
        import ezc3d
    except ImportError:
        raise ImportError("reading C3D files needs ezc3d: pip install optikin[c3d] (or pip install ezc3d)") from None
    return ezc3d


def _labels(group: dict[str, Any], name: str) -> list[str]:
    """``NAME``, ``NAME2``, ``NAME3``, ... of a parameter group, joined (C3D splits lists over 255 entries)."""
    labels: list[str] = []
    k = 1
    while (key := name if k == 1 else f"{name}{k}") in group:
        labels += [str(v).strip() for v in group[key]["value"]]
        k += 1
    return labels


def _value(group: dict[str, Any], name: str, default: Any = None) -> Any:
    value = group.get(name, {}).get("value", [])
    return value[0] if len(value) else default


def _unique(labels: list[str], source: str, what: str) -> None:
    seen: set[str] = set()
    for label in labels:
        if label in seen:
            raise InputDataError(f"two {what} are labelled {label[:40]!r}", source=source, field=label)
        seen.add(label)


def read_c3d(path: str | Path, frame: FrameOptions | None = None, units: Units | None = None) -> Recording:
    """Read a C3D file (sections in the module docstring) into a :class:`Recording`.

    Parameters
    ----------
    path:
        The file.
    frame:
        The axes of the file (default z-up, the biomechanics convention; Motive's C3D
        export keeps its y-up unless told otherwise).
    units:
        The length unit; default ``POINT:UNITS`` (refused when they differ).

    Returns
    -------
    Recording
        In SI and optikin's base frame, :attr:`Recording.frames` the file's frame numbers,
        with notes for NaN cells and label swaps.

    Raises
    ------
    ImportError
        Without ezc3d (``pip install optikin[c3d]``).
    InputDataError
        Naming the file, frame and channel: a file ezc3d cannot parse, duplicate labels,
        an infinite coordinate or analog sample, a ROTATION matrix that is not a rotation,
        an analog rate that is not a multiple of the point rate, a unit other than ``units``.
    """
    ezc3d = _ezc3d()
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise InputDataError("cannot read: not a regular file", source=source)
    declared = _declared_frames(path)
    try:
        c3d = ezc3d.c3d(source, extract_forceplat_data=False)
    except Exception as exc:  # ezc3d raises RuntimeError / ValueError / IndexError on a corrupt file
        if declared is not None and declared[0] > 0 and path.stat().st_size <= declared[1]:
            raise InputDataError(
                f"truncated: the header declares {declared[0]} frames, the file ends before its data", source=source
            ) from None
        raise InputDataError(
            f"not a readable C3D file ({type(exc).__name__}: {str(exc)[:80]})", source=source
        ) from None
    parameters, header = c3d["parameters"], c3d["header"]
    point = parameters["POINT"]
    rate = float(header["points"]["frame_rate"])
    first = int(header["points"]["first_frame"])
    points = np.asarray(c3d["data"]["points"], dtype=float)
    n = points.shape[2]
    if declared is not None and n < declared[0]:
        raise InputDataError(
            f"truncated: the header declares {declared[0]} frames, the file holds {n} (cut short?)", source=source
        )
    if n == 0:
        raise InputDataError("no frames", source=source)
    if not rate > 0:
        raise InputDataError(f"point rate {rate:g}: not positive", source=source, field="POINT:RATE")
    labels = _labels(point, "LABELS")[: points.shape[1]]
    if len(labels) < points.shape[1]:
        raise InputDataError(
            f"{points.shape[1]} points but {len(labels)} POINT:LABELS", source=source, field="POINT:LABELS"
        )
    _unique(labels, source, "points")
    unit = resolve_units(_value(point, "UNITS"), units, source, "POINT:UNITS")
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=float)
    markers = {}
    for k, label in enumerate(labels):
        xyz = points[:3, k, :].T.copy()
        bad = np.flatnonzero(np.isinf(xyz).any(axis=1))
        if bad.size:
            raise InputDataError(
                f"an infinite coordinate (frame {first + int(bad[0])})", source=source, sample=int(bad[0]), field=label
            )
        if residuals.size:
            xyz[residuals[0, k, :] < 0] = np.nan
        xyz[np.isnan(xyz).any(axis=1)] = np.nan
        markers[label] = xyz
    bodies = _rotations(c3d, parameters, n, first, source)
    actuators = _analogs(c3d, parameters, rate, n, first, source)
    raw = Recording(
        np.arange(n) / rate,
        markers=markers,
        bodies=bodies,
        actuators=actuators,
        source=source,
        frames=first + np.arange(n),
    )
    return finish(raw, frame or FrameOptions(), unit, numbered=True, declared=_value(point, "UNITS"))


def _rotations(c3d: Any, parameters: Any, n: int, first: int, source: str) -> dict[str, RigidBodyTrack]:
    rotations = np.asarray(c3d["data"].get("rotations", np.zeros((4, 4, 0, 0))), dtype=float)
    if "ROTATION" not in parameters or rotations.ndim != 4 or rotations.shape[2] == 0:
        return {}
    labels = _labels(parameters["ROTATION"], "LABELS")
    if len(labels) < rotations.shape[2]:
        raise InputDataError(
            f"{rotations.shape[2]} rotations but {len(labels)} ROTATION:LABELS", source=source, field="ROTATION:LABELS"
        )
    _unique(labels, source, "rotations")
    if rotations.shape[3] != n:
        raise InputDataError(
            f"{rotations.shape[3]} rotation frames for {n} point frames (ROTATION:RATIO other than 1 is not read)",
            source=source,
            field="ROTATION:RATIO",
        )
    bodies = {}
    for k, label in enumerate(labels[: rotations.shape[2]]):
        matrices = np.moveaxis(rotations[:3, :3, k, :], -1, 0)
        positions = rotations[:3, 3, k, :].T.copy()
        seen = np.isfinite(matrices).all(axis=(1, 2)) & np.isfinite(positions).all(axis=1)
        if np.isinf(matrices).any() or np.isinf(positions).any():
            i = int(np.flatnonzero(np.isinf(matrices).any(axis=(1, 2)) | np.isinf(positions).any(axis=1))[0])
            raise InputDataError(f"an infinite entry (frame {first + i})", source=source, sample=i, field=label)
        q = np.full((n, 4), np.nan)
        if seen.any():
            r = matrices[seen]
            error = np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max(axis=(1, 2))
            error = np.maximum(error, np.abs(np.linalg.det(r) - 1.0))
            bad = np.flatnonzero(~(error <= ROTATION_TOLERANCE))
            if bad.size:
                i = int(np.flatnonzero(seen)[bad[0]])
                raise InputDataError(
                    f"not a rotation matrix (|R^T R - I|, |det R - 1| = {error[bad[0]]:.3g} > "
                    f"{ROTATION_TOLERANCE:g}; frame {first + i})",
                    source=source,
                    sample=i,
                    field=label,
                )
            unit_q = np.asarray(quat_from_matrix(r))
            q[seen] = unit_q / np.linalg.norm(unit_q, axis=1)[:, None]
        positions[~seen] = np.nan
        bodies[label] = RigidBodyTrack(positions, q)
    return bodies


def _analogs(c3d: Any, parameters: Any, rate: float, n: int, first: int, source: str) -> dict[str, np.ndarray]:
    analogs = np.asarray(c3d["data"]["analogs"], dtype=float)
    if analogs.ndim != 3 or analogs.shape[1] == 0 or analogs.shape[2] == 0:
        return {}
    analog = parameters["ANALOG"]
    labels = _labels(analog, "LABELS")
    if len(labels) < analogs.shape[1]:
        raise InputDataError(
            f"{analogs.shape[1]} analog channels but {len(labels)} ANALOG:LABELS", source=source, field="ANALOG:LABELS"
        )
    _unique(labels, source, "analog channels")
    analog_rate = float(_value(analog, "RATE", rate))
    ratio = analog_rate / rate
    if not (ratio >= 1 and abs(ratio - round(ratio)) < 1e-9) or analogs.shape[2] < n * round(ratio):
        raise InputDataError(
            f"analog rate {analog_rate:g} Hz is not a multiple of the point rate {rate:g} Hz "
            f"with {analogs.shape[2]} samples for {n} frames",
            source=source,
            field="ANALOG:RATE",
        )
    step = int(round(ratio))
    channels = {}
    for k, label in enumerate(labels[: analogs.shape[1]]):
        values = analogs[0, k, : n * step : step].copy()
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            i = int(bad[0])
            raise InputDataError(
                f"{values[i]} is not a finite number (frame {first + i})", source=source, sample=i, field=label
            )
        channels[label] = values
    return channels


def _read(path: Path, params: RecordingParams) -> Recording:
    return read_c3d(path, params.frame, params.units)


@register_source(
    FAMILY, "c3d", "a C3D file: points, rotations, analog channels (needs ezc3d: optikin[c3d])", params=RecordingParams
)
def c3d_source(arm: object, data: DataSpec, params: RecordingParams, path: Path) -> Recording:
    """:func:`read_c3d` of ``params.file``, then the steps of :mod:`optikin.data.readers.common`."""
    return load_recording(_read, data, params, path)
