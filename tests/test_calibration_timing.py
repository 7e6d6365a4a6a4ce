"""Calibration of a three-section CC arm on 669 postures x 3 markers (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    pytest tests/test_calibration_timing.py --benchmark-only

The recording of ``problems/trunk-calibrate.yaml`` (669 postures, three disks, 0.3 mm
noise), clean and with 3 % of the postures' labels swapped; one round is a whole
:func:`optikin.calibration.calibrate.calibrate` (start, screening fit, outliers,
final fit, covariance), the CasADi functions built once beforehand (they are cached
per marker layout). ``extra_info`` holds the median thread CPU time of a round.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.calibration.calibrate import calibrate
from optikin.calibration.synthetic import rpy_matrix, synthetic_recording

NAMES = ["disk1", "disk2", "disk3"]


@pytest.mark.parametrize("corrupted", [0.0, 0.03], ids=["clean", "swaps_3pc"])
def test_calibrate_669_postures(benchmark, corrupted):
    recording = synthetic_recording(
        ConstantCurvatureArm((0.1, 0.1, 0.1)),
        669,
        np.random.default_rng([7, 0]),
        section_lengths=np.array([0.1058, 0.0949, 0.1144]),
        base_position=np.array([0.03, -0.02, 0.65]),
        base_rotation=rpy_matrix(np.radians(183.0), np.radians(-2.0), np.radians(20.0)),
        theta_max=1.2,
        corrupted_fraction=corrupted,
    )
    measured = recording.marker_array(NAMES)
    calibrate(measured[:20], [0.1, 0.1, 0.1], [1, 2, 3])  # build the functions
    cpu: list[float] = []

    def once():
        start = time.thread_time()
        result = calibrate(measured, [0.1, 0.1, 0.1], [1, 2, 3], NAMES)
        cpu.append(time.thread_time() - start)
        return result

    cal = benchmark.pedantic(once, rounds=5, iterations=1)
    benchmark.extra_info["thread_cpu_median_s"] = float(np.median(cpu))
    benchmark.extra_info["rejected"] = len(cal.outliers)
    assert len(cal.outliers) == int(recording.truth.corrupted.sum())
    assert np.abs(cal.lengths - recording.truth.section_lengths).max() < 0.5e-3
