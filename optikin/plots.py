"""Figures people would rather look at than read: backbones in 3-D, signals over time, one style.

Every drawing function draws into a new figure, saves it to ``path`` (PNG) and closes
it. The matplotlib backend is the caller's: the command line picks Agg, a
notebook keeps its own. Lengths are given in metres and drawn in millimetres.

The style lives here, in one place, and every kind's figures use it:

* :func:`method_styles` gives each method a line style by its role: optikin's own
  solvers solid and wide, each baseline its own colour, dash pattern and marker (the
  markers of overlapping curves sit at staggered places, so each stays visible), any
  new method name a style of its own;
* the reference is a wide grey band under the curves (:data:`REFERENCE`), limits are
  red dashed lines with a legend entry (:func:`limit_lines`);
* legends sit outside the axes (:func:`legend_outside`), so they never cover data;
* 3-D axes have one scale on every axis (:func:`equal_axes_3d`) and a colour bar that
  says what their colours mean (:func:`colour_scale`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

MM = 1e3
DPI = 110

REFERENCE: dict[str, Any] = {"color": "0.55", "lw": 3.5, "alpha": 0.55, "solid_capstyle": "butt", "zorder": 1}
"""Style of a reference curve: a wide grey band the methods' curves are drawn over."""
LIMIT: dict[str, Any] = {"color": "tab:red", "lw": 1.0, "ls": (0, (4, 2))}
"""Style of a limit (bound, margin) line."""
SOLVER_COLOURS = ("tab:blue", "tab:cyan", "midnightblue", "slateblue")
"""Colours of optikin's own methods (role ``solver``), in order."""
BASELINE_COLOURS = ("tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:gray", "gold")
"""Colours of the other methods (baselines, comparators), in order; red is kept for limits."""
DASHES: tuple[Any, ...] = ("--", "-.", (0, (1, 1.2)), (0, (6, 1.5, 1, 1.5, 1, 1.5)), (0, (9, 2.5)))
"""Dash patterns of the other methods, in order."""
MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*")
"""Markers of the other methods, in order."""
MARK_STEP = 0.09
"""Spacing of a curve's markers along the line, as a fraction of the axes' diagonal."""
COINCIDENT = 0.004
"""Curves closer than this fraction of a panel's range everywhere are labelled as lying on one another."""
SEQUENCE = "viridis"
"""Colour map of samples or times."""


def roles_of(summary: Mapping[str, Any]) -> dict[str, str]:
    """``{method: role}`` of a result summary's comparison rows (``solver`` for optikin's own methods)."""
    return {str(row["method"]): str(row.get("role", "")) for row in summary.get("comparison", []) if "method" in row}


def method_styles(methods: Sequence[str], roles: Mapping[str, str] | None = None) -> dict[str, dict[str, Any]]:
    """A line style (keyword arguments of ``Axes.plot``) per method name.

    Parameters
    ----------
    methods:
        Method names in drawing order.
    roles:
        ``{method: role}``; role ``solver`` marks optikin's own methods. A method missing
        from ``roles`` is a baseline; without ``roles`` the first method is optikin's.

    Returns
    -------
    dict
        ``{method: style}``: solvers solid, wide and unmarked; every other method its own
        colour, dash pattern and marker, its markers placed between those of the others.
    """
    roles = roles if roles is not None else ({methods[0]: "solver"} if methods else {})
    solvers = [m for m in methods if roles.get(m) == "solver"]
    others = [m for m in methods if m not in solvers]
    styles: dict[str, dict[str, Any]] = {}
    for k, m in enumerate(solvers):
        styles[m] = {"color": SOLVER_COLOURS[k % len(SOLVER_COLOURS)], "lw": 2.2 - 0.4 * min(k, 2), "ls": "-"}
        styles[m]["zorder"] = 2.5
    for k, m in enumerate(others):
        styles[m] = {
            "color": BASELINE_COLOURS[k % len(BASELINE_COLOURS)],
            "lw": 1.3,
            "ls": DASHES[k % len(DASHES)],
            "marker": MARKERS[(k + k // len(BASELINE_COLOURS)) % len(MARKERS)],  # colour and marker repeat apart
            "ms": 4.5,
            "markevery": (MARK_STEP * (k + 0.5) / max(len(others), 1), MARK_STEP),
            "markerfacecolor": "none",
            "zorder": 2.0,
        }
    return styles


def unmarked(style: Mapping[str, Any]) -> dict[str, Any]:
    """``style`` without its markers (for dense scatter-like plots and box plots)."""
    return {k: v for k, v in style.items() if k not in ("marker", "ms", "markevery", "markerfacecolor")}


def coincident(panels: Sequence[Mapping[str, np.ndarray]], tolerance: float = COINCIDENT) -> dict[str, str]:
    """Methods whose curves lie on an earlier method's in every panel: ``{method: earlier method}``.

    ``panels`` holds, per panel, ``{method: y}``; two curves coincide in a panel when they differ
    by at most ``tolerance`` times the panel's range of values anywhere.
    """
    names = list(panels[0]) if panels else []
    out: dict[str, str] = {}
    for i, name in enumerate(names):
        for earlier in names[:i]:
            if earlier in out:
                continue
            if all(_close(panel, name, earlier, tolerance) for panel in panels):
                out[name] = earlier
                break
    return out


def _close(panel: Mapping[str, np.ndarray], a: str, b: str, tolerance: float) -> bool:
    if a not in panel or b not in panel or np.shape(panel[a]) != np.shape(panel[b]):
        return False
    values = np.concatenate([np.ravel(v) for v in panel.values()])
    values = values[np.isfinite(values)]
    span = float(np.ptp(values)) if values.size else 0.0
    diff = np.abs(np.asarray(panel[a], dtype=float) - np.asarray(panel[b], dtype=float))
    return bool(np.all(np.nan_to_num(diff, nan=np.inf) <= tolerance * max(span, 1e-300)))


def labelled(methods: Sequence[str], on: Mapping[str, str]) -> dict[str, str]:
    """Legend labels of ``methods``: ``"B (on A's curve)"`` for a method ``B`` that :func:`coincident` put on ``A``."""
    return {m: f"{m} (on {on[m]}'s curve)" if m in on else m for m in methods}


def subplots(rows: int = 1, cols: int = 1, **kwargs: Any) -> tuple[Figure, np.ndarray]:
    """``plt.subplots`` with the layout every figure here uses (constrained) and axes as a 2-D array."""
    fig, axes = plt.subplots(rows, cols, layout="constrained", squeeze=False, **kwargs)
    return fig, axes


def figure_3d(figsize: tuple[float, float] = (7.4, 6.0)) -> tuple[Figure, Any]:
    """A figure with one 3-D axes (an ``Axes3D``), constrained layout."""
    fig = plt.figure(figsize=figsize, layout="constrained")
    return fig, fig.add_subplot(projection="3d")


def limit_lines(ax: Axes, values: Sequence[float], label: str = "limits") -> None:
    """Horizontal limit lines at ``values``, all in :data:`LIMIT` style under one legend ``label``."""
    for value in values:
        ax.axhline(value, label=label, **LIMIT)


def legend_outside(fig: Figure, axes: Sequence[Axes] | None = None, title: str | None = None, **kwargs: Any) -> None:
    """One legend for the labelled artists of ``axes`` (default: all of ``fig``), right of the axes.

    A label drawn in several panels appears once. The figure needs a constrained layout
    (:func:`subplots`), which makes room for it. Nothing is drawn when no artist is labelled.
    """
    handles: dict[str, Any] = {}
    for ax in axes if axes is not None else fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="outside right upper", fontsize=8, title=title, **kwargs)


def equal_axes_3d(ax: Any, points: np.ndarray, unit: str = "mm") -> None:
    """Limits of a 3-D ``ax`` around ``points (..., 3)`` (drawn units) with one scale on all three axes.

    The box's aspect is the data's extent per axis (an axis with almost no extent gets 5 % of the
    largest one), so a millimetre is as long along x, y and z.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    lo, hi = (p.min(axis=0), p.max(axis=0)) if len(p) else (np.zeros(3), np.ones(3))
    largest = max(float((hi - lo).max()), 1e-9)
    span = np.maximum(hi - lo, 0.05 * largest) + 0.06 * largest
    centre = 0.5 * (lo + hi)
    ax.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
    ax.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
    ax.set_zlim(centre[2] - span[2] / 2, centre[2] + span[2] / 2)
    ax.set_box_aspect(tuple(span))
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    ax.set_zlabel(f"z [{unit}]", labelpad=4)


def colour_scale(fig: Figure, ax: Axes | Sequence[Axes], values: np.ndarray, label: str) -> np.ndarray:
    """Colours ``(N, 4)`` of ``values`` on :data:`SEQUENCE`, with a colour bar labelled ``label`` beside ``ax``."""
    values = np.asarray(values, dtype=float)
    lo, hi = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
    norm = Normalize(lo, hi if hi > lo else lo + 1.0)
    mappable = ScalarMappable(norm=norm, cmap=SEQUENCE)
    fig.colorbar(mappable, ax=ax, shrink=0.6, pad=0.08, label=label)
    return np.asarray(mappable.to_rgba(values))


def save(fig: Figure, path: Path) -> None:
    """Write ``fig`` to ``path`` (PNG) and close it."""
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def pick_samples(n: int, count: int) -> np.ndarray:
    """``count`` sample indices spread evenly over ``n``."""
    return np.unique(np.linspace(0, n - 1, min(n, count)).astype(int))


def backbones_3d(
    path: Path,
    backbones: np.ndarray,
    title: str,
    section_ends: np.ndarray | None = None,
    max_shapes: int = 12,
    extra: dict[str, np.ndarray] | None = None,
    t: np.ndarray | None = None,
) -> None:
    """Up to ``max_shapes`` backbones, evenly picked, coloured by sample (or time) with a colour bar.

    Parameters
    ----------
    backbones:
        ``(N, K, 3)`` backbone points [m].
    section_ends:
        ``(N, m, 3)`` section end positions [m], drawn as dots.
    extra:
        ``{label: (P, 3)}`` further curves [m], black dashed.
    t:
        ``(N,)`` sample times [s]; the colours are times when given, sample indices otherwise.
    """
    pick = pick_samples(backbones.shape[0], max_shapes)
    fig, ax = figure_3d()
    values, label = (np.asarray(t)[pick], "t [s]") if t is not None else (pick.astype(float), "sample")
    colours = colour_scale(fig, ax, values, label)
    for k, (c, i) in enumerate(zip(colours, pick)):
        b = backbones[i] * MM
        ax.plot(b[:, 0], b[:, 1], b[:, 2], color=c, lw=1.6, label="backbone" if k == 0 else None)
        if section_ends is not None:
            e = section_ends[i] * MM
            ax.scatter(
                e[:, 0],
                e[:, 1],
                e[:, 2],
                color=c,
                s=14,
                edgecolor="k",
                lw=0.4,
                label="section ends" if k == 0 else None,
            )
    drawn = [backbones[pick].reshape(-1, 3) * MM]
    for name, pts in (extra or {}).items():
        p = np.asarray(pts) * MM
        ax.plot(p[:, 0], p[:, 1], p[:, 2], "k--", lw=0.8, label=name)
        drawn.append(p.reshape(-1, 3))
    ax.legend(loc="upper left", fontsize=8)
    equal_axes_3d(ax, np.concatenate(drawn))
    ax.set_title(title)
    save(fig, path)


def time_series(
    path: Path,
    t: np.ndarray,
    series: dict[str, np.ndarray],
    ylabel: str | Mapping[str, str],
    title: str,
    labels: Sequence[str] = ("x", "y", "z"),
) -> None:
    """One panel per named array ``(N, d)`` against time ``t`` [s]; ``labels`` name the d columns.

    ``ylabel`` is the unit of every panel (``"[mm]"``) or a unit per series name; a panel's y label
    is its name and unit. Columns are named in one legend beside the panels (none for single columns).
    """
    fig, axes = subplots(len(series), 1, figsize=(7.6, 1.2 + 2.0 * len(series)), sharex=True)
    for ax, (name, y) in zip(axes[:, 0], series.items()):
        y = np.atleast_2d(np.asarray(y).T).T
        unit = ylabel if isinstance(ylabel, str) else ylabel.get(name, "")
        for j in range(y.shape[1]):
            ax.plot(t, y[:, j], lw=1.2, color=f"C{j}", label=labels[j] if y.shape[1] > 1 and j < len(labels) else None)
        ax.set_ylabel(f"{name}\n{unit}" if unit else name)
        ax.grid(alpha=0.3)
    legend_outside(fig)
    axes[-1, 0].set_xlabel("t [s]")
    axes[0, 0].set_title(title)
    save(fig, path)


def scatter_3d(
    path: Path, points: np.ndarray, title: str, colour: np.ndarray | None = None, colour_label: str = ""
) -> None:
    """Points ``(N, 3)`` in metres, optionally coloured by a value per point (with a colour bar)."""
    fig, ax = figure_3d()
    p = points * MM
    if colour is not None:
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=colour_scale(fig, ax, colour, colour_label), s=6)
    else:
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=6)
    equal_axes_3d(ax, p)
    ax.set_title(title)
    save(fig, path)


def draw_shapes(
    ax: Any,
    curves: Sequence[np.ndarray],
    markers: Sequence[np.ndarray],
    truths: Sequence[np.ndarray] | None = None,
    colours: Sequence[Any] | np.ndarray | None = None,
    curve_label: str = "PH backbone",
) -> None:
    """On a 3-D ``ax``: each curve ``(T, 3)`` [m] (line), its markers ``(K, 3)`` (dots), the ground truth (dashed).

    Sets equal scales (:func:`equal_axes_3d`) and a legend of the three kinds of artist; ``colours``
    (one per curve) are the caller's to explain.
    """
    colours = colours if colours is not None else plt.get_cmap(SEQUENCE)(np.linspace(0, 1, len(curves)))
    for k, (c, m) in enumerate(zip(curves, markers)):
        ax.plot(*(c * MM).T, color=colours[k], lw=1.6, label=curve_label if k == 0 else None)
        ax.scatter(*(m * MM).T, color=colours[k], s=14, edgecolor="k", lw=0.4, label="markers" if k == 0 else None)
        if truths is not None:
            ax.plot(*(truths[k] * MM).T, "--", color="0.35", lw=0.8, label="ground truth" if k == 0 else None)
    every = [np.asarray(c).reshape(-1, 3) for c in curves] + [np.asarray(m).reshape(-1, 3) for m in markers]
    equal_axes_3d(ax, np.concatenate(every) * MM)
    ax.legend(loc="upper left", fontsize=8)


def shapes_3d(
    path: Path, curves: np.ndarray, markers: np.ndarray, title: str, truths: np.ndarray | None = None, count: int = 6
) -> None:
    """Curves ``(N, T, 3)`` [m] with their markers ``(N, K, 3)`` (and true backbones) of ``count`` samples,
    coloured by sample."""
    pick = pick_samples(len(curves), count)
    fig, ax = figure_3d()
    colours = colour_scale(fig, ax, pick.astype(float), "sample")
    draw_shapes(
        ax,
        [curves[i] for i in pick],
        [markers[i] for i in pick],
        None if truths is None else [truths[i] for i in pick],
        colours,
    )
    ax.set_title(title)
    save(fig, path)


def chains_3d(
    path: Path,
    links: Sequence[np.ndarray],
    markers: Sequence[np.ndarray],
    truths: Sequence[np.ndarray],
    title: str,
    count: int = 3,
) -> None:
    """Chains of links: per link curves ``(N, T, 3)`` [m], markers ``(N, K, 3)``, truth ``(N, M, 3)``;
    ``count`` samples, coloured by sample."""
    pick = pick_samples(len(links[0]), count)
    fig, ax = figure_3d()
    colours = colour_scale(fig, ax, pick.astype(float), "sample")
    curves, dots, true, cols = [], [], [], []
    for c, i in zip(colours, pick):
        for link, m, tr in zip(links, markers, truths):
            curves.append(link[i])
            dots.append(m[i])
            true.append(tr[i])
            cols.append(c)
    draw_shapes(ax, curves, dots, true, colours=cols, curve_label="PH link")
    ax.set_title(title)
    save(fig, path)


def per_sample(
    path: Path,
    series: dict[str, np.ndarray],
    ylabel: str,
    title: str,
    labels: dict[str, list[str]] | None = None,
    reference: dict[str, float] | None = None,
) -> None:
    """One panel per named array ``(N,)`` or ``(N, K)`` against the sample index, in unit ``ylabel``;
    ``labels`` name the columns; dotted lines at ``reference`` values (labelled)."""
    fig, axes = subplots(len(series), 1, figsize=(7.8, 1.2 + 2.2 * len(series)), sharex=True)
    for ax, (name, y) in zip(axes[:, 0], series.items()):
        y = np.asarray(y, dtype=float)
        y = y[:, None] if y.ndim == 1 else y
        names = (labels or {}).get(name, [str(j + 1) for j in range(y.shape[1])])
        for j in range(y.shape[1]):
            label = names[j] if j < len(names) else str(j + 1)
            ax.plot(np.arange(len(y)), y[:, j], ".-", lw=0.8, ms=3, label=label)
        for label, value in (reference or {}).items():
            ax.axhline(value, ls=":", color="0.4", lw=0.8, label=label)
        ax.set_ylabel(f"{name}\n{ylabel}")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)
    axes[-1, 0].set_xlabel("sample")
    axes[0, 0].set_title(title)
    save(fig, path)


def times_per_sample(
    path: Path, seconds: dict[str, np.ndarray], title: str, roles: Mapping[str, str] | None = None
) -> None:
    """Wall time per sample [us] of each method (log scale), each in its :func:`method_styles` style."""
    fig, axes = subplots(1, 1, figsize=(8.4, 3.6))
    ax = axes[0, 0]
    styles = method_styles(list(seconds), roles)
    for name, s in seconds.items():
        s = np.asarray(s, dtype=float)
        style = unmarked(styles[name]) | {"lw": 1.0}
        ax.semilogy(
            np.arange(len(s)), np.maximum(s, 1e-12) * 1e6, label=f"{name} (median {np.median(s) * 1e6:.0f} us)", **style
        )
    ax.set(xlabel="sample", ylabel="time per sample [us]")
    ax.grid(alpha=0.3, which="both")
    legend_outside(fig)
    ax.set_title(title)
    save(fig, path)
