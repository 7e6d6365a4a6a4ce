"""Data family ``actuation_commands``: the actuation and tip force of a ``dynamics`` run, as functions of time.

Every source gives the values at rest before the run (``t <= 0``, the start equilibrium) and
at the time of every step. Actuation vectors have one entry per actuator of the arm
(:attr:`optikin.physics.RodArm.actuator_names`; tendon tensions [N], chamber pressures [Pa]);
``None`` means zeros.

``step``  ``initial`` until ``at``, then ``final`` (the tip force likewise): a release when
          ``tip_force_initial`` is set and ``tip_force_final`` is zero.
``ramp``  linear from ``initial`` at ``at`` to ``final`` at ``at + duration``.
``sine``  ``mean + amplitude sin(2 pi f t + phase)``, the tip force constant.
``csv``   a recorded command file: a ``t`` column [s] (strictly increasing) and one column per
          actuator named like the arm's configuration (``tendons.0``, ``chambers.1``), linear
          between its rows, its first row before them (and at rest), its last after them; the
          tip force constant.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, StrictFloat

from optikin.data.configurations import read_configuration_csv
from optikin.data.files import data_file
from optikin.data.sources import register_source
from optikin.errors import InputDataError
from optikin.options import Options

FAMILY = "actuation_commands"

Vector3 = tuple[StrictFloat, StrictFloat, StrictFloat]


@dataclass(frozen=True)
class Commands:
    """Actuation and tip force as functions of time.

    Attributes
    ----------
    kind : str
        The source.
    initial_actuation, initial_tip_force : numpy.ndarray
        At rest before the run, ``(n_act,)`` and ``(3,)``.
    params : Options
        The source's parameters.
    table : tuple of numpy.ndarray, optional
        ``csv``: the file's times ``(R,)`` and actuation ``(R, n_act)``.
    """

    kind: str
    initial_actuation: np.ndarray
    initial_tip_force: np.ndarray
    params: Any
    table: tuple[np.ndarray, np.ndarray] | None = None

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(actuation (T, n_act), tip force (T, 3))`` at the times ``t (T,)`` [s]."""
        t = np.asarray(t, dtype=float)[:, None]
        p = self.params
        a0, f0 = self.initial_actuation[None, :], self.initial_tip_force[None, :]
        if self.table is not None:
            times, values = self.table
            actuation = np.column_stack([np.interp(t[:, 0], times, values[:, j]) for j in range(values.shape[1])])
            return actuation.reshape(t.shape[0], values.shape[1]), np.repeat(f0, t.shape[0], axis=0)
        if self.kind == "sine":
            wave = np.sin(2 * np.pi * p.frequency * t + p.phase)
            return a0 + np.asarray(p.amplitude, dtype=float)[None, :] * wave, np.repeat(f0, t.shape[0], axis=0)
        a1 = np.asarray(p.final if p.final is not None else self.initial_actuation, dtype=float)[None, :]
        f1 = np.asarray(p.tip_force_final if p.tip_force_final is not None else p.tip_force_initial)[None, :]
        if self.kind == "step":
            share = (t >= p.at).astype(float)
        else:
            share = np.clip((t - p.at) / p.duration, 0.0, 1.0)
        return a0 + share * (a1 - a0), f0 + share * (f1 - f0)


class StepParams(Options):
    """``data.params`` of source ``step``."""

    initial: list[StrictFloat] | None = Field(None, description="actuation at rest before the run; None: zeros")
    final: list[StrictFloat] | None = Field(None, description="actuation from time at; None: the initial one")
    at: StrictFloat = Field(0.0, ge=0, description="time of the step [s] (0: from the first step)")
    tip_force_initial: Vector3 = Field((0.0, 0.0, 0.0), description="tip force at rest, base frame [N]")
    tip_force_final: Vector3 | None = Field(None, description="tip force from time at [N]; None: the initial one")


class RampParams(StepParams):
    """``data.params`` of source ``ramp``."""

    duration: StrictFloat = Field(gt=0, description="duration of the ramp [s]")


class SineParams(Options):
    """``data.params`` of source ``sine``."""

    mean: list[StrictFloat] | None = Field(None, description="mean actuation (and the value at rest); None: zeros")
    amplitude: list[StrictFloat] = Field(description="amplitude per actuator")
    frequency: StrictFloat = Field(gt=0, description="frequency [Hz]")
    phase: StrictFloat = Field(0.0, description="phase [rad]")
    tip_force_initial: Vector3 = Field((0.0, 0.0, 0.0), description="constant tip force [N]")


class CsvCommandParams(Options):
    """``data.params`` of source ``csv``."""

    file: str = Field(
        min_length=1, description="CSV file with a t column and one per actuator, relative to the problem"
    )
    tip_force: Vector3 = Field((0.0, 0.0, 0.0), description="constant tip force, base frame [N]")


def _vector(values: list[float] | None, n: int, field: str, path: Path) -> np.ndarray:
    if values is None:
        return np.zeros(n)
    out = np.asarray(values, dtype=float)
    if out.shape != (n,):
        raise InputDataError(f"give one value per actuator ({n}), got {out.size}", source=str(path), field=field)
    return out


def _actuators(arm: Any) -> int:
    return len(arm.rod_arm.actuator_names)


def _analytic(name: str, arm: Any, params: Any, path: Path, start: str, other: str) -> Commands:
    """The commands of an analytic source: the actuation at rest is ``params.<start>``, and both it and
    ``params.<other>`` hold one value per actuator of ``arm`` (else an error naming the field)."""
    n = _actuators(arm)
    _vector(getattr(params, other), n, f"data.params.{other}", path)
    at_rest = _vector(getattr(params, start), n, f"data.params.{start}", path)
    return Commands(name, at_rest, np.asarray(params.tip_force_initial, dtype=float), params)


@register_source(FAMILY, "step", "actuation and tip force stepping from their values at rest", params=StepParams)
def step_commands(arm: Any, data: Any, params: StepParams, path: Path) -> Commands:
    """Source ``step``: ``initial`` until ``at``, then ``final`` (the tip force likewise)."""
    return _analytic("step", arm, params, path, start="initial", other="final")


@register_source(
    FAMILY, "ramp", "actuation and tip force ramping linearly from their values at rest", params=RampParams
)
def ramp_commands(arm: Any, data: Any, params: RampParams, path: Path) -> Commands:
    """Source ``ramp``: linear from ``initial`` at ``at`` to ``final`` at ``at + duration``."""
    return _analytic("ramp", arm, params, path, start="initial", other="final")


@register_source(FAMILY, "sine", "a sinusoidal actuation about its mean", params=SineParams)
def sine_commands(arm: Any, data: Any, params: SineParams, path: Path) -> Commands:
    """Source ``sine``: ``mean + amplitude sin(2 pi frequency t + phase)``, the tip force constant."""
    return _analytic("sine", arm, params, path, start="mean", other="amplitude")


@register_source(
    FAMILY,
    "csv",
    "recorded actuation commands (a t column and one per actuator), linear between rows",
    params=CsvCommandParams,
)
def csv_commands(arm: Any, data: Any, params: CsvCommandParams, path: Path) -> Commands:
    """Source ``csv``: the file's commands, interpolated linearly in time (module docstring).

    Raises
    ------
    InputDataError
        Naming the file: no ``t`` column (the format and the checks of every value:
        :func:`optikin.data.configurations.read_configuration_csv`).
    """
    file = data_file(path, params.file)
    values, t = read_configuration_csv(file, tuple(arm.config_names))
    if t is None:
        raise InputDataError("a command file needs a t column [s]", source=str(file), field="t")
    return Commands("csv", values[0].copy(), np.asarray(params.tip_force, dtype=float), params, (t, values))
