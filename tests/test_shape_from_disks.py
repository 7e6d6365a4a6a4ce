"""Shape from positions-only disks: the tip tangent from the circle through the last three disks, checked
against constant-curvature arcs in closed form, and the ``ph_shape`` kind scoring each disk on a backbone
that did not use it (source ``disks`` of :mod:`optikin.data.markers`)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from optikin.algebra import quat_from_axis_angle, quat_rotate
from optikin.data.markers import MarkerRecording, circle_tangent, disk_recording, rotation_onto, write_marker_csv
from optikin.errors import SpecError
from optikin.runner import solve

EZ = np.array([0.0, 0.0, 1.0])


def arcs(n: int, seed: int = 0):
    """``n`` circular arcs in closed form (Webster & Jones 2010): each leaves ``p0`` along ``t0`` and bends towards
    ``n0`` with curvature ``kappa``; the point at arc length ``s`` is ``p0 + sin(k s)/k t0 + (1 - cos(k s))/k n0`` and
    its tangent ``cos(k s) t0 + sin(k s) n0``. Returns ``point(s)``, ``tangent(s)`` (``s`` ``(n,)`` or a number, [m])
    and the base pose ``(p0 (n, 3), q0 (n, 4))`` (``q0``'s z axis is ``t0``)."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(n, 3))
    q0 = quat_from_axis_angle(axis / np.linalg.norm(axis, axis=1, keepdims=True), rng.uniform(0, np.pi, n))
    t0 = quat_rotate(q0, EZ, check=False)
    phi = rng.uniform(-np.pi, np.pi, n)
    n0 = np.cos(phi)[:, None] * quat_rotate(q0, np.array([1.0, 0, 0]), check=False) + np.sin(phi)[
        :, None
    ] * quat_rotate(q0, np.array([0, 1.0, 0]), check=False)
    kappa = rng.uniform(0.5, 8.0, n)[:, None]  # [1/m]: up to 2.4 rad over 0.3 m
    p0 = rng.normal(0.0, 0.2, (n, 3))

    def point(s):
        s = np.broadcast_to(np.asarray(s, dtype=float), (n,))[:, None]
        return p0 + np.sin(kappa * s) / kappa * t0 + (1 - np.cos(kappa * s)) / kappa * n0

    def tangent(s):
        s = np.broadcast_to(np.asarray(s, dtype=float), (n,))[:, None]
        return np.cos(kappa * s) * t0 + np.sin(kappa * s) * n0

    return point, tangent, (p0, q0)


def test_circle_tangent_is_the_arcs_tangent_at_the_last_point():
    point, tangent, _ = arcs(200)
    rng = np.random.default_rng(1)
    s = np.sort(rng.uniform(0.01, 0.3, (3, 200)), axis=0)
    got = circle_tangent(point(s[0]), point(s[1]), point(s[2]))
    np.testing.assert_allclose(got, tangent(s[2]), atol=1e-9)


def test_circle_tangent_of_collinear_points_is_their_direction():
    a, d = np.array([[0.1, -0.2, 0.3]]), np.array([[2.0, -1.0, 2.0]]) / 3.0
    np.testing.assert_allclose(circle_tangent(a, a + 0.05 * d, a + 0.2 * d), d, atol=1e-14)


def test_rotation_onto_turns_the_z_axis_by_the_smallest_rotation():
    _, tangent, (_, q0) = arcs(50, seed=2)
    target = tangent(0.2)
    q = rotation_onto(q0, target)
    np.testing.assert_allclose(quat_rotate(q, EZ, check=False), target, atol=1e-12)
    # the smallest rotation: by the angle between the two z axes, no more
    angle = np.arccos(np.clip(np.sum(quat_rotate(q0, EZ, check=False) * target, axis=1), -1, 1))
    w = np.abs(np.sum(q * q0, axis=1))  # cos of half the rotation between the two orientations
    np.testing.assert_allclose(w, np.cos(angle / 2), atol=1e-12)


def test_disk_recording_of_one_arc_has_the_exact_tip_tangent_with_and_without_each_disk():
    point, tangent, (p0, q0) = arcs(1, seed=3)
    s = np.array([0.1058, 0.2007, 0.3151])  # the trunk's section ends
    disks = np.stack([point(v) for v in s], axis=1)  # (1, 3, 3)
    recording = disk_recording(disks, p0[0], q0[0])
    np.testing.assert_allclose(recording.tip_position, disks[:, -1])
    np.testing.assert_allclose(recording.tip_direction, tangent(s[-1]), atol=1e-10)
    np.testing.assert_allclose(recording.base_direction, tangent(0.0), atol=1e-12)
    assert recording.held_out_tip_directions is not None
    np.testing.assert_allclose(recording.held_out_tip_directions[:, 0], tangent(s[-1]), atol=1e-10)
    np.testing.assert_allclose(recording.held_out_tip_directions[:, 1], tangent(s[-1]), atol=1e-10)
    assert recording.tip_markers == (0, 1)
    assert recording.take(slice(0, 1)).held_out_tip_directions is not None


def test_disk_recording_refuses_two_disks_and_coincident_points():
    point, _, (p0, q0) = arcs(2, seed=4)
    with pytest.raises(ValueError, match="three disks"):
        disk_recording(np.stack([point(0.1), point(0.2)], axis=1), p0[0], q0[0])
    disks = np.stack([point(0.1), point(0.1), point(0.2)], axis=1)
    with pytest.raises(ValueError, match="posture 0: disk 1 and disk 2 coincide"):
        disk_recording(disks, p0[0], q0[0])


def write_case(tmp_path, samples: int = 6, calibration: bool = True, explicit_base: bool = False):
    """A problem of kind ph_shape on disks of single arcs from one base pose (each disk at a section end of a
    three-section constant-curvature arm bent as one arc), with a calibrated arm file holding that base
    (``calibration``); ``explicit_base``: the base pose given in ``data.params.base`` instead."""
    _, _, (p0, q0) = arcs(1, seed=5)
    rng = np.random.default_rng(6)
    q, p = q0[0], p0[0]
    t0 = quat_rotate(q, EZ, check=False)
    rows = []
    ends = (0.1058, 0.2007, 0.3151)
    for _ in range(samples):
        phi = rng.uniform(-np.pi, np.pi)
        n0 = np.cos(phi) * quat_rotate(q, np.array([1.0, 0, 0]), check=False) + np.sin(phi) * quat_rotate(
            q, np.array([0, 1.0, 0]), check=False
        )
        k = rng.uniform(0.5, 6.0)
        rows.append([v for s in ends for v in p + np.sin(k * s) / k * t0 + (1 - np.cos(k * s)) / k * n0])
    header = [f"disk{d}_{c}" for d in (1, 2, 3) for c in "xyz"]
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "disks.csv").write_text(
        ",".join(header) + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in rows) + "\n"
    )
    arm: dict = {"arm": {"type": "constant_curvature", "params": {"section_lengths": [0.1058, 0.0949, 0.1144]}}}
    if calibration:
        arm["calibration"] = {"base_position": [float(v) for v in p], "base_quaternion": [float(v) for v in q]}
    (tmp_path / "arm.yaml").write_text(yaml.safe_dump(arm))
    pose = {"position": [float(v) for v in p], "quaternion": [float(v) for v in q]}
    base = pose if explicit_base else "arm"
    problem = {
        "name": "disks-shape",
        "title": "PH backbones from disks on circular arcs",
        "kind": "ph_shape",
        "arm": "arm.yaml",
        "data": {
            "source": "disks",
            "params": {"file": "disks.csv", "disks": ["disk1", "disk2", "disk3"], "base": base},
        },
        "solver": "ph-newton",
        "options": {"length": "arc"},
    }
    path = tmp_path / "disks-shape.yaml"
    path.write_text(yaml.safe_dump(problem, sort_keys=False))
    return path


def test_ph_shape_on_disks_scores_each_disk_on_a_backbone_that_did_not_use_it(tmp_path):
    result, _ = solve(str(write_case(tmp_path)), figures=False)
    held = np.asarray(result.arrays["held_out_marker_distance"])
    assert held.shape == (6, 2)
    # one circular arc: the PH quintic between its exact end poses and arc length lies within a fraction of a mm
    assert np.all(held < 1e-3)
    metrics = result.metrics
    assert metrics["markers the tip estimate used"] == [1, 2]
    assert len(metrics["held-out distance per marker, median [mm]"]) == 2
    assert not any(key.startswith("seed 002") for key in metrics)  # not the seed's CBHA
    assert metrics["fairness"]["methods sharing the truth's model"] is False
    row = result.comparison[0].metrics
    assert row["held-out m1 median [mm]"] == pytest.approx(np.median(held[:, 0]) * 1e3)
    assert row["held-out marker distance median [mm]"] == pytest.approx(np.median(held) * 1e3)


def test_disks_source_needs_a_calibrated_base(tmp_path):
    with pytest.raises(SpecError, match="calibration.base_position"):
        solve(str(write_case(tmp_path, calibration=False)), figures=False)


def test_an_explicit_base_pose_is_the_calibrated_one(tmp_path):
    calibrated, _ = solve(str(write_case(tmp_path / "a")), figures=False)
    given, _ = solve(str(write_case(tmp_path / "b", calibration=False, explicit_base=True)), figures=False)
    np.testing.assert_array_equal(given.arrays["base_position"], calibrated.arrays["base_position"])
    np.testing.assert_allclose(
        given.arrays["held_out_marker_distance"], calibrated.arrays["held_out_marker_distance"], rtol=0, atol=1e-12
    )


def test_option_tip_circle_on_recorded_end_poses_is_the_disks_estimate(tmp_path):
    """The same disks as a marker CSV whose recorded tip orientation is wrong (the base's): ``tip: circle``
    replaces it by the circle estimate, so the held-out distances are those of source ``disks``."""
    disks_problem = write_case(tmp_path)
    reference, _ = solve(str(disks_problem), figures=False)
    rows = np.loadtxt(tmp_path / "disks.csv", delimiter=",", skiprows=1).reshape(-1, 3, 3)
    arm = yaml.safe_load((tmp_path / "arm.yaml").read_text())["calibration"]
    recording = MarkerRecording(
        t=np.arange(len(rows), dtype=float),
        base_position=np.tile(arm["base_position"], (len(rows), 1)),
        base_orientation=np.tile(arm["base_quaternion"], (len(rows), 1)),
        tip_position=rows[:, 2],
        tip_orientation=np.tile(arm["base_quaternion"], (len(rows), 1)),
        markers=rows[:, :2],
    )
    write_marker_csv(recording, tmp_path / "markers.csv")
    spec = yaml.safe_load(disks_problem.read_text())
    spec["data"] = {"source": "csv", "params": {"file": "markers.csv"}}
    spec["options"]["tip"] = "circle"
    disks_problem.write_text(yaml.safe_dump(spec, sort_keys=False))
    circle, _ = solve(str(disks_problem), figures=False)
    np.testing.assert_allclose(
        circle.arrays["held_out_marker_distance"], reference.arrays["held_out_marker_distance"], rtol=0, atol=1e-12
    )
    spec["options"]["tip"] = "recorded"
    disks_problem.write_text(yaml.safe_dump(spec, sort_keys=False))
    recorded, _ = solve(str(disks_problem), figures=False)
    assert "held_out_marker_distance" not in recorded.arrays and "tip pose" not in recorded.metrics


def test_the_seed_figures_are_printed_for_the_seed_cbha_only(tmp_path):
    cbha, _ = solve("cbha-ph-shape", figures=False, overrides=[("data.samples", 2), ("baselines", [])])
    assert cbha.metrics["seed 002 V.A mean distance per marker [mm]"] == [1.2, 3.7, 3.1]
    other, _ = solve(str(write_case(tmp_path, samples=2)), figures=False)
    assert "seed 002 V.A mean distance per marker [mm]" not in other.metrics


def test_option_tip_circle_needs_two_intermediate_markers():
    overrides = [("data.samples", 2), ("baselines", []), ("options.tip", "circle"), ("data.params.intermediate", [9])]
    with pytest.raises(SpecError) as info:
        solve("cbha-ph-shape", figures=False, overrides=overrides)
    assert info.value.field == "options.tip" and "needs three disks" in str(info.value)
