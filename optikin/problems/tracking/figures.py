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

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, Callable, Mapping

import matplotlib.pyplot as plt
import numpy as np

from optikin.algebra import dq_rotation, dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.control.simulate import DEG, MM, TrackingRun
from optikin.results import Drawer


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
    """What the figures draw: times, the reference tip position, the arm's limits and one :class:`Trace` per label."""

    t: np.ndarray
    reference_position: np.ndarray
    arm: Mapping[str, Any]
    traces: dict[str, Trace]

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
    view = TrackingView(arrays["t"], arrays["reference_position"], summary.get("arm", {}), traces(arrays, summary))
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
        out["obstacles"] = partial(obstacles, arrays=arrays, labels=labels, title=f"{title}: backbones and obstacles")
    return out


def obstacles(path: Path, arrays: Mapping[str, np.ndarray], labels: Mapping[str, str], title: str) -> None:
    """3-D backbones of the QP and the first baseline at a few instants with the obstacles, and every
    method's least backbone-to-obstacle distance over time against the margin."""
    fig = plt.figure(figsize=(11.0, 4.8))
    shown = list(labels)[:2]
    times = arrays["snapshot_t"]
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 1.0, len(times)))
    for panel, name in enumerate(shown):
        ax = fig.add_subplot(1, len(shown) + 1, panel + 1, projection="3d")
        for k, colour in enumerate(colours):
            shell = arrays["snapshot_obstacles"][k] * MM
            ax.scatter(*shell.T, s=2, color=colour, alpha=0.3)
            backbone = arrays[f"snapshot_backbone_{name}"][k] * MM
            ax.plot(*backbone, color=colour, lw=2.0, label=f"t = {times[k]:.2g} s")
        ax.set_title(labels[name], fontsize=9)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_zlabel("z [mm]")
    fig.axes[0].legend(fontsize=7, loc="upper left")
    ax = fig.add_subplot(1, len(shown) + 1, len(shown) + 1)
    for name, label in labels.items():
        ax.plot(arrays["t"], arrays[f"clearance_{name}"] * MM, lw=1.0, label=label)
    ax.axhline(arrays["barrier_margin"][0] * MM, color="r", ls=":", lw=1.0, label="margin")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("least backbone distance [mm]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
    return str(BASELINES[name].name) if name in BASELINES else name


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
    fig.axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def reference_vs_actual(path: Path, view: TrackingView, title: str) -> None:
    """Tip position x, y, z of every method against the reference (Seleem et al. 2020, Fig. 26)."""
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.0), sharex=True)
    for j, (ax, label) in enumerate(zip(axes, "xyz")):
        ax.plot(view.t, view.reference_position[:, j] * MM, "k--", lw=1.5, label="reference")
        for name, position in view.curves("position").items():
            ax.plot(view.t, position[:, j] * MM, lw=1.0, label=name)
        ax.set_ylabel(f"{label} [mm]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=2)
    _save(fig, path, title)


def errors(path: Path, view: TrackingView, title: str) -> None:
    """Position error [mm] and, for pose tracking, orientation error [deg] over time (Figs. 25, 27)."""
    angles = view.curves("orientation_error")
    pose = bool(angles)
    fig, axes = plt.subplots(2 if pose else 1, 1, figsize=(7.0, 5.0 if pose else 3.0), sharex=True, squeeze=False)
    for name, error in view.curves("position_error").items():
        axes[0, 0].semilogy(view.t, np.maximum(error * MM, 1e-6), lw=1.0, label=name)
        if name in angles:
            axes[1, 0].semilogy(view.t, np.maximum(angles[name] * DEG, 1e-6), lw=1.0, label=name)
    axes[0, 0].set_ylabel("position error [mm]")
    if pose:
        axes[1, 0].set_ylabel("orientation error [deg]")
    for ax in axes[:, 0]:
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].legend(fontsize=8)
    _save(fig, path, title)


def limits(path: Path, view: TrackingView, title: str) -> None:
    """Every bounded variable (lengths in mm, bending angles in deg) of every method, with its limits."""
    names, lower, upper = view.arm["config_names"], view.arm["lower"], view.arm["upper"]
    shown = [i for i, name in enumerate(names) if name.startswith(("S", "theta"))]
    fig, axes = plt.subplots(len(shown), 1, figsize=(7.0, 1.9 * len(shown)), sharex=True, squeeze=False)
    for ax, i in zip(axes[:, 0], shown):
        scale, unit = (MM, "mm") if names[i].startswith("S") else (DEG, "deg")
        for method, q in view.curves("q").items():
            ax.plot(view.t, q[:, i] * scale, lw=1.0, label=method)
        for bound in (lower[i], upper[i]):
            ax.axhline(bound * scale, color="r", lw=0.8, ls=":")
        ax.set_ylabel(f"{names[i]} [{unit}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=2)
    _save(fig, path, title)


def lyapunov(path: Path, view: TrackingView, title: str) -> None:
    """``V(e) = e'e/2`` along every run (Seleem et al. 2020, eq. 36 with P = I)."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    for name, V in view.curves("lyapunov").items():
        ax.semilogy(view.t, np.maximum(V, 1e-16), lw=1.0, label=name)
    ax.set_ylabel("V(e) = e'e/2")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    _save(fig, path, title)


def step_times(path: Path, view: TrackingView, title: str) -> None:
    """Wall time of every control step (Jacobian evaluation included), per method."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    for name, seconds in view.curves("step_time").items():
        label = f"{name} (median {np.median(seconds) * 1e6:.0f} us)"
        ax.semilogy(view.t, seconds * 1e6, ".", ms=1.5, label=label)
    ax.set_ylabel("step time [us]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, markerscale=6)
    _save(fig, path, title)
