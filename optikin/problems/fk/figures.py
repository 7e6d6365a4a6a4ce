"""Figures of an ``fk`` result, from its arrays and summary alone (``optikin plot`` redraws them).

``backbones``  up to 12 backbones in 3-D with their section ends (arrays ``backbone``, ``section_dq``),
               coloured by time (``t``) or sample.
``tip``        the tip position over time (``tip_position``, ``t``), or, without sample times,
               the tip positions in 3-D coloured by their distance from the base.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.algebra import dq_translation
from optikin.results import Drawer

MM = 1e3


def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Drawer]:
    """``{name: draw(path)}`` for the figures whose arrays the result has."""
    name = summary.get("problem", "fk")
    arm = (summary.get("arm") or {}).get("name", "arm")
    drawers: dict[str, Drawer] = {}
    if "backbone" in arrays:
        backbone = arrays["backbone"]
        ends = dq_translation(arrays["section_dq"]) if "section_dq" in arrays else None
        times = arrays.get("t")

        def draw_backbones(path: Path) -> None:
            from optikin import plots

            plots.backbones_3d(path, backbone, f"{name}: backbones ({arm})", ends, t=times)

        drawers["backbones"] = draw_backbones
    if "tip_position" in arrays:
        position, t = arrays["tip_position"], arrays.get("t")

        def draw_tip(path: Path) -> None:
            from optikin import plots

            if t is not None:
                plots.time_series(path, t, {"tip position": position * MM}, "[mm]", f"{name}: tip position")
            else:
                plots.scatter_3d(
                    path,
                    position,
                    f"{name}: tip positions",
                    colour=np.linalg.norm(position, axis=1) * MM,
                    colour_label="distance from base [mm]",
                )

        drawers["tip"] = draw_tip
    return drawers
