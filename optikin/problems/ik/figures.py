"""Figures of an ``ik`` result, drawn from its arrays and summary alone (so ``optikin plot`` redraws them).

``targets``
    the target positions (or, for leg targets, the tips of the solved configurations),
    coloured by the solver's log10 residual;
``trajectory``
    the solver's residual and error along a trajectory;
``comparison``
    per method, the tip errors, the median time per solve with its share of ``ok``
    samples and, on a CBHA, the smallest leg margins to Table I.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.ticker import NullFormatter

from optikin import plots
from optikin.algebra import dq_translation
from optikin.problems.ik.report import array_key
from optikin.results import SOLVED, Drawer

FLOOR = 1e-17
"""Tip errors are drawn on a log scale; exact zeros sit at this floor [m]."""


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """The figures whose arrays are present: ``targets``, ``trajectory``, ``comparison`` (module docstring)."""
    name, solver = summary["problem"], summary["solver"]
    residual = arrays.get(f"residual_{array_key(solver)}")
    drawers: dict[str, Drawer] = {}
    if residual is not None and ("solution_tips" in arrays or "targets" in arrays):
        tips: np.ndarray | None
        if "solution_tips" in arrays:
            tips, title = arrays["solution_tips"], f"{name}: tips of the solved configurations ({solver})"
        elif "measured_points" in arrays:
            tips, title = arrays["measured_points"].reshape(-1, 3), f"{name}: measured points ({solver})"
        else:
            tips, title = target_positions(arrays["targets"]), f"{name}: targets ({solver})"
        if tips is not None:
            colours = np.repeat(residual, len(tips) // len(residual))  # one per measured point of a sample
            drawers["targets"] = partial(draw_targets, tips=tips, residual=colours, title=title)
    if residual is not None and "t" in arrays and "error" in arrays:
        drawers["trajectory"] = partial(
            draw_trajectory,
            t=arrays["t"],
            residual=residual,
            error=arrays["error"],
            title=f"{name}: along the trajectory",
        )
    methods = [row["method"] for row in summary.get("comparison", []) if f"status_{array_key(row['method'])}" in arrays]
    keys = [array_key(m) for m in methods]
    error = "rms_distance" if all(f"rms_distance_{k}" in arrays for k in keys) else "tip_error"
    if methods and all(f"{what}_{k}" in arrays for k in keys for what in (error, "time", "status")):
        margins = (
            {m: arrays[f"leg_margin_{k}"] for m, k in zip(methods, keys)}
            if all(f"leg_margin_{k}" in arrays for k in keys)
            else None
        )
        drawers["comparison"] = partial(
            draw_comparison,
            title=name,
            errors={m: arrays[f"{error}_{k}"] for m, k in zip(methods, keys)},
            error_label="RMS point distance [m]" if error == "rms_distance" else "tip error [m] (fk_dq of the answer)",
            seconds={m: arrays[f"time_{k}"] for m, k in zip(methods, keys)},
            status={m: arrays[f"status_{k}"] for m, k in zip(methods, keys)},
            margins=margins,
        )
    return drawers


def target_positions(targets: np.ndarray) -> np.ndarray | None:
    """Positions ``(N, 3)`` [m] of position ``(N, 3)`` or dual-quaternion ``(N, 8)`` targets; None otherwise."""
    if targets.ndim == 2 and targets.shape[1] == 3:
        return targets
    if targets.ndim == 2 and targets.shape[1] == 8:
        return dq_translation(targets)
    return None


def draw_targets(path: Path, tips: np.ndarray, residual: np.ndarray, title: str) -> None:
    """Points ``tips (N, 3)`` [m] coloured by ``log10 residual``."""
    colour = np.log10(np.maximum(residual, 1e-18))
    plots.scatter_3d(path, tips, title, colour=colour, colour_label="log10 solver residual (units of r)")


def draw_trajectory(path: Path, t: np.ndarray, residual: np.ndarray, error: np.ndarray, title: str) -> None:
    """The solver's residual ``norm(r(q))`` (units of its residual ``r``) and the error [mm] against time ``t`` [s]."""
    series = {"solver residual": residual[:, None], "error (fk check)": error[:, None] * 1e3}
    units = {"solver residual": "[units of r]", "error (fk check)": "[mm]"}
    plots.time_series(path, t, series, units, title, labels=("",))


def draw_comparison(
    path: Path,
    title: str,
    errors: Mapping[str, np.ndarray],
    seconds: Mapping[str, np.ndarray],
    status: Mapping[str, np.ndarray],
    margins: Mapping[str, np.ndarray] | None = None,
    error_label: str = "tip error [m] (fk_dq of the answer)",
) -> None:
    """Per method: the distribution of tip errors (or RMS point distances) [m], the median time per solve
    [us] with the share of solved samples and, when ``margins`` are given, the smallest leg margins to
    Table I [mm]. Methods that were not applicable have no arrays and are left out."""
    names = list(errors)
    panels = 3 if margins is not None else 2
    fig, grid = plots.subplots(1, panels, figsize=(4.6 * panels + 1.6, 0.45 * len(names) + 2.2), sharey=True)
    axes = grid[0]
    y = np.arange(len(names))

    finite = [np.maximum(errors[n][np.isfinite(errors[n])], FLOOR) for n in names]
    axes[0].boxplot(
        finite, positions=y, orientation="horizontal", widths=0.6, manage_ticks=False, flierprops={"markersize": 2}
    )
    axes[0].set_xscale("log")
    axes[0].xaxis.set_minor_formatter(NullFormatter())  # minor labels of a short log range overlap
    axes[0].set_xlabel(error_label)

    median_us = [np.median(seconds[n]) * 1e6 for n in names]
    ok = [100.0 * np.mean(np.isin(np.asarray(status[n]), SOLVED)) for n in names]
    bars = axes[1].barh(y, median_us, color="tab:blue")
    axes[1].set_xscale("log")
    axes[1].set_xlim(right=max(median_us) * 40)  # room for the labels
    axes[1].set_xlabel("median time per solve [us]")
    for bar, share in zip(bars, ok):
        axes[1].text(
            bar.get_width(), bar.get_y() + bar.get_height() / 2, f" {share:.0f}% solved", va="center", fontsize=8
        )

    if margins is not None:
        values = [margins[n][np.isfinite(margins[n])] * 1e3 for n in names]
        axes[2].boxplot(
            values, positions=y, orientation="horizontal", widths=0.6, manage_ticks=False, flierprops={"markersize": 2}
        )
        axes[2].axvline(0.0, label="Table I limit (margin 0)", **plots.LIMIT)
        axes[2].set_xlabel("smallest leg margin to Table I [mm]")
        plots.legend_outside(fig)
    axes[0].set_yticks(y, names)
    axes[0].set_ylim(len(names) - 0.5, -0.5)  # first method on top
    for ax in axes:
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(title)
    plots.save(fig, path)
