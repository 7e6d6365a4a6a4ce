"""Configuration samples for an arm: random, smooth trajectory, one-variable sweep, or a CSV file.

Each source takes the arm, the problem file's ``data`` section and the problem
file's path, and returns ``(Q, t)``: configurations ``(N, n_config)`` and
sample times ``(N,)`` (``None`` when the samples are not a trajectory).
Every random draw uses ``data.seed``.

CSV files have a header row naming the arm's configuration variables (e.g.
``S1,theta1,phi1,S2,theta2,phi2`` in metres and radians) and optionally a
``t`` column in seconds; other columns are ignored.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Callable

import numpy as np

from optikin.arms.base import ArmModel
from optikin.errors import InputDataError, SpecError
from optikin.registry import Registry
from optikin.spec import DataSpec

ConfigurationSource = Callable[[ArmModel, DataSpec, Path], tuple[np.ndarray, np.ndarray | None]]
CONFIGURATION_SOURCES: Registry[ConfigurationSource] = Registry("configuration source")


def _params(data: DataSpec, path: Path, allowed: dict[str, object]) -> dict[str, object]:
    for key in data.params:
        if key not in allowed:
            raise SpecError(path, f"data.params.{key}",
                            f"unknown parameter of source {data.source!r}; known: {', '.join(allowed) or 'none'}")
    return {**allowed, **data.params}


@CONFIGURATION_SOURCES.register("random")
def random_configurations(arm: ArmModel, data: DataSpec, path: Path):
    """Uniform draws inside the arm's bounds."""
    _params(data, path, {})
    return arm.sample_configurations(data.samples, np.random.default_rng(data.seed)), None


@CONFIGURATION_SOURCES.register("trajectory")
def smooth_trajectory(arm: ArmModel, data: DataSpec, path: Path):
    """A smooth motion: every variable a sinusoid about its mid-range with a random frequency and phase.

    params: ``rate`` (Hz, default 100), ``amplitude`` (fraction of the half range, default 0.8),
    ``frequency`` (``[low, high]`` Hz, default ``[0.1, 0.4]``).
    """
    p = _params(data, path, {"rate": 100.0, "amplitude": 0.8, "frequency": [0.1, 0.4]})
    rate, amplitude = float(p["rate"]), float(p["amplitude"])
    low, high = (float(f) for f in p["frequency"])
    if rate <= 0:
        raise SpecError(path, "data.params.rate", "must be positive")
    if not 0 <= amplitude <= 1:
        raise SpecError(path, "data.params.amplitude", "must be within [0, 1]")
    rng = np.random.default_rng(data.seed)
    t = np.arange(data.samples) / rate
    freq = rng.uniform(low, high, arm.n_config)
    phase = rng.uniform(-np.pi, np.pi, arm.n_config)
    mid, half = 0.5 * (arm.lower + arm.upper), 0.5 * (arm.upper - arm.lower)
    Q = mid + amplitude * half * np.sin(2 * np.pi * freq * t[:, None] + phase)
    return Q, t


@CONFIGURATION_SOURCES.register("sweep")
def sweep(arm: ArmModel, data: DataSpec, path: Path):
    """One variable swept over its whole range, the others held at ``fixed`` (default: mid-range).

    params: ``variable`` (a configuration name), ``fixed`` (mapping name -> value).
    """
    p = _params(data, path, {"variable": arm.config_names[1], "fixed": {}})
    name = p["variable"]
    if name not in arm.config_names:
        raise SpecError(path, "data.params.variable",
                        f"{name!r} is not a variable of {arm.name}; known: {', '.join(arm.config_names)}")
    q = 0.5 * (arm.lower + arm.upper)
    for key, value in dict(p["fixed"]).items():
        if key not in arm.config_names:
            raise SpecError(path, f"data.params.fixed.{key}", f"not a variable of {arm.name}")
        q[arm.config_names.index(key)] = float(value)
    j = arm.config_names.index(name)
    Q = np.tile(q, (data.samples, 1))
    Q[:, j] = np.linspace(arm.lower[j], arm.upper[j], data.samples)
    return Q, None


@CONFIGURATION_SOURCES.register("csv")
def configurations_from_csv(arm: ArmModel, data: DataSpec, path: Path):
    """Read configurations from a CSV file (``params.file``, relative to the problem file)."""
    p = _params(data, path, {"file": None})
    if not p["file"]:
        raise SpecError(path, "data.params.file", "required by source 'csv'")
    csv_path = (Path(path).parent / str(p["file"])).resolve()
    Q, t = read_configuration_csv(csv_path, arm.config_names)
    return Q[: data.samples], (None if t is None else t[: data.samples])


def read_configuration_csv(csv_path: Path, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray | None]:
    """Columns ``names`` (and ``t`` if present) of a CSV file with a header row."""
    try:
        with open(csv_path, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise InputDataError(f"cannot read: {exc.strerror or exc}", source=str(csv_path)) from None
    if not rows:
        raise InputDataError("empty file", source=str(csv_path))
    header = [h.strip() for h in rows[0]]
    missing = [n for n in names if n not in header]
    if missing:
        raise InputDataError(f"missing column(s) {', '.join(missing)}; header is {', '.join(header)}",
                             source=str(csv_path))
    wanted = list(names) + (["t"] if "t" in header else [])
    index = [header.index(n) for n in wanted]
    values = np.empty((len(rows) - 1, len(wanted)))
    for i, row in enumerate(rows[1:]):
        for k, j in enumerate(index):
            try:
                values[i, k] = float(row[j])
            except (IndexError, ValueError):
                cell = row[j] if j < len(row) else "<missing>"
                raise InputDataError(f"{cell!r} is not a number", source=str(csv_path), sample=i,
                                     field=wanted[k]) from None
    if len(values) == 0:
        raise InputDataError("no data rows", source=str(csv_path))
    t = values[:, len(names)] if "t" in wanted else None
    return values[:, : len(names)], t
