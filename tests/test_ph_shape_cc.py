"""Baseline ``cc-arc`` of ``ph_shape`` (optikin.problems.ph_shape.cc) and its place in sweep ``ph-noise``.

Independent references: recordings whose backbones are exact circular arcs (and a
straight one), built here from the arc's own equation, on which the constant-curvature
reconstruction must be exact; brute-force closest points on densely sampled arcs for
the closed-form distance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from optikin.algebra import quat_from_matrix
from optikin.data.markers import CBHATruth, MarkerRecording, write_marker_csv
from optikin.physics.comparison import cc_arc_points
from optikin.problems.ph_shape import cc
from optikin.problems.ph_shape.wrench import distances_to_polylines
from optikin.problems.ph_shared import problem_variant
from optikin.runner import solve
from optikin.sweep import expand, load_sweep, run_sweep

VERTEBRAE = 17
ARCS = (  # (length [m], turning angle [rad], bending-plane azimuth [rad])
    (0.3, 0.0, 0.0),
    (0.25, 1e-6, 0.3),
    (0.35, 1.1, 2.0),
    (0.3, math.pi / 2, -1.0),
    (0.2, 4.0, 0.7),  # more than half a turn: the tip behind the base plane
)


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix about the unit ``axis``."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def arc_recording(rng: np.random.Generator) -> MarkerRecording:
    """One posture per entry of :data:`ARCS`: a circular-arc backbone of a random base pose, noise-free."""
    t, p0s, q0s, p1s, q1s, markers, nodes = [], [], [], [], [], [], []
    for i, (length, angle, azimuth) in enumerate(ARCS):
        R0 = rotation(np.array([0.6, -0.48, 0.64]), rng.uniform(-np.pi, np.pi))
        p0, t0 = rng.normal(size=3) * 0.1, R0[:, 2]
        n = R0 @ np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
        kappa = angle / length

        def point(s: np.ndarray) -> np.ndarray:  # 1 - cos(x) as 2 sin(x / 2)^2: exact at small turns
            if kappa == 0.0:
                return p0 + np.outer(s, t0)
            return p0 + np.outer(np.sin(kappa * s) / kappa, t0) + np.outer(2 * np.sin(kappa * s / 2) ** 2 / kappa, n)

        R1 = rotation(np.cross(t0, n), angle) @ R0  # the frame carried along the arc: z stays tangent
        t.append(float(i))
        p0s.append(p0)
        q0s.append(quat_from_matrix(R0))
        p1s.append(point(np.array([length]))[0])
        q1s.append(quat_from_matrix(R1))
        markers.append(point(length * np.array([0.25, 0.5, 0.75])))
        nodes.append(point(np.linspace(0.0, length, VERTEBRAE)))
    N = len(ARCS)
    truth = CBHATruth(np.zeros((N, 48)), np.array(nodes), np.array([a[0] for a in ARCS]), np.array(markers))
    return MarkerRecording(
        t=np.array(t),
        base_position=np.array(p0s),
        base_orientation=np.array(q0s),
        tip_position=np.array(p1s),
        tip_orientation=np.array(q1s),
        markers=np.array(markers),
        truth=truth,
    )


def test_cc_arc_is_exact_on_circular_arcs():
    recording = arc_recording(np.random.default_rng(5))
    arcs = cc.run_cc(recording)
    assert recording.truth is not None
    assert np.max(arcs.distances(recording.markers)) < 1e-12
    assert np.max(arcs.distances(recording.truth.vertebrae)) < 1e-12
    np.testing.assert_allclose(arcs.arc_length, [a[0] for a in ARCS], rtol=1e-12)
    np.testing.assert_allclose(arcs.tip_tangent, recording.tip_direction, atol=1e-12)
    np.testing.assert_allclose(arcs.angle, [a[1] for a in ARCS], atol=1e-9)
    assert np.all(arcs.seconds > 0)


def test_closed_form_distance_is_the_closest_point_of_the_arc():
    """Points near the arcs, beyond their ends and near their centres, against 200001 samples of each arc."""
    rng = np.random.default_rng(11)
    recording = arc_recording(rng)
    arcs = cc.run_cc(recording)
    fractions = np.linspace(-0.3, 1.3, 9)
    near = np.stack(
        [cc_arc_points(p, t, q, fractions)[0] for p, t, q in zip(arcs.base, arcs.tangent, arcs.points[:, -1])]
    )
    points = np.concatenate([near + 0.05 * rng.normal(size=near.shape), near + 0.002 * rng.normal(size=near.shape)], 1)
    dense = np.stack(
        [
            cc_arc_points(p, t, q, np.linspace(0, 1, 200001))[0]
            for p, t, q in zip(arcs.base, arcs.tangent, arcs.points[:, -1])
        ]
    )
    brute = np.array([np.min(np.linalg.norm(P[:, None] - D[None], axis=-1), axis=1) for P, D in zip(points, dense)])
    np.testing.assert_allclose(arcs.distances(points), brute, rtol=0, atol=1e-9)


def test_cc_row_is_exact_through_a_csv_problem_file(tmp_path):
    """A recorded file whose backbones are circular arcs: the ``cc-arc`` row's marker distances vanish."""
    write_marker_csv(arc_recording(np.random.default_rng(7)), tmp_path / "arcs.csv")
    path = problem_variant("cbha-ph-shape", tmp_path, baselines=["cc-arc"], data_params={"file": "arcs.csv"})
    raw = yaml.safe_load(path.read_text())
    raw["data"] = {"source": "csv", "params": {"file": "arcs.csv"}}
    raw["options"]["fixed_base"] = False
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    result, _ = solve(str(path), out=tmp_path / "out")
    rows = {row.method: row for row in result.comparison}
    row = rows["cc-arc"]
    assert row.role == "baseline" and row.metrics["ok"] == f"{len(ARCS)}/{len(ARCS)}"
    assert row.metrics["mean marker distance [mm]"] < 1e-9
    assert np.max(row.metrics["max distance per marker [mm]"]) < 1e-9
    assert row.metrics["mean tip tangent error [deg]"] < 1e-6
    assert "truth backbone: largest node distance [mm]" not in row.metrics  # a recorded file has no truth


@pytest.mark.parametrize("name", ["cbha-ph-shape", "cbha-ph-shape-cosserat"])
def test_shipped_problem_reports_the_cc_row(tmp_path, name):
    problem = problem_variant(name, tmp_path / "problems", samples=3, baselines=["ph-ipopt", "cc-arc"])
    result, _ = solve(str(problem), out=tmp_path / "out")
    rows = {row.method: row for row in result.comparison}
    assert list(rows) == ["ph-newton", "ph-ipopt", "cc-arc"] and rows["cc-arc"].role == "baseline"
    metrics = rows["cc-arc"].metrics
    per_marker = np.asarray(metrics["mean distance per marker [mm]"])
    assert per_marker.shape == (3,) and np.all(np.isfinite(per_marker)) and np.all(per_marker > 0)
    assert metrics["median time per sample [us]"] > 0
    assert result.arrays["seconds_cc-arc"].shape == (3,)
    # the closed-form distance is the distance to the sampled arc's polyline within the sagitta of one of its
    # chords (bounded by the sagitta of two chords: the middle point's distance to its neighbours' midpoint)
    truth = result.arrays.get("vertebrae", result.arrays.get("truth_backbone"))
    points = result.arrays["points_cc-arc"]
    polyline = distances_to_polylines(points, truth)
    exact = result.arrays["truth_backbone_distance_cc-arc"]
    sagitta = np.linalg.norm(points[:, 1:-1] - 0.5 * (points[:, :-2] + points[:, 2:]), axis=-1).max(axis=1)
    assert np.all(np.abs(polyline - exact) <= sagitta[:, None]) and np.all(sagitta < 1e-4)
    assert metrics["truth backbone: mean of the largest node distance [mm]"] == pytest.approx(
        np.mean(exact.max(axis=1)) * 1e3, rel=1e-12
    )
    for method in ("ph-newton", "ph-ipopt"):
        assert np.isfinite(rows[method].metrics["truth backbone: mean of the largest node distance [mm]"])


def test_ph_noise_sweep_lists_the_cc_arc_and_collects_its_row(tmp_path):
    spec, path = load_sweep("ph-noise")
    cells = expand(spec, path)
    assert all(dict(cell.overrides)["baselines"] == ["ph-ipopt", "cc-arc"] for cell in cells)
    assert "truth backbone: mean of the largest node distance [mm]" in spec.metrics
    raw = yaml.safe_load(path.read_text())
    raw["problem"] = "cbha-ph-shape"
    raw["set"]["data.samples"] = 2
    raw["axes"] = {"data.params.noise": [0.0001, 0.001], "data.seed": [2018]}
    small = tmp_path / "ph-noise.yaml"
    small.write_text(yaml.safe_dump(raw, sort_keys=False))
    report = run_sweep(str(small), out=tmp_path / "out", figures=False, progress=False)
    assert (report.cells, report.failed) == (2, 0)
    for row in report.rows:
        for method in ("solver", "ph-ipopt", "cc-arc"):
            for metric in ("mean marker distance [mm]", "truth backbone: mean of the largest node distance [mm]"):
                assert math.isfinite(row[f"{method}: {metric}"])
