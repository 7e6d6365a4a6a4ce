"""A plain CSV file whose columns the problem file maps to markers, rigid bodies, IMUs and actuators.

The file is what :mod:`optikin.data.csvread` reads (a header row, one row per frame,
decimal numbers; its refusals: not a regular file, over 200 MiB, binary, not UTF-8).
The problem file says which column is what::

    data:
      source: csv
      params:
        file: trunk.csv
        frame: {up: y}
        units: mm
        time: t
        marker_columns: {disk1: [d1_x, d1_y, d1_z]}
        body_columns: {disk1: {position: [b1_x, b1_y, b1_z], quaternion: [b1_qw, b1_qx, b1_qy, b1_qz]}}
        actuator_columns: {tendon1: {column: l1_mm, scale: 0.001}}

A missing marker or body is written ``nan`` in its cells (noted per frame, dropped
unless ``drop_incomplete: false``); time, actuator and IMU cells must be finite, times
must increase strictly, quaternions (``w, x, y, z``) be within 1e-3 of unit length
(then normalised). A steady-state file (postures, no time column) is read with ``time: null``:
its rows are numbered 0, 1, 2, ... as their times. Other columns are ignored. Errors name the file, the row
(``sample``, data rows from 0; the message gives the line) and the column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field, model_validator

from optikin.data.csvread import columns_of, read_table
from optikin.data.readers.common import FAMILY, RecordingParams, finish, load_recording, normalised_quaternions
from optikin.data.recording import ImuTrack, Recording, RigidBodyTrack
from optikin.data.sources import register_source
from optikin.options import Options
from optikin.spec import DataSpec


class BodyColumns(Options):
    """The columns of one rigid body."""

    position: tuple[str, str, str] = Field(description="x, y, z columns [file units]")
    quaternion: tuple[str, str, str, str] = Field(description="w, x, y, z columns (unit quaternion)")


class ActuatorColumn(Options):
    """One actuator channel: its column and the factor to SI."""

    column: str = Field(description="the column")
    scale: float = Field(1.0, description="SI units per file unit (0.001 for a length in mm)")


class ImuColumns(Options):
    """The columns of one IMU, sampled on the file's time column."""

    angular_velocity: tuple[str, str, str] = Field(description="x, y, z columns [rad/s]")
    linear_acceleration: tuple[str, str, str] = Field(description="x, y, z columns [m/s^2]")
    orientation: tuple[str, str, str, str] | None = Field(None, description="w, x, y, z columns, if any")


class PlainCsvParams(RecordingParams):
    """``data.params`` of source ``csv`` (family ``recordings``): the file and its column mapping."""

    time: str | None = Field(
        "t",
        description="the time column; null: a steady-state file without one, its rows postures whose times are "
        "their numbers 0, 1, 2, ... (no IMU columns then)",
    )
    time_scale: float = Field(1.0, gt=0, description="seconds per unit of the time column (0.001 for ms)")
    marker_columns: dict[str, tuple[str, str, str]] = Field(
        default_factory=dict, description="marker name -> its x, y, z columns"
    )
    body_columns: dict[str, BodyColumns] = Field(default_factory=dict, description="rigid body name -> its columns")
    imu_columns: dict[str, ImuColumns] = Field(default_factory=dict, description="IMU name -> its columns")
    actuator_columns: dict[str, ActuatorColumn | str] = Field(
        default_factory=dict, description="channel name -> its column (SI), or column and scale"
    )

    @model_validator(mode="after")
    def _imu_needs_time(self) -> PlainCsvParams:
        if self.time is None and self.imu_columns:
            raise ValueError("imu_columns need a time column: give time")
        return self


def read_plain_csv(path: str | Path, params: PlainCsvParams) -> Recording:
    """Read a CSV file with the column mapping of ``params`` into a :class:`Recording`.

    Parameters
    ----------
    path:
        The file.
    params:
        The mapping, ``frame`` and ``units`` (default metres).

    Returns
    -------
    Recording
        In SI and optikin's base frame, frames numbered by data row, with notes for time
        gaps, NaN cells and label swaps.

    Raises
    ------
    InputDataError
        Naming the file, row and column (module docstring).
    """
    source = str(path)
    actuators = {
        name: (spec, 1.0) if isinstance(spec, str) else (spec.column, spec.scale)
        for name, spec in params.actuator_columns.items()
    }
    nan_allowed = [c for cols in params.marker_columns.values() for c in cols]
    nan_allowed += [c for b in params.body_columns.values() for c in (*b.position, *b.quaternion)]
    finite = ([params.time] if params.time is not None else []) + [c for c, _ in actuators.values()]
    for imu in params.imu_columns.values():
        finite += [*imu.angular_velocity, *imu.linear_acceleration, *(imu.orientation or ())]
    names = list(dict.fromkeys(finite + nan_allowed))
    table = read_table(path, lambda header: (columns_of(source, names)(header)[0], finite))
    if params.time is not None:
        table.check_increasing(params.time)

    def where(row: int) -> tuple[int, str]:
        return row, f" (line {int(table.lines[row])})"

    bodies = {}
    for name, cols in params.body_columns.items():
        position = table.stacked(cols.position)
        quaternion = table.stacked(cols.quaternion)
        missing = np.isnan(position).any(axis=1) | np.isnan(quaternion).any(axis=1)
        position[missing], quaternion[missing] = np.nan, np.nan
        q = normalised_quaternions(quaternion, source, ", ".join(cols.quaternion), where)
        bodies[name] = RigidBodyTrack(position, q)
    markers = {}
    for name, xyz in params.marker_columns.items():
        block = table.stacked(xyz)
        block[np.isnan(block).any(axis=1)] = np.nan
        markers[name] = block
    time = np.arange(len(table), dtype=float) if params.time is None else table.column(params.time) * params.time_scale
    imus = {}
    for name, imu in params.imu_columns.items():
        orientation = None
        if imu.orientation is not None:
            orientation = normalised_quaternions(
                table.stacked(imu.orientation), source, ", ".join(imu.orientation), where
            )
        imus[name] = ImuTrack(
            time, table.stacked(imu.angular_velocity), table.stacked(imu.linear_acceleration), orientation
        )
    raw = Recording(
        time,
        markers=markers,
        bodies=bodies,
        imu=imus,
        actuators={name: table.column(column) * scale for name, (column, scale) in actuators.items()},
        source=source,
    )
    return finish(raw, params.frame, params.units or "m", numbered=False)


def _read(path: Path, params: PlainCsvParams) -> Recording:
    return read_plain_csv(path, params)


@register_source(FAMILY, "csv", "a plain CSV file with a column mapping in data.params", params=PlainCsvParams)
def csv_source(arm: object, data: DataSpec, params: PlainCsvParams, path: Path) -> Recording:
    """:func:`read_plain_csv` of ``params.file``, then the steps of :mod:`optikin.data.readers.common`."""
    return load_recording(_read, data, params, path)
