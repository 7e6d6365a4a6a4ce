"""Figures of an ``actuation`` result, drawn from its arrays and summary alone.

``learning_curve``
    each method's held-out largest marker error per posture (median, and p95 dashed) [mm] against the
    postures it was trained on (the share of each training fold), log scales; a statistic that a posture
    without a prediction reaches (infinite) is not drawn.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from optikin import plots
from optikin.results import Drawer


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """The figures whose arrays are present (module docstring)."""
    errors = {k[len("errors_") :]: v for k, v in arrays.items() if k.startswith("errors_")}
    if not errors or "training" not in arrays:
        return {}
    titles = {row["method"]: row["method"] for row in summary.get("comparison", [])}
    return {
        "learning_curve": partial(
            draw_learning_curve,
            training=np.asarray(arrays["training"]).mean(axis=0),
            errors=errors,
            floor=arrays.get("truth_errors"),
            title=f"{summary['problem']}: held-out error against training postures",
            labels=list(titles) if len(titles) == len(errors) else list(errors),
        )
    }


def draw_learning_curve(
    path: Path,
    training: np.ndarray,
    errors: Mapping[str, np.ndarray],
    floor: np.ndarray | None,
    title: str,
    labels: list[str],
) -> None:
    """Median (solid) and p95 (dashed) of ``errors`` (per method ``(F, N)`` [m]) against ``training (F,)``, as the
    report counts them (a posture without a prediction is an infinite error: a share whose statistic it reaches
    is not drawn)."""
    fig, axes = plots.subplots(1, 1, figsize=(7.4, 4.2))
    ax = axes[0, 0]
    for (method, e), label in zip(errors.items(), labels):
        e = e * 1e3
        median = np.nanpercentile(e, 50, axis=1, method="higher")
        (line,) = ax.loglog(training, median, "o-", label=f"{label} median")
        ax.loglog(training, np.nanpercentile(e, 95, axis=1, method="higher"), "s--", color=line.get_color(), alpha=0.6)
    if floor is not None:
        ax.axhline(float(np.nanmedian(floor)) * 1e3, color="0.4", ls=":", label="noise-free markers (median)")
    ax.set_xlabel("training postures (mean over folds)")
    ax.set_ylabel("largest marker error per posture [mm]\n(solid median, dashed p95)", fontsize=8)
    ax.grid(alpha=0.3, which="both")
    plots.legend_outside(fig)
    ax.set_title(title, fontsize=9)
    plots.save(fig, path)
