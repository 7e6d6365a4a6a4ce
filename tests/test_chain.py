"""Chains of PH quintics (`optikin.curves.chain`, seed 002 section III and IV.B).

Checks: joint continuity of C1 and C0 chains (eqs. 15-22) from the curves
themselves; joints that do not meet are rejected naming the link; the closed chain
of seed 002 section IV.B (two constant-curvature arms holding a rope) reconstructed
link by link, against ground truth that is not a PH curve: the arms' circular-arc
backbones (closed form) and the rope's exact catenary.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.curves.catenary import catenary
from optikin.curves.chain import c1_links, check_joints, solve_chain
from optikin.curves import ShapeData, ShapeEnergyModel
from optikin.errors import InputDataError


@pytest.fixture(scope="module")
def model():
    return ShapeEnergyModel()


def helix(t, radius=0.1, pitch=0.05):
    points = np.column_stack([radius * np.cos(t), radius * np.sin(t), pitch * t])
    derivative = np.column_stack([-radius * np.sin(t), radius * np.cos(t), np.full_like(t, pitch)])
    return points, derivative


def test_c1_chain_is_c1_at_its_joints(model):
    t = np.linspace(0, 3 * np.pi, 9)
    points, derivative = helix(t)
    step = t[1] - t[0]
    speeds = np.linalg.norm(derivative, axis=1) * step  # r'(u) for u in [0, 1] per link
    links = solve_chain(c1_links(points, derivative, speeds), model, "C1")
    for before, after in zip(links[:-1], links[1:]):
        a, b = before.curve, after.curve
        np.testing.assert_allclose(a.point(1.0), b.point(0.0), atol=1e-13)
        np.testing.assert_allclose(a.hodograph(1.0), b.hodograph(0.0), atol=1e-13)
    # The chain follows the helix: within 1% of its radius.
    for k, link in enumerate(links):
        truth, _ = helix(np.linspace(t[k], t[k + 1], 50))
        assert max_distance(truth, link.curve) < 1e-2 * 0.1


def test_joints_that_do_not_meet_are_rejected(model):
    a = ShapeData.checked([0, 0, 0], [0, 0, 1], [0, 0.1, 0.3], [0, 1, 0], length=0.4)
    b = ShapeData.checked([0, 0.1, 0.31], [0, 1, 0], [0, 0.4, 0.3], [0, 1, 0], length=0.35)
    with pytest.raises(InputDataError, match="sample 1: p0"):
        solve_chain([a, b], model, "C0", source="chain.yaml")
    b_met = ShapeData.checked([0, 0.1, 0.3], [0, 0, 1], [0, 0.4, 0.3], [0, 1, 0], speeds=(0.4, 0.4))
    a_speeds = ShapeData.checked([0, 0, 0], [0, 0, 1], [0, 0.1, 0.3], [0, 1, 0], speeds=(0.4, 0.4))
    check_joints([a_speeds, b_met], "C0")
    with pytest.raises(InputDataError, match="sample 1: t0"):
        check_joints([a_speeds, b_met], "C1")


def arc_backbone(base, direction, bend_axis, theta, length, n=200):
    """Points of a circular arc from ``base`` leaving along ``direction``, bending by ``theta`` about ``bend_axis``."""
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    normal = np.cross(bend_axis, direction)
    normal /= np.linalg.norm(normal)
    s = np.linspace(0, length, n)
    radius = length / theta
    points = (
        base + radius * np.sin(s / radius)[:, None] * direction + radius * (1 - np.cos(s / radius))[:, None] * normal
    )
    tip_direction = np.cos(theta) * direction + np.sin(theta) * normal
    return points, tip_direction


def max_distance(truth: np.ndarray, curve) -> float:
    """Largest distance from the ground-truth points to the curve (sampled densely)."""
    samples = curve.point(np.linspace(0, 1, 4001))
    return float(np.max(np.min(np.linalg.norm(truth[:, None, :] - samples[None, :, :], axis=2), axis=1)))


def test_closed_chain_of_two_arms_and_a_rope():
    """Seed 002 section IV.B: links CBHA1 (A->B), rope (B->C), CBHA2 (C->D) as PH curves (a C0 chain).

    Measured here (arms 0.36 m bent 0.9 rad, rope 0.7 m over a 0.6 m span, 0.16 m
    sag): per-link largest error 0.17 / 22.9 / 0.17 mm with the end speeds set to
    the link lengths, 0.045 / 0.10 / 0.045 mm with the link lengths held (free speeds).
    """
    arm_length, rope_length = 0.36, 0.7
    A, D = np.zeros(3), np.array([0.9, 0.0, 0.0])
    arm1, tip1 = arc_backbone(A, [0, 0, 1], [0, 1, 0], 0.9, arm_length)  # leans towards +x
    arm2, tip2 = arc_backbone(D, [0, 0, 1], [0, -1, 0], 0.9, arm_length)  # leans towards -x
    B, C = arm1[-1], arm2[-1]
    rope = catenary(B, C, rope_length)
    rope_points = rope.points(np.linspace(0, rope_length, 300))
    links = [
        ShapeData.checked(A, [0, 0, 1], B, tip1, length=arm_length),
        ShapeData.checked(B, rope.tangents(np.array(0.0)), C, rope.tangents(np.array(rope_length)), length=rope_length),
        ShapeData.checked(C, -tip2, D, [0, 0, -1], length=arm_length),  # arm 2 traversed from its tip
    ]
    truths = [arm1, rope_points, arm2[::-1]]
    errors = {}
    for name, m in (("given", ShapeEnergyModel()), ("free", ShapeEnergyModel(free_speeds=True))):
        chain = solve_chain(links, m, "C0", method="nlp")
        for before, after in zip(chain[:-1], chain[1:]):
            np.testing.assert_allclose(before.curve.point(1.0), after.curve.point(0.0), atol=1e-13)
        errors[name] = [max_distance(truth, link.curve) for truth, link in zip(truths, chain)]
    # Arms (circular arcs) within a millimetre either way; the rope only when its length is held.
    assert max(errors["given"][0], errors["given"][2]) < 1e-3
    assert max(errors["free"]) < 1e-3
    assert all(f < g for f, g in zip(errors["free"], errors["given"]))
