"""The ``dmp`` problem kind end to end: every shipped ``problems/dmp-*.yaml`` on a reduced setting.

Each shipped file is copied with fewer samples, fewer basis functions and a
smaller tuning budget (same structure, same kind code), solved through the
command line, and its result checked for what the file sets out to show.
Bad options must name the field.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from optikin.cli import EXIT_BAD_INPUT, EXIT_OK, main
from optikin.errors import SpecError
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


def test_all_five_problem_files_ship():
    assert SHIPPED == ["dmp-goal-switch", "dmp-imu-dualquat", "dmp-kinect-position", "dmp-perturbation",
                       "dmp-rpy-gimbal"]


def test_imu_dual_quaternion_problem(tmp_path):
    summary = solved("dmp-imu-dualquat", tmp_path)
    table = rows(summary)
    seed, sound = table["dmp seed (cvxpy)"], table["dmp dual-quaternion (cvxpy)"]
    assert seed["vs true motion position max [mm]"] > 3 * sound["vs true motion position max [mm]"]
    assert sound["unit-norm error"] < 1e-12
    assert table["dmp seed (lstsq)"]["fit residual"] == pytest.approx(seed["fit residual"], rel=1e-6)
    tuned = table["tuning quaternion (ipopt)"]
    assert tuned["eq. 29 error"] <= tuned["eq. 29 error at start"]
    assert "tuning quaternion (genetic)" in table


def test_rpy_gimbal_problem(tmp_path):
    table = rows(solved("dmp-rpy-gimbal", tmp_path))
    rpy = table["dmp rpy (cvxpy)"]["reproduction orientation max [mrad]"]
    quaternion = table["dmp quaternion (cvxpy)"]["reproduction orientation max [mrad]"]
    assert rpy > 100.0 and quaternion < 1.0  # the per-angle DMP misrepresents the orientation at the lock


def test_goal_switch_problem(tmp_path):
    summary = solved("dmp-goal-switch", tmp_path)
    assert summary["status_counts"] == {"ok": summary["samples"]}  # every roll-out reached its last goal
    table = rows(summary)
    assert table["tuning quaternion (ipopt)"]["eq. 29 error"] <= table["tuning quaternion (ipopt)"][
        "eq. 29 error at start"]


def test_perturbation_problem(tmp_path):
    metrics = solved("dmp-perturbation", tmp_path)["metrics"]
    plain = metrics["quaternion: perturbation plain final orientation deviation [mrad]"]
    coupled = metrics["quaternion: perturbation coupled final orientation deviation [mrad]"]
    assert metrics["quaternion: perturbation plain peak orientation deviation [mrad]"] > 1.0
    assert coupled < 0.05 * plain
    # eq. (15): exp(-zeta) = 0.01 at tau; the seed's eq. (28) lags even without the push
    assert metrics["quaternion: perturbation coupled undisturbed phase at the end"] == pytest.approx(0.01, rel=1e-6)
    assert metrics["quaternion: perturbation coupled + phase stopping (seed eq. 28) undisturbed phase at the end"] > 0.3


def test_tracking_phase_stopping_against_the_demonstration_is_refused(tmp_path):
    path = reduced("dmp-perturbation", tmp_path, couplings={"stopped": {"alpha_s": 5.0, "alpha": 5.0}})
    with pytest.raises(SpecError, match=r"options\.couplings\.stopped\.alpha.*robot's pose"):
        solve(str(path))


def test_kinect_problem_through_the_command_line(tmp_path):
    path = reduced("dmp-kinect-position", tmp_path)
    assert main(["solve", str(path), "--out", str(tmp_path / "out")]) == EXIT_OK
    summary = json.loads((tmp_path / "out" / path.stem / "result.json").read_text())
    table = rows(summary)
    assert table["dmp position (cvxpy)"]["reproduction position max [mm]"] < 20.0
    assert table["dmp position (lwr)"]["fit residual"] >= table["dmp position (lstsq)"]["fit residual"]
    assert {"reproduction_error.png", "quaternion_reproduction.png"} <= set(summary["figures"])
    assert (tmp_path / "out" / path.stem / "reproduction_error.png").stat().st_size > 0


@pytest.mark.parametrize("options, field", [
    ({"variants": ["euler"]}, "options.variants.0"),
    ({"regression": {"method": "lstsq", "bound": 10.0}}, "options.regression.bound"),
    ({"goal_switches": [{"time": 1.0, "rotate": [0, 1]}]}, "options.goal_switches.0.rotate"),
    ({"tuning": {"gains": ["stiffness"]}}, "options.tuning.gains.0"),
    ({"tuning": {"screen": -1}}, "options.tuning.screen"),
    ({"smoothing": -2.5}, "options.smoothing"),
    ({"colour": "blue"}, "options.colour"),
])
def test_bad_options_name_the_field(tmp_path, options, field):
    path = reduced("dmp-kinect-position", tmp_path, **options)
    with pytest.raises(SpecError, match=field.replace(".", r"\.")):
        solve(str(path))
    assert main(["solve", str(path)]) == EXIT_BAD_INPUT
