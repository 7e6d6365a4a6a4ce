"""Figures of a ``calibrate`` result, drawn from its arrays and summary alone.

``residuals``
    per marker, the marker error of every posture [mm] (fit and held out), rejected
    postures marked;
``markers``
    in 3-D [mm], the measured markers over the calibrated arm's backbone for a few postures,
    coloured by posture;
``identifiability``
    the singular values of the whitened geometry Jacobian at the solution (largest first) against the
    level below which a combination is weakly determined (noise level / largest standard deviation,
    :mod:`optikin.calibration.identifiability`), with the verdict.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from optikin import plots
from optikin.results import Drawer

MM = 1e3
FLOOR = 1e-15
"""Marker errors are drawn on a log scale; exact zeros sit at this floor [m]."""
BACKBONES_DRAWN = 12
"""Postures whose backbone the ``markers`` figure draws."""


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """The figures whose arrays are present (module docstring)."""
    name = summary["problem"]
    markers = str(summary.get("metrics", {}).get("markers", "")).split(", ")
    drawers: dict[str, Drawer] = {}
    if all(k in arrays for k in ("errors", "held_out_errors", "outlier")):
        drawers["residuals"] = partial(
            draw_residuals,
            errors=arrays["errors"],
            held_out=arrays["held_out_errors"],
            outlier=arrays["outlier"],
            names=markers,
            title=f"{name}: marker errors",
        )
    if all(k in arrays for k in ("measured", "backbone", "outlier")):
        drawers["markers"] = partial(
            draw_markers,
            measured=arrays["measured"],
            backbone=arrays["backbone"],
            outlier=arrays["outlier"],
            title=f"{name}: measured markers and the calibrated arm",
        )
    identifiability = summary.get("metrics", {}).get("identifiability", {})
    if "singular_values" in arrays and len(arrays["singular_values"]) and identifiability:
        level = identifiability["noise level per coordinate [mm]"] / identifiability["std threshold [mm or deg]"]
        drawers["identifiability"] = partial(
            draw_singular_values,
            singular=arrays["singular_values"],
            level=level,
            title=f"{name}: {identifiability['verdict']}",
        )
    return drawers


def draw_singular_values(path: Path, singular: np.ndarray, level: float, title: str) -> None:
    """The singular values ``(n,)`` (largest first) on a log scale against the weak-determination ``level``."""
    fig, axes = plots.subplots(1, 1, figsize=(7.0, 3.4))
    ax = axes[0, 0]
    k = np.arange(1, len(singular) + 1)
    weak = singular < level
    ax.semilogy(k[~weak], np.maximum(singular[~weak], FLOOR), "o", color="tab:blue", label="determined")
    ax.semilogy(k[weak], np.maximum(singular[weak], FLOOR), "x", color="tab:red", ms=8, label="weakly determined")
    ax.axhline(level, color="0.4", ls="--", lw=1.0, label="noise / largest std")
    ax.set_xlabel("combination of the geometry (largest singular value first)")
    ax.set_ylabel("singular value\n[mm of markers per mm or deg]", fontsize=8)
    ax.set_xticks(k)
    ax.grid(alpha=0.3)
    plots.legend_outside(fig)
    ax.set_title(title)
    plots.save(fig, path)


def draw_residuals(
    path: Path, errors: np.ndarray, held_out: np.ndarray, outlier: np.ndarray, names: list[str], title: str
) -> None:
    """One panel per marker: errors ``(N, M)`` [m] against the posture, fit and held out, log scale [mm]."""
    M = errors.shape[1]
    fig, axes = plots.subplots(M, 1, figsize=(9.2, 1.9 * M + 1.0), sharex=True)
    k = np.arange(len(errors))
    for j, ax in enumerate(axes[:, 0]):
        ax.semilogy(k, np.maximum(errors[:, j], FLOOR) * 1e3, ".", ms=3, color="tab:blue", label="fit")
        ax.semilogy(
            k, np.maximum(held_out[:, j], FLOOR) * 1e3, ".", ms=3, alpha=0.6, color="tab:orange", label="held out"
        )
        if outlier.any():
            bad = np.maximum(errors[outlier, j], FLOOR) * 1e3
            ax.semilogy(k[outlier], bad, "x", color="tab:red", ms=6, label="rejected posture")
        ax.set_ylabel(f"{names[j] if j < len(names) else j + 1}\nerror [mm]", fontsize=8)
        ax.grid(alpha=0.3)
    plots.legend_outside(fig, markerscale=2)
    axes[-1, 0].set_xlabel("posture")
    axes[0, 0].set_title(title)
    plots.save(fig, path)


def draw_markers(path: Path, measured: np.ndarray, backbone: np.ndarray, outlier: np.ndarray, title: str) -> None:
    """Measured markers ``(N, M, 3)`` [m] of every posture and the backbones ``(N, 3, K)`` of a few kept ones
    (coloured by posture), in millimetres."""
    fig, ax = plots.figure_3d()
    points = measured.reshape(-1, 3) * MM
    ax.scatter(*points.T, s=2, alpha=0.25, color="0.5", label="measured markers, all postures")
    kept = np.flatnonzero(~outlier)
    drawn = kept[np.linspace(0, len(kept) - 1, min(BACKBONES_DRAWN, len(kept))).astype(int)] if len(kept) else kept
    colours: Any = plots.colour_scale(fig, ax, drawn.astype(float), "posture") if len(drawn) else []
    for n, (i, colour) in enumerate(zip(drawn, colours)):
        ax.plot(*backbone[i] * MM, lw=1.4, color=colour, label="calibrated backbone" if n == 0 else None)
        ax.scatter(
            *measured[i].T * MM, s=14, color=colour, edgecolor="k", lw=0.4, label="its markers" if n == 0 else None
        )
    if outlier.any():
        bad = measured[outlier].reshape(-1, 3) * MM
        ax.scatter(*bad.T, s=14, c="tab:red", marker="x", label="rejected postures")
    plots.equal_axes_3d(ax, np.concatenate([points, *(backbone[i].T * MM for i in drawn)]))
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title(title, fontsize=9)
    plots.save(fig, path)
