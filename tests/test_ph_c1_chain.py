"""The C1 chain of ``ph_shape`` (``c1_joint``, seed 002 Fig. 2, eqs. 15-18): two PH quintics joined at the end of
section 1.

Independent references: a two-section constant-curvature backbone (two circular arcs in
different planes, closed form), which the chain follows and one quintic cannot; the
derivative at the joint by finite differences of the curve points; the Cosserat truth's
material frame at the end of section 1 (the joint pose from the tube markers).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from optikin.curves import ShapeData, ShapeEnergyModel, arc_length_estimate
from optikin.data.cosserat_markers import CosseratMarkerParams, cosserat_recording
from optikin.data.markers import synthetic_recording
from optikin.arms.cbha import CBHAArm
from optikin.errors import InputDataError
from optikin.problems.ph_shape.c1 import SECTIONS, c1_chain_data, joint_poses
from optikin.problems.ph_shared import problem_variant
from optikin.runner import solve

L = 0.18
Z = np.array([0.0, 0.0, 1.0])


def arc(base: np.ndarray, direction: np.ndarray, axis: np.ndarray, theta: float, n: int = 400):
    """Points of the circular arc of length ``L`` leaving ``base`` along ``direction``, turning by ``theta`` about
    ``axis`` (normal to ``direction``), and its end tangent."""
    normal = np.cross(axis, direction)
    normal /= np.linalg.norm(normal)
    radius = L / theta
    phi = np.linspace(0.0, theta, n)[:, None]
    points = base + radius * np.sin(phi) * direction + radius * (1.0 - np.cos(phi)) * normal
    return points, np.cos(theta) * direction + np.sin(theta) * normal


def nearest(points: np.ndarray, curve) -> float:
    """Largest distance of ``points`` to the densely sampled ``curve``."""
    dense = curve.point(np.linspace(0.0, 1.0, 4001))
    return float(np.max(np.min(np.linalg.norm(points[:, None] - dense[None], axis=2), axis=1)))


@pytest.mark.parametrize("theta1, theta2, azimuth", [(1.2, -0.8, 0.0), (1.0, 1.4, 1.3), (0.5, 1.5, 2.0)])
def test_the_chain_follows_two_arcs_that_one_quintic_cannot(theta1, theta2, azimuth):
    arc1, tm = arc(np.zeros(3), Z, np.array([0.0, 1.0, 0.0]), theta1)
    axis = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    axis = (axis - (axis @ tm) * tm) / np.linalg.norm(axis - (axis @ tm) * tm)
    arc2, t1 = arc(arc1[-1], tm, axis, theta2)
    links = c1_chain_data(
        (np.zeros((1, 3)), Z[None]), (arc1[-1][None], tm[None]), (arc2[-1][None], t1[None]), "two arcs"
    )
    model = ShapeEnergyModel()
    first, second = (model.curve(model.solve_newton(links[name][0]), links[name][0]) for name in SECTIONS)
    h = 1e-6  # one-sided differences on either side of the joint: the same derivative, |r'| = L
    before = (first.point(1.0) - first.point(1.0 - h)) / h
    after = (second.point(h) - second.point(0.0)) / h
    np.testing.assert_allclose(before, after, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(after), L, rtol=1e-5)
    np.testing.assert_allclose(first.point(1.0), second.point(0.0), atol=1e-15)
    chain = max(nearest(arc1, first), nearest(arc2, second))
    length = float(arc_length_estimate(np.zeros(3), Z, arc2[-1], t1))
    data = ShapeData.checked(np.zeros(3), Z, arc2[-1], t1, length=length)
    single = nearest(np.concatenate([arc1, arc2]), model.curve(model.solve_newton(data), data))
    assert chain < 0.5e-3 < 3e-3 < single  # measured: 0.20-0.39 mm against 4.1-5.8 mm


def test_the_joint_pose_is_the_truth_frame_at_the_end_of_section_1():
    recording = cosserat_recording(CosseratMarkerParams(), 30, np.random.default_rng([4, 0]))
    position, orientation, marker = joint_poses(recording, "test")
    assert marker == 1 and recording.marker_vertebrae == (5, 9, 13)
    node = int(np.argmin(np.abs(recording.truth.s - CosseratMarkerParams().section_lengths[0])))
    np.testing.assert_allclose(position, recording.markers[:, marker], atol=1e-15)  # the same tube markers' centroid
    assert np.max(np.linalg.norm(position - recording.truth.vertebrae[:, node], axis=1)) < 1.5e-3
    truth = Rotation.from_quat(recording.truth.orientations[:, node][:, [1, 2, 3, 0]])
    measured = Rotation.from_quat(orientation[:, [1, 2, 3, 0]])
    angle = (truth.inv() * measured).magnitude()
    assert np.median(angle) < 0.015 and np.max(angle) < 0.04  # 0.3 mm on three markers 32-35 mm from the axis


def test_a_recording_without_tube_markers_is_refused():
    recording = synthetic_recording(CBHAArm(), 2, np.random.default_rng(0))
    with pytest.raises(InputDataError, match="c1_joint: a C1 joint needs the rigid body"):
        joint_poses(recording, "synthetic")


def test_the_problem_reports_the_chain_next_to_the_single_curve(tmp_path):
    result, _ = solve(str(problem_variant("cbha-c1-chain", tmp_path, samples=4, baselines=[])))
    assert result.status == ["ok"] * 4
    m, a = result.metrics, result.arrays
    chain, single = (
        m["C1 chain: truth backbone: mean of the largest node distance [mm]"],
        m["truth backbone: mean of the largest node distance [mm]"],
    )
    assert chain < 0.5 * single
    points = a["c1_points"]  # (N, section, T, 3)
    np.testing.assert_allclose(points[:, 0, -1], points[:, 1, 0], atol=1e-13)
    np.testing.assert_allclose(points[:, 0, -1], a["c1_joint_position"], atol=1e-13)
    step = 1.0 / (points.shape[2] - 1)  # first-order differences either side of the joint agree to O(step)
    before, after = (points[:, 0, -1] - points[:, 0, -2]) / step, (points[:, 1, 1] - points[:, 1, 0]) / step
    assert np.max(np.linalg.norm(before - after, axis=1) / np.linalg.norm(after, axis=1)) < 0.05
    assert any(row.method == "ph-newton (C1 section 2)" for row in result.comparison)
