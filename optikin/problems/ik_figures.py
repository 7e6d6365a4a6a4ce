"""The comparison figure of an ``ik`` run: tip error, time per solve and (CBHA) leg margins, one row per method."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from optikin.solvers.base import SolutionBatch

FLOOR = 1e-17
"""Tip errors are drawn on a log scale; exact zeros sit at this floor [m]."""


def draw_comparison(path: Path, title: str, reports: dict[str, SolutionBatch],
                    checks: dict[str, dict[str, np.ndarray]]) -> None:
    """Per method: the distribution of tip errors, the median time per solve and, on a CBHA, the leg margins."""
    names = list(reports)
    margins = all("leg_margin" in checks[n] for n in names)
    panels = 3 if margins else 2
    fig, axes = plt.subplots(1, panels, figsize=(4.6 * panels, 0.45 * len(names) + 2.2), sharey=True)
    y = np.arange(len(names))

    errors = [np.maximum(checks[n]["tip_error"][np.isfinite(checks[n]["tip_error"])], FLOOR) for n in names]
    axes[0].boxplot(errors, positions=y, vert=False, widths=0.6, manage_ticks=False, flierprops={"markersize": 2})
    axes[0].set_xscale("log")
    axes[0].set_xlabel("tip error [m] (fk_dq of the answer)")

    median_us = [np.median(reports[n].seconds) * 1e6 for n in names]
    ok = [100.0 * np.mean(np.array(reports[n].status) == "ok") for n in names]
    bars = axes[1].barh(y, median_us, color="tab:blue")
    axes[1].set_xscale("log")
    axes[1].set_xlabel("median time per solve [us]")
    for bar, share in zip(bars, ok):
        axes[1].text(bar.get_width(), bar.get_y() + bar.get_height() / 2, f" {share:.0f}% ok", va="center",
                     fontsize=8)

    if margins:
        values = [checks[n]["leg_margin"][np.isfinite(checks[n]["leg_margin"])] * 1e3 for n in names]
        axes[2].boxplot(values, positions=y, vert=False, widths=0.6, manage_ticks=False,
                        flierprops={"markersize": 2})
        axes[2].axvline(0.0, color="tab:red", lw=1)
        axes[2].set_xlabel("smallest leg margin to Table I [mm]")
    axes[0].set_yticks(y, names)
    axes[0].set_ylim(len(names) - 0.5, -0.5)  # first method on top
    for ax in axes:
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
