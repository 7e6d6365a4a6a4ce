"""The ``tracking`` problem kind end to end: shipped scenarios run (shortened by ``overrides``), QP presets solve,
bad input is named."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from optikin.errors import SpecError
from optikin.problems.tracking.figures import figures, traces
from optikin.results import read_result, redraw
from optikin.runner import solve
from optikin.spec import available, load_problem, project_root

SCENARIOS = sorted(name for name in available("problems") if name.startswith("track-"))


def short(name: str, baselines: bool = False, **changes: Any) -> list[tuple[str, Any]]:
    """``overrides`` running shipped scenario ``name`` at 100 Hz with short segments (and no baselines unless
    asked), then ``changes`` (dotted field -> value)."""
    spec, _ = load_problem(name)
    if spec.data.source == "dmp":
        params = {"rate": 100, "demonstration_samples": 300, "basis": 20}
    elif spec.data.source == "kinect-dmp":
        params = {"rate": 100, "demonstration_samples": 60, "basis": 10, "hold": 0.5}
    else:
        params = {"rate": 100, "segment_time": 0.6, "hold": 0.6}
    overrides: list[tuple[str, Any]] = [(f"data.params.{key}", value) for key, value in params.items()]
    if not baselines:
        overrides.append(("baselines", []))
    if "disturbance_window" in spec.options.get("plant", {}):
        overrides.append(("options.plant.disturbance_window", [0.3, 0.6]))
    return overrides + list(changes.items())


def test_the_shipped_scenarios_cover_the_issue():
    assert {
        "track-nominal",
        "track-into-limits",
        "track-start-outside",
        "track-model-mismatch",
        "track-disturbance",
        "track-sensor-noise",
        "track-position",
        "track-dmp",
        "track-nominal-cosserat",
        "track-payload-cosserat",
        "track-kinect-dmp",
    } <= set(SCENARIOS)


def test_dmp_reference_starts_at_the_demonstration_and_is_tracked_within_limits():
    """The reference is a DMP roll-out of the (smoothed) IMU demonstration: it starts and ends at its poses."""
    from optikin.algebra import dq_rotation, dq_translation, quat_angle, quat_conjugate, quat_multiply
    from optikin.data.demonstrations import imu_interface_recording

    result, _ = solve("track-dmp", figures=False, overrides=short("track-dmp", baselines=True))
    recording = imu_interface_recording(samples=300, seed=load_problem("track-dmp")[0].data.seed)
    demo = recording.demonstration.dual_quaternion
    reference = result.arrays["reference"]
    # The smoother (2.5 Hz) moves the end samples of this short 3 s demonstration by a few mm / degrees.
    for ref, pose, (metres, radians) in ((reference[0], demo[0], (5e-3, 0.05)), (reference[-1], demo[-1], (5e-3, 0.1))):
        assert np.linalg.norm(dq_translation(ref) - dq_translation(pose)) < metres
        assert quat_angle(quat_multiply(quat_conjugate(dq_rotation(pose)), dq_rotation(ref))) < radians
    rows = {row.method: row.metrics for row in result.comparison}
    assert rows["qp (daqp-active-set)"]["outside limits"] == 0
    assert (
        rows["qp (daqp-active-set)"]["rms [mm]"] < 10.0
    )  # 100 Hz on a 3 s demonstration; the shipped 500 Hz run: ~1 mm


def test_kinect_chain_reference_is_the_dmp_of_the_filtered_wrist_and_the_arm_starts_on_it():
    """Seed 000 Figs. 26-27: Kinect wrist -> moving average (eq. 31) -> DMP -> tip-position reference."""
    from optikin.arms.constant_curvature import ConstantCurvatureArm
    from optikin.data.demonstrations import kinect_recording

    result, _ = solve("track-kinect-dmp", figures=False, overrides=short("track-kinect-dmp", baselines=True))
    spec = load_problem("track-kinect-dmp")[0]
    recording = kinect_recording(
        samples=60, seed=spec.data.seed, cube_edge=0.10, workspace_centre=(0.18, 0.0, 0.26), window=5
    )
    reference = result.arrays["reference"]
    assert reference.shape[1] == 3
    # a DMP starts at the demonstration's first sample and ends near its goal
    np.testing.assert_allclose(reference[0], recording.filtered_position[0], atol=1e-9)
    assert np.linalg.norm(reference[-1] - recording.filtered_position[-1]) < 5e-3
    # the filtered wrist, not the raw one: the moving average removes most of the 8 mm jitter
    raw, filtered = (np.abs(np.diff(x, 2, axis=0)).mean() for x in (recording.position, recording.filtered_position))
    assert filtered < 0.3 * raw
    tip = ConstantCurvatureArm().evaluate("fk_position", result.arrays["q_qp"][:1])[0]
    np.testing.assert_allclose(tip, reference[0], atol=1e-6)
    assert [row.method for row in result.comparison][:3] == ["qp (daqp-active-set)", "mrac", "mrac (seed gains)"]
    assert result.metrics["steps the controller kept or took outside"] == 0


def test_a_kinect_cube_outside_the_workspace_is_named():
    far = short("track-kinect-dmp", **{"data.params.workspace_centre": [0.0, 0.0, 0.6]})
    with pytest.raises(SpecError) as error:
        solve("track-kinect-dmp", overrides=far)
    assert error.value.field == "data.params.workspace_centre"


def test_mrac_starts_from_the_task_gain_and_mrac_seed_from_the_seeds_optimised_gains():
    """Seed 000 section VII prints K = diag(7.45, 3.43, 3.70, 3.02, 9.62, 5.06, 4.69, 8.15) for the pose task."""
    result, _ = solve("track-nominal", figures=False, overrides=short("track-nominal", baselines=True))
    first = {name: result.arrays[f"gains_{name}"][0] for name in ("mrac", "mrac_seed")}
    np.testing.assert_allclose(first["mrac"], 10.0, rtol=1e-3)  # options.gain, after one adaptation step
    np.testing.assert_allclose(first["mrac_seed"], [7.45, 3.43, 3.70, 3.02, 9.62, 5.06, 4.69, 8.15], rtol=1e-3)
    methods = [row.method for row in result.comparison]
    unlimited = ["mrac", "mrac (seed gains)", "pseudo-inverse", "damped least squares"]
    saturated = ["mrac (saturated)", "pseudo-inverse (saturated)", "damped least squares (saturated)"]
    assert methods == ["qp (daqp-active-set)", *unlimited, *saturated]


def test_every_method_settles_after_the_disturbance_and_the_settling_times_are_reported():
    overrides = short("track-disturbance", baselines=True, **{"data.params.hold": 2.5})
    result, _ = solve("track-disturbance", figures=False, overrides=overrides)
    settle = {row.method: row.metrics["settle [s]"] for row in result.comparison}
    assert all(value is not None and 0 < value < 2.5 for value in settle.values()), settle
    assert settle["mrac (seed gains)"] > settle["mrac"]  # the seed's K is below 10 on most rows
    brief = short("track-disturbance", baselines=True, **{"data.params.hold": 0.7})
    notes = solve("track-disturbance", figures=False, overrides=brief)[0].notes
    assert any("not settled within the tolerance by the end of the run" in note for note in notes)


@pytest.mark.parametrize("name", SCENARIOS)
def test_every_scenario_runs_and_the_qp_never_takes_the_arm_outside_a_limit(tmp_path, name):
    result, written = solve(name, out=tmp_path / "out", figures=False, overrides=short(name))
    assert (written / "result.json").is_file() and (written / "arrays.npz").is_file()
    assert result.status_counts() == {"ok": result.samples}  # no QP failure on any step
    q = result.arrays["q_qp"]
    assert np.all(np.isfinite(q)) and len(q) == len(result.arrays["t"])
    if name != "track-sensor-noise":  # with noise the limits hold on the measured configuration only
        assert result.metrics["steps the controller kept or took outside"] == 0
    if load_problem(name)[0].kind == "tracking":
        # the shipped step (qp-active-set) is exact: its rates lie in the box, nothing for the projection to remove
        # (OSQP at eps 1e-7 returns rates up to a few 1e-7 outside, which the projection takes off)
        assert result.metrics["max bound slip removed"] < 1e-9


def test_nominal_scenario_compares_the_qp_with_every_baseline_and_draws_its_figures(tmp_path):
    overrides = short("track-nominal", baselines=True, **{"data.params.hold": 2.0})
    result, written = solve("track-nominal", out=tmp_path / "out", overrides=overrides)
    assert [row.role for row in result.comparison] == ["solver"] + ["baseline"] * 7
    saturated = [row for row in result.comparison if row.method.endswith("(saturated)")]
    assert len(saturated) == 3 and all(row.metrics["outside limits"] == 0 for row in saturated)
    assert all(row.metrics["converged"] for row in result.comparison if row not in saturated)
    for figure in ("tracking", "errors", "limits", "lyapunov", "step_times"):
        assert (written / f"{figure}.png").stat().st_size > 10_000
    assert "gains_mrac" in result.arrays and result.arrays["gains_mrac"].shape[1] == 8


@pytest.mark.parametrize("preset", ["qp-osqp", "qp-daqp", "qp-cvxpy"])
def test_other_qp_presets_give_the_same_run(preset):
    overrides = short("track-into-limits")
    reference, _ = solve("track-into-limits", overrides=overrides)
    assert reference.comparison[0].method == "qp (daqp-active-set)"  # the shipped preset: qp-active-set
    other, _ = solve("track-into-limits", solver=preset, overrides=overrides)
    np.testing.assert_allclose(other.arrays["q_qp"], reference.arrays["q_qp"], atol=1e-5)


@pytest.mark.parametrize(
    "key,value,field",
    [
        ("data.params.rate", 5000, "data.params.rate"),
        ("data.params.waypoints", [[0.18, 0.1, 0.0]], "data.params.waypoints"),
        ("data.params.speed", 1.0, "data.params.speed"),
        ("options.fallback", "pray", "options.fallback"),
        ("options.plant.wind", 3.0, "options.plant.wind"),
        ("options.plant.length_scale", [1.05, 1.05, 1.05], "options.plant.length_scale"),
        ("options.plant.configuration_noise", [0.1, 0.2], "options.plant.configuration_noise"),
        ("options.mrac.gamma", 3.0, "options.mrac.gamma"),
        ("options.start", [0.18, 0.1], "options.start"),
        ("data.samples", 10, "data.samples"),
    ],
)
def test_bad_tracking_input_names_the_field(key, value, field):
    with pytest.raises(SpecError) as error:
        solve("track-nominal", overrides=short("track-nominal", **{key: value}))
    assert field in str(error.value)


def test_a_qp_preset_with_an_unknown_solver_is_named(tmp_path):
    preset = tmp_path / "qp-nothing.yaml"
    preset.write_text("name: qp-nothing\nbackend: qp_qpsolvers\noptions: {solver: nothing}\n")
    with pytest.raises(SpecError, match="qp-nothing.yaml: options.solver: .*'nothing'") as error:
        solve("track-nominal", solver=str(preset), overrides=short("track-nominal"))
    assert error.value.field == "options.solver"


def test_an_evaluation_preset_cannot_solve_a_tracking_problem():
    with pytest.raises(SpecError, match="cannot solve kind 'tracking'"):
        solve("track-nominal", solver=str(project_root() / "solvers/casadi-map.yaml"), overrides=short("track-nominal"))


FIGURES = {"tracking", "errors", "limits", "lyapunov", "step_times"}


def test_the_figures_are_drawn_again_from_the_written_arrays_and_summary(tmp_path):
    result, written = solve("track-position", out=tmp_path / "out", overrides=short("track-position", baselines=True))
    assert {path.stem for path in written.glob("*.png")} == FIGURES
    summary, arrays = read_result(written)
    drawers = figures(arrays, summary)
    assert set(drawers) == FIGURES
    again = tmp_path / "again"
    again.mkdir()
    assert {path.stem for path in redraw(again, figures, summary, arrays)} == FIGURES
    assert all((again / f"{name}.png").stat().st_size > 10_000 for name in FIGURES)
    # the curves are labelled and ordered as the comparison rows, and are the runs' own
    assert list(traces(arrays, summary)) == [row.method for row in result.comparison]
    qp_trace = traces(arrays, summary)[result.comparison[0].method]
    np.testing.assert_allclose(qp_trace.position_error, result.residuals, rtol=1e-12, atol=1e-15)


def test_a_figure_whose_arrays_are_missing_is_left_out(tmp_path):
    _, written = solve("track-nominal", out=tmp_path / "out", figures=False, overrides=short("track-nominal"))
    summary, arrays = read_result(written)
    kept = {k: v for k, v in arrays.items() if not k.startswith(("V_", "step_time_"))}
    assert set(figures(kept, summary)) == FIGURES - {"lyapunov", "step_times"}
    assert figures({}, summary) == {}


# --------------------------------------------------------------------------- typos in every option section


def preset(tmp_path: Path, backend: str, options: dict) -> Path:
    name = f"qp-typo-{backend.replace('_', '-')}"
    out = tmp_path / f"{name}.yaml"
    out.write_text(yaml.safe_dump({"name": name, "backend": backend, "options": options}))
    return out


@pytest.mark.parametrize(
    "problem,key",
    [
        ("track-nominal", "options.gian"),
        ("track-nominal", "options.plant.lenght_scale"),
        ("track-nominal", "options.mrac.gain_limt"),
        ("track-nominal", "options.tolerance.position"),
        ("track-nominal", "data.params.segment_tme"),
        ("track-dmp", "data.params.basis_functions"),
    ],
)
def test_a_typo_in_an_option_section_is_an_unknown_field(problem, key):
    with pytest.raises(SpecError) as error:
        solve(problem, overrides=short(problem, **{key: 1.0}))
    assert error.value.field == key
    assert "unknown field" in str(error.value)


@pytest.mark.parametrize(
    "backend,options,field,words",
    [
        ("qp_osqp", {"eps_ab": 1e-7}, "options.eps_ab", "unknown field"),
        ("qp_osqp", {"eps_abs": -1}, "options.eps_abs", "greater than 0"),
        ("qp_osqp", {"max_iter": "many"}, "options.max_iter", "integer"),
        ("qp_qpsolvers", {"solver": "daqp", "setings": {}}, "options.setings", "unknown field"),
        ("qp_cvxpy", {"solvr": "CLARABEL"}, "options.solvr", "unknown field"),
        ("qp_cvxpy", {"solver": "GUROBI9"}, "options.solver", "GUROBI9"),
        ("qp_cvxpy_rebuild", {"solver": "CLARABEL", "warm": True}, "options.warm", "unknown field"),
    ],
)
def test_a_bad_qp_preset_option_names_the_preset_and_the_field(tmp_path, backend, options, field, words):
    path = preset(tmp_path, backend, options)
    with pytest.raises(SpecError) as error:
        solve("track-nominal", solver=str(path), overrides=short("track-nominal"))
    assert error.value.path == str(path) and error.value.field == field
    assert words in str(error.value)
