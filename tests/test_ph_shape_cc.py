"""Baselines ``cc-arc`` and ``cc-two-arcs`` of ``ph_shape`` (optikin.problems.ph_shape.cc), sweep ``ph-noise``.

Independent references: recordings whose backbones are exact circular arcs (and straight
ones), one per section, built here from the arc's own equation and the frame carried
along it, on which the constant-curvature reconstructions must be exact; brute-force
closest points on densely sampled arcs for the closed-form distance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from optikin.algebra import quat_from_matrix
from optikin.data.markers import CBHATruth, MarkerRecording, write_marker_csv
from optikin.errors import InputDataError
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
TWO_SECTIONS = (  # two such arcs, the second in its own plane, joined with C1 continuity
    ((0.15, 0.8, 0.3), (0.17, 1.3, 2.2)),
    ((0.2, 0.0, 0.0), (0.15, 1.0, 1.0)),
    ((0.15, 1.2, 0.5), (0.15, 0.0, 0.0)),
    ((0.16, 2.0, -0.4), (0.18, 1.5, math.pi)),  # section 2 bends back
)


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix about the unit ``axis``."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def on_arc(p0: np.ndarray, R0: np.ndarray, section: tuple[float, float, float], s: np.ndarray):
    """Points at arc lengths ``s`` of the arc leaving ``p0`` along the z axis of frame ``R0``, and its end frame."""
    length, angle, azimuth = section
    t0, n = R0[:, 2], R0 @ np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    kappa = angle / length
    if kappa == 0.0:
        points = p0 + np.outer(s, t0)
    else:  # 1 - cos(x) as 2 sin(x / 2)^2: exact at small turns
        points = p0 + np.outer(np.sin(kappa * s) / kappa, t0) + np.outer(2 * np.sin(kappa * s / 2) ** 2 / kappa, n)
    return points, rotation(np.cross(t0, n), angle) @ R0  # the frame carried along the arc: z stays tangent


def arc_recording(rng: np.random.Generator, postures=None) -> MarkerRecording:
    """One posture per entry of ``postures`` (default: :data:`ARCS` as two halves of one arc), a random base pose,
    noise-free: markers at the middle of section 1, the joint (vertebra 9) and the middle of section 2."""
    if postures is None:
        postures = [((a[0] / 2, a[1] / 2, a[2]),) * 2 for a in ARCS]
    base, base_q, tip, tip_q, markers, nodes = [], [], [], [], [], []
    for first, second in postures:
        R0 = rotation(np.array([0.6, -0.48, 0.64]), rng.uniform(-np.pi, np.pi))
        p0 = rng.normal(size=3) * 0.1
        ends = np.array([0.5, 1.0]) * first[0]
        points1, R1 = on_arc(p0, R0, first, np.concatenate([np.linspace(0.0, first[0], 9), ends]))
        pm = points1[-1]
        points2, R2 = on_arc(pm, R1, second, np.concatenate([np.linspace(0.0, second[0], 9)[1:], [0.5 * second[0]]]))
        base.append(p0)
        base_q.append(quat_from_matrix(R0))
        tip.append(points2[-2])
        tip_q.append(quat_from_matrix(R2))
        markers.append([points1[-2], pm, points2[-1]])
        nodes.append(np.concatenate([points1[:9], points2[:8]]))
    N = len(postures)
    lengths = np.array([first[0] + second[0] for first, second in postures])
    truth = CBHATruth(np.zeros((N, 48)), np.array(nodes), lengths, np.array(markers))
    return MarkerRecording(
        t=np.arange(N, dtype=float),
        base_position=np.array(base),
        base_orientation=np.array(base_q),
        tip_position=np.array(tip),
        tip_orientation=np.array(tip_q),
        markers=np.array(markers),
        truth=truth,
        marker_vertebrae=(5, 9, 13),
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


def test_two_arcs_are_exact_on_two_section_arcs():
    """Piecewise constant curvature, C1 at the joint: both arcs rebuilt from the base pose, the joint marker
    and the tip point (the tip tangent too, which they do not use)."""
    recording = arc_recording(np.random.default_rng(3), TWO_SECTIONS)
    assert recording.truth is not None
    two = cc.run_two_arcs(recording, "test")
    assert two.joint_marker == 1
    assert np.max(two.distances(recording.markers)) < 1e-12
    assert np.max(two.distances(recording.truth.vertebrae)) < 1e-12
    lengths = [(a[0], b[0]) for a, b in TWO_SECTIONS]
    np.testing.assert_allclose(np.stack([arc.arc_length for arc in two.sections], 1), lengths, rtol=1e-12)
    np.testing.assert_allclose(two.sections[1].tip_tangent, recording.tip_direction, atol=1e-12)
    single = cc.run_cc(recording)  # one arc cannot follow them
    assert np.min(single.distances(recording.truth.vertebrae).max(axis=1)) > 1e-3


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


def csv_problem(tmp_path, baselines: list[str], intermediate: list[int] | None):
    """A problem file reading ``arcs.csv`` (written by the caller) with ``baselines``."""
    path = problem_variant("cbha-ph-shape", tmp_path, baselines=baselines)
    raw = yaml.safe_load(path.read_text())
    raw["data"] = {"source": "csv", "params": {"file": "arcs.csv"}}
    if intermediate is not None:
        raw["data"]["params"]["intermediate"] = intermediate
    raw["options"]["fixed_base"] = False
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_cc_rows_are_exact_through_a_csv_problem_file(tmp_path):
    """A recorded file whose backbones are circular arcs: both arc rows' marker distances vanish."""
    write_marker_csv(arc_recording(np.random.default_rng(7)), tmp_path / "arcs.csv")
    result, _ = solve(str(csv_problem(tmp_path, ["cc-arc", "cc-two-arcs"], [5, 9, 13])), out=tmp_path / "out")
    rows = {row.method: row for row in result.comparison}
    for name in ("cc-arc", "cc-two-arcs"):
        row = rows[name]
        assert row.role == "baseline" and row.metrics["ok"] == f"{len(ARCS)}/{len(ARCS)}"
        assert np.max(row.metrics["max distance per marker [mm]"]) < 1e-9
        assert row.metrics["mean tip tangent error [deg]"] < 1e-6
        assert "truth backbone: largest node distance [mm]" not in row.metrics  # a recorded file has no truth
    assert rows["cc-arc"].metrics["mean marker distance [mm]"] < 1e-9
    assert rows["cc-two-arcs"].metrics["mean marker distance off the joint [mm]"] < 1e-9


def test_two_arcs_need_a_marker_at_the_joint(tmp_path):
    write_marker_csv(arc_recording(np.random.default_rng(7)), tmp_path / "arcs.csv")
    with pytest.raises(InputDataError, match="end of section 1") as error:
        solve(str(csv_problem(tmp_path, ["cc-two-arcs"], None)), out=tmp_path / "out")
    assert error.value.field == "baselines"


@pytest.mark.parametrize("name", ["cbha-ph-shape", "cbha-ph-shape-cosserat"])
def test_shipped_problem_reports_the_cc_rows(tmp_path, name):
    problem = problem_variant(name, tmp_path / "problems", samples=3, baselines=["ph-ipopt", "cc-arc", "cc-two-arcs"])
    result, _ = solve(str(problem), out=tmp_path / "out")
    rows = {row.method: row for row in result.comparison}
    assert list(rows) == ["ph-newton", "ph-ipopt", "cc-arc", "cc-two-arcs"]
    truth = result.arrays.get("vertebrae", result.arrays.get("truth_backbone"))
    for method in ("cc-arc", "cc-two-arcs"):
        metrics = rows[method].metrics
        assert rows[method].role == "baseline"
        per_marker = np.asarray(metrics["mean distance per marker [mm]"])
        assert per_marker.shape == (3,) and np.all(np.isfinite(per_marker))
        assert metrics["median time per sample [us]"] > 0
        assert result.arrays[f"seconds_{method}"].shape == (3,)
        # the closed-form distance is the distance to the sampled arcs' polyline within the sagitta of one of
        # its chords (bounded by the sagitta of two chords: the middle point's distance to its neighbours' midpoint;
        # not at the joint of two arcs, whose chords differ)
        points = result.arrays[f"points_{method}"]
        polyline = distances_to_polylines(points, truth)
        exact = result.arrays[f"truth_backbone_distance_{method}"]
        middle = np.linalg.norm(points[:, 1:-1] - 0.5 * (points[:, :-2] + points[:, 2:]), axis=-1)
        if method == "cc-two-arcs":
            middle = np.delete(middle, cc.CURVE_POINTS - 2, axis=1)  # points[CURVE_POINTS - 1]: the joint
        sagitta = middle.max(axis=1)
        assert np.all(np.abs(polyline - exact) <= sagitta[:, None]) and np.all(sagitta < 1e-4)
        assert metrics["truth backbone: mean of the largest node distance [mm]"] == pytest.approx(
            np.mean(exact.max(axis=1)) * 1e3, rel=1e-12
        )
    assert np.all(np.asarray(rows["cc-arc"].metrics["mean distance per marker [mm]"]) > 0)
    assert rows["cc-two-arcs"].metrics["mean distance per marker [mm]"][1] < 1e-9  # the joint marker: its own
    for method in ("ph-newton", "ph-ipopt"):
        assert np.isfinite(rows[method].metrics["truth backbone: mean of the largest node distance [mm]"])


def test_ph_noise_sweep_lists_the_cc_baselines_and_collects_their_rows(tmp_path):
    spec, path = load_sweep("ph-noise")
    cells = expand(spec, path)
    assert all(dict(cell.overrides)["baselines"] == ["ph-ipopt", "cc-arc", "cc-two-arcs"] for cell in cells)
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
        for method in ("solver", "ph-ipopt", "cc-arc", "cc-two-arcs"):
            assert math.isfinite(row[f"{method}: truth backbone: mean of the largest node distance [mm]"])
            assert math.isfinite(row[f"{method}: median time per sample [us]"])
        for method in ("solver", "ph-ipopt", "cc-arc"):
            assert math.isfinite(row[f"{method}: mean marker distance [mm]"])
        assert math.isfinite(row["cc-two-arcs: mean marker distance off the joint [mm]"])
