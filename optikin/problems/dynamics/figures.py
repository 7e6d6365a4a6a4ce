"""Figures of a ``dynamics`` result, from its arrays and summary alone (``optikin plot`` redraws them).

``tip``        the tip position against time [mm] (array ``tip_position``, ``t``).
``energy``     kinetic, elastic, gravitational and total energy against time [J] (``energy``).
``backbones``  up to 12 backbones in 3-D, coloured by time (``backbone``, ``t``).
``actuation``  the applied actuation and, where the chamber pressures lag it, the command (``actuation``,
               ``command``).
``step_time``  wall time per step [us] (``step_time``).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.results import Drawer

MM = 1e3


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{name: draw(path)}`` for the figures whose arrays the result has (module docstring)."""
    name = summary.get("problem", "dynamics")
    drawers: dict[str, Drawer] = {}
    if "tip_position" in arrays and "t" in arrays:
        drawers["tip"] = partial(draw_tip, t=arrays["t"], tips=arrays["tip_position"], title=f"{name}: tip position")
    if "energy" in arrays and "t" in arrays:
        drawers["energy"] = partial(draw_energy, t=arrays["t"], energy=arrays["energy"], title=f"{name}: energy")
    if "backbone" in arrays:
        drawers["backbones"] = partial(
            draw_backbones, backbone=arrays["backbone"], t=arrays.get("t"), title=f"{name}: backbones"
        )
    if "actuation" in arrays and arrays["actuation"].ndim == 2 and arrays["actuation"].shape[1]:
        drawers["actuation"] = partial(
            draw_actuation,
            t=arrays["t"],
            applied=arrays["actuation"],
            command=arrays.get("command"),
            title=f"{name}: actuation",
        )
    if "step_time" in arrays and len(arrays["step_time"]):
        drawers["step_time"] = partial(draw_step_time, seconds=arrays["step_time"], title=f"{name}: time per step")
    return drawers


def draw_tip(path: Path, t: np.ndarray, tips: np.ndarray, title: str) -> None:
    """Tip ``(n, 3)`` [m] against ``t`` [s], in mm."""
    from optikin import plots

    plots.time_series(path, t, {"tip position": tips * MM}, "[mm]", title)


def draw_energy(path: Path, t: np.ndarray, energy: np.ndarray, title: str) -> None:
    """The energy terms ``(n, 3)`` [J] and their sum against ``t`` [s]."""
    from optikin import plots

    fig, axes = plots.subplots(1, 1, figsize=(8.4, 3.4))
    ax = axes[0, 0]
    for k, label in enumerate(("kinetic", "elastic", "gravitational")):
        ax.plot(t, energy[:, k], lw=1.0, label=label)
    ax.plot(t, energy.sum(axis=1), lw=1.5, color="black", label="total")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("energy [J]")
    ax.grid(alpha=0.3)
    plots.legend_outside(fig)
    ax.set_title(title)
    plots.save(fig, path)


def draw_backbones(path: Path, backbone: np.ndarray, t: np.ndarray | None, title: str) -> None:
    """Up to 12 backbones ``(F, K, 3)`` [m], coloured by time."""
    from optikin import plots

    plots.backbones_3d(path, backbone, title, t=t)


def draw_actuation(path: Path, t: np.ndarray, applied: np.ndarray, command: np.ndarray | None, title: str) -> None:
    """Applied actuation ``(n, n_act)`` and, where it differs, the command, against ``t`` [s]."""
    from optikin import plots

    series = {"applied": applied}
    if command is not None and not np.array_equal(command, applied):
        series["command"] = command
    names = tuple(f"actuator {j}" for j in range(applied.shape[1]))
    plots.time_series(path, t, series, "[N or Pa]", title, labels=names)


def draw_step_time(path: Path, seconds: np.ndarray, title: str) -> None:
    """Wall time per step [us], in step order, on a log scale."""
    from optikin import plots

    fig, axes = plots.subplots(1, 1, figsize=(8.4, 3.0))
    ax = axes[0, 0]
    ax.plot(np.arange(1, len(seconds) + 1), np.maximum(seconds, 1e-9) * 1e6, lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("step")
    ax.set_ylabel("time [us]")
    ax.grid(alpha=0.3, which="both")
    ax.set_title(title)
    plots.save(fig, path)
