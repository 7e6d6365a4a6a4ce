"""Source ``cosserat`` of family ``recordings``: the Cosserat-rod CBHA of :mod:`optikin.data.cosserat_markers`,
its tube markers as a :class:`~optikin.data.recording.Recording`.

The recorder is :func:`optikin.data.cosserat_markers.cosserat_recording` (two pneumatic
Cosserat sections under gravity, five markers on each tube at its offset from the
backbone, rigid bodies at the base and the tip; every value and its source in
:class:`~optikin.data.cosserat_markers.CosseratMarkerParams`, the ``data.params`` of
this source too). The recording holds:

* markers ``tube<m>_<station>``: tube ``m``'s marker at each station, named ``base``,
  ``s<x>`` for an intermediate station ``x`` in sections from the base (``s1.0``: the end
  of section 1) and ``tip``; each sits at the tube's offset from the backbone, at the
  tube's angle about it from the disk's x axis;
* rigid bodies ``base`` and ``tip``: the material frames at the ends (z along the backbone,
  x the reference of the tube angles), with their noise.

The arm is not a constant-curvature one (gravity, extension, shear): a CC calibration of
it fits effective geometry, and its held-out error says how far a CC model is from it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from optikin.arms.base import ArmModel
from optikin.calibration.synthetic import FAMILY
from optikin.data.cosserat_markers import CosseratMarkerParams, cosserat_recording
from optikin.data.recording import Recording, RigidBodyTrack
from optikin.data.sources import register_source
from optikin.errors import SpecError
from optikin.spec import DataSpec


def station_names(intermediate: tuple[float, ...]) -> list[str]:
    """``base``, ``s<x>`` per intermediate station, ``tip``."""
    return ["base"] + [f"s{x:g}" if x != int(x) else f"s{x:.1f}" for x in intermediate] + ["tip"]


@register_source(
    FAMILY,
    "cosserat",
    "a two-section pneumatic Cosserat-rod CBHA (gravity) recorded by motion capture: tube markers, end bodies",
    params=CosseratMarkerParams,
)
def load_cosserat(arm: ArmModel, data: DataSpec, params: CosseratMarkerParams, path: Path, **_: Any) -> Recording:
    """:func:`~optikin.data.cosserat_markers.cosserat_recording` of ``data.samples`` postures (seed ``data.seed``)
    as a :class:`~optikin.data.recording.Recording` (module docstring)."""
    try:
        rec = cosserat_recording(
            params, data.samples, np.random.default_rng([data.seed, 0]), source=f"{Path(path).name}: cosserat"
        )
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
    names = station_names(tuple(params.intermediate))
    markers = {
        f"tube{m + 1}_{station}": rec.tube_markers[:, m, j].copy()
        for m in range(rec.tube_markers.shape[1])
        for j, station in enumerate(names)
    }
    bodies = {
        "base": RigidBodyTrack(rec.base_position.copy(), rec.base_orientation.copy()),
        "tip": RigidBodyTrack(rec.tip_position.copy(), rec.tip_orientation.copy()),
    }
    return Recording(time=np.asarray(rec.t, dtype=float), markers=markers, bodies=bodies, source=rec.source)
