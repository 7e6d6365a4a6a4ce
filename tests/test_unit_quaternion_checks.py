"""Every option holding a unit quaternion is checked by optikin.checks.check_quaternion, with its one tolerance."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from optikin.checks import UNIT_TOLERANCE
from optikin.data.cosserat_markers import CosseratMarkerParams
from optikin.data.targets import BasePose
from optikin.physics import Rod, RodArm

ROD = Rod(length=0.3, radius=0.01, youngs_modulus=1e6, poisson_ratio=0.5)


def _off_unit(by: float) -> tuple[float, float, float, float]:
    """A quaternion whose norm is ``1 + by``."""
    return tuple(float(v) for v in (1.0 + by) * np.array([0.6, 0.0, 0.8, 0.0]))  # type: ignore[return-value]


@pytest.mark.parametrize(
    "make",
    [
        lambda q: RodArm.single(ROD, base_orientation=q),
        lambda q: CosseratMarkerParams(base_orientation=q),
        lambda q: BasePose(quaternion=q),
    ],
    ids=["RodArm", "CosseratMarkerParams", "BasePose"],
)
def test_a_norm_off_one_by_more_than_the_tolerance_is_refused_and_within_it_accepted(make):
    make(_off_unit(0.5 * UNIT_TOLERANCE))
    with pytest.raises(ValidationError, match=r"has norm 1\.00001: not a unit quaternion \(\| \|q\| - 1 \| > 1e-06\)"):
        make(_off_unit(1e-5))
