"""Configuration samples for an arm (data family ``configurations``): random, trajectory, sweep or CSV.

Each source is registered with :func:`~optikin.data.sources.register_source` and a
params model, and returns :class:`Configurations` (unpacked as ``Q, t``):
configurations ``(N, n_config)`` and sample times ``(N,)`` in seconds (``None`` when
the samples are not a trajectory). Every random draw uses ``data.seed``.

``random``      uniform draws inside the arm's bounds (no params).
``trajectory``  every variable a sinusoid about its mid-range (``rate``, ``amplitude``, ``frequency``).
``sweep``       one variable over its whole range, the others fixed (``variable``, ``fixed``).
``csv``         rows of a CSV file (``file``).

CSV files (:func:`read_configuration_csv`) have a header row naming the arm's
configuration variables (e.g. ``S1,theta1,phi1,S2,theta2,phi2`` in metres and radians)
and optionally a ``t`` column in seconds; other columns are ignored. The source reads
every row, or the first ``data.samples`` when the problem file gives it (the rows left
out are counted in :attr:`Configurations.skipped_rows`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np
from pydantic import Field, StrictFloat, field_validator

from optikin.arms.base import ArmModel
from optikin.data.csvread import columns_of, read_table
from optikin.data.files import data_file
from optikin.data.sources import register_source
from optikin.errors import SpecError
from optikin.options import NoOptions, Options
from optikin.spec import DataSpec

FAMILY = "configurations"


@dataclass(frozen=True)
class Configurations:
    """What a source of family ``configurations`` returns; unpacks as ``Q, t``.

    Attributes
    ----------
    values:
        Configurations ``(N, n_config)``.
    t:
        Sample times ``(N,)`` [s], or None when the samples are not a trajectory.
    skipped_rows:
        Rows of a file source left out because ``data.samples`` asked for fewer (0 otherwise).
    """

    values: np.ndarray
    t: np.ndarray | None = None
    skipped_rows: int = 0

    def __iter__(self) -> Iterator[Any]:
        return iter((self.values, self.t))


def first_rows(data: DataSpec, rows: int) -> tuple[int, int]:
    """How many of a file's ``rows`` a file source keeps, and how many it skips.

    Every row unless the problem file gives ``data.samples``; then the first ``data.samples``.
    """
    keep = min(rows, data.samples) if "samples" in data.model_fields_set else rows
    return keep, rows - keep


def skipped_rows_notes(skipped: int, params: Any) -> list[str]:
    """The note of a result whose file source skipped rows: ``["N rows of FILE skipped (data.samples)"]``,
    FILE as ``params.file`` names it; no note when none were skipped."""
    return [f"{skipped} rows of {params.file} skipped (data.samples)"] if skipped else []


class TrajectoryParams(Options):
    """``data.params`` of source ``trajectory``."""

    rate: StrictFloat = Field(100.0, gt=0, description="sample rate [Hz]")
    amplitude: StrictFloat = Field(
        0.8, ge=0, le=1, description="amplitude of every variable, as a fraction of its half range"
    )
    frequency: tuple[StrictFloat, StrictFloat] = Field(
        (0.1, 0.4), description="[low, high]: the range each variable's frequency is drawn from [Hz], 0 <= low <= high"
    )

    @field_validator("frequency")
    @classmethod
    def _ordered(cls, frequency: tuple[float, float]) -> tuple[float, float]:
        if not 0 <= frequency[0] <= frequency[1]:
            raise ValueError(f"expected [low, high] with 0 <= low <= high, got {list(frequency)}")
        return frequency


class SweepParams(Options):
    """``data.params`` of source ``sweep``."""

    variable: str | None = Field(
        None, description="the configuration variable swept over its range (default: the arm's second variable)"
    )
    fixed: dict[str, StrictFloat] = Field(
        default_factory=dict, description="values of other variables (name -> value; default mid-range)"
    )


class CsvParams(Options):
    """``data.params`` of source ``csv``."""

    file: str = Field(min_length=1, description="CSV file with a header row, relative to the problem file")


@register_source(FAMILY, "random", "uniform draws inside the arm's bounds", params=NoOptions)
def random_configurations(arm: ArmModel, data: DataSpec, params: NoOptions, path: Path) -> Configurations:
    """``data.samples`` configurations drawn uniformly inside the arm's bounds; no sample times."""
    return Configurations(arm.sample_configurations(data.samples, np.random.default_rng(data.seed)))


def smooth_motion(arm: ArmModel, samples: int, seed: int, params: TrajectoryParams) -> tuple[np.ndarray, np.ndarray]:
    """A smooth motion through the arm's range.

    Every variable is a sinusoid about its mid-range, ``params.amplitude`` times its
    half range, with a frequency drawn uniformly from ``params.frequency`` and a phase
    from ``[-pi, pi)``, sampled at ``params.rate``.

    Parameters
    ----------
    arm:
        The arm (bounds ``lower``, ``upper``).
    samples, seed:
        Number of samples and the seed of the draws.
    params:
        Rate [Hz], amplitude (fraction of the half range) and frequency range [Hz].

    Returns
    -------
    Q, t:
        Configurations ``(samples, n_config)`` and times ``(samples,)`` [s] from 0.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(samples) / params.rate
    low, high = params.frequency
    freq = rng.uniform(low, high, arm.n_config)
    phase = rng.uniform(-np.pi, np.pi, arm.n_config)
    mid, half = 0.5 * (arm.lower + arm.upper), 0.5 * (arm.upper - arm.lower)
    Q = mid + params.amplitude * half * np.sin(2 * np.pi * freq * t[:, None] + phase)
    return Q, t


@register_source(
    FAMILY, "trajectory", "a smooth sinusoidal motion about mid-range, sampled in time", params=TrajectoryParams
)
def smooth_trajectory(arm: ArmModel, data: DataSpec, params: TrajectoryParams, path: Path) -> Configurations:
    """:func:`smooth_motion` with ``data.samples`` samples from ``data.seed``."""
    return Configurations(*smooth_motion(arm, data.samples, data.seed, params))


@register_source(FAMILY, "sweep", "one variable over its whole range, the others held fixed", params=SweepParams)
def sweep(arm: ArmModel, data: DataSpec, params: SweepParams, path: Path) -> Configurations:
    """One variable swept linearly from its lower to its upper bound, the others at ``fixed`` or mid-range.

    Raises
    ------
    SpecError
        ``data.params.variable`` or a key of ``data.params.fixed`` is not a variable of the arm.
    """
    name = arm.config_names[1] if params.variable is None else params.variable
    if name not in arm.config_names:
        raise SpecError(
            str(path),
            "data.params.variable",
            f"{name!r} is not a variable of {arm.name}; known: {', '.join(arm.config_names)}",
        )
    q = 0.5 * (arm.lower + arm.upper)
    for key, value in params.fixed.items():
        if key not in arm.config_names:
            raise SpecError(str(path), f"data.params.fixed.{key}", f"not a variable of {arm.name}")
        q[arm.config_names.index(key)] = float(value)
    j = arm.config_names.index(name)
    Q = np.tile(q, (data.samples, 1))
    Q[:, j] = np.linspace(arm.lower[j], arm.upper[j], data.samples)
    return Configurations(Q)


@register_source(
    FAMILY, "csv", "configurations read from a CSV file (one column per variable, optional t)", params=CsvParams
)
def configurations_from_csv(arm: ArmModel, data: DataSpec, params: CsvParams, path: Path) -> Configurations:
    """The rows of ``params.file`` (relative to the problem file's folder): all of them, or the first
    ``data.samples`` when the problem file gives it (:func:`first_rows`)."""
    csv_path = data_file(path, params.file)
    Q, t = read_configuration_csv(csv_path, arm.config_names)
    keep, skipped = first_rows(data, len(Q))
    return Configurations(Q[:keep], None if t is None else t[:keep], skipped)


def read_configuration_csv(csv_path: Path, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray | None]:
    """Columns ``names`` (and ``t`` if present) of a CSV file with a header row.

    The format (:mod:`optikin.data.csvread` for what every reader refuses):

    ================  ======================================================================
    ``names``         one column per configuration variable, in the arm's units (lengths in
                      metres, angles in radians); any number, NaN and infinities included:
                      the kind checks them against the arm's bounds and names the sample
    ``t``             optional: sample time in seconds, finite and strictly increasing
    other columns     ignored
    ================  ======================================================================

    Parameters
    ----------
    csv_path:
        The file.
    names:
        The columns wanted, in order.

    Returns
    -------
    values, t:
        ``(rows, len(names))`` and the ``t`` column ``(rows,)`` [s], or None without one.

    Raises
    ------
    InputDataError
        Naming the file, the row (``sample`` from 0, and its line) and the column: the file
        cannot be read or is refused (not a regular file, over 200 MiB, binary, not UTF-8),
        is empty, lacks a column, has no data rows, a short row or a cell that is not a
        number; ``t`` is not finite or does not increase strictly.
    """
    source = str(csv_path)
    table = read_table(csv_path, columns_of(source, names, optional=("t",), finite=("t",)))
    if "t" not in table.columns:
        return table.stacked(names), None
    table.check_increasing("t")
    return table.stacked(names), table.column("t")
