"""The ``dmp`` kind's figures, drawn from a result's arrays and summary alone.

``reproduction_error``
    the position [mm] and orientation [mrad] error of every variant's
    reproduction against the demonstration, one panel each; the ``seed`` variants'
    position panels also draw the structural bound ``| |p(t)| - 2 |Q_d| |``;
``<variant>_<scenario>``
    the unit quaternion ``Q_r`` [-] (and ``Q_d`` [m] of the dual-quaternion variants)
    of the reproduction, the goal-switch roll-out and the roll-out coupled to
    the demonstration under the disturbance, over the demonstration where the
    lengths agree (variants with an orientation quaternion only).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.algebra import dq_from_rotation_translation
from optikin.problems.dmp.report import rollout_key
from optikin.problems.dmp.variants import DUAL, pose_errors, structural_bound, unit_of, variant_pose
from optikin.results import Drawer

QUATERNION_SCENARIOS = ("reproduction", "goal switch", "perturbation coupled")
"""The roll-outs whose quaternions are drawn."""


def variants_of(arrays: Mapping[str, np.ndarray]) -> list[str]:
    """The variants of a result, in the order they were run (each has a reproduction array)."""
    suffix = "__reproduction"
    return [name[: -len(suffix)] for name in arrays if name.endswith(suffix)]


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{figure name: drawer}`` of a ``dmp`` result (the module docstring); empty without the demonstration."""
    if not {"t", "demo_position", "demo_quaternion"} <= set(arrays):
        return {}
    name = str(summary["problem"])
    variants = variants_of(arrays)
    out: dict[str, Drawer] = {}
    if variants:
        out["reproduction_error"] = _errors_figure(arrays, variants, name, "reproduction")
    for variant in variants:
        if variant in ("position", "rpy"):
            continue
        for scenario in QUATERNION_SCENARIOS:
            if rollout_key(variant, scenario) in arrays:
                out[f"{variant}_{scenario.replace(' ', '_')}"] = _quaternion_figure(arrays, variant, name, scenario)
    return out


def _errors_figure(arrays: Mapping[str, np.ndarray], variants: list[str], name: str, scenario: str) -> Drawer:
    t, position, quaternion = arrays["t"], arrays["demo_position"], arrays["demo_quaternion"]

    def draw(path: Path) -> None:
        from optikin import plots

        series, units, n = {}, {}, len(t)
        for variant in variants:
            y = arrays[rollout_key(variant, scenario)]
            n = min(len(y), len(t))
            bound = structural_bound(variant, y[:n], position[:n])
            for k, v in pose_errors(variant, y[:n], position[:n], quaternion[:n]).items():
                unit, factor = unit_of(k)
                label = f"{k} error" if variant == k else f"{variant}\n{k} error"
                lines = [v] if k != "position" or bound is None else [v, bound[1]]  # beside |Q_d| fixed's bound
                series[label], units[label] = np.stack(lines, axis=1) * factor, f"[{unit}]"
        labels = ("error", "structural bound (|Q_d| fixed)")
        plots.time_series(path, t[:n], series, units, f"{name}: {scenario} error", labels=labels)

    return draw


def _quaternion_figure(arrays: Mapping[str, np.ndarray], variant: str, name: str, scenario: str) -> Drawer:
    demo_t, demo_q = arrays["t"], arrays["demo_quaternion"]
    y = arrays[rollout_key(variant, scenario)]
    dual = variant in DUAL

    def draw(path: Path) -> None:
        from optikin import plots

        _, q = variant_pose(variant, y)
        assert q is not None, f"variant {variant} has no orientation quaternion"
        t = np.arange(len(y)) * (demo_t[1] - demo_t[0])
        series = {f"{variant} Q_r": q}
        if dual:
            series[f"{variant} Q_d"] = y[:, 4:]
        if len(y) == len(demo_t):  # the demonstration above its reproduction
            shown: dict[str, np.ndarray] = {"demonstration Q_r": demo_q}
            if dual:
                demo_dq = dq_from_rotation_translation(demo_q, arrays["demo_position"], check=False)
                shown["demonstration Q_d"] = demo_dq[:, 4:]
            series = shown | series
        units = {label: "[m]" if label.endswith("Q_d") else "[-]" for label in series}  # Q_d = t Q_r / 2
        plots.time_series(path, t, series, units, f"{name}: {variant}, {scenario}", labels=("w", "x", "y", "z"))

    return draw
