"""Figures of a ``statics`` result, from its arrays and summary alone (``optikin plot`` redraws them).

``backbones``  up to 12 equilibrium backbones in 3-D (forward; array ``backbone``), coloured by time ``t``.
``tip``        the tip path: against time for a trajectory, else the tips in 3-D (forward ``tip_position``,
               inverse ``targets`` coloured by the solver's log10 tip error).
``time``       time per sample [ms] of every method (forward ``time``, ``time_collocation``; inverse
               ``time_<method>``).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.problems.statics.report import array_key
from optikin.results import Drawer

MM = 1e3
FLOOR = 1e-17
"""Tip errors are drawn on a log scale; exact zeros sit at this floor [m]."""


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{name: draw(path)}`` for the figures whose arrays the result has (module docstring)."""
    name = summary.get("problem", "statics")
    drawers: dict[str, Drawer] = {}
    if "backbone" in arrays:
        drawers["backbones"] = partial(
            draw_backbones, backbone=arrays["backbone"], title=f"{name}: equilibria", t=arrays.get("t")
        )
    if "tip_position" in arrays:
        drawers["tip"] = partial(
            draw_tip, tips=arrays["tip_position"], t=arrays.get("t"), title=f"{name}: tip position"
        )
    methods = [row["method"] for row in summary.get("comparison", [])]
    if "targets" in arrays and methods:
        error = arrays.get(f"tip_error_{array_key(methods[0])}")
        drawers["tip"] = partial(
            draw_tip, tips=arrays["targets"][:, :3], t=arrays.get("t"), title=f"{name}: targets", error=error
        )
    times: dict[str, np.ndarray] = {}
    if "time" in arrays and methods:
        times[methods[0]] = arrays["time"]
        if "time_collocation" in arrays:
            times["collocation"] = arrays["time_collocation"]
    for method in methods:
        if f"time_{array_key(method)}" in arrays:
            times[method] = arrays[f"time_{array_key(method)}"]
    if times:
        drawers["time"] = partial(
            draw_times,
            seconds=times,
            title=f"{name}: time per sample",
            roles={row["method"]: row.get("role", "") for row in summary.get("comparison", [])},
        )
    return drawers


def draw_backbones(path: Path, backbone: np.ndarray, title: str, t: np.ndarray | None = None) -> None:
    """Up to 12 backbones ``(N, K, 3)`` [m], coloured by time ``t`` [s] (or sample)."""
    from optikin import plots

    plots.backbones_3d(path, backbone, title, t=t)


def draw_tip(path: Path, tips: np.ndarray, t: np.ndarray | None, title: str, error: np.ndarray | None = None) -> None:
    """Tips ``(N, 3)`` [m] against time ``t`` [s], or in 3-D (coloured by log10 ``error`` when given)."""
    from optikin import plots

    if t is not None:
        plots.time_series(path, t, {"tip position": tips * MM}, "[mm]", title)
    elif error is not None:
        colour = np.log10(np.maximum(np.where(np.isfinite(error), error, 1.0), FLOOR))
        plots.scatter_3d(path, tips, title, colour=colour, colour_label="log10 tip error [m]")
    else:
        plots.scatter_3d(path, tips, title, colour=np.arange(len(tips)), colour_label="sample")


def draw_times(
    path: Path, seconds: Mapping[str, np.ndarray], title: str, roles: Mapping[str, str] | None = None
) -> None:
    """Time per sample [ms] of each method, in sample order, on a log scale, in the methods' styles."""
    from optikin import plots

    fig, axes = plots.subplots(1, 1, figsize=(8.4, 3.4))
    ax = axes[0, 0]
    styles = plots.method_styles(list(seconds), roles or None)
    for method, values in seconds.items():
        y = np.maximum(np.asarray(values, dtype=float), 1e-9) * 1e3
        ax.plot(np.arange(len(values)), y, label=method, **(plots.unmarked(styles[method]) | {"lw": 1.0}))
    ax.set_yscale("log")
    ax.set_xlabel("sample")
    ax.set_ylabel("time [ms]")
    ax.grid(alpha=0.3, which="both")
    plots.legend_outside(fig)
    ax.set_title(title)
    plots.save(fig, path)
