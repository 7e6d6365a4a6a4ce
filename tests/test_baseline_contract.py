"""Baselines are data: every kind declares the baselines it runs (:class:`optikin.problems.Baseline`), the runner
resolves each name of ``baselines:`` once (:func:`optikin.runner.resolve_baselines`), and every listed name gets
its row, under its own title.

For every kind a small shipped problem lists every baseline the kind declares and a solver preset of its family
(where it runs presets as baselines); the comparison must hold exactly the rows the kind's labelling gives each
name: one row under its title, except the kinds whose rows are split by part (``ph_chain``: per link; ``dmp``: the
regressions on the first variant, the tuning per term).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np
import pytest

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.cli import EXIT_BAD_INPUT, main
from optikin.control.limits import RateBounds, rate_limit_vector
from optikin.errors import SpecError
from optikin.problems import load_kinds
from optikin.registry import PROBLEM_KINDS
from optikin.runner import prepare, solve

load_kinds()
SHORT_PATH = [("data.params.rate", 100), ("data.params.segment_time", 0.5), ("data.params.hold", 0.2)]
Labels = Callable[[str], list[str]]
TRACKING = [
    "qp-osqp",
    "mrac",
    "mrac_seed",
    "pseudo_inverse",
    "damped_least_squares",
    "mrac_saturated",
    "mrac_seed_saturated",
    "pseudo_inverse_saturated",
    "damped_least_squares_saturated",
    "mpc",
    "mpc_ipopt",
]


def one(title: str) -> list[str]:
    return [title]


def per_link(title: str) -> list[str]:
    return [f"{title} (CBHA 1)", f"{title} (rope)", f"{title} (CBHA 2)"]


def dmp_rows(title: str) -> list[str]:
    return [f"tuning Q_r ({title})"] if title == "genetic" else [f"dmp seed ({title})"]


DMP_SMALL = [
    ("data.samples", 200),
    ("options.variants", ["seed"]),
    ("options.n_basis", 10),
    ("options.tuning.terms", ["Q_r"]),
    ("options.tuning.reference", {"Q_r": {"beta": 348.348, "gamma": 977.24}}),
    ("options.tuning.seeds", 1),
    ("options.tuning.budget", 20),
    ("options.tuning.screen", 4),
    ("options.tuning.max_iterations", 3),
    ("options.tuning.population", 6),
]
NN_SMALL = [
    ("data.samples", 40_000),
    ("options.setting", "small"),
    ("options.exact_samples", 3),
    ("options.latency_repeats", 3),
    ("options.variants", ["adam"]),
]
CASES: dict[str, list[tuple[str, list[tuple[str, Any]], list[str], Labels]]] = {
    "fk": [("cc-two-section-fk", [("data.samples", 20)], ["numpy", "casadi-call"], one)],
    "ik": [("cc-ik-position", [("data.samples", 5)], ["lm"], one)],
    "ph_chain": [("cbha-rope-chain", [("data.samples", 2)], ["ph-ipopt"], per_link)],
    "tracking": [("track-nominal", SHORT_PATH, TRACKING, one)],
    "two_arms": [
        (
            "track-two-arms-shared-space",
            [("data.params.rate", 100)],
            ["qp-osqp", "no_collision_rows", "pseudo_inverse", "pseudo_inverse_saturated"],
            one,
        )
    ],
    "dmp": [("dmp-imu-dualquat", DMP_SMALL, ["lstsq", "lwr", "genetic"], dmp_rows)],
    "statics": [
        ("cosserat-cbha-fk", [("data.samples", 2)], ["collocation"], one),
        ("cosserat-tendon-ik", [("data.samples", 2)], ["lm"], one),
    ],
    "ph_shape": [
        (
            "cbha-ph-shape-cosserat",
            [("data.samples", 2)],
            ["ph-ipopt", "cosserat-wrench", "cc-arc", "cc-two-arcs"],
            one,
        )
    ],
    "ph_ik": [
        (
            "cbha-ph-ik",
            [("data.samples", 3)],
            ["ph-ipopt", "newton-raphson", "newton-raphson-pose", "hybrid", "hybrid-coupled"],
            one,
        )
    ],
    "nn_fkm": [
        (
            "cbha-nn-fkm",
            NN_SMALL,
            ["newton"],
            one,
        )
    ],
    "nn_ikm": [
        (
            "cbha-nn-ikm",
            NN_SMALL,
            ["ipopt"],
            one,
        )
    ],
    "actuation": [
        (
            "trunk-lab-actuation",
            [("options.postures", 40), ("options.fractions", [1.0]), ("options.max_evaluations", 4)],
            ["knn", "mlp", "gp"],
            one,
        )
    ],
}
"""Per kind that runs baselines: ``(problem, overrides making it small, baselines listed, the labels of a
baseline's rows)``."""
FAST = {"fk", "ik", "ph_chain", "tracking", "two_arms", "dmp"}
"""The kinds whose contract run takes a few seconds; the others are marked slow."""


def test_every_kind_has_a_contract_case_listing_every_baseline_it_runs():
    """A kind without a case runs no baseline at all (neither its own nor a preset)."""
    assert set(CASES) <= set(PROBLEM_KINDS.names())
    for name in set(PROBLEM_KINDS.names()) - set(CASES):
        kind = PROBLEM_KINDS.get(name)
        assert not kind.baselines and kind.preset_baseline is None, f"kind {name} runs baselines: give it a case"
    for name, cases in CASES.items():
        kind = PROBLEM_KINDS.get(name)
        listed = {baseline for case in cases for baseline in case[2]}
        assert set(kind.baselines) <= listed, f"kind {name}: no case lists {set(kind.baselines) - listed}"
        presets = listed - set(kind.baselines)
        assert bool(presets) == (kind.preset_baseline is not None), f"kind {name}: presets listed {presets}"


@pytest.mark.parametrize(
    "kind,problem,overrides,names,labels",
    [
        pytest.param(kind, *case, marks=() if kind in FAST else pytest.mark.slow, id=f"{kind}-{case[0]}")
        for kind, cases in CASES.items()
        for case in cases
    ],
)
def test_every_listed_baseline_gets_its_rows_under_its_title(solved, kind, problem, overrides, names, labels):
    _, ctx = prepare(problem, overrides=[*overrides, ("baselines", names)])
    assert [b.name for b in ctx.baselines] == names
    result = solved(problem, [*overrides, ("baselines", names)])
    methods = [row.method for row in result.comparison]
    for baseline in ctx.baselines:
        for label in labels(baseline.title):
            assert methods.count(label) == 1, f"{baseline.name}: {label!r} in {methods}"
    rows_of = {label for b in ctx.baselines for label in labels(b.title)}
    assert len(rows_of) == sum(len(labels(b.title)) for b in ctx.baselines)  # no two names share a row


def test_calibrate_runs_no_baseline_and_refuses_a_preset_naming_the_entry(tmp_path, capsys):
    overrides = ["--set", "baselines=[lm]"]
    assert main(["solve", "trunk-calibrate", *overrides, "--out", str(tmp_path)]) == EXIT_BAD_INPUT
    message = capsys.readouterr().err
    assert "baselines.0" in message and "runs no solver presets" in message


def test_a_preset_of_a_family_the_kind_does_not_run_is_refused_when_validated():
    with pytest.raises(SpecError) as err:
        prepare("track-nominal", overrides=[("baselines", ["pseudo_inverse", "lm"])])
    assert err.value.field == "baselines.1" and "presets of qp" in str(err.value)


def test_a_kind_declaring_baselines_by_name_alone_is_refused_when_registered():
    from optikin.problems import Baseline, ProblemKind, register_kind

    def kind(baselines: Any) -> ProblemKind:
        return ProblemKind("plugin-kind", "", print, (), None, "", baselines=baselines)

    with pytest.raises(TypeError, match="'plugin-kind': baselines must map names to Baseline"):
        register_kind(kind(("mine",)))
    with pytest.raises(ValueError, match="declares baseline 'mine' under the name 'yours'"):
        register_kind(kind({"yours": Baseline("mine", "mine")}))
    assert "plugin-kind" not in PROBLEM_KINDS


def test_a_baseline_listed_twice_is_refused_naming_the_second():
    with pytest.raises(SpecError) as err:
        prepare("track-nominal", overrides=[("baselines", ["mrac", "pseudo_inverse", "mrac"])])
    assert err.value.field == "baselines.2" and "baselines.0" in str(err.value)


def test_a_qp_preset_and_the_pseudo_inverse_of_a_tracking_problem_are_two_different_rows():
    """The QP by OSQP stays inside the limits and tracks as the QP by DAQP does (same QP, another solver, to
    OSQP's tolerance); the pseudo-inverse leaves the limits on this path."""
    overrides = [*SHORT_PATH, ("baselines", ["qp-osqp", "pseudo_inverse"])]
    result, _ = solve("track-nominal", figures=False, overrides=overrides)
    rows = {row.method: row.metrics for row in result.comparison}
    assert list(rows)[1:] == ["qp-osqp", "pseudo-inverse"]
    qp, osqp, pinv = rows.values()
    assert osqp["outside limits"] == 0 and pinv["outside limits"] > 0
    assert osqp["rms [mm]"] == pytest.approx(qp["rms [mm]"], rel=0.02)
    assert abs(pinv["rms [mm]"] - osqp["rms [mm]"]) > 1e-3
    assert not np.array_equal(result.arrays["q_qp-osqp"], result.arrays["q_pseudo_inverse"])


def box(arm: ConstantCurvatureArm, q: np.ndarray, dt: float, margin: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """The QP's box written out (optikin.control.limits module docstring), periodic variables by rate only."""
    rate = rate_limit_vector(arm)
    lower, upper = arm.lower + margin, arm.upper - margin
    lower[arm.periodic], upper[arm.periodic] = -np.inf, np.inf
    return np.clip((lower - q) / dt, -rate, rate), np.clip((upper - q) / dt, -rate, rate)


def test_a_saturated_controllers_command_is_its_own_clipped_into_the_qps_box(cc_arm):
    from optikin.baselines.mrac import MRACController
    from optikin.baselines.pseudo_inverse import DampedLeastSquaresController, PseudoInverseController

    dt, rng = 0.01, np.random.default_rng(4)
    for make in (
        lambda: PseudoInverseController(cc_arm, dt, "pose", 10.0),
        lambda: DampedLeastSquaresController(cc_arm, dt, "pose", 10.0),
        lambda: MRACController(cc_arm, dt, "pose", 10.0),
    ):
        free, saturated = make(), make()
        saturated.saturate_at(RateBounds(cc_arm, dt))
        assert saturated.name == f"{free.name} (saturated)"
        clipped = 0
        for _ in range(5):
            q = cc_arm.sample_configurations(1, rng)[0]
            q[0] = cc_arm.upper[0] - 1e-4  # near the first length limit: the command is clipped there
            x = np.asarray(cc_arm.fk_dq(q)).ravel()
            x_ref = np.asarray(cc_arm.fk_dq(cc_arm.sample_configurations(1, rng)[0])).ravel()
            for controller in (free, saturated):
                controller.reset(q, x)
            own = free.command(q, x, x_ref, np.zeros(8)).copy()
            expected = np.clip(own, *box(cc_arm, q, dt))
            np.testing.assert_allclose(saturated.command(q, x, x_ref, np.zeros(8)), expected, rtol=0, atol=1e-12)
            clipped += not np.allclose(expected, own)
        assert clipped > 0


def test_saturated_baselines_stay_inside_the_limits_the_pseudo_inverse_leaves(solved):
    """On ``track-nominal`` the pseudo-inverse leaves the limits; the saturated baselines do not: their
    configurations and commanded rates lie inside the arm's limits on every step."""
    result = solved("track-nominal", [*SHORT_PATH, ("baselines", TRACKING)])
    rows = {row.method: row.metrics for row in result.comparison}
    assert rows["pseudo-inverse"]["outside limits"] > 0
    arm = ConstantCurvatureArm()
    rate, bounded = rate_limit_vector(arm), ~arm.periodic
    for name in (name for name in TRACKING if name.endswith("_saturated")):
        q, qdot = result.arrays[f"q_{name}"][:, bounded], result.arrays[f"qdot_{name}"]
        assert np.all(q >= arm.lower[bounded] - 1e-12) and np.all(q <= arm.upper[bounded] + 1e-12), name
        assert np.all(np.abs(qdot) <= rate * (1 + 1e-12)), name
    saturated = [row for row in result.comparison if row.method.endswith("(saturated)")]
    assert len(saturated) == 4 and all(row.metrics["outside limits"] == 0 for row in saturated)
