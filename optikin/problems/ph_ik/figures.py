"""Figures of a ``ph_ik`` result, from its arrays and summary alone (``optikin plot`` redraws them).

``errors``  the solver's tube-length errors and the reference lengths per sample (arrays
            ``tube_lengths``, ``reference_tube_lengths``; the frame is the one whose other-frame
            array ``tube_lengths_<frame>`` is absent).
``times``   IK time per sample of every method and comparator (``ik_seconds_<method>``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.problems.ph_shape.figures import prefixed
from optikin.results import Drawer

MM = 1e3
TUBES = ["L1", "L2", "L3"]


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{name: draw(path)}`` for the figures whose arrays the result has."""
    name, solver = summary.get("problem", "ph_ik"), summary.get("solver", "")
    drawers: dict[str, Drawer] = {}
    if "tube_lengths" in arrays and "reference_tube_lengths" in arrays:
        reference = arrays["reference_tube_lengths"]
        series = {
            "tube-length error": np.abs(arrays["tube_lengths"] - reference) * MM,
            "reference length": reference * MM,
        }
        frame = "euler_rodrigues" if "tube_lengths_rmf" in arrays else "rmf"

        def draw_errors(path: Path) -> None:
            from optikin import plots

            plots.per_sample(
                path,
                series,
                "[mm]",
                f"{name}: tube-length errors abs(L - L_ref) ({solver}, {frame} frame)",
                {"tube-length error": TUBES, "reference length": TUBES},
            )

        drawers["errors"] = draw_errors
    seconds = prefixed(arrays, "ik_seconds_")
    if seconds:

        def draw_times(path: Path) -> None:
            from optikin import plots

            plots.times_per_sample(
                path, seconds, f"{name}: IK time per sample (shape + tubes)", plots.roles_of(summary)
            )

        drawers["times"] = draw_times
    return drawers
