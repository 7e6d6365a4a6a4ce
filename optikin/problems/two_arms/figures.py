"""Figures of two-arm runs, drawn from a result's arrays and summary alone.

Backbones (and the rope) in 3-D at a few instants for the joint QP and the first baseline, the
least distance between the two tubes over time against the margin, and the task against its
reference (the rope's lowest point per coordinate, or each arm's tip error).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Any, Mapping

import matplotlib.pyplot as plt
import numpy as np

from optikin.results import Drawer

MM = 1e3
NAMES = {
    "no_collision_rows": "joint QP without collision rows",
    "pseudo_inverse": "pseudo-inverse",
    "pseudo_inverse_saturated": "pseudo-inverse (saturated)",
}
"""Labels of the baselines' curves (the joint QP's comes from its comparison row)."""


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """The figures whose arrays are present."""
    if "t" not in arrays or "reference" not in arrays:
        return {}
    labels = run_labels(arrays, summary)
    title = summary.get("problem", "two_arms")
    out: dict[str, Drawer] = {
        "arm_distance": partial(
            arm_distance, arrays=arrays, labels=labels, title=f"{title}: distance between the arms"
        ),
        "task": partial(task, arrays=arrays, labels=labels, title=f"{title}: task against its reference"),
    }
    if "snapshot_t" in arrays:
        out["backbones"] = partial(backbones, arrays=arrays, labels=labels, title=f"{title}: backbones in 3-D")
    return out


def run_labels(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, str]:
    """Run name -> label, for every run in the arrays (the joint QP first)."""
    solver = [row["method"] for row in summary.get("comparison", []) if row.get("role") == "solver"]
    names = [key[len("clearance_") :] for key in arrays if key.startswith("clearance_")]
    return {name: (solver[0] if solver else "joint QP") if name == "qp" else NAMES.get(name, name) for name in names}


def draw_scene(ax: Any, arrays: Mapping[str, np.ndarray], name: str) -> None:
    """Both backbones (and the rope) of run ``name`` at the snapshot instants on a 3-D axis (mm)."""
    times = arrays["snapshot_t"]
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 1.0, len(times)))
    for k, colour in enumerate(colours):
        for arm in ("arm1", "arm2"):
            points = arrays[f"snapshot_{arm}_{name}"][k] * MM
            ax.plot(*points.T, color=colour, lw=2.5, label=f"t = {times[k]:.2g} s" if arm == "arm1" else None)
        rope = arrays.get(f"snapshot_rope_{name}")
        if rope is not None:
            ax.plot(*(rope[k] * MM).T, color=colour, lw=1.0, ls="--")
    everything = np.concatenate([arrays[f"snapshot_{arm}_{name}"].reshape(-1, 3) for arm in ("arm1", "arm2")]) * MM
    ax.set_box_aspect(np.maximum(np.ptp(everything, axis=0), 1.0))
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")


def backbones(path: Path, arrays: Mapping[str, np.ndarray], labels: Mapping[str, str], title: str) -> None:
    """3-D backbones (solid) and rope (dashed) of the joint QP and the first baseline at a few instants."""
    shown = list(labels)[:2]
    fig = plt.figure(figsize=(5.2 * len(shown), 4.8))
    for panel, name in enumerate(shown):
        ax = fig.add_subplot(1, len(shown), panel + 1, projection="3d")
        draw_scene(ax, arrays, name)
        ax.set_title(labels[name], fontsize=9)
    fig.axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def arm_distance(path: Path, arrays: Mapping[str, np.ndarray], labels: Mapping[str, str], title: str) -> None:
    """The least sampled clearance between the two tubes of every run over time, with the margin and zero."""
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    for name, label in labels.items():
        ax.plot(arrays["t"], arrays[f"clearance_{name}"] * MM, lw=1.0, label=label)
    ax.axhline(arrays["collision_margin"][0] * MM, color="r", ls=":", lw=1.0, label="margin")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("least tube clearance [mm]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def task(path: Path, arrays: Mapping[str, np.ndarray], labels: Mapping[str, str], title: str) -> None:
    """The rope's lowest point per coordinate against its reference, or each arm's tip error over time."""
    t, reference = arrays["t"], arrays["reference"]
    rope = reference.shape[1] == 3
    fig, axes = plt.subplots(3 if rope else 2, 1, figsize=(7.0, 6.5 if rope else 5.0), sharex=True)
    for name, label in labels.items():
        x = arrays[f"x_{name}"]
        if rope:
            for j, ax in enumerate(axes):
                ax.plot(t, x[:, j] * MM, lw=1.0, label=label)
        else:
            for k, ax in enumerate(axes):
                error = np.linalg.norm(x[:, 3 * k : 3 * k + 3] - reference[:, 3 * k : 3 * k + 3], axis=1)
                ax.plot(t, error * MM, lw=1.0, label=label)
    for j, ax in enumerate(axes):
        if rope:
            ax.plot(t, reference[:, j] * MM, "k--", lw=1.2, label="reference")
            ax.set_ylabel(f"lowest point {'xyz'[j]} [mm]")
        else:
            ax.set_ylabel(f"arm {j + 1} tip error [mm]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[0].set_title(title, fontsize=10)
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
