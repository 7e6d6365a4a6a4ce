"""The calibrated arm as a problem-file ``arm:`` section, and the calibration facts that go with it.

:func:`arm_section` gives ``{"type": "constant_curvature", "params": {...}}`` with the
estimated section lengths (an extensible arm: the median lengths, with the
``length_range`` covering every posture's length), ready for the ``arm:`` field
of other problem files. :func:`write_arm_file` writes it as YAML under the key
``arm``, next to a ``calibration`` mapping holding what an arm section cannot carry:
the base pose in the recording frame, the marker offsets, the standard deviations
and the held-out error.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from optikin.algebra import quat_from_matrix
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.calibration.calibrate import Calibration


def arm_section(calibration: Calibration, nominal: ConstantCurvatureArm) -> dict[str, Any]:
    """The ``arm:`` section of the calibrated arm.

    Parameters
    ----------
    calibration : Calibration
        The calibration.
    nominal : ConstantCurvatureArm
        The arm the calibration started from (its bounds on ``theta`` and its ``length_range``
        are kept, widened to every posture's length for an extensible arm).

    Returns
    -------
    dict
        ``{"type": "constant_curvature", "params": {section_lengths, length_range, theta_max, name}}``.
    """
    lengths = calibration.lengths
    lo, hi = nominal.length_range
    if calibration.layout.extensible:
        ranges = calibration.length_ranges / lengths[:, None]
        lo, hi = min(lo, float(ranges[:, 0].min())), max(hi, float(ranges[:, 1].max()))
    return {
        "type": "constant_curvature",
        "params": {
            "section_lengths": [round(float(v), 7) for v in lengths],
            "length_range": [round(float(lo), 6), round(float(hi), 6)],
            "theta_max": float(nominal.theta_max),
            "name": f"{nominal.name}-calibrated",
        },
    }


def calibration_facts(calibration: Calibration, held_out_median: float | None = None) -> dict[str, Any]:
    """The base pose [m, unit quaternion (w, x, y, z)], marker offsets [m], standard deviations and held-out error."""
    names = calibration.names
    std = calibration.fit.std
    facts: dict[str, Any] = {
        "base_position": [round(float(v), 7) for v in calibration.base_position],
        "base_quaternion": [round(float(v), 9) for v in quat_from_matrix(calibration.base_rotation)],
        "marker_offsets": {
            name: [round(float(v), 7) for v in offset]
            for name, offset in zip(calibration.marker_names, calibration.offsets)
        },
        "std": {n: float(f"{s:.3g}") for n, s in zip(names, std) if s > 0},
        "postures_used": int(len(calibration.kept)),
        "postures_rejected": len(calibration.outliers),
        "median_marker_error": float(f"{np.nanmedian(calibration.fit.errors):.4g}"),
    }
    if held_out_median is not None:
        facts["held_out_median_marker_error"] = float(f"{held_out_median:.4g}")
    return facts


def write_arm_file(path: Path, section: dict[str, Any], facts: dict[str, Any], origin: str) -> None:
    """Write ``{"arm": section, "calibration": facts}`` as YAML to ``path``, with a header naming ``origin``."""
    text = yaml.safe_dump({"arm": section, "calibration": facts}, sort_keys=False)
    header = f"# calibrated arm written by optikin (kind calibrate) from {origin}; lengths in metres\n"
    Path(path).write_text(header + text)
