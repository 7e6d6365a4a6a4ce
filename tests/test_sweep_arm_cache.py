"""A sweep worker's per-process arm cache: one arm per distinct ``{type, params}``, answers of a fresh arm."""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms import build_arm
from optikin.errors import SpecError
from optikin.sweep.cell import cached_arm

PARAMS = {"section_lengths": [0.18, 0.18], "length_range": [0.9, 1.1], "theta_max": 2.0}


def test_one_arm_per_spec_with_the_answers_of_a_fresh_one():
    arm = cached_arm("constant_curvature", dict(PARAMS))
    assert cached_arm("constant_curvature", dict(reversed(list(PARAMS.items())))) is arm  # key order is no matter
    other = cached_arm("constant_curvature", PARAMS | {"theta_max": 1.5})
    assert other is not arm and other.upper.tolist() != arm.upper.tolist()
    Q = arm.sample_configurations(5, np.random.default_rng(0))
    fresh = build_arm("constant_curvature", PARAMS)
    assert arm.evaluate("fk_dq", Q).tobytes() == fresh.evaluate("fk_dq", Q).tobytes()


def test_a_bad_arm_fails_every_time():
    for _ in range(2):
        with pytest.raises(SpecError, match="arm.params"):
            cached_arm("constant_curvature", PARAMS | {"theta_max": "wide"})
