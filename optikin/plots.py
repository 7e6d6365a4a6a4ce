"""Figures people would rather look at than read: backbones in 3-D, signals over time.

Every function draws into a new figure, saves it to ``path`` (PNG) and closes
it. The matplotlib backend is the caller's: the command line picks Agg, a
notebook keeps its own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib.pyplot as plt
import numpy as np

MM = 1e3


def _equal_3d_axes(ax, points: np.ndarray) -> None:
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * max(float((hi - lo).max()), 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")


def backbones_3d(
    path: Path,
    backbones: np.ndarray,
    title: str,
    section_ends: np.ndarray | None = None,
    max_shapes: int = 12,
    extra: dict[str, np.ndarray] | None = None,
) -> None:
    """Draw up to ``max_shapes`` backbones ``(N, K, 3)`` (metres), evenly picked; marks section ends ``(N, m, 3)``."""
    n = backbones.shape[0]
    pick = np.unique(np.linspace(0, n - 1, min(n, max_shapes)).astype(int))
    fig = plt.figure(figsize=(6.4, 6.0))
    ax = fig.add_subplot(projection="3d")
    colours = plt.cm.viridis(np.linspace(0, 1, len(pick)))
    for c, i in zip(colours, pick):
        b = backbones[i] * MM
        ax.plot(b[:, 0], b[:, 1], b[:, 2], color=c, lw=1.5)
        if section_ends is not None:
            e = section_ends[i] * MM
            ax.scatter(e[:, 0], e[:, 1], e[:, 2], color=c, s=12)
    for label, pts in (extra or {}).items():
        p = np.asarray(pts) * MM
        ax.plot(p[:, 0], p[:, 1], p[:, 2], "k--", lw=0.8, label=label)
    if extra:
        ax.legend(loc="upper left")
    _equal_3d_axes(ax, backbones[pick].reshape(-1, 3) * MM)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def time_series(
    path: Path,
    t: np.ndarray,
    series: dict[str, np.ndarray],
    ylabel: str,
    title: str,
    labels: Sequence[str] = ("x", "y", "z"),
) -> None:
    """One panel per named array ``(N, d)`` against time ``t``; ``labels`` name the d columns."""
    fig, axes = plt.subplots(len(series), 1, figsize=(7.0, 2.4 * len(series)), sharex=True, squeeze=False)
    for ax, (name, y) in zip(axes[:, 0], series.items()):
        y = np.atleast_2d(np.asarray(y).T).T
        for j in range(y.shape[1]):
            ax.plot(t, y[:, j], lw=1.2, label=labels[j] if j < len(labels) else str(j))
        ax.set_ylabel(f"{name}\n{ylabel}")
        ax.grid(alpha=0.3)
        if any(not str(line.get_label()).startswith("_") for line in ax.get_lines()):
            ax.legend(loc="upper right", fontsize=8, ncol=min(4, y.shape[1]))
    axes[-1, 0].set_xlabel("t [s]")
    axes[0, 0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def scatter_3d(
    path: Path, points: np.ndarray, title: str, colour: np.ndarray | None = None, colour_label: str = ""
) -> None:
    """Points ``(N, 3)`` in metres, optionally coloured by a value per point."""
    fig = plt.figure(figsize=(6.4, 5.6))
    ax = fig.add_subplot(projection="3d")
    p = points * MM
    art = ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=colour, s=6, cmap="viridis")
    if colour is not None:
        fig.colorbar(art, ax=ax, shrink=0.6, label=colour_label)
    _equal_3d_axes(ax, p)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
