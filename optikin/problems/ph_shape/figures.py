"""Figures of a ``ph_shape`` result, from its arrays and summary alone (``optikin plot`` redraws them).

``shapes``  PH backbones of six postures with their end points and markers (and the model's vertebra
            centres): arrays ``ph_points``, ``markers``, ``base_position``, ``tip_position`` (``vertebrae`` or
            ``truth_backbone``).
``errors``  distance of each marker to the PH backbone per sample (``marker_distance``; the largest
            vertebra distance, ``vertebra_distance``, when the recording is synthetic; for a Cosserat
            recording the largest truth-backbone distance, ``truth_backbone_distance``, and the tube
            markers' distances to the PH tube curves, ``tube_marker_distance``; with ``c1_joint`` the
            markers' distances to the C1 chain, ``c1_marker_distance``).
``times``   time per sample of every method (``seconds_<method>``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.results import Drawer

MM = 1e3


def prefixed(arrays: Mapping[str, np.ndarray], prefix: str) -> dict[str, np.ndarray]:
    """The arrays whose names start with ``prefix``, by the rest of their name."""
    return {name[len(prefix) :]: value for name, value in arrays.items() if name.startswith(prefix)}


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{name: draw(path)}`` for the figures whose arrays the result has."""
    name, solver = summary.get("problem", "ph_shape"), summary.get("solver", "")
    drawers: dict[str, Drawer] = {}
    if all(k in arrays for k in ("ph_points", "markers", "base_position", "tip_position")):
        points = np.concatenate(
            [arrays["base_position"][:, None], arrays["markers"], arrays["tip_position"][:, None]], axis=1
        )

        def draw_shapes(path: Path) -> None:
            from optikin import plots

            plots.shapes_3d(
                path,
                arrays["ph_points"],
                points,
                f"{name}: PH backbones ({solver}) and markers",
                arrays.get("vertebrae", arrays.get("truth_backbone")),
            )

        drawers["shapes"] = draw_shapes
    if "marker_distance" in arrays:
        distance = arrays["marker_distance"] * MM
        series = {"marker distance": distance}
        labels = {"marker distance": [f"marker {k + 1}" for k in range(distance.shape[1])]}
        if "vertebra_distance" in arrays:
            series["model backbone distance"] = arrays["vertebra_distance"].max(axis=1) * MM
            labels["model backbone distance"] = ["largest vertebra distance"]
        if "truth_backbone_distance" in arrays:
            series["truth backbone distance"] = arrays["truth_backbone_distance"].max(axis=1) * MM
            labels["truth backbone distance"] = ["largest node distance"]
        if "c1_marker_distance" in arrays:
            series["marker distance to C1 chain"] = arrays["c1_marker_distance"] * MM
            labels["marker distance to C1 chain"] = [f"marker {k + 1}" for k in range(distance.shape[1])]
        if "tube_marker_distance" in arrays:
            tubes = arrays["tube_marker_distance"] * MM  # (N, tube, station)
            series["tube marker distance"] = tubes.mean(axis=1)
            labels["tube marker distance"] = [f"station {j + 1}" for j in range(tubes.shape[2])]  # mean of the tubes

        def draw_errors(path: Path) -> None:
            from optikin import plots

            plots.per_sample(path, series, "[mm]", f"{name}: distance to the PH backbone", labels)

        drawers["errors"] = draw_errors
    seconds = prefixed(arrays, "seconds_")
    if seconds:

        def draw_times(path: Path) -> None:
            from optikin import plots

            plots.times_per_sample(path, seconds, f"{name}: time per sample", plots.roles_of(summary))

        drawers["times"] = draw_times
    return drawers
