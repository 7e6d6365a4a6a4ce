"""Figures of a ``calibrate`` result, drawn from its arrays and summary alone.

``residuals``
    per marker, the marker error of every posture [mm] (fit and held out), rejected
    postures marked;
``markers``
    in 3-D, the measured markers over the calibrated arm's backbone for a few postures.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from optikin.results import Drawer

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
    return drawers


def draw_residuals(
    path: Path, errors: np.ndarray, held_out: np.ndarray, outlier: np.ndarray, names: list[str], title: str
) -> None:
    """One panel per marker: errors ``(N, M)`` [m] against the posture, fit and held out, log scale."""
    M = errors.shape[1]
    fig, axes = plt.subplots(M, 1, figsize=(8, 1.9 * M + 0.8), sharex=True, squeeze=False)
    k = np.arange(len(errors))
    for j, ax in enumerate(axes[:, 0]):
        ax.semilogy(k, np.maximum(errors[:, j], FLOOR) * 1e3, ".", ms=3, label="fit")
        ax.semilogy(k, np.maximum(held_out[:, j], FLOOR) * 1e3, ".", ms=3, alpha=0.6, label="held out")
        if outlier.any():
            ax.semilogy(k[outlier], np.maximum(errors[outlier, j], FLOOR) * 1e3, "rx", ms=6, label="rejected")
        ax.set_ylabel(f"{names[j] if j < len(names) else j} [mm]", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("posture")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def draw_markers(path: Path, measured: np.ndarray, backbone: np.ndarray, outlier: np.ndarray, title: str) -> None:
    """Measured markers ``(N, M, 3)`` [m] of every posture and the backbones ``(N, 3, K)`` of a few kept ones."""
    fig = plt.figure(figsize=(6.5, 6))
    ax = fig.add_subplot(projection="3d")
    points = measured.reshape(-1, 3)
    ax.scatter(points[:, 0], points[:, 1], points[:, 2], s=2, alpha=0.25, label="measured markers")
    kept = np.flatnonzero(~outlier)
    for i in kept[np.linspace(0, len(kept) - 1, min(BACKBONES_DRAWN, len(kept))).astype(int)] if len(kept) else []:
        ax.plot(*backbone[i], lw=1.2)
        ax.scatter(*measured[i].T, s=12, c="k")
    if outlier.any():
        bad = measured[outlier].reshape(-1, 3)
        ax.scatter(bad[:, 0], bad[:, 1], bad[:, 2], s=14, c="r", marker="x", label="rejected postures")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend(fontsize=7)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
