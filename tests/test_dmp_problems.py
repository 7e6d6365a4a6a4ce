"""The ``dmp`` problem kind end to end: every shipped ``problems/dmp-*.yaml`` on a reduced setting.

Each shipped file is copied with fewer samples, fewer basis functions and a
smaller tuning budget (same structure, same kind code), solved through the
command line, and its result checked for what the file sets out to show.
Bad options and data parameters must name the field; the figures must redraw
from a written result.
"""

from __future__ import annotations

import inspect
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from optikin.cli import EXIT_BAD_INPUT, EXIT_OK, main
from optikin.data import demonstrations
from optikin.data.sources import DATA_SOURCES
from optikin.errors import SpecError
from optikin.problems.dmp import figures
from optikin.results import read_result, redraw
from optikin.runner import solve

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"
SHIPPED = sorted(p.stem for p in PROBLEMS.glob("dmp-*.yaml"))


def reduced(name: str, tmp_path: Path, **options) -> Path:
    spec = yaml.safe_load((PROBLEMS / f"{name}.yaml").read_text())
    spec["data"]["samples"] = min(spec["data"].get("samples", 300), 300)
    if spec["data"]["source"] == "imu":  # keep the 10 s of the seed's scenarios
        spec["data"]["params"]["rate"] = 30.0
    spec["options"]["n_basis"] = 20
    if "tuning" in spec["options"]:
        spec["options"]["tuning"] |= {"max_iterations": 8, "population": 6, "generations": 3}
    spec["options"] |= options
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def solved(name: str, tmp_path: Path, **options) -> dict:
    """The result summary of a reduced copy, solved without drawing figures (they are drawn in one test)."""
    result, _ = solve(str(reduced(name, tmp_path, **options)))
    return result.summary()


def rows(summary: dict) -> dict[str, dict]:
    return {row["method"]: row["metrics"] for row in summary["comparison"]}


def test_all_seven_problem_files_ship():
    assert SHIPPED == [
        "dmp-cosserat-imu",
        "dmp-goal-switch",
        "dmp-imu-dualquat",
        "dmp-kinect-position",
        "dmp-orientation-variants",
        "dmp-perturbation",
        "dmp-rpy-gimbal",
    ]


def test_orientation_variants_problem(tmp_path):
    """Ude's quaternion form amplifies the seed's output push near half a turn from the goal; Koutras-Doulgeri's
    form, linear in the gap, is moved by the push alone; every variant reaches the switched goal."""
    summary = solved("dmp-orientation-variants", tmp_path)
    assert summary["status_counts"] == {"ok": summary["samples"]}
    metrics = summary["metrics"]
    key = "{}: perturbation plain peak orientation deviation [mrad]"
    assert metrics[key.format("koutras-doulgeri")] == pytest.approx(1000.0, abs=1e-6)
    assert metrics[key.format("quaternion")] > 1.5 * metrics[key.format("koutras-doulgeri")]


def test_imu_dual_quaternion_problem(tmp_path):
    summary = solved("dmp-imu-dualquat", tmp_path)
    table = rows(summary)
    seed, sound = table["dmp seed (cvxpy)"], table["dmp dual-quaternion (cvxpy)"]
    assert seed["vs true motion position max [mm]"] > 3 * sound["vs true motion position max [mm]"]
    assert sound["unit-norm error"] < 1e-12
    assert table["dmp seed (lstsq)"]["fit residual"] == pytest.approx(seed["fit residual"], rel=1e-6)
    start = table["dmp seed-qd-start (cvxpy)"]
    for row in (seed, start):  # labelled structural, the error not below the bound that |Q_d| fixed implies
        assert row["limitation"].startswith("structural")
        assert row["reproduction position max [mm]"] >= row["structural bound position max [mm]"] - 0.05
        assert row["reproduction position rms [mm]"] >= row["structural bound position rms [mm]"] - 0.05
    assert "structural bound position max [mm]" not in sound and "limitation" not in sound
    assert start["reproduction position at t = 0 [mm]"] < 1.0 < seed["reproduction position at t = 0 [mm]"]
    for term in ("Q_r", "Q_d"):  # the seed's two quaternion DMPs (Figs. 5a, 5b), on one budget of evaluations
        ipopt, multistart = table[f"tuning {term} (ipopt)"], table[f"tuning {term} (multistart)"]
        genetic = table[f"tuning {term} (genetic)"]
        assert ipopt["eq. 29 error"] <= ipopt["eq. 29 error at start"]
        used = ipopt["objective evaluations"]
        assert used - 6 < genetic["objective evaluations"] <= used  # 6 new individuals a generation
        assert abs(multistart["objective evaluations"] - used) <= 0.1 * used + 4
        assert f"tuning {term} (genetic, seed 2021)" in table and f"tuning {term} (multistart, seed 2021)" in table
        assert "eq. 29 error" in table[f"tuning {term} (reference gains)"]


def test_rpy_gimbal_problem(tmp_path):
    table = rows(solved("dmp-rpy-gimbal", tmp_path))
    rpy = table["dmp rpy (cvxpy)"]["reproduction orientation max [mrad]"]
    quaternion = table["dmp quaternion (cvxpy)"]["reproduction orientation max [mrad]"]
    assert rpy > 100.0 and quaternion < 1.0  # the per-angle DMP misrepresents the orientation at the lock


def test_goal_switch_problem(tmp_path):
    summary = solved("dmp-goal-switch", tmp_path)
    assert summary["status_counts"] == {"ok": summary["samples"]}  # every roll-out reached its last goal
    table = rows(summary)
    assert (
        table["tuning quaternion (ipopt)"]["eq. 29 error"]
        <= table["tuning quaternion (ipopt)"]["eq. 29 error at start"]
    )


def test_perturbation_problem(tmp_path):
    metrics = solved("dmp-perturbation", tmp_path)["metrics"]
    plain = metrics["quaternion: perturbation plain final orientation deviation [mrad]"]
    coupled = metrics["quaternion: perturbation coupled final orientation deviation [mrad]"]
    assert metrics["quaternion: perturbation plain peak orientation deviation [mrad]"] > 1.0
    assert coupled < 0.05 * plain
    # eq. (15): exp(-zeta) = 0.01 at tau; the seed's eq. (28) lags even without the push
    assert metrics["quaternion: perturbation coupled undisturbed phase at the end"] == pytest.approx(0.01, rel=1e-6)
    assert metrics["quaternion: perturbation coupled + phase stopping (seed eq. 28) undisturbed phase at the end"] > 0.3


def test_perturbation_output_reading_against_the_force_reading(tmp_path):
    """Seed 000's "output step disturbance" of amplitude 1 moves the pose by the full 1 rad (the scale of
    Figs. 20-21); read as a force on eq. (17) (kind: force) the same amplitude moves it by under 10 mrad."""
    key = "quaternion: perturbation plain peak orientation deviation [mrad]"
    output = solved("dmp-perturbation", tmp_path)["metrics"][key]
    disturbance = {"kind": "force", "start": 5.0, "stop": 7.0, "amplitude": 1.0, "component": 0}
    force = solved("dmp-perturbation", tmp_path, disturbance=disturbance)["metrics"][key]
    assert output >= 1000.0 - 1e-6
    assert force < 10.0


def test_tracking_phase_stopping_against_the_demonstration_is_refused(tmp_path):
    path = reduced("dmp-perturbation", tmp_path, couplings={"stopped": {"alpha_s": 5.0, "alpha": 5.0}})
    with pytest.raises(SpecError, match=r"options\.couplings\.stopped\.alpha.*robot's pose") as info:
        solve(str(path))
    assert info.value.field == "options.couplings.stopped.alpha"


def test_kinect_problem_through_the_command_line(tmp_path):
    path = reduced("dmp-kinect-position", tmp_path)
    assert main(["solve", str(path), "--out", str(tmp_path / "out")]) == EXIT_OK
    summary = json.loads((tmp_path / "out" / path.stem / "result.json").read_text())
    table = rows(summary)
    assert table["dmp position (cvxpy)"]["reproduction position max [mm]"] < 20.0
    assert table["dmp position (lwr)"]["fit residual"] >= table["dmp position (lstsq)"]["fit residual"]
    assert {"reproduction_error.png", "quaternion_reproduction.png"} <= set(summary["figures"])
    assert (tmp_path / "out" / path.stem / "reproduction_error.png").stat().st_size > 0


@pytest.mark.parametrize(
    "options, field",
    [
        ({"variants": ["euler"]}, "options.variants.0"),
        ({"variants": []}, "options.variants"),
        ({"n_basis": 1}, "options.n_basis"),
        ({"regression": {"method": "lstsq", "bound": 10.0}}, "options.regression.bound"),
        ({"regression": {"method": "qr"}}, "options.regression.method"),
        ({"goal_switches": [{"time": 1.0, "rotate": [0, 1]}]}, "options.goal_switches.0.rotate"),
        ({"goal_switches": [{"rotate": [0, 0, 1]}]}, "options.goal_switches.0.time"),
        ({"goal_switches": [{"time": 100.0}]}, "options.goal_switches.0.time"),  # beyond 3 tau
        ({"disturbance": {"component": 3}}, "options.disturbance.component"),  # the position DMP has 3
        ({"couplings": {"c": {"phase_stopping": "sometimes"}}}, "options.couplings.c.phase_stopping"),
        ({"tuning": {"gains": ["stiffness"]}}, "options.tuning.gains.0"),
        ({"tuning": {"screen": -1}}, "options.tuning.screen"),
        ({"tuning": {"scenario": "goal"}}, "options.tuning.scenario"),  # without goal switches
        ({"gains": {"beta": 0.0}}, "options.gains.beta"),
        ({"smoothing": -2.5}, "options.smoothing"),
        ({"colour": "blue"}, "options.colour"),
    ],
)
def test_bad_options_name_the_field(tmp_path, options, field):
    path = reduced("dmp-kinect-position", tmp_path, **options)
    with pytest.raises(SpecError, match=field.replace(".", r"\.")) as info:
        solve(str(path))
    assert info.value.field == field
    assert main(["solve", str(path)]) == EXIT_BAD_INPUT


SECTIONS: dict[str, Any] = {  # a section of options -> a valid value of it, to put a typo in
    "gains": {},
    "regression": {},
    "goal_switches": [{"time": 1.0}],
    "disturbance": {},
    "couplings": {"coupled": {}},
    "tuning": {},
    "tolerance": {},
}


def typo_field(section: str) -> tuple[dict, str]:
    """Options with an unknown key in ``section`` and the dotted field it must be reported at."""
    value = SECTIONS[section]
    if section == "goal_switches":
        return {section: [{**value[0], "tyme": 1.0}]}, f"options.{section}.0.tyme"
    if section == "couplings":
        return {section: {"coupled": {"alpha_z": 1.0}}}, f"options.{section}.coupled.alpha_z"
    return {section: {**value, "colour": "blue"}}, f"options.{section}.colour"


@pytest.mark.parametrize("section", [None, *SECTIONS])
def test_a_typo_in_each_option_section_is_an_unknown_field(tmp_path, section):
    options, field = ({"colour": "blue"}, "options.colour") if section is None else typo_field(section)
    path = reduced("dmp-kinect-position", tmp_path, **options)
    with pytest.raises(SpecError, match="unknown field") as info:
        solve(str(path))
    assert info.value.field == field


def small_problem(tmp_path: Path, source: str, params: dict, samples: int = 60) -> Path:
    spec = {
        "name": f"small-{source}",
        "title": "a small dmp problem",
        "kind": "dmp",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": {"source": source, "seed": 3, "samples": samples, "params": params},
        "options": {"variants": ["quaternion"], "n_basis": 8},
    }
    path = tmp_path / f"small-{source}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def csv_params(tmp_path: Path) -> dict:
    demonstrations.write_csv(tmp_path / "demo.csv", demonstrations.smooth_pose_demonstration(samples=50, seed=2))
    return {"file": "demo.csv"}  # relative to the problem file


def source_params(source: str, tmp_path: Path) -> dict:
    return csv_params(tmp_path) if source == "csv" else {}


DEMONSTRATION_SOURCES = ("imu", "kinect", "smooth", "gimbal", "csv", "cosserat-imu")


def test_every_demonstration_source_is_registered():
    assert set(DATA_SOURCES["demonstrations"].names()) == set(DEMONSTRATION_SOURCES)


@pytest.mark.parametrize("source", DEMONSTRATION_SOURCES)
def test_a_typo_in_the_params_of_each_demonstration_source_is_an_unknown_field(tmp_path, source):
    path = small_problem(tmp_path, source, {**source_params(source, tmp_path), "nosie": 0.1})
    with pytest.raises(SpecError, match="unknown field") as info:
        solve(str(path))
    assert info.value.field == "data.params.nosie"


@pytest.mark.parametrize("source", DEMONSTRATION_SOURCES)
def test_each_demonstration_source_solves(tmp_path, source):
    result, _ = solve(str(small_problem(tmp_path, source, source_params(source, tmp_path))))
    assert result.succeeded
    assert result.metrics["demonstration samples"] == (50 if source == "csv" else 60)


def test_csv_source_resamples_and_needs_its_file(tmp_path):
    params = {**csv_params(tmp_path), "samples": 40}
    result, _ = solve(str(small_problem(tmp_path, "csv", params)))
    assert result.metrics["demonstration samples"] == 40
    with pytest.raises(SpecError, match="required") as info:
        solve(str(small_problem(tmp_path, "csv", {})))
    assert info.value.field == "data.params.file"


@pytest.mark.parametrize(
    "model, function",
    [
        (demonstrations.ImuParams, demonstrations.imu_interface_recording),
        (demonstrations.KinectParams, demonstrations.kinect_recording),
        (demonstrations.SmoothParams, demonstrations.smooth_pose_demonstration),
        (demonstrations.GimbalParams, demonstrations.gimbal_demonstration),
    ],
)
def test_source_params_default_to_the_functions_defaults(model, function):
    defaults = {k: p.default for k, p in inspect.signature(function).parameters.items() if k not in ("samples", "seed")}
    given = model().model_dump()
    if model is demonstrations.ImuParams:
        assert given.pop("section_lengths") is None  # the arm's sections
        defaults.pop("section_lengths")
    assert given == defaults


def test_figures_redraw_from_the_written_result(tmp_path):
    goals = [{"time": 4.0, "rotate": [0.3, -0.3, 0.2], "translate": [0.03, -0.02, 0.02]}]
    path = reduced("dmp-perturbation", tmp_path, goal_switches=goals)
    _, written = solve(str(path), out=tmp_path / "out")
    assert written is not None
    summary, arrays = read_result(written)
    drawn = set(figures.figures(arrays, summary))
    assert drawn == {Path(f).stem for f in summary["figures"]}
    assert {
        "reproduction_error",
        "quaternion_reproduction",
        "quaternion_goal_switch",
        "quaternion_perturbation_coupled",
        "dual-quaternion_perturbation_coupled",
    } <= drawn
    redrawn = redraw(written, figures.figures, summary, arrays)
    assert {p.stem for p in redrawn} == drawn and all(p.stat().st_size > 0 for p in redrawn)
    without = {k: v for k, v in arrays.items() if not k.endswith("__goal_switch")}
    assert not any(name.endswith("goal_switch") for name in figures.figures(without, summary))
