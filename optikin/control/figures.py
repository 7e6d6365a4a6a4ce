"""Figures of tracking runs: reference vs actual (seed 000 Figs. 22-23, 26), errors (Figs. 25, 27),
configuration against its limits, the Lyapunov function and per-step solve times.

Each function takes ``{method name: TrackingRun}`` and a PNG path (Agg backend via :mod:`optikin.plots`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from optikin import plots  # noqa: F401  (selects the Agg backend)
from optikin.control.simulate import DEG, MM, TrackingRun

import matplotlib.pyplot as plt  # noqa: E402


def _save(fig, path: Path, title: str) -> None:
    fig.axes[0].set_title(title)
    fig.axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def reference_vs_actual(path: Path, runs: dict[str, TrackingRun], title: str) -> None:
    """Tip position x, y, z of every method against the reference (seed 000 Fig. 26)."""
    first = next(iter(runs.values()))
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.0), sharex=True)
    for j, (ax, label) in enumerate(zip(axes, "xyz")):
        ax.plot(first.t, first.reference.position[:, j] * MM, "k--", lw=1.5, label="reference")
        for name, run in runs.items():
            ax.plot(run.t, run.position[:, j] * MM, lw=1.0, label=name)
        ax.set_ylabel(f"{label} [mm]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=2)
    _save(fig, path, title)


def errors(path: Path, runs: dict[str, TrackingRun], title: str) -> None:
    """Position error (mm) and, for pose tracking, orientation error (deg) over time (seed 000 Figs. 25, 27)."""
    pose = next(iter(runs.values())).reference.task == "pose"
    fig, axes = plt.subplots(2 if pose else 1, 1, figsize=(7.0, 5.0 if pose else 3.0), sharex=True, squeeze=False)
    for name, run in runs.items():
        axes[0, 0].semilogy(run.t, np.maximum(run.position_error * MM, 1e-6), lw=1.0, label=name)
        if pose:
            axes[1, 0].semilogy(run.t, np.maximum(run.orientation_error * DEG, 1e-6), lw=1.0, label=name)
    axes[0, 0].set_ylabel("position error [mm]")
    if pose:
        axes[1, 0].set_ylabel("orientation error [deg]")
    for ax in axes[:, 0]:
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].legend(fontsize=8)
    _save(fig, path, title)


def limits(path: Path, runs: dict[str, TrackingRun], title: str) -> None:
    """Every bounded variable (lengths in mm, bending angles in deg) of every method, with its limits."""
    first = next(iter(runs.values()))
    arm = first.arm
    shown = [i for i, n in enumerate(arm.config_names) if n.startswith(("S", "theta"))]
    fig, axes = plt.subplots(len(shown), 1, figsize=(7.0, 1.9 * len(shown)), sharex=True, squeeze=False)
    for ax, i in zip(axes[:, 0], shown):
        name = arm.config_names[i]
        scale, unit = (MM, "mm") if name.startswith("S") else (DEG, "deg")
        for method, run in runs.items():
            ax.plot(run.t, run.q[:, i] * scale, lw=1.0, label=method)
        for bound in (arm.lower[i], arm.upper[i]):
            ax.axhline(bound * scale, color="r", lw=0.8, ls=":")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=2)
    _save(fig, path, title)


def lyapunov(path: Path, runs: dict[str, TrackingRun], title: str) -> None:
    """``V(e) = e'e/2`` along every run (seed 000 eq. 36, P = I)."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    for name, run in runs.items():
        ax.semilogy(run.t, np.maximum(run.lyapunov, 1e-16), lw=1.0, label=name)
    ax.set_ylabel("V(e) = e'e/2")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    _save(fig, path, title)


def step_times(path: Path, runs: dict[str, TrackingRun], title: str) -> None:
    """Wall time of every control step (Jacobian evaluation included), per method."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    for name, run in runs.items():
        label = f"{name} (median {np.median(run.step_time) * 1e6:.0f} us)"
        ax.semilogy(run.t, run.step_time * 1e6, ".", ms=1.5, label=label)
    ax.set_ylabel("step time [us]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, markerscale=6)
    _save(fig, path, title)

