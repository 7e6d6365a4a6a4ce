"""Figures of the PH problem kinds: reconstructed shapes against markers, errors and times per sample.

Every function draws into a new figure and saves it to ``path`` (PNG), like
:mod:`optikin.plots`; lengths are given in metres and drawn in millimetres. The kinds'
figure builders (``optikin/problems/ph_*/figures.py``) call these from a result's
arrays alone.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

MM = 1e3


def pick_samples(n: int, count: int) -> np.ndarray:
    """``count`` sample indices spread evenly over ``n``."""
    return np.unique(np.linspace(0, n - 1, min(n, count)).astype(int))


def draw_shapes(
    ax, curves: list[np.ndarray], markers: list[np.ndarray], truths: list[np.ndarray] | None = None, colours=None
) -> None:
    """On a 3-D axis: each PH curve ``(T, 3)`` (line), its markers ``(K, 3)`` (dots), the ground truth (dashed)."""
    colours = colours if colours is not None else plt.cm.viridis(np.linspace(0, 1, len(curves)))
    for k, (c, m) in enumerate(zip(curves, markers)):
        ax.plot(*(c * MM).T, color=colours[k], lw=1.6, label="PH backbone" if k == 0 else None)
        ax.scatter(*(m * MM).T, color=colours[k], s=14, edgecolor="k", lw=0.4, label="markers" if k == 0 else None)
        if truths is not None:
            ax.plot(*(truths[k] * MM).T, "--", color="0.35", lw=0.8, label="ground truth" if k == 0 else None)
    every = np.concatenate([c for c in curves] + [m for m in markers]) * MM
    lo, hi = np.nanmin(every, axis=0), np.nanmax(every, axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * max(float(np.nanmax(hi - lo)), 1e-6)
    ax.set(
        xlim=(centre[0] - half, centre[0] + half),
        ylim=(centre[1] - half, centre[1] + half),
        zlim=(centre[2] - half, centre[2] + half),
        xlabel="x [mm]",
        ylabel="y [mm]",
        zlabel="z [mm]",
    )
    ax.legend(loc="upper left", fontsize=8)


def shapes_3d(
    path: Path, curves: np.ndarray, markers: np.ndarray, title: str, truths: np.ndarray | None = None, count: int = 6
) -> None:
    """PH curves ``(N, T, 3)`` with their markers ``(N, K, 3)`` (and model backbones), ``count`` samples."""
    pick = pick_samples(len(curves), count)
    fig = plt.figure(figsize=(6.4, 6.0))
    ax = fig.add_subplot(projection="3d")
    draw_shapes(
        ax, [curves[i] for i in pick], [markers[i] for i in pick], None if truths is None else [truths[i] for i in pick]
    )
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def per_sample(
    path: Path,
    series: dict[str, np.ndarray],
    ylabel: str,
    title: str,
    labels: dict[str, list[str]] | None = None,
    reference: dict[str, float] | None = None,
) -> None:
    """One panel per named array ``(N,)`` or ``(N, K)`` against the sample index; dotted lines at ``reference``."""
    fig, axes = plt.subplots(len(series), 1, figsize=(7.0, 2.5 * len(series)), sharex=True, squeeze=False)
    for ax, (name, y) in zip(axes[:, 0], series.items()):
        y = np.asarray(y, dtype=float)
        y = y[:, None] if y.ndim == 1 else y
        names = (labels or {}).get(name, [str(j + 1) for j in range(y.shape[1])])
        for j in range(y.shape[1]):
            ax.plot(np.arange(len(y)), y[:, j], ".-", lw=0.8, ms=3, label=names[j] if j < len(names) else str(j))
        for label, value in (reference or {}).items():
            ax.axhline(value, ls=":", color="0.4", lw=0.8)
            ax.annotate(label, (0, value), fontsize=7, color="0.3", va="bottom")
        ax.set_ylabel(f"{name}\n{ylabel}")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=min(4, y.shape[1]))
    axes[-1, 0].set_xlabel("sample")
    axes[0, 0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def times_per_sample(path: Path, seconds: dict[str, np.ndarray], title: str) -> None:
    """Wall time per sample of each method (log scale, microseconds)."""
    fig, ax = plt.subplots(figsize=(7.0, 3.4))
    for name, s in seconds.items():
        ax.semilogy(
            np.arange(len(s)),
            np.asarray(s) * 1e6,
            ".-",
            lw=0.8,
            ms=3,
            label=f"{name} (median {np.median(s) * 1e6:.0f} us)",
        )
    ax.set(xlabel="sample", ylabel="time per sample [us]", title=title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def chains_3d(
    path: Path, links: list[np.ndarray], markers: list[np.ndarray], truths: list[np.ndarray], title: str, count: int = 3
) -> None:
    """Chains of PH links: per link curves ``(N, T, 3)``, markers ``(N, K, 3)``, truth ``(N, M, 3)``.

    ``count`` samples are drawn.
    """
    pick = pick_samples(len(links[0]), count)
    fig = plt.figure(figsize=(6.4, 6.0))
    ax = fig.add_subplot(projection="3d")
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(pick)))
    curves, dots, true, cols = [], [], [], []
    for c, i in zip(colours, pick):
        for link, m, tr in zip(links, markers, truths):
            curves.append(link[i])
            dots.append(m[i])
            true.append(tr[i])
            cols.append(c)
    draw_shapes(ax, curves, dots, true, colours=cols)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
