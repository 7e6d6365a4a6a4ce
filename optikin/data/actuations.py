"""Actuation samples of a Cosserat arm (data family ``actuations``), or tip targets for inverse statics.

Each source is registered with :func:`~optikin.data.sources.register_source` and
returns :class:`Actuations`: tendon tensions [N] and chamber pressures [Pa], one
column per actuator of the arm (:attr:`optikin.arms.cosserat.CosseratArm.config_names`,
``tendons.i`` / ``chambers.i`` as numbered in ``arm.params``), or, for
``target_csv``, tip targets. The ``statics`` kind checks every actuation against the
arm's bounds (a negative tension is an error naming the sample and the tendon).

``trajectory``  every actuator a sinusoid about its mid-range, sampled in time
                (:class:`~optikin.data.configurations.TrajectoryParams`; seeded).
``random``      uniform draws inside the bounds (seeded).
``grid``        a full grid over some actuators (:class:`GridParams`), the others fixed, in order.
``csv``         rows of a CSV file, one column per actuator, optional ``t`` (:class:`CsvParams`).
``target_csv``  inverse statics only: tip targets read from a CSV file (``x, y, z`` [m], plus
                ``qw, qx, qy, qz`` for poses, optional ``t``; :func:`optikin.data.targets.read_target_csv`).
``cosserat``    inverse statics only: tip targets of the Cosserat-rod CBHA along its pressure motion,
                optionally measured by a depth camera (registered by :mod:`optikin.data.cosserat_sensors`).

A file source reads every row, or the first ``data.samples`` when the problem file
gives it (the rows left out counted in :attr:`Actuations.skipped_rows`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, StrictBool, StrictFloat, StrictInt

from optikin.arms.base import ArmModel
from optikin.data.configurations import TrajectoryParams, first_rows, read_configuration_csv, smooth_motion
from optikin.data.csvread import UNIT_METRES
from optikin.data.files import data_file
from optikin.data.recording import FrameOptions
from optikin.data.sources import register_source
from optikin.data.targets import from_file_frame, read_target_csv
from optikin.errors import SpecError
from optikin.options import NoOptions, Options
from optikin.spec import DataSpec

FAMILY = "actuations"
"""The data family of the ``statics`` kind."""
MAX_GRID = 10_000_000
"""Most samples a ``grid`` may have (the limit of ``data.samples``)."""


@dataclass(frozen=True)
class Actuations:
    """What a source of family ``actuations`` returns.

    Attributes
    ----------
    values:
        ``(N, n_actuators)`` tensions [N] and pressures [Pa], or None for targets read from a file.
    targets:
        ``(N, 3)`` tip positions [m] or ``(N, 8)`` unit dual quaternions (``target_csv``), else None.
    t:
        Sample times ``(N,)`` [s], or None.
    trajectory:
        Whether the samples are a sequence to be solved in order, each warm-started from the last.
    skipped_rows:
        Rows of a file source left out because ``data.samples`` asked for fewer.
    """

    values: np.ndarray | None
    targets: np.ndarray | None = None
    t: np.ndarray | None = None
    trajectory: bool = False
    skipped_rows: int = 0

    def __len__(self) -> int:
        data = self.values if self.values is not None else self.targets
        assert data is not None
        return len(data)


class GridParams(Options):
    """``data.params`` of source ``grid``."""

    actuators: list[str] | None = Field(
        None, description="the actuators on the grid (names tendons.i / chambers.i); default every actuator"
    )
    points: StrictInt | None = Field(
        None, ge=2, description="values per actuator, from its lower to its upper bound; default data.samples^(1/k)"
    )
    fixed: dict[str, StrictFloat] = Field(
        default_factory=dict, description="values of the actuators not on the grid (default their lower bound)"
    )


class CsvParams(Options):
    """``data.params`` of source ``csv`` (and the base of ``target_csv``'s)."""

    file: str = Field(min_length=1, description="CSV file with a header row, relative to the problem file")
    trajectory: StrictBool = Field(
        True, description="solve the rows in order, each warm-started from the previous solution"
    )


class TargetCsvParams(CsvParams):
    """``data.params`` of source ``target_csv``: a target file, its length unit and its axes."""

    units: Literal["m", "cm", "mm"] = Field("m", description="length unit of the file's positions")
    frame: FrameOptions = Field(
        default_factory=FrameOptions,
        description="axes of the file's frame (frame: {up: y} for a y-up recording), converted to optikin's z-up "
        "frame as a recording's (optikin.data.recording)",
    )


@register_source(
    FAMILY, "trajectory", "a smooth sinusoidal actuation about mid-range, sampled in time", params=TrajectoryParams
)
def actuation_trajectory(arm: ArmModel, data: DataSpec, params: TrajectoryParams, path: Path) -> Actuations:
    """:func:`~optikin.data.configurations.smooth_motion` over the actuation bounds, ``data.samples`` samples."""
    values, t = smooth_motion(arm, data.samples, data.seed, params)
    return Actuations(values, t=t, trajectory=True)


@register_source(FAMILY, "random", "uniform draws inside the actuation bounds", params=NoOptions)
def random_actuations(arm: ArmModel, data: DataSpec, params: NoOptions, path: Path) -> Actuations:
    """``data.samples`` actuations drawn uniformly inside the bounds from ``data.seed``."""
    return Actuations(arm.sample_configurations(data.samples, np.random.default_rng(data.seed)))


@register_source(FAMILY, "grid", "a full grid over some actuators, the others fixed", params=GridParams)
def grid_actuations(arm: ArmModel, data: DataSpec, params: GridParams, path: Path) -> Actuations:
    """Every combination of ``points`` values per listed actuator (row-major, the last actuator fastest).

    Raises
    ------
    SpecError
        ``data.params.actuators.i`` or a key of ``data.params.fixed`` is not an actuator of the arm.
    """
    names = list(arm.config_names)
    chosen = names if params.actuators is None else params.actuators
    for i, name in enumerate(chosen):
        if name not in names:
            raise SpecError(str(path), f"data.params.actuators.{i}", f"{name!r} is not an actuator; known: {names}")
    base = arm.lower.copy()
    for key, value in params.fixed.items():
        if key not in names:
            raise SpecError(str(path), f"data.params.fixed.{key}", f"not an actuator; known: {names}")
        base[names.index(key)] = value
    points = params.points or max(2, int(np.floor(data.samples ** (1.0 / max(len(chosen), 1)) + 1e-9)))
    columns = [names.index(n) for n in chosen]
    if points ** len(columns) > MAX_GRID:
        raise SpecError(str(path), "data.params.points", f"{points}^{len(columns)} grid points, more than {MAX_GRID:,}")
    axes = [np.linspace(arm.lower[j], arm.upper[j], points) for j in columns]
    values = np.tile(base, (points ** len(columns), 1))
    for row, combination in enumerate(itertools.product(*axes)):
        values[row, columns] = combination
    return Actuations(values, trajectory=True)


@register_source(
    FAMILY, "csv", "actuations read from a CSV file (one column per actuator, optional t)", params=CsvParams
)
def csv_actuations(arm: ArmModel, data: DataSpec, params: CsvParams, path: Path) -> Actuations:
    """The rows of ``params.file`` (relative to the problem file), columns named like the actuators.

    The format is :func:`optikin.data.configurations.read_configuration_csv` with the
    actuator names as columns (tensions in N, pressures in Pa).
    """
    values, t = read_configuration_csv(data_file(path, params.file), arm.config_names)
    keep, skipped = first_rows(data, len(values))
    return Actuations(
        values[:keep], t=None if t is None else t[:keep], trajectory=params.trajectory, skipped_rows=skipped
    )


@register_source(
    FAMILY,
    "target_csv",
    "inverse statics: tip targets read from a CSV file (x, y, z [, qw, qx, qy, qz] [, t])",
    params=TargetCsvParams,
)
def csv_targets(
    arm: ArmModel, data: DataSpec, params: TargetCsvParams, path: Path, kind: str = "position"
) -> Actuations:
    """Tip targets of ``params.file`` (:func:`optikin.data.targets.read_target_csv`), ``kind`` ``position`` or
    ``pose``, in metres and optikin's axes (``params.units``, ``params.frame``)."""
    targets, t = read_target_csv(data_file(path, params.file), kind, scale=UNIT_METRES[params.units])
    try:
        targets = from_file_frame(targets, kind, None, params.frame)
    except ValueError as exc:
        raise SpecError(str(path), "data.params.frame", str(exc)) from None
    keep, skipped = first_rows(data, len(targets))
    return Actuations(
        None,
        targets=targets[:keep],
        t=None if t is None else t[:keep],
        trajectory=params.trajectory,
        skipped_rows=skipped,
    )
