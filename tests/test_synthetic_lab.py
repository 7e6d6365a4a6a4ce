"""The synthetic tendon lab: its grid, friction and hysteresis, its recording against its own truth (frame,
offsets, noise, occlusions, the hanging rod), the cache, and a calibration of it through the problem kind."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.simulate.tendon_lab import TendonLabParams, boustrophedon, exit_pose, lab_recording, tensions_of

SMALL = {"levels": [0.0, 5.0]}
"""Two levels per motor: the 64 corners of the grid."""


def test_the_grid_is_visited_one_motor_step_at_a_time():
    order = boustrophedon(3, 6)
    assert len(order) == 3**6 and len({tuple(r) for r in order}) == 3**6
    steps = np.abs(np.diff(order, axis=0))
    assert np.all(steps.sum(axis=1) == 1)


def test_friction_and_hysteresis_depend_on_the_direction_an_input_was_reached_from():
    u = np.array([[0.0], [2.0], [4.0], [2.0], [0.0]])
    t = tensions_of(u, friction=0.3, hysteresis=0.1)[:, 0]
    assert t[1] == pytest.approx(2.0 - 0.3 - 0.2)  # pulled in: friction takes its share
    assert t[3] == pytest.approx(2.0 + 0.3 + 0.2)  # paid out: friction holds the tendon
    assert t[0] == t[4] == 0.0  # a slack motor carries nothing
    assert t[3] - t[1] == pytest.approx(2 * (0.3 + 0.1 * 2.0))


@pytest.fixture(scope="module")
def small():
    """The 64 corners of the grid (the equilibria: about 10 s on a quiet machine the first time, then cached)."""
    params = TendonLabParams(**SMALL)
    return params, lab_recording(params, 64, np.random.default_rng(1))


@pytest.mark.slow
def test_the_recording_against_the_lab_truth(small):
    params, rec = small
    truth = rec.truth
    assert sorted(rec.markers) == ["disk1", "disk2", "disk3"] and len(rec.actuators) == 6
    measured = rec.marker_array(["disk1", "disk2", "disk3"])
    # occlusions: whole rows, about 3 %; noise: 0.3 mm per coordinate around the clean bodies
    lost = np.isnan(measured).any(axis=2)
    assert np.array_equal(lost, np.isnan(measured).all(axis=2)) and 0 < lost.mean() < 0.1
    residual = (measured - truth.clean_markers)[~lost]
    assert np.std(residual) == pytest.approx(0.3e-3, rel=0.2)
    # the bodies sit at their offsets from the disks, in the disks' frames
    local = np.einsum("nsji,nsj->nsi", rec.lab.disk_rotations, truth.clean_markers - rec.lab.disk_positions)
    assert np.abs(local - np.array(params.marker_offsets)).max() < 1e-12
    # hanging below its mount (y up in the lab is z up here), the backbone leaving at the mount offset and tilt
    p0, R0 = exit_pose(params)
    assert np.linalg.norm(p0) == pytest.approx(np.linalg.norm(params.mount_offset))
    assert np.degrees(np.arccos(-R0[2, 2])) == pytest.approx(np.hypot(*params.mount_tilt_deg), abs=0.05)
    assert np.median(rec.lab.disk_positions[:, 2, 2]) < np.median(rec.lab.disk_positions[:, 0, 2]) < p0[2]
    # slack tendons: the trunk hangs nearly straight, its inextensible backbone as long as the sections
    slack = np.flatnonzero(np.all(rec.lab.inputs == 0.0, axis=1))[0]
    assert np.linalg.norm(rec.lab.disk_positions[slack, 2] - p0) == pytest.approx(sum(params.section_lengths), abs=1e-3)
    # pulled tendons bend it: bends up to tens of degrees per section, four tendons at 5 N curl it up past level
    assert np.degrees(truth.configurations[:, 1::3]).max() > 20.0
    assert np.any(rec.lab.disk_positions[:, 2, 2] > rec.lab.disk_positions[:, 0, 2])


@pytest.mark.slow
def test_the_equilibria_are_cached(small):
    params, rec = small
    started = time.perf_counter()
    again = lab_recording(params, 64, np.random.default_rng(1))
    assert time.perf_counter() - started < 2.0
    assert np.array_equal(again.truth.clean_markers, rec.truth.clean_markers)


@pytest.mark.slow
def test_the_lab_is_a_source_the_calibration_reads(tmp_path: Path):
    from optikin.runner import solve

    source = Path(__file__).resolve().parent.parent / "problems" / "trunk-lab-calibrate.yaml"
    data = yaml.safe_load(source.read_text())
    data["name"] = "lab-small"
    data["data"]["samples"] = 64
    data["data"]["params"] = dict(SMALL)
    data["options"] = {"offsets": "per_marker", "base": {"starts": "data"}, "holdout": {"folds": 4}}
    problem = tmp_path / "lab-small.yaml"
    problem.write_text(yaml.safe_dump(data))
    result, _ = solve(str(problem), out=tmp_path / "out", figures=False)
    m = result.metrics
    assert m["verdict"] in ("ok", "not_identifiable")
    assert m["postures"] == 64 and "max section length error [mm]" in m
    assert len(m["max marker offset error, axial and radial [mm]"]) == 2
    headline = m["held-out largest-marker error per posture, 64 of 64 postures (kfold) [mm]"]
    assert headline["median"] > 0.3  # the rod is not a constant-curvature arm: more than the noise


@pytest.mark.slow
def test_the_mount_plane_and_direction_are_read_in_the_recordings_frame(tmp_path: Path):
    """The lab records y up: plane {y: 0} and direction [0, -1, 0] hold the base at z = 0 along -z of optikin's
    frame (the mount point and straight down), whatever the mount offset the lab really has."""
    from optikin.runner import solve

    source = Path(__file__).resolve().parent.parent / "problems" / "trunk-lab-calibrate.yaml"
    data = yaml.safe_load(source.read_text())
    data["name"] = "lab-mount"
    data["data"]["samples"] = 64
    data["data"]["params"] = dict(SMALL)
    data["options"] = {"base": {"plane": {"y": 0.0}, "direction": [0.0, -1.0, 0.0]}, "holdout": {"folds": 2}}
    problem = tmp_path / "lab-mount.yaml"
    problem.write_text(yaml.safe_dump(data))
    result, _ = solve(str(problem), out=tmp_path / "out", figures=False)
    m = result.metrics
    assert m["base position [mm]"][2] == 0.0
    assert np.allclose(m["base axis (z) in the recording frame"], [0.0, 0.0, -1.0])
    assert "base_z" not in m["identifiability"]["std [mm or deg]"]
    assert "base_rx" not in m["identifiability"]["std [mm or deg]"]
    assert [r.method for r in result.comparison] == ["levenberg-marquardt-schur"]  # a held base: one start
