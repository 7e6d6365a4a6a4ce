"""Two arms by one QP: the distance Jacobian between two backbones and the rope task's Jacobian against central
differences, the sampling bound against densely sampled backbones, the shipped scenarios without a collision
(their baselines' collisions reported), and bad input refused naming the field."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import casadi as ca
import numpy as np
import pytest

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.self_collision import PlacedArm, TwoTubes, collision_density, rotation_from_quaternion
from optikin.control.two_arm import Rope, TwoArmModel, TwoArmQP, qp_factory
from optikin.curves.catenary_sensitivity import CatenarySensitivity
from optikin.errors import SpecError
from optikin.runner import prepare, solve
from optikin.spec import load_problem

ARM = ConstantCurvatureArm()
DT = 0.002


def two_arms(points_per_section: int | None = None) -> tuple[PlacedArm, PlacedArm]:
    pps = collision_density(ARM, 0.02) if points_per_section is None else points_per_section
    turn = rotation_from_quaternion([np.cos(0.3), 0.0, 0.0, np.sin(0.3)]) @ rotation_from_quaternion([0, 0, 0, 1])
    return (
        PlacedArm(ARM, np.array([-0.15, 0.01, 0.0]), np.eye(3), 0.015, pps),
        PlacedArm(ARM, np.array([0.15, -0.02, 0.01]), turn, 0.012, pps),
    )


def central_differences(f, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    columns = []
    for i in range(len(q)):
        up, down = q.copy(), q.copy()
        up[i] += step
        down[i] -= step
        columns.append((f(up) - f(down)) / (2 * step))
    return np.stack(columns, axis=-1)


Q = np.array([0.17, 0.7, 0.3, 0.19, 0.5, -0.4, 0.18, 0.6, -0.2, 0.17, 0.8, 0.5])


def test_distance_jacobian_between_two_backbones_matches_central_differences():
    first, second = two_arms()
    tubes = TwoTubes(first, second, margin=0.02, gamma=20.0, dt=DT, pairs=5)
    first.evaluate(Q[:6])
    second.evaluate(Q[6:])
    tubes.update()

    def pair_distances(q: np.ndarray) -> np.ndarray:
        P1, P2 = first.points_at(q[:6]), second.points_at(q[6:])
        i, j = tubes.chosen.T
        return np.linalg.norm(P1[i] - P2[j], axis=1) - first.radius - second.radius

    assert np.allclose(tubes.A, central_differences(pair_distances, Q), atol=1e-8)
    d = pair_distances(Q)
    assert np.allclose(tubes.b, -20.0 * (d - 0.02))
    # The rows are the nearest pairs: no other sample of arm 1 is nearer to arm 2 than the farthest chosen one.
    all_pairs = tubes.clearance_matrix(first.points_at(Q[:6]), second.points_at(Q[6:]))
    assert d.max() <= np.sort(all_pairs.min(axis=1))[tubes.pairs - 1] + 1e-12


def test_rope_task_jacobian_is_the_lowest_points_derivative_in_both_configurations():
    first, second = two_arms(4)
    model = TwoArmModel([first, second], "rope", Rope(CatenarySensitivity(0.5)))
    q = np.array([0.18, 0.3, 0.1, 0.18, 0.3, 0.0, 0.17, 0.25, -0.1, 0.18, 0.35, 0.2])

    def lowest(q: np.ndarray) -> np.ndarray:
        model.evaluate(q)
        return model.x.copy()

    numeric = central_differences(lowest, q)
    model.evaluate(q)
    assert np.allclose(model.J, numeric, atol=1e-8)


def test_sampled_clearance_less_half_the_spacings_bounds_the_dense_backbones():
    first, second = two_arms()
    tubes = TwoTubes(first, second, margin=0.02, gamma=20.0, dt=DT)
    s = ca.SX.sym("q", 6)
    backbone = ca.Function("dense", [s], [ARM.backbone_points(s, 120)])

    def dense(placed: PlacedArm, q: np.ndarray) -> np.ndarray:
        return placed.base + (placed.rotation @ np.asarray(backbone(q))).T

    rng = np.random.default_rng(3)
    for _ in range(10):
        q = np.concatenate([ARM.sample_configurations(1, rng)[0] for _ in range(2)])
        sampled = tubes.clearance_matrix(first.points_at(q[:6]), second.points_at(q[6:])).min()
        continuous = tubes.clearance_matrix(dense(first, q[:6]), dense(second, q[6:])).min()
        assert sampled - tubes.between_samples <= continuous + 1e-12  # the bound between samples holds
        assert continuous <= sampled + 1e-12  # the dense backbones hold the samples: one rounding apart at most


def test_joint_qp_without_active_rows_is_the_damped_least_squares_step():
    first, second = two_arms(4)
    model = TwoArmModel([first, second], "tips")
    qp = TwoArmQP(model, DT, 10.0, factory=qp_factory("qp_qpsolvers", solver="daqp"), damping=1e-3)
    q = np.array([0.18, 0.5, 0.1, 0.18, 0.4, 0.0, 0.18, 0.45, -0.1, 0.18, 0.35, 0.2])
    model.evaluate(q)
    x_ref = model.x + 1e-4 * np.arange(6)
    qdot = qp.command(q, x_ref, np.zeros(6))
    J, v = model.J, 10.0 * (x_ref - model.x)
    expected = np.linalg.solve(J.T @ J + 1e-3 * np.eye(12), J.T @ v)
    assert qp.status == "ok" and np.allclose(qdot, expected, atol=1e-9)


@pytest.mark.parametrize("name", ["rope-skipping", "track-two-arms-shared-space"])
def test_shipped_scenario_has_no_collision_for_the_joint_qp_and_reports_the_baselines(tmp_path, name):
    result, _ = solve(name, out=tmp_path / "out", figures=False, overrides=[("baselines", ["no_collision_rows"])])
    rows = {row.role + ":" + row.method: row.metrics for row in result.comparison}
    qp = rows["solver:joint QP"]
    baseline = rows["baseline:joint QP without collision rows"]
    assert result.criteria == {"no collision": True, "within limits": True}
    assert result.status_counts() == {"ok": result.samples}
    assert qp["collision steps"] == 0 and result.metrics["tube clearance bound [mm]"] > 0
    assert qp["clearance [mm]"] >= 20.0 - 0.5  # the margin, to the linearisation over one step
    assert baseline["collision steps"] > 0 and baseline["depth [mm]"] > 0
    assert any("interpenetrate" in note for note in result.notes)


def test_saturated_pseudo_inverse_keeps_both_arms_inside_the_limits_and_rates():
    """Both arms' configurations and their steps of the saturated pseudo-inverse, checked against the arm's limits
    and the default rate limits, on the shared-space scenario where the plain pseudo-inverse leaves them."""
    from optikin.control.limits import rate_limit_vector

    overrides = [("data.params.rate", 100), ("baselines", ["pseudo_inverse", "pseudo_inverse_saturated"])]
    result, _ = solve("track-two-arms-shared-space", figures=False, overrides=overrides)
    rows = {row.method: row.metrics for row in result.comparison}
    assert rows["pseudo-inverse"]["outside limits"] > 0 and rows["pseudo-inverse (saturated)"]["outside limits"] == 0
    q, dt = result.arrays["q_pseudo_inverse_saturated"], float(np.diff(result.arrays["t"])[0])
    bounded = np.tile(~ARM.periodic, 2)
    lower, upper = np.tile(ARM.lower, 2)[bounded], np.tile(ARM.upper, 2)[bounded]
    assert np.all(q[:, bounded] >= lower - 1e-12) and np.all(q[:, bounded] <= upper + 1e-12)
    steps = np.abs(np.diff(q[:, bounded], axis=0))
    assert np.all(steps <= np.tile(rate_limit_vector(ARM), 2)[bounded] * dt * (1 + 1e-9))


def test_joint_qp_of_the_shipped_rope_problem_is_the_exact_qp_warm_started_where_its_rows_bind():
    """The kind's step solver (qp_daqp on the controller's buffers) against quadprog (Goldfarb-Idnani) on every
    step of the rope loop at 100 Hz, rows and bounds as the QP has them; warm-started, a step rarely iterates."""
    qpsolvers = pytest.importorskip("qpsolvers")
    from optikin.control.limits import periodic_mask, wrap_periodic
    from optikin.problems.two_arms.run import setup
    from optikin.solvers.qp.qp_daqp import ActiveSetStepSolver

    _, ctx = prepare("rope-skipping", overrides=[("data.params.rate", 100), ("data.params.cycles", 1)])
    problem = setup(ctx)
    qp, reference = problem.controllers["qp"], problem.reference
    assert isinstance(qp.solver, ActiveSetStepSolver)
    wrapped = np.concatenate([periodic_mask(placed.arm) for placed in problem.plant.arms])
    q, d, binding, iterations = problem.q0.copy(), qp.data, 0, []
    qp.reset()
    for k in range(len(reference.t)):
        qdot = qp.command(q, reference.value[k], reference.rate[k])
        assert qp.status == "ok"
        exact = qpsolvers.solve_qp(d.H, d.g, -d.A, -d.b, lb=d.lb, ub=d.ub, solver="quadprog")
        np.testing.assert_allclose(qdot, exact, atol=1e-9)
        binding += bool(np.any(d.A @ exact <= d.b + 1e-9))
        iterations.append(qp.solver.solution.iterations)
        q = wrap_periodic(q + qp.dt * qdot, wrapped)
    assert binding > 5  # the tube and rope rows hold in the deep part of the loop
    assert np.median(iterations) == 1


def error_field(problem: str | Path, overrides: Sequence[tuple[str, Any]] = ()) -> str:
    kind, ctx = prepare(str(problem), overrides=overrides)
    with pytest.raises(SpecError) as err:
        kind.run(ctx)
    return err.value.field


def test_rope_shorter_than_the_grips_distance_is_refused_naming_the_length():
    assert error_field("rope-skipping", [("options.rope.length", 0.2)]) == "options.rope.length"


def test_overlapping_bases_are_refused_naming_the_base(problem_variant):
    problem = problem_variant(
        "track-two-arms-shared-space", lambda d: d["options"]["arms"][1].update(base=[-0.13, 0, 0])
    )
    assert error_field(problem) == "options.arms.1.base"


@pytest.mark.parametrize(
    "change,field",
    [
        (lambda d: d["options"].pop("rope"), "options.rope"),
        (lambda d: d["options"]["arms"][0].update(start=[0.18, 0.3]), "options.arms.0.start"),
        (lambda d: d["options"]["arms"][0].pop("start"), "options.arms.0.start"),
        (lambda d: d["options"]["rope"].update(floor=0.3), "options.rope.floor"),
    ],
)
def test_bad_rope_task_input_names_the_field(problem_variant, change, field):
    assert error_field(problem_variant("rope-skipping", change)) == field


def test_start_with_the_tubes_within_the_margin_is_refused(problem_variant):
    def closer(d):
        d["options"]["arms"][0]["base"] = [-0.1, 0.0, 0.0]
        d["options"]["arms"][1]["base"] = [0.1, 0.0, 0.0]

    assert error_field(problem_variant("rope-skipping", closer)) == "options.arms"


def test_floor_row_keeps_the_ropes_lowest_point_above_a_floor_the_loop_dips_below(tmp_path):
    floor = [
        ("baselines", []),
        ("data.params.cycles", 1),
        ("data.params.hold", 0.0),
        ("options.rope.floor", 0.12),  # the loop's bottom lies at about 95 mm
    ]
    result, _ = solve("rope-skipping", out=tmp_path / "out", figures=False, overrides=floor)
    reference_low = float(result.arrays["reference"][:, 2].min())
    assert reference_low < 0.12
    assert result.metrics["lowest point above the floor min [mm]"] >= 20.0 - 0.5  # the margin, to one step's error
    assert np.all(result.arrays["x_qp"][:, 2] >= 0.12)


def test_rope_rows_are_the_derivative_of_the_rope_samples_clearance_to_each_tube():
    from optikin.control.two_arm import RopeTubes, rope_samples

    first, second = two_arms(6)
    sensitivity = CatenarySensitivity(0.5)
    model = TwoArmModel([first, second], "rope", Rope(sensitivity, samples=rope_samples(sensitivity, 0.07, 0.01)))
    rows = RopeTubes(model, margin=0.01, gamma=20.0, dt=DT, pairs=3)
    q = np.array([0.18, 0.3, 0.1, 0.18, 0.3, 0.0, 0.17, 0.25, -0.1, 0.18, 0.35, 0.2])
    model.evaluate(q)
    rows.update()
    chosen = []  # (rope sample, arm, backbone sample) of every row, recovered from the clearances
    R = model.rope.samples.P.copy()
    for arm, placed in enumerate(model.arms):
        d = np.linalg.norm(R[:, None, :] - placed.P[None, :, :], axis=2) - placed.radius
        for b in rows.b[3 * arm : 3 * arm + 3]:
            i, j = np.argwhere(np.isclose(-20.0 * (d - 0.01), b, rtol=0, atol=1e-12))[0]
            chosen.append((i, arm, j))

    def clearances(q: np.ndarray) -> np.ndarray:
        model.evaluate(q)
        R, out = model.rope.samples.P, []
        for i, arm, j in chosen:
            placed = model.arms[arm]
            out.append(np.linalg.norm(R[i] - placed.P[j]) - placed.radius)
        return np.array(out)

    numeric = central_differences(clearances, q)
    assert np.allclose(rows.A, numeric, atol=1e-8)


def test_rope_rows_keep_the_rope_off_the_tubes_where_the_baseline_comes_closer(tmp_path):
    margin = [("baselines", ["no_collision_rows"]), ("options.collision.rope_margin", 0.044)]  # the start: 44.8 mm
    result, _ = solve("rope-skipping", out=tmp_path / "out", figures=False, overrides=margin)
    assert result.criteria == {"no collision": True, "within limits": True}
    # Dense rope points on every 10th step; between the QP's samples the rope may come (5 + 9.9)/2 mm closer.
    assert result.metrics["rope to the arms' tubes min [mm]"] >= 44.0 - 7.5
    baseline = run_metrics_of(result, "no_collision_rows")
    assert baseline < 44.0 - 1.0


def run_metrics_of(result, name: str) -> float:
    """The least dense rope clearance of run ``name`` from its arrays (every 10th step, 60 rope points)."""
    from optikin.curves.catenary import catenary

    first, second = two_arms_of("rope-skipping")
    tips, Q = result.arrays[f"tips_{name}"], result.arrays[f"q_{name}"]
    s = np.linspace(0.0, 0.3, 60)
    keep = (s >= 0.07) & (s <= 0.3 - 0.07)
    least = np.inf
    for k in range(0, len(Q), 10):
        rope = catenary(tips[k, 0], tips[k, 1], 0.3).points(s)[keep]
        for placed, q in ((first, Q[k, :6]), (second, Q[k, 6:])):
            least = min(least, np.linalg.norm(rope[:, None] - placed.points_at(q)[None], axis=2).min() - placed.radius)
    return float(least * 1e3)


def two_arms_of(name: str) -> tuple[PlacedArm, PlacedArm]:
    spec, _ = load_problem(name)
    return tuple(  # type: ignore[return-value]
        PlacedArm(ARM, np.array(a["base"]), rotation_from_quaternion(a["orientation"]), a["radius"], 4)
        for a in spec.options["arms"]
    )


def test_solve_of_a_rope_shorter_than_its_grips_exits_2_naming_file_and_field(tmp_path, capsys):
    from optikin.cli import EXIT_BAD_INPUT, main

    shorter = ["--set", "options.rope.length=0.2"]
    assert main(["solve", "rope-skipping", *shorter, "--out", str(tmp_path / "out")]) == EXIT_BAD_INPUT
    message = capsys.readouterr().err
    assert str(load_problem("rope-skipping")[1]) in message and "options.rope.length" in message
    assert not (tmp_path / "out").exists()


def test_obstacle_rows_are_the_derivative_of_each_bodys_clearance_and_hold_a_moving_obstacles_step():
    from optikin.control.obstacles import Obstacle
    from optikin.control.two_arm import rope_samples
    from optikin.control.two_arm_obstacles import TwoArmObstacleRows

    first, second = two_arms(6)
    sensitivity = CatenarySensitivity(0.5)
    model = TwoArmModel([first, second], "rope", Rope(sensitivity, samples=rope_samples(sensitivity, 0.07, 0.01)))
    obstacles = [
        Obstacle("sphere", center=(0.0, 0.05, 0.15), radius=0.03, path=((0.0, 0, 0, 0), (1.0, 0.1, 0, 0))),
        Obstacle("box", center=(0.1, -0.1, 0.1), half_extents=(0.02, 0.03, 0.04)),
    ]
    rows = TwoArmObstacleRows(model, obstacles, margin=0.01, gamma=20.0, dt=DT, points_per_obstacle=2)
    q = np.array([0.18, 0.3, 0.1, 0.18, 0.3, 0.0, 0.17, 0.25, -0.1, 0.18, 0.35, 0.2])
    model.evaluate(q)
    rows.step = 50  # t = 0.1 s: the sphere moves at 0.1 m/s along x
    rows.update()
    t = 50 * DT
    chosen = []  # (obstacle, flat sample index) of every row, recovered from b
    for o, (clearance, gradient) in enumerate(rows.distances(t)):
        moved = obstacles[o].offset(t + DT) - obstacles[o].offset(t)
        expected = -20.0 * (clearance - 0.01) + gradient @ moved / DT
        for b in rows.b[o * 6 : o * 6 + 6]:
            chosen.append((o, int(np.argmin(np.abs(expected - b)))))
            assert np.min(np.abs(expected - b)) < 1e-12

    def clearances(q: np.ndarray) -> np.ndarray:
        model.evaluate(q)
        per_obstacle = [c.copy() for c, _ in rows.distances(t)]
        return np.array([per_obstacle[o][i] for o, i in chosen])

    assert np.allclose(rows.A, central_differences(clearances, q), atol=1e-8)


@pytest.mark.parametrize(
    "name,center,body",
    [("track-two-arms-shared-space", [0.0, 0.0, 0.35], "arm 1"), ("rope-skipping", [0.0, 0.04, 0.12], "rope")],
)
def test_obstacle_kept_off_the_arms_and_the_rope_where_the_baseline_goes_through(tmp_path, name, center, body):
    sphere = [
        ("baselines", ["no_collision_rows"]),
        ("options.obstacles", [{"type": "sphere", "center": center, "radius": 0.03}]),
    ]
    result, _ = solve(name, out=tmp_path / "out", figures=False, overrides=sphere)
    assert result.criteria["no obstacle penetration"] and result.criteria["no collision"]
    assert result.metrics[f"{body} to obstacles min [mm]"] >= 10.0 - 0.5  # the margin, to one step's linearisation
    rows = {row.role: row.metrics for row in result.comparison}
    assert rows["solver"]["obstacle steps"] == 0 and rows["baseline"]["obstacle steps"] > 0
    assert rows["baseline"]["obstacle [mm]"] < 0
    assert any("inside an obstacle" in note for note in result.notes)


@pytest.mark.parametrize(
    "center,field",
    [([-0.15, 0.0, 0.0], "options.obstacles.0"), ([-0.12, 0.0, 0.2], "options.obstacles")],
    ids=["base", "start"],
)
def test_obstacle_at_a_base_or_on_the_start_is_refused_naming_it(center, field):
    sphere = [("options.obstacles", [{"type": "sphere", "center": center, "radius": 0.02}])]
    assert error_field("track-two-arms-shared-space", sphere) == field
