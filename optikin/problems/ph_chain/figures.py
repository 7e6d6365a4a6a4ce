"""Figures of a ``ph_chain`` result, from its arrays and summary alone (``optikin plot`` redraws them).

``shapes``  the chain CBHA 1, rope, CBHA 2 of three postures: PH links, markers and ground truth (arrays
            ``<link>_ph_points``, ``<link>_markers``, ``arm1_vertebrae``, ``rope_truth``, ``arm2_vertebrae``;
            links ``arm1``, ``rope``, ``arm2``).
``errors``  marker distance per link and sample (``<link>_marker_distance``).
``times``   time per sample of every method and link (``seconds_<link>_<method>``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.results import Drawer

MM = 1e3
LINKS = {"arm1": "CBHA 1", "rope": "rope", "arm2": "CBHA 2"}
TRUTHS = {"arm1": "arm1_vertebrae", "rope": "rope_truth", "arm2": "arm2_vertebrae"}


def time_series(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``{"<method> (<link>)": seconds}`` of the ``seconds_<link>_<method>`` arrays."""
    out: dict[str, np.ndarray] = {}
    for key, link in LINKS.items():
        prefix = f"seconds_{key}_"
        out |= {f"{name[len(prefix) :]} ({link})": value for name, value in arrays.items() if name.startswith(prefix)}
    return out


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{name: draw(path)}`` for the figures whose arrays the result has."""
    name, solver = summary.get("problem", "ph_chain"), summary.get("solver", "")
    drawers: dict[str, Drawer] = {}
    needed = [f"{k}_{part}" for k in LINKS for part in ("ph_points", "markers")] + list(TRUTHS.values())
    if all(k in arrays for k in needed):

        def draw_shapes(path: Path) -> None:
            from optikin import plots

            plots.chains_3d(
                path,
                [arrays[f"{k}_ph_points"] for k in LINKS],
                [arrays[f"{k}_markers"] for k in LINKS],
                [arrays[TRUTHS[k]] for k in LINKS],
                f"{name}: CBHA 1, rope, CBHA 2 ({solver})",
            )

        drawers["shapes"] = draw_shapes
    if all(f"{k}_marker_distance" in arrays for k in LINKS):
        series = {link: arrays[f"{k}_marker_distance"] * MM for k, link in LINKS.items()}

        def draw_errors(path: Path) -> None:
            from optikin import plots

            plots.per_sample(path, series, "marker distance [mm]", f"{name}: marker distance per link")

        drawers["errors"] = draw_errors
    seconds = time_series(arrays)
    if seconds:

        def draw_times(path: Path) -> None:
            from optikin import plots

            plots.times_per_sample(path, seconds, f"{name}: time per sample and link", plots.roles_of(summary))

        drawers["times"] = draw_times
    return drawers
