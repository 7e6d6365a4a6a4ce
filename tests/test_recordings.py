"""The shared recording type and the readers of the lab formats (Motive CSV, C3D, ROS 2 bag, plain CSV).

Frame and unit conversion is checked against rotations written out by hand and against
scipy's; gap, NaN and swap notes against recordings built with known faults.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from optikin.data.recording import (
    FrameOptions,
    ImuTrack,
    Recording,
    RigidBodyTrack,
    convert_quaternions,
    frame_matrix,
    inspect_frames,
    to_base_frame,
)


def _wxyz(rotation: Rotation) -> np.ndarray:
    xyzw = rotation.as_quat()
    return np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1)


# ------------------------------------------------------------------------------ frame and units
def test_y_up_is_plus_90_degrees_about_x():
    """``up: y``: (x, y, z) -> (x, -z, y), the rotation by +90 degrees about x."""
    a = frame_matrix(FrameOptions(up="y"))
    np.testing.assert_allclose(a, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=0)
    np.testing.assert_allclose(a, Rotation.from_euler("x", 90, degrees=True).as_matrix(), atol=1e-15)


def test_x_up_and_forward_and_left_handed():
    np.testing.assert_allclose(frame_matrix(FrameOptions(up="x")), [[0, 0, -1], [0, 1, 0], [1, 0, 0]], atol=0)
    np.testing.assert_allclose(frame_matrix(FrameOptions(up="z")), np.eye(3), atol=0)
    # y up, z forward (Motive's calibration-square convention read as "z is forward")
    a = frame_matrix(FrameOptions(up="y", forward="z"))
    np.testing.assert_allclose(a @ [0, 0, 1], [1, 0, 0], atol=0)
    np.testing.assert_allclose(a @ [0, 1, 0], [0, 0, 1], atol=0)
    assert np.linalg.det(a) == pytest.approx(1.0)
    # Unity's left-handed y-up frame: x right, y up, z forward -> optikin x forward, y left, z up
    left = frame_matrix(FrameOptions(up="y", forward="z", handedness="left"))
    np.testing.assert_allclose(left, [[0, 0, 1], [-1, 0, 0], [0, 1, 0]], atol=0)
    assert np.linalg.det(left) == pytest.approx(-1.0)
    with pytest.raises(ValueError, match="perpendicular"):
        FrameOptions(up="y", forward="-y")


@pytest.mark.parametrize("handedness", ["right", "left"])
def test_quaternions_convert_as_a_r_a_transposed(handedness):
    """``(w, det(A) A v)`` equals ``A R A^T`` computed by scipy on the matrices."""
    a = frame_matrix(FrameOptions(up="y", forward="z", handedness=handedness))
    rotations = Rotation.random(20, random_state=3)
    converted = convert_quaternions(_wxyz(rotations), a)
    expected = a @ rotations.as_matrix() @ a.T
    got = Rotation.from_quat(np.concatenate([converted[:, 1:], converted[:, :1]], axis=1)).as_matrix()
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_to_base_frame_scales_lengths_only():
    time = np.array([0.0, 0.01])
    rec = Recording(
        time,
        markers={"m": np.array([[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan]])},
        bodies={"b": RigidBodyTrack(np.array([[0.0, 1000.0, 0.0]] * 2), np.array([[1.0, 0, 0, 0]] * 2))},
        imu={"i": ImuTrack(time, np.array([[0.0, 1.0, 0.0]] * 2), np.array([[0.0, 9.81, 0.0]] * 2))},
        actuators={"tendon": np.array([0.1, 0.2])},
    )
    out = to_base_frame(rec, FrameOptions(up="y"), "mm")
    np.testing.assert_allclose(out.markers["m"][0], [1e-3, -3e-3, 2e-3], rtol=1e-15)
    assert np.isnan(out.markers["m"][1]).all()
    np.testing.assert_allclose(out.bodies["b"].positions[0], [0, 0, 1.0], atol=1e-15)
    np.testing.assert_allclose(out.bodies["b"].quaternions, rec.bodies["b"].quaternions)
    np.testing.assert_allclose(out.imu["i"].angular_velocity[0], [0, 0, 1.0], atol=1e-15)
    np.testing.assert_allclose(out.imu["i"].linear_acceleration[0], [0, 0, 9.81], atol=1e-15)
    np.testing.assert_array_equal(out.actuators["tendon"], [0.1, 0.2])


# ------------------------------------------------------------------------------ notes
def _walk(n: int = 10) -> dict[str, np.ndarray]:
    t = np.arange(n)[:, None] * 0.01
    return {
        "a": np.hstack([t, 0 * t, 0 * t]),
        "b": np.hstack([t, 0 * t + 0.5, 0 * t]),
        "c": np.hstack([0 * t, t, 0 * t + 1.0]),
    }


def test_nan_swap_and_gap_notes_and_dropping():
    markers = _walk()
    markers["a"][3, 1] = np.nan  # a NaN cell
    markers["a"][6:8], markers["b"][6:8] = markers["b"][6:8].copy(), markers["a"][6:8].copy()  # swapped twice
    frames = np.array([0, 1, 2, 3, 4, 7, 8, 9, 10, 11])  # frames 5, 6 dropped by the recorder
    rec = inspect_frames(Recording(frames / 100.0, markers=markers, frames=frames), numbered=True)
    by_kind = {k: [(n.frame, n.detail) for n in rec.notes if n.what == k] for k in ("gap", "nan", "swap")}
    assert by_kind["gap"] == [(7, "2 frame(s) missing before it")]
    assert by_kind["nan"] == [(3, "marker a missing")]
    assert [f for f, _ in by_kind["swap"]] == [8, 9]
    assert all("a and b" in d for _, d in by_kind["swap"])
    kept = rec.drop_incomplete()
    np.testing.assert_array_equal(kept.frame_index, [0, 1, 2, 4, 7, 10, 11])
    dropped = {n.frame: n.detail for n in kept.notes if n.what == "dropped"}
    assert dropped == {3: "missing a", 8: "labels swapped", 9: "labels swapped"}
    assert kept.marker_array(["a", "c"]).shape == (7, 2, 3)
    with pytest.raises(KeyError, match="'z'"):
        kept.marker_array(["z"])


def test_gap_by_time_without_frame_numbers():
    time = np.array([0.0, 0.01, 0.02, 0.05, 0.06])
    rec = inspect_frames(Recording(time, markers={"a": np.zeros((5, 3))}))
    assert [(n.frame, n.what) for n in rec.notes] == [(3, "gap")]
    assert "about 2 frame(s)" in rec.notes[0].detail
