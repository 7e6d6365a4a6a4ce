"""Demonstration sources of `optikin.data.demonstrations` (seed 000 secs. III-A and IV).

References: the generator's own noise-free truth (the configurations it
draws), scipy's ``Rotation`` for eq. (7) and for the roll-pitch-yaw angles of
eq. (30), eq. (31) written out as a convolution, pytransform3d's slerp, and
exact CSV round trips.
"""

from __future__ import annotations

import numpy as np
import pytest
import pytransform3d.rotations as pr
from scipy.spatial.transform import Rotation

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.data.demonstrations import (
    PoseDemonstration,
    gimbal_demonstration,
    imu_interface_recording,
    kinect_recording,
    moving_average,
    read_csv,
    resample_uniform,
    smooth_pose_demonstration,
    write_csv,
)
from optikin.errors import InputDataError


def scipy_rotation(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.asarray(q)[..., [1, 2, 3, 0]])  # scipy: (x, y, z, w)


def test_noise_free_imu_recording_recovers_the_true_configuration():
    rec = imu_interface_recording(samples=200, seed=3, noise_deg=0.0, drift_deg_per_s=0.0)
    assert np.allclose(np.diff(rec.t), 0.01)
    truth = rec.configuration[:, [1, 2, 4, 5]]
    measured = rec.angles.reshape(-1, 4)
    np.testing.assert_allclose(measured[:, [0, 2]], truth[:, [0, 2]], atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (measured[:, [1, 3]] - truth[:, [1, 3]]))), 0.0, atol=1e-12)
    # eq. (7): the second section relative to the first, against scipy
    expected = (scipy_rotation(rec.imu[:, 0]).inv() * scipy_rotation(rec.imu[:, 1])).as_matrix()
    np.testing.assert_allclose(scipy_rotation(rec.relative[:, 1]).as_matrix(), expected, atol=1e-12)
    # the tip pose is the forward kinematics of the true configuration
    quaternion, position = ConstantCurvatureArm().section_frames(rec.configuration)[-1]
    np.testing.assert_allclose(rec.demonstration.position, position, atol=1e-12)
    assert np.abs(np.abs(np.sum(rec.demonstration.quaternion * quaternion, axis=1)) - 1).max() < 1e-12


def test_imu_noise_and_drift_have_the_stated_size():
    rec = imu_interface_recording(samples=1000, seed=5, noise_deg=0.1, drift_deg_per_s=0.0)
    clean = imu_interface_recording(samples=1000, seed=5, noise_deg=0.0, drift_deg_per_s=0.0)
    error = (scipy_rotation(rec.imu[:, 0]) * scipy_rotation(clean.imu[:, 0]).inv()).as_rotvec()
    assert np.std(error, axis=0) == pytest.approx(np.full(3, np.deg2rad(0.1)), rel=0.15)
    drifting = imu_interface_recording(samples=1000, seed=5, noise_deg=0.0, drift_deg_per_s=0.05)
    yaw = (scipy_rotation(drifting.imu[:, 1]) * scipy_rotation(clean.imu[:, 1]).inv()).as_rotvec()
    np.testing.assert_allclose(yaw[:, :2], 0.0, atol=1e-12)  # the drift is about the vertical only
    rate = np.polyfit(rec.t, yaw[:, 2], 1)[0]
    assert 0 < abs(rate) <= np.deg2rad(0.05) * (1 + 1e-9)


def test_kinect_recording_fills_the_cube_at_30_fps_with_eq30_angles():
    rec = kinect_recording(samples=240, seed=1)
    assert np.allclose(np.diff(rec.t), 1 / 30)
    span = np.ptp(rec.position, axis=0)
    assert span.max() == pytest.approx(0.36) and np.all(span <= 0.36 + 1e-12)
    np.testing.assert_allclose(0.5 * (rec.position.min(axis=0) + rec.position.max(axis=0)), [0, 0, 0.27], atol=1e-12)
    yaw_pitch_roll = scipy_rotation(rec.orientation).as_euler("ZYX")
    wrapped = np.angle(np.exp(1j * (rec.rpy - yaw_pitch_roll[:, ::-1])))
    np.testing.assert_allclose(wrapped, 0.0, atol=1e-9)
    # the filter smooths: second differences shrink
    rough = lambda x: np.std(np.diff(x, 2, axis=0))  # noqa: E731
    assert rough(rec.filtered_position) < 0.3 * rough(rec.position)


def test_moving_average_is_eq31():
    x = np.random.default_rng(0).normal(size=(50, 2))
    M = 4
    out = moving_average(x, M)
    for i in range(M, 50):
        np.testing.assert_allclose(out[i], x[i - M : i].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(out[2], x[:2].mean(axis=0))
    np.testing.assert_allclose(out[0], x[0])
    window_means = np.convolve(x[:, 0], np.ones(M) / M, mode="valid")  # mean of x[j .. j+M-1]
    np.testing.assert_allclose(out[M:, 0], window_means[:-1], rtol=1e-12)


def test_gimbal_demonstration_crosses_pitch_90_and_its_angles_jump():
    from optikin.algebra import rpy_from_quat

    demo = gimbal_demonstration(samples=500, seed=2)
    rpy = np.unwrap(rpy_from_quat(demo.quaternion), axis=0)
    assert np.abs(rpy[:, 1]).max() > np.deg2rad(89)
    jumps = np.abs(np.diff(rpy, axis=0)).max(axis=0)
    assert jumps[0] > 3.0 and jumps[2] > 3.0  # roll and yaw flip by ~pi at the lock
    # while the quaternion path itself is smooth
    steps = (
        Rotation.from_quat(demo.quaternion[1:, [1, 2, 3, 0]])
        * Rotation.from_quat(demo.quaternion[:-1, [1, 2, 3, 0]]).inv()
    )
    assert np.linalg.norm(steps.as_rotvec(), axis=1).max() < 0.02


def test_csv_round_trip_and_resampling(tmp_path):
    demo = smooth_pose_demonstration(samples=120, duration=2.0, seed=6)
    path = tmp_path / "demo.csv"
    write_csv(path, demo)
    back = read_csv(path)
    np.testing.assert_array_equal(back.t, demo.t)
    np.testing.assert_array_equal(back.position, demo.position)
    np.testing.assert_allclose(back.quaternion, demo.quaternion, rtol=0, atol=1e-15)  # renormalised

    rng = np.random.default_rng(1)
    t = np.sort(demo.t + np.concatenate([[0.0], rng.uniform(-0.004, 0.004, 118), [0.0]]))
    jittery = PoseDemonstration(t=t, position=demo.position, quaternion=demo.quaternion)
    uniform = resample_uniform(jittery)
    np.testing.assert_allclose(np.diff(uniform.t), np.diff(uniform.t).mean(), rtol=1e-9)
    k = 50
    j = np.searchsorted(t, uniform.t[k], side="right") - 1
    u = (uniform.t[k] - t[j]) / (t[j + 1] - t[j])
    np.testing.assert_allclose(uniform.position[k], (1 - u) * demo.position[j] + u * demo.position[j + 1])
    expected = pr.quaternion_slerp(demo.quaternion[j], demo.quaternion[j + 1], u)
    assert abs(abs(expected @ uniform.quaternion[k]) - 1) < 1e-12


@pytest.mark.parametrize(
    "text, message",
    [
        ("t,x,y,z,qw,qx,qy\n0,0,0,0,1,0,0\n", "missing column.*qz"),
        (
            "t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n0.1,0,zero,0,1,0,0,0\n0.2,0,0,0,1,0,0,0\n",
            "sample 1.*y.*not a number",
        ),
        ("t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n0.1,0,0,0,1,0,0,0\n0.1,0,0,0,1,0,0,0\n", "sample 2.*t.*increase"),
        ("t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n0.1,0,0,0,1.1,0,0,0\n0.2,0,0,0,1,0,0,0\n", "sample 1.*qw.*not 1"),
        ("t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n", "at least 3 rows"),
    ],
)
def test_bad_csv_files_name_row_and_column(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputDataError, match=message) as info:
        read_csv(path)
    assert "bad.csv" in str(info.value)
    with pytest.raises(InputDataError, match="cannot read"):
        read_csv(tmp_path / "missing.csv")
