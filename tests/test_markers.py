"""Synthetic motion capture of the CBHA and the marker CSV format (`optikin.data.markers`).

Independent references: seed 004's printed leg-length equations (7)-(9) and Table I
for the postures; the model's own vertebra frames for the rigid-body fits; sample
statistics for the noise; a round trip through the CSV file.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.algebra import dq_rotation, quat_angle, quat_conjugate, quat_multiply, quat_rotate
from optikin.arms.cbha import CBHAArm, printed_leg_lengths
from optikin.data.markers import (
    FRAME_RATE,
    INTERMEDIATE_VERTEBRAE,
    configurations_from_fractions,
    read_marker_csv,
    synthetic_recording,
    synthetic_rope_chain,
    tube_fractions,
    write_marker_csv,
)
from optikin.errors import InputDataError


@pytest.fixture(scope="module")
def arm():
    return CBHAArm()


@pytest.fixture(scope="module")
def recording(arm):
    return synthetic_recording(arm, 100, np.random.default_rng(4))


def test_postures_are_the_commanded_tube_elongations_within_table_i(arm):
    """Every leg equals q_min + f (q_max - q_min) of its section's tube, by seed 004's printed eqs. (7)-(9)."""
    rng = np.random.default_rng(1)
    t = np.arange(30) * 0.1
    fractions = tube_fractions(arm.n_sections, t, rng, (0.05, 0.2), 0.9)
    Q = configurations_from_fractions(arm, fractions).reshape(30, 16, 3)
    r = arm.geometry.radii
    lo, hi = np.array(arm.geometry.leg_min), np.array(arm.geometry.leg_max)
    for k in range(16):
        section = 0 if k < 8 else 1
        legs = np.column_stack(printed_leg_lengths(Q[:, k, 0], Q[:, k, 1], Q[:, k, 2], r[k], r[k + 1]))
        np.testing.assert_allclose(legs, lo[k] + fractions[:, section, :] * (hi[k] - lo[k]), rtol=0, atol=1e-12)
        assert np.all((legs >= lo[k]) & (legs <= hi[k]))
    arm.validate(Q.reshape(30, -1))  # bounds and Table I, by the model's own check


def test_recording_is_timed_at_240_hz_and_smooth(recording):
    assert FRAME_RATE == 240.0
    np.testing.assert_allclose(np.diff(recording.t), 24 / 240.0, rtol=1e-12)  # one posture every 24 frames
    tip = recording.truth.vertebrae[:, -1]
    step, bend = np.diff(tip, axis=0), np.diff(tip, n=2, axis=0)
    assert np.linalg.norm(bend, axis=1).max() < 0.25 * np.linalg.norm(step, axis=1).max()
    assert np.ptp(tip, axis=0).max() > 0.05  # the arm does move


def test_marker_noise_is_0_3_mm_per_coordinate(arm):
    rec = synthetic_recording(arm, 400, np.random.default_rng(7))
    noise = (rec.markers - rec.truth.marker_truth).ravel()
    assert np.std(noise) == pytest.approx(0.3e-3, rel=0.05)  # 3,600 samples: ~1.2 % standard error
    assert abs(np.mean(noise)) < 3 * 0.3e-3 / np.sqrt(noise.size)
    np.testing.assert_allclose(rec.truth.marker_truth, rec.truth.vertebrae[:, np.array(INTERMEDIATE_VERTEBRAE) - 1])


def test_rigid_bodies_recover_the_vertebra_frames(arm):
    """Without noise the Kabsch fit gives the base and tip vertebra frames exactly; with noise, to ~0.3 mm / 40 mm."""
    exact = synthetic_recording(arm, 20, np.random.default_rng(2), noise=0.0)
    frames = arm.evaluate("vertebra_frames", exact.truth.configurations).transpose(0, 2, 1)
    for q, p, index in (
        (exact.base_orientation, exact.base_position, 0),
        (exact.tip_orientation, exact.tip_position, -1),
    ):
        truth = dq_rotation(frames[:, index])
        assert np.max(quat_angle(quat_multiply(quat_conjugate(truth), q))) < 1e-10
        np.testing.assert_allclose(p, exact.truth.vertebrae[:, index], atol=1e-14)
    noisy = synthetic_recording(arm, 200, np.random.default_rng(3))
    frames = arm.evaluate("vertebra_frames", noisy.truth.configurations).transpose(0, 2, 1)
    true_tip = quat_rotate(dq_rotation(frames[:, -1]), np.array([0.0, 0.0, 1.0]))
    angle = np.arccos(np.clip(np.sum(true_tip * noisy.tip_direction, axis=1), -1, 1))
    assert 1e-3 < np.mean(angle) < 0.3e-3 / 0.029 * 2  # tilt of a 29 mm triangle of markers, 0.3 mm noise
    assert np.mean(np.linalg.norm(noisy.tip_position - noisy.truth.vertebrae[:, -1], axis=1)) < 0.3e-3


def test_reference_tube_lengths_are_the_leg_sums(arm, recording):
    legs = arm.evaluate("leg_lengths", recording.truth.configurations).reshape(len(recording), 16, 3)
    np.testing.assert_allclose(recording.tube_lengths, legs.sum(axis=1), rtol=1e-13)
    np.testing.assert_allclose(recording.section_tube_lengths, legs[:, :8].sum(axis=1), rtol=1e-13)


def test_same_seed_same_recording(arm):
    a, b = (synthetic_recording(arm, 5, np.random.default_rng(9)) for _ in range(2))
    c = synthetic_recording(arm, 5, np.random.default_rng(10))
    np.testing.assert_array_equal(a.markers, b.markers)
    assert not np.allclose(a.markers, c.markers)


def test_fixed_base_averages_the_base_pose(recording):
    fixed = recording.with_fixed_base()
    np.testing.assert_allclose(fixed.base_position[0], recording.base_position.mean(axis=0), atol=1e-15)
    truth = recording.truth.vertebrae[0, 0]  # the base never moves
    assert np.linalg.norm(fixed.base_position[0] - truth) < np.mean(
        np.linalg.norm(recording.base_position - truth, axis=1)
    )
    np.testing.assert_allclose(np.linalg.norm(fixed.base_orientation, axis=1), 1.0, atol=1e-15)


def test_rope_chain_hangs_between_the_true_tips(arm):
    chain = synthetic_rope_chain(arm, 6, np.random.default_rng(5))
    rope = chain.rope_truth
    np.testing.assert_allclose(rope[:, 0], chain.arm1.truth.vertebrae[:, -1], atol=1e-12)
    np.testing.assert_allclose(rope[:, -1], chain.arm2.truth.vertebrae[:, -1], atol=1e-12)
    length = np.linalg.norm(np.diff(rope, axis=1), axis=2).sum(axis=1)  # polyline of 200 points: just below
    assert np.all((length < chain.rope_length) & (length > 0.999 * chain.rope_length))
    np.testing.assert_allclose(chain.arm2.base_position.mean(axis=0), [0.25, 0.0, 0.0], atol=3e-4)
    np.testing.assert_allclose(np.linalg.norm(chain.rope_directions, axis=2), 1.0, atol=1e-14)
    # end directions from a marker 20 mm along the rope: the rope's own end tangents within a few degrees
    chord = rope[:, 1] - rope[:, 0], rope[:, -1] - rope[:, -2]
    for k, tangent in enumerate(chord):
        tangent = tangent / np.linalg.norm(tangent, axis=1, keepdims=True)
        assert np.all(np.sum(tangent * chain.rope_directions[:, k], axis=1) > np.cos(np.radians(8.0)))


# -- CSV ------------------------------------------------------------------------------------


def test_csv_round_trip(recording, tmp_path):
    path = write_marker_csv(recording, tmp_path / "rec.csv")
    back = read_marker_csv(path)
    for name in ("t", "base_position", "tip_position", "markers", "tube_lengths", "section_tube_lengths"):
        np.testing.assert_array_equal(getattr(back, name), getattr(recording, name), err_msg=name)
    for name in ("base_orientation", "tip_orientation"):  # normalised again on reading
        np.testing.assert_allclose(getattr(back, name), getattr(recording, name), rtol=0, atol=1e-15)
    assert back.truth is None and back.source == str(path)


def write_rows(path, header, rows):
    path.write_text("\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n")
    return path


HEADER = (
    ["t"]
    + [f"{b}_{c}" for b in ("base", "tip") for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
    + ["m1_x", "m1_y", "m1_z"]
)
GOOD = ["0", "0", "0", "0", "1", "0", "0", "0", "0", "0", "0.2", "1", "0", "0", "0", "0", "0", "0.1"]


@pytest.mark.parametrize(
    "header, rows, match",
    [
        (HEADER[:-1], [GOOD[:-1]], r"rec.csv: m1_z: missing column"),
        (
            HEADER,
            [GOOD, GOOD[:4] + ["abc"] + GOOD[5:]],
            r"rec.csv: sample 1: base_qw: 'abc' is not a finite number \(line 3\)",
        ),
        (HEADER, [GOOD[:-1] + [""]], r"rec.csv: sample 0: m1_z: an empty cell"),
        (HEADER, [GOOD[:-1] + ["nan"]], r"sample 0: m1_z: 'nan' is not a finite number"),
        (
            HEADER,
            [GOOD, GOOD[:11] + ["0.9"] + GOOD[12:]],
            r"sample 1: tip_qw, tip_qx, tip_qy, tip_qz: .* not a unit quaternion",
        ),
        (HEADER, [], r"rec.csv: no data rows"),
    ],
)
def test_csv_errors_name_file_row_and_column(tmp_path, header, rows, match):
    with pytest.raises(InputDataError, match=match):
        read_marker_csv(write_rows(tmp_path / "rec.csv", header, rows))


def test_csv_without_lengths_and_with_extra_columns(tmp_path):
    path = write_rows(tmp_path / "rec.csv", HEADER + ["comment"], [GOOD + ["first"]])
    rec = read_marker_csv(path)
    assert rec.tube_lengths is None and rec.markers.shape == (1, 1, 3)
    np.testing.assert_allclose(rec.tip_direction, [[0.0, 0.0, 1.0]])
    with pytest.raises(InputDataError, match="cannot read"):
        read_marker_csv(tmp_path / "missing.csv")
