"""Figures of tracking runs, drawn from a result's arrays and summary alone.

Reference vs actual tip position (Seleem et al. 2020, Figs. 22-23, 26), errors
(Figs. 25, 27), the configuration against its limits, the Lyapunov function
``V(e) = e'e/2`` and the time of every control step. :func:`figures` reads the
arrays ``t``, ``reference``, ``reference_position`` and, per controller name
``K``, ``q_K``, ``x_K``, ``V_K``, ``step_time_K``; the curves are labelled with
the methods of the summary's comparison rows. :meth:`TrackingView.of_runs` draws
the same figures from :class:`~optikin.control.simulate.TrackingRun` objects.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Callable, Mapping

import matplotlib.pyplot as plt
import numpy as np

from optikin import plots
from optikin.algebra import dq_rotation, dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.control.simulate import DEG, MM, TrackingRun
from optikin.results import Drawer

FLOOR = 1e-6
"""Errors are drawn on a log scale; smaller ones (exact zeros too) sit at this floor [mm or deg]."""


@dataclass(frozen=True)
class Trace:
    """One controller's curves along a run (``N`` steps); ``None`` where the result does not hold them."""

    position: np.ndarray | None = None  # (N, 3) true tip position [m]
    position_error: np.ndarray | None = None  # (N,) [m]
    orientation_error: np.ndarray | None = None  # (N,) [rad], pose task only
    q: np.ndarray | None = None  # (N, n) plant configuration
    lyapunov: np.ndarray | None = None  # (N,) V(e) = e'e/2
    step_time: np.ndarray | None = None  # (N,) [s]


@dataclass(frozen=True)
class TrackingView:
    """What the figures draw: times, the reference tip position, the arm's limits and one :class:`Trace` per label.

    ``roles`` maps labels to their comparison role (``solver`` for optikin's own controllers), which
    picks their line styles (:func:`optikin.plots.method_styles`); without it the first label is optikin's.
    """

    t: np.ndarray
    reference_position: np.ndarray
    arm: Mapping[str, Any]
    traces: dict[str, Trace]
    roles: Mapping[str, str] = field(default_factory=dict)

    @classmethod
    def of_runs(cls, runs: Mapping[str, TrackingRun]) -> "TrackingView":
        """The view of simulated runs ``{label: run}`` of one reference."""
        first = next(iter(runs.values()))
        traces = {
            label: Trace(run.position, run.position_error, run.orientation_error, run.q, run.lyapunov, run.step_time)
            for label, run in runs.items()
        }
        return cls(first.t, first.reference.position, first.arm.describe(), traces)

    def curves(self, field: str) -> dict[str, np.ndarray]:
        """``field`` of every trace that holds it, by label."""
        out = {label: getattr(trace, field) for label, trace in self.traces.items()}
        return {label: curve for label, curve in out.items() if curve is not None}


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """The figures of a tracking result whose arrays are present (a figure without its arrays is left out)."""
    if "t" not in arrays or "reference_position" not in arrays:
        return {}
    view = TrackingView(
        arrays["t"],
        arrays["reference_position"],
        summary.get("arm", {}),
        traces(arrays, summary),
        plots.roles_of(summary),
    )
    title = summary.get("problem", "tracking")
    drawn: dict[str, tuple[Callable[..., None], str, str]] = {
        "tracking": (reference_vs_actual, "position", "tip position"),
        "errors": (errors, "position_error", "tracking errors"),
        "limits": (limits, "q", "configuration and limits"),
        "lyapunov": (lyapunov, "lyapunov", "V(e) = e'e/2"),
        "step_times": (step_times, "step_time", "time per control step"),
    }
    out: dict[str, Drawer] = {
        name: partial(draw, view=view, title=f"{title}: {words}")
        for name, (draw, field, words) in drawn.items()
        if view.curves(field) and (name != "limits" or "config_names" in view.arm)
    }
    if "snapshot_obstacles" in arrays:
        labels = {name: _label(name, summary) for name in (key[10:] for key in arrays if key.startswith("clearance_"))}
        out["obstacles"] = partial(
            obstacles, arrays=arrays, labels=labels, title=f"{title}: backbones and obstacles", roles=view.roles
        )
    return out


def obstacles(
    path: Path,
    arrays: Mapping[str, np.ndarray],
    labels: Mapping[str, str],
    title: str,
    roles: Mapping[str, str] | None = None,
) -> None:
    """3-D backbones of the first two controllers at a few instants with the obstacles, coloured by
    time, and every method's least backbone-to-obstacle distance [mm] over time against the margin."""
    shown = list(labels)[:2]
    times = arrays["snapshot_t"]
    fig = plt.figure(figsize=(14.0, 5.2), layout="constrained")
    spaces = [fig.add_subplot(1, len(shown) + 1, panel + 1, projection="3d") for panel in range(len(shown))]
    colours: Any = plots.colour_scale(fig, spaces, times, "snapshot t [s]") if spaces else []
    for ax, name in zip(spaces, shown):
        drawn = []
        for k, colour in enumerate(colours):
            shell = arrays["snapshot_obstacles"][k] * MM
            ax.scatter(*shell.T, s=2, color=colour, alpha=0.3, label="obstacle surface" if k == 0 else None)
            backbone = arrays[f"snapshot_backbone_{name}"][k] * MM
            ax.plot(*backbone, color=colour, lw=2.0, label="backbone" if k == 0 else None)
            drawn += [shell.reshape(-1, 3), backbone.T]
        plots.equal_axes_3d(ax, np.concatenate(drawn))
        ax.set_title(labels[name], fontsize=9)
        ax.legend(fontsize=7, loc="upper left")
    ax = fig.add_subplot(1, len(shown) + 1, len(shown) + 1)
    methods = list(labels.values())
    styles = plots.method_styles(methods, roles or None)
    clearance = {labels[name]: arrays[f"clearance_{name}"] * MM for name in labels}
    legend = plots.labelled(methods, plots.coincident([clearance]))
    for method, values in clearance.items():
        ax.plot(arrays["t"], values, label=legend[method], **styles[method])
    plots.limit_lines(ax, [arrays["barrier_margin"][0] * MM], label="margin")
    ax.axhline(0.0, color="k", lw=0.8, label="contact")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("least backbone-obstacle distance [mm]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.15), ncol=2)
    fig.suptitle(title, fontsize=10)
    plots.save(fig, path)


def traces(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Trace]:
    """One trace per controller name of the arrays, labelled and ordered as the comparison rows."""
    names = [key[2:] for key in arrays if key.startswith("q_")]
    names += [key[2:] for key in arrays if key.startswith("x_") and key[2:] not in names]
    labels = {name: _label(name, summary) for name in names}
    order = [row.get("method") for row in summary.get("comparison", [])]
    names.sort(key=lambda name: order.index(labels[name]) if labels[name] in order else len(order))
    return {labels[name]: _trace(arrays, name) for name in names}


def _label(name: str, summary: Mapping[str, Any]) -> str:
    """The method label of controller ``name``: the solver row's for ``qp``, the baseline controller's otherwise."""
    from optikin.problems.tracking.run import BASELINES

    if name == "qp":
        rows = [row["method"] for row in summary.get("comparison", []) if row.get("role") == "solver"]
        return rows[0] if rows else name
    return BASELINES[name].title if name in BASELINES else name


def _trace(arrays: Mapping[str, np.ndarray], name: str) -> Trace:
    x = arrays.get(f"x_{name}")
    position = position_error = orientation_error = None
    if x is not None:
        pose = x.shape[1] == 8
        position = dq_translation(x) if pose else x
        position_error = np.linalg.norm(arrays["reference_position"] - position, axis=1)
        if pose and "reference" in arrays:
            relative = quat_multiply(quat_conjugate(dq_rotation(arrays["reference"])), dq_rotation(x))
            orientation_error = quat_angle(relative)
    return Trace(
        position,
        position_error,
        orientation_error,
        arrays.get(f"q_{name}"),
        arrays.get(f"V_{name}"),
        arrays.get(f"step_time_{name}"),
    )


def _save(fig: Any, path: Path, title: str) -> None:
    fig.axes[0].set_title(title)
    plots.save(fig, path)


def _styles(view: TrackingView, field: str) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
    curves = view.curves(field)
    return curves, plots.method_styles(list(curves), view.roles or None)


def reference_vs_actual(path: Path, view: TrackingView, title: str) -> None:
    """Tip position x, y, z [mm] of every method against the reference (Seleem et al. 2020, Fig. 26)."""
    positions, styles = _styles(view, "position")
    panels = [
        {"reference": view.reference_position[:, j]} | {m: p[:, j] for m, p in positions.items()} for j in range(3)
    ]
    on = plots.coincident(panels)  # a method on the reference says so: the band under it is hidden
    labels = plots.labelled(list(positions), on)
    fig, axes = plots.subplots(3, 1, figsize=(8.6, 7.0), sharex=True)
    for j, (ax, axis) in enumerate(zip(axes[:, 0], "xyz")):
        ax.plot(view.t, view.reference_position[:, j] * MM, label="reference", **plots.REFERENCE)
        for name, position in positions.items():
            ax.plot(view.t, position[:, j] * MM, label=labels[name], **styles[name])
        ax.set_ylabel(f"tip {axis} [mm]")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t [s]")
    plots.legend_outside(fig)
    _save(fig, path, title)


def errors(path: Path, view: TrackingView, title: str) -> None:
    """Position error [mm] and, for pose tracking, orientation error [deg] over time (Figs. 25, 27)."""
    angles = view.curves("orientation_error")
    pose = bool(angles)
    lengths, styles = _styles(view, "position_error")
    drawn = [{m: np.maximum(e * MM, FLOOR) for m, e in lengths.items()}]
    if pose:
        drawn.append({m: np.maximum(angles[m] * DEG, FLOOR) for m in lengths if m in angles})
    on = plots.coincident([{m: np.log10(v) for m, v in panel.items()} for panel in drawn])
    labels = plots.labelled(list(lengths), on)
    fig, axes = plots.subplots(len(drawn), 1, figsize=(8.6, 5.0 if pose else 3.2), sharex=True)
    for ax, panel, unit in zip(axes[:, 0], drawn, ("position error [mm]", "orientation error [deg]")):
        for name, values in panel.items():
            ax.semilogy(view.t, values, label=labels[name], **styles[name])
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3, which="both")
    axes[-1, 0].set_xlabel("t [s]")
    plots.legend_outside(fig)
    _save(fig, path, title)


def limits(path: Path, view: TrackingView, title: str) -> None:
    """Every bounded variable (lengths in mm, bending angles in deg) of every method, with its limits."""
    names, lower, upper = view.arm["config_names"], view.arm["lower"], view.arm["upper"]
    shown = [i for i, name in enumerate(names) if name.startswith(("S", "theta"))]
    scales = {i: (MM, "mm") if names[i].startswith("S") else (DEG, "deg") for i in shown}
    q, styles = _styles(view, "q")
    on = plots.coincident([{m: c[:, i] for m, c in q.items()} for i in shown])
    labels = plots.labelled(list(q), on)
    fig, axes = plots.subplots(len(shown), 1, figsize=(8.6, 1.2 + 1.9 * len(shown)), sharex=True)
    for ax, i in zip(axes[:, 0], shown):
        scale, unit = scales[i]
        for method, values in q.items():
            ax.plot(view.t, values[:, i] * scale, label=labels[method], **styles[method])
        plots.limit_lines(ax, (lower[i] * scale, upper[i] * scale), label="limits (lower, upper)")
        ax.set_ylabel(f"{names[i]} [{unit}]")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t [s]")
    plots.legend_outside(fig)
    _save(fig, path, title)


def lyapunov(path: Path, view: TrackingView, title: str) -> None:
    """``V(e) = e'e/2`` along every run (Seleem et al. 2020, eq. 36 with P = I)."""
    values, styles = _styles(view, "lyapunov")
    clipped = {m: np.maximum(V, 1e-16) for m, V in values.items()}
    labels = plots.labelled(list(clipped), plots.coincident([{m: np.log10(v) for m, v in clipped.items()}]))
    fig, axes = plots.subplots(1, 1, figsize=(8.6, 3.2))
    for name, V in clipped.items():
        axes[0, 0].semilogy(view.t, V, label=labels[name], **styles[name])
    pose = bool(view.curves("orientation_error"))
    axes[0, 0].set_ylabel("V(e) = e'e/2\n[dual-quaternion error]" if pose else "V(e) = e'e/2 [m^2]")
    axes[0, 0].set_xlabel("t [s]")
    axes[0, 0].grid(alpha=0.3, which="both")
    plots.legend_outside(fig)
    _save(fig, path, title)


def step_times(path: Path, view: TrackingView, title: str) -> None:
    """Wall time of every control step (Jacobian evaluation included) [us], per method."""
    seconds_of, styles = _styles(view, "step_time")
    fig, axes = plots.subplots(1, 1, figsize=(8.6, 3.2))
    for name, seconds in seconds_of.items():
        label = f"{name} (median {np.median(seconds) * 1e6:.0f} us)"
        style = {"color": styles[name]["color"], "marker": styles[name].get("marker", "o")}
        axes[0, 0].semilogy(view.t, seconds * 1e6, ls="none", ms=1.5, label=label, **style)
    axes[0, 0].set_ylabel("step time [us]")
    axes[0, 0].set_xlabel("t [s]")
    axes[0, 0].grid(alpha=0.3, which="both")
    plots.legend_outside(fig, markerscale=3)
    _save(fig, path, title)
