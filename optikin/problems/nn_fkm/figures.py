"""Figures of ``nn_fkm`` from a result's arrays and summary: width searches and tip errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np
from matplotlib.ticker import MaxNLocator

from optikin.problems import nn_shared
from optikin.results import Drawer


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``search`` and ``tip_errors`` (:func:`optikin.problems.nn_shared.figures`), the search in the shared style."""
    return hybrid_figures(arrays, summary, "FKM")


def hybrid_figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any], what: str) -> dict[str, Drawer]:
    """The figures of either hybrid kind (``what``: ``FKM`` or ``IKM``): ``search`` drawn by
    :func:`draw_search`, ``tip_errors`` as :func:`optikin.problems.nn_shared.figures` draws it."""
    out = nn_shared.figures(arrays, summary, what)
    rows = summary.get("comparison", [])
    searches = nn_shared.searches_of(arrays, [row["method"] for row in rows if row["role"] == "solver"])
    if "search" in out:
        title = f"{summary['problem']}: width search"
        out["search"] = lambda path: draw_search(path, searches, title)
    return out


def draw_search(path: Path, searches: Mapping[str, np.ndarray], title: str) -> None:
    """Validation criterion against width, one line per model (``(widths, 2)`` arrays), legend beside the axes."""
    from optikin import plots

    fig, axes = plots.subplots(1, 1, figsize=(8.8, 4.2))
    ax = axes[0, 0]
    styles = plots.method_styles(list(searches), {})
    for label, search in searches.items():
        style = plots.unmarked(styles[label]) | {"marker": styles[label]["marker"], "ms": 5}
        ax.semilogy(search[:, 0], search[:, 1], label=label, **style)
    ax.set_xlabel("neurons per hidden layer")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("validation MSE (+ eq. 11 penalty)\n[SI units squared]")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    plots.legend_outside(fig)
    plots.save(fig, path)
