"""What a calibration's postures can determine: not_identifiable on degenerate recordings (identical postures,
collinear markers, too few measurements, a free base without excitation, a length on its bound), ok with
estimates within a few standard deviations of the generator's truth on a well-excited recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.calibration.calibrate import calibrate
from optikin.calibration.identifiability import MAX_STD
from optikin.calibration.synthetic import rpy_matrix, synthetic_recording
from optikin.runner import solve

TRUE_LENGTHS = np.array([0.1058, 0.0949, 0.1144])
BASE = np.array([0.03, -0.02, 0.65])
ROTATION = rpy_matrix(np.radians(183.0), np.radians(-2.0), np.radians(20.0))
NAMES = ["disk1", "disk2", "disk3"]


def measured(samples: int, seed: int = 0, **kw) -> np.ndarray:
    rec = synthetic_recording(
        ConstantCurvatureArm((0.1, 0.1, 0.1)),
        samples,
        np.random.default_rng(seed),
        section_lengths=TRUE_LENGTHS,
        base_position=BASE,
        base_rotation=ROTATION,
        theta_max=kw.pop("theta_max", 2.0),
        **kw,
    )
    return rec.marker_array(NAMES)


def test_identical_postures_are_not_identifiable_even_noise_free():
    same = np.repeat(measured(1, noise=0.0), 40, axis=0)
    cal = calibrate(same, [0.1, 0.1, 0.1], [1, 2, 3], NAMES)
    report = cal.identifiability
    assert np.nanmax(cal.fit.errors) < 1e-9  # the fit is exact: the residual cannot tell
    assert cal.verdict == "not_identifiable"
    assert any("not determined" in r for r in report.reasons)
    # the reported standard deviations are never zero on an undetermined geometry
    assert np.all(report.scaled_std > MAX_STD)
    assert set(report.weak_parameters) & {"L1", "base_x", "base_y", "base_z"}
    assert any("hold the base" in r for r in report.summary()["remedies"])


def test_collinear_markers_leave_the_base_along_its_axis_undetermined():
    straight = measured(60, noise=0.0, theta_max=1e-9)
    cal = calibrate(straight, [0.1, 0.1, 0.1], [1, 2, 3], NAMES, loss="linear")
    assert cal.verdict == "not_identifiable"
    # the base slides along its axis while the first section shortens: L1 and the base position together
    combo = next(c for c in cal.identifiability.weak if "L1" in c.weights)
    assert not np.isfinite(combo.std)
    along = ROTATION[:, 2]
    position = np.array([combo.weights.get(f"base_{a}", 0.0) for a in "xyz"])
    assert abs(abs(position @ along) - abs(combo.weights["L1"])) < 0.1


def test_fewer_measurements_than_unknowns():
    cal = calibrate(measured(2), [0.1, 0.1, 0.1], [1, 2, 3], NAMES)
    report = cal.identifiability
    assert report.measurements == 18 and report.unknowns == 2 * 6 + 8
    assert cal.verdict == "not_identifiable"
    assert "18 measured coordinates for 20 unknowns" in report.reasons[0]


def test_free_base_without_enough_excitation():
    cal = calibrate(measured(100, theta_max=0.05), [0.1, 0.1, 0.1], [1, 2, 3], NAMES)
    report = cal.identifiability
    assert cal.verdict == "not_identifiable"
    assert {"L1", "base_z"} <= set(report.weak_parameters)
    # the same recording with the base held in its mount plane along its true axis determines the lengths
    held = calibrate(
        measured(100, theta_max=0.05),
        [0.1, 0.1, 0.1],
        [1, 2, 3],
        NAMES,
        plane=(2, float(BASE[2])),
        direction=ROTATION[:, 2],
    )
    assert "L1" not in held.identifiability.weak_parameters
    assert abs(held.lengths[0] - TRUE_LENGTHS[0]) < 1e-3


def test_a_length_on_its_bound_is_not_an_estimate():
    # nominal 90 mm sections bounded to +-10 %: the true 114.4 mm third section lies outside
    cal = calibrate(measured(150), [0.09, 0.09, 0.09], [1, 2, 3], NAMES, length_bounds=(0.9, 1.1))
    assert cal.lengths[2] == 0.099
    assert cal.verdict == "not_identifiable"
    assert ("L3", "upper", 0.099) in [(n, s, round(v, 6)) for n, s, v in cal.identifiability.at_bounds]


def test_well_excited_recording_is_ok_and_within_three_std_of_the_truth():
    cal = calibrate(measured(300, seed=4), [0.1, 0.1, 0.1], [1, 2, 3], NAMES, length_bounds=(0.5, 2.0))
    report = cal.identifiability
    assert cal.verdict == "ok" and not report.reasons
    assert np.all(report.scaled_std < MAX_STD)
    lay = cal.layout
    std = report.std[: lay.n_sections]
    assert np.all(np.abs(cal.lengths - TRUE_LENGTHS) < 3 * std)
    position_std = report.std[lay.n_sections : lay.n_sections + 3]
    assert np.all(np.abs(cal.base_position - BASE) < 3 * position_std)
    # the start's report is computed too (from the chords), the solution's singular values are all positive
    assert cal.identifiability_start is not None and np.all(report.singular_values > 0)


def test_the_kind_ends_not_identifiable_with_rc_1_semantics(tmp_path: Path):
    source = Path(__file__).resolve().parent.parent / "problems" / "trunk-calibrate.yaml"
    data = yaml.safe_load(source.read_text())
    data["data"]["samples"] = 40
    data["data"]["params"]["theta_max"] = 0.03
    data["data"]["params"]["corrupted_fraction"] = 0.0
    data["options"]["base"] = {"starts": "data"}
    data["options"]["holdout"] = {"method": "kfold", "folds": 2}
    data["name"] = "flat"
    problem = tmp_path / "flat.yaml"
    problem.write_text(yaml.safe_dump(data))
    result, _ = solve(str(problem), out=tmp_path / "out", figures=False)
    assert not result.succeeded and result.criteria["identifiable"] is False
    assert result.metrics["verdict"] == "not_identifiable"
    assert "ok" not in result.status
    assert any(n.startswith("not identifiable") and "L1" in n for n in result.notes)
    assert any("options.base.plane" in n for n in result.notes)


def test_the_identifiability_figure_marks_the_weak_combinations(tmp_path: Path):
    from optikin.problems.calibrate.figures import figures

    summary = {
        "problem": "p",
        "metrics": {
            "identifiability": {
                "verdict": "not_identifiable",
                "noise level per coordinate [mm]": 0.3,
                "std threshold [mm or deg]": 1.0,
            }
        },
    }
    drawers = figures({"singular_values": np.array([20.0, 5.0, 0.2])}, summary)
    drawers["identifiability"](tmp_path / "identifiability.png")
    assert (tmp_path / "identifiability.png").stat().st_size > 1000
    assert "identifiability" not in figures({"singular_values": np.zeros(0)}, summary)


def test_the_base_axis_is_given_once(tmp_path: Path):
    from optikin.errors import SpecError

    source = Path(__file__).resolve().parent.parent / "problems" / "trunk-calibrate.yaml"
    data = yaml.safe_load(source.read_text())
    data["name"] = "twice"
    data["data"]["samples"] = 20
    data["options"]["base"] = {"direction": [0.0, 0.0, -1.0], "orientation": [0.0, 1.0, 0.0, 0.0]}
    problem = tmp_path / "twice.yaml"
    problem.write_text(yaml.safe_dump(data))
    with pytest.raises(SpecError, match="options.base.direction"):
        solve(str(problem), figures=False)
