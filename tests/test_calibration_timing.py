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


def scipy_calibration(measured: np.ndarray, lengths: list[float]) -> tuple[np.ndarray, float]:
    """The same problem (clean, one robust fit of every posture) by ``scipy.optimize.least_squares``: method
    ``trf``, ``loss="soft_l1"``, ``f_scale`` 1 mm, the exact Jacobian from the same CasADi functions as a sparse
    matrix (``jac_sparsity`` given), from the same start. Returns the section lengths and the wall time."""
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    from optikin.calibration.calibrate import chord_configurations, initial_base, marker_model
    from optikin.calibration.model import Layout

    layout = Layout(3, (1, 2, 3))
    model = marker_model(layout)
    N, M = measured.shape[:2]
    p0, ref = initial_base(measured, (1, 2, 3), lengths[0])
    X0 = chord_configurations(measured, layout, np.array(lengths), p0, ref)
    beta0 = np.zeros(layout.n_beta)
    beta0[layout.lengths], beta0[layout.position] = lengths, p0
    free = np.zeros(layout.n_beta, dtype=bool)
    free[: 3 + 3 + 2] = True  # lengths, position, tilt
    nx, nf, k = layout.n_x, int(free.sum()), 3 * M
    rows = np.repeat(np.arange(N * k), nx + nf)
    cols = np.concatenate(
        [np.concatenate([np.arange(n * nx, (n + 1) * nx), N * nx + np.arange(nf)]) for n in range(N) for _ in range(k)]
    )
    sparsity = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(N * k, N * nx + nf))

    def split(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        beta = beta0.copy()
        beta[free] = z[N * nx :]
        return z[: N * nx].reshape(N, nx), beta

    def residual(z: np.ndarray) -> np.ndarray:
        X, beta = split(z)
        return (model.evaluate(X, beta, ref, False)[0] - measured.reshape(N, k)).ravel()

    def jacobian(z: np.ndarray) -> csr_matrix:
        X, beta = split(z)
        _, Jx, Jb = model.evaluate(X, beta, ref, True)
        values = np.concatenate([Jx, Jb[:, :, free]], axis=2).ravel()
        return csr_matrix((values, (rows, cols)), shape=sparsity.shape)

    start = time.perf_counter()
    z0 = np.concatenate([X0.ravel(), beta0[free]])
    solution = least_squares(residual, z0, jac=jacobian, method="trf", loss="soft_l1", f_scale=1e-3, x_scale="jac")
    seconds = time.perf_counter() - start
    return split(solution.x)[1][:3], seconds


def test_scipy_trf_on_the_same_problem(benchmark):
    """The alternative the solver was chosen against (BENCHMARKS.md): scipy's sparse trust-region reflective."""
    recording = synthetic_recording(
        ConstantCurvatureArm((0.1, 0.1, 0.1)),
        669,
        np.random.default_rng([7, 0]),
        section_lengths=np.array([0.1058, 0.0949, 0.1144]),
        base_position=np.array([0.03, -0.02, 0.65]),
        base_rotation=rpy_matrix(np.radians(183.0), np.radians(-2.0), np.radians(20.0)),
        theta_max=1.2,
    )
    measured = recording.marker_array(NAMES)
    lengths, _ = benchmark.pedantic(scipy_calibration, args=(measured, [0.1, 0.1, 0.1]), rounds=3, iterations=1)
    assert np.abs(lengths - recording.truth.section_lengths).max() < 0.5e-3
