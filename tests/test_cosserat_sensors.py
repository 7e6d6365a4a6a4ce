"""Sensors on the Cosserat CBHA: gyro integration against closed-form rotations, the noise statistics and the bias
random walk's variance growth against the stated figures, the depth camera's depth-dependent sigma, and the sources."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from optikin.data.cosserat_sensors import (
    CosseratSensorParams,
    DepthCameraModel,
    ImuModel,
    body_rates,
    cosserat_sensor_recording,
    depth_camera_readings,
    gyro_readings,
    integrate_gyro,
)

DT = 0.01


def wxyz(r: Rotation) -> np.ndarray:
    """``(w, x, y, z)`` quaternions of scipy rotations."""
    return r.as_quat()[..., [3, 0, 1, 2]]


def test_integrating_a_constant_rate_gives_the_rotation_about_its_axis_by_rate_times_time():
    omega = np.array([0.3, -0.4, 1.2])  # rad/s, body frame
    q0 = wxyz(Rotation.from_euler("xyz", [0.2, -0.5, 1.0]))
    q = integrate_gyro(q0, np.tile(omega, (500, 1)), DT)
    t = np.arange(501) * DT
    expected = Rotation.from_quat(q0[[1, 2, 3, 0]]) * Rotation.from_rotvec(t[:, None] * omega)
    error = (Rotation.from_quat(q[:, [1, 2, 3, 0]]).inv() * expected).magnitude()
    assert error.max() < 1e-12


def test_body_rates_recover_the_rate_that_made_a_motion():
    rng = np.random.default_rng(0)
    rates = rng.normal(size=(50, 2, 3))
    q0 = wxyz(Rotation.random(2, random_state=1))
    q = integrate_gyro(q0, rates, DT)
    assert np.abs(body_rates(q, DT) - rates).max() < 1e-9


def test_white_gyro_noise_has_the_standard_deviation_of_its_density_over_root_dt():
    model = ImuModel(noise_density=1e-3, bias_random_walk=0.0)
    measured, bias = gyro_readings(np.zeros((200_000, 3)), DT, model, np.random.default_rng(2))
    assert np.all(bias == 0)
    sigma = 1e-3 / np.sqrt(DT)
    assert np.abs(measured.std(axis=0) / sigma - 1).max() < 0.01  # 3 sigma of the estimate: 0.5 %
    assert np.abs(measured.mean(axis=0)).max() < 5 * sigma / np.sqrt(200_000)


def test_the_bias_variance_grows_linearly_in_time_at_the_random_walk_density_squared():
    model = ImuModel(noise_density=0.0, bias_random_walk=2e-3, initial_bias=0.0)
    runs = 4000
    _, bias = gyro_readings(np.zeros((400, runs, 3)), DT, model, np.random.default_rng(3))
    for k in (100, 200, 399):
        variance = bias[k].var()  # over runs and axes: 12,000 samples
        assert abs(variance / (2e-3**2 * k * DT) - 1) < 0.05


def test_the_integrated_angle_error_grows_like_the_angle_random_walk():
    # Small angles: the error about an axis is sum(noise * dt), standard deviation noise_density sqrt(t).
    model = ImuModel(noise_density=2e-3, bias_random_walk=0.0)
    runs, steps = 2000, 400
    q0 = np.tile([1.0, 0.0, 0.0, 0.0], (runs, 1))
    measured, _ = gyro_readings(np.zeros((steps, runs, 3)), DT, model, np.random.default_rng(4))
    q = integrate_gyro(q0, measured, DT)
    angle = Rotation.from_quat(q[-1][:, [1, 2, 3, 0]]).as_rotvec()
    assert abs(angle.std() / (2e-3 * np.sqrt(steps * DT)) - 1) < 0.03


@pytest.mark.parametrize("depth", [0.8, 2.5])
def test_the_depth_camera_noise_follows_the_axial_and_lateral_sigma_at_the_depth(depth):
    camera = DepthCameraModel(position=(0.0, 0.0, 0.0), look_at=(0.0, 0.0, -1.0))  # looking down -z
    point = np.array([0.05, -0.02, -depth])
    measured = depth_camera_readings(np.tile(point, (100_000, 1)), camera, np.random.default_rng(5))
    error = measured - point
    axial = 1.2e-3 + 1.9e-3 * (depth - 0.4) ** 2  # Nguyen et al. 2012
    lateral = 0.8 / 585 * depth
    assert abs(error[:, 2].std() / axial - 1) < 0.02
    assert np.abs(error[:, :2].std(axis=0) / lateral - 1).max() < 0.02
    assert np.abs(error.mean(axis=0)).max() < 5 * axial / np.sqrt(100_000)


def test_a_noise_free_imu_recording_integrates_back_to_the_cosserat_frames():
    params = CosseratSensorParams(imu=ImuModel(noise_density=0.0, bias_random_walk=0.0))
    rec = cosserat_sensor_recording(params, 40, np.random.default_rng(6))
    angle = (
        Rotation.from_quat(rec.imu[..., [1, 2, 3, 0]].reshape(-1, 4)).inv()
        * Rotation.from_quat(rec.truth.frames[..., [1, 2, 3, 0]].reshape(-1, 4))
    ).magnitude()
    assert angle.max() < 1e-9
    assert rec.camera_t[-1] <= rec.t[-1] and len(rec.camera_t) == 12  # 0.39 s at 30 frames/s
    # The two IMUs see the same truth as the camera: at t = 0 the same posture.
    assert np.allclose(rec.camera_truth.tip_position[0], rec.truth.tip_position[0])


def test_the_targets_source_gives_the_cosserat_tips_as_positions_and_unit_dual_quaternions():
    from optikin.algebra import dq_translation
    from optikin.arms.constant_curvature import ConstantCurvatureArm
    from optikin.data.sources import DATA_SOURCES
    from optikin.data.targets import FAMILY
    from optikin.problems import load_kinds
    from optikin.spec import DataSpec

    load_kinds()
    source = DATA_SOURCES[FAMILY].get("cosserat")
    arm, data = ConstantCurvatureArm(section_lengths=(0.18, 0.18)), DataSpec(source="cosserat", seed=1, samples=6)
    exact = source.load(arm, data, source.params(), "t.yaml", kind="position")
    pose = source.load(arm, data, source.params(), "t.yaml", kind="pose")
    measured = source.load(arm, data, source.params(measured=True), "t.yaml", kind="position")
    assert exact.trajectory and np.all(np.isnan(exact.configurations))
    assert np.abs(dq_translation(pose.values) - exact.values).max() < 1e-12
    assert np.allclose(np.linalg.norm(pose.values[:, :4], axis=1), 1.0)
    # The real-size arm, upright: tips 0.3-0.5 m above the base; the camera's error a few mm at ~1.2 m depth.
    assert np.all((exact.values[:, 2] > 0.25) & (exact.values[:, 2] < 0.5))
    error = np.linalg.norm(measured.values - exact.values, axis=1)
    assert 0 < error.max() < 0.02


def test_inverse_statics_reads_the_same_tips_as_targets_without_actuations():
    from optikin.data.actuations import FAMILY as ACTUATIONS
    from optikin.data.sources import DATA_SOURCES
    from optikin.data.targets import FAMILY as TARGETS
    from optikin.problems import load_kinds
    from optikin.spec import DataSpec

    load_kinds()
    data = DataSpec(source="cosserat", seed=2, samples=4)
    statics, ik = DATA_SOURCES[ACTUATIONS].get("cosserat"), DATA_SOURCES[TARGETS].get("cosserat")
    arm = type("Arm", (), {"n_config": 6})()
    for kind in ("position", "pose"):
        a = statics.load(arm, data, statics.params(), "t.yaml", kind=kind)
        t = ik.load(arm, data, ik.params(), "t.yaml", kind=kind)
        assert a.values is None and a.trajectory and np.array_equal(a.targets, t.values)
