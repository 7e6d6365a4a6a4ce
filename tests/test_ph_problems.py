"""The PH problem kinds (ph_shape, ph_ik, ph_chain), their ``ph`` backends and problem files.

Independent references: brute-force closest points on densely sampled curves; the
closed-form length of circular arcs; IPOPT against Newton and the grid (the NLP is
never worse than the grid); the numpy tube lengths against the compiled-Function
path; a CSV round trip through the same problem file.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms.cbha import CBHAArm
from optikin.curves import EnergySettings, PHQuintic, ShapeData, arc_length_estimate, ph_quintic_hermite
from optikin.curves.tubes import TubeLayout, tube_lengths
from optikin.data.markers import write_marker_csv
from optikin.errors import InputDataError, SpecError
from optikin.problems.ph_shared import distances_to_curves, problem_variant, recording_of
from optikin.problems.ph_ik import tube_length_function
from optikin.runner import solve
from optikin.solvers import load_preset, preset_of
from optikin.solvers.ph_backends import shared_model
from optikin.spec import SolverSpec

PRESETS = ("ph-newton", "ph-newton-compiled", "ph-ipopt", "ph-ipopt-cold", "ph-grid")


def run_variant(tmp_path, name, **changes):
    result, _ = solve(str(problem_variant(name, tmp_path, **changes)))
    return result


# -- pieces ----------------------------------------------------------------------------


def test_presets_load_and_bad_options_name_the_field():
    for name in PRESETS:
        preset = load_preset(name)
        assert preset.backend.family == "ph"
        preset.build()
    for backend, options, field, message in (
        ("ph_newton", {"tolerance": 1e-8}, "options.tolerance", "unknown field"),
        ("ph_grid", {"n": 1.5}, "options.n", "integer"),
        ("ph_grid", {"n": 1}, "options.n", "greater than or equal to 2"),
        ("ph_newton", {"compile": "yes"}, "options.compile", "boolean"),
    ):
        with pytest.raises(SpecError, match=message) as err:
            preset_of(SolverSpec(name="x", backend=backend, options=options))
        assert err.value.field == field


@pytest.mark.parametrize("theta, azimuth", [(1e-6, 0.0), (0.7, 1.0), (2.5, -2.0)])
def test_arc_length_estimate_is_exact_on_circular_arcs(theta, azimuth):
    """An arc of length 0.2 through theta, turned into a tilted plane: the estimate returns 0.2."""
    length = 0.2
    R = length / theta
    u = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    z = np.array([0.0, 0.0, 1.0])
    tilt = np.array([[1, 0, 0], [0, np.cos(0.4), -np.sin(0.4)], [0, np.sin(0.4), np.cos(0.4)]])
    p1 = tilt @ (R * (1 - np.cos(theta)) * u + R * np.sin(theta) * z)
    t1 = tilt @ (np.sin(theta) * u + np.cos(theta) * z)
    estimate = arc_length_estimate(np.zeros(3), tilt @ z, p1, t1)
    assert estimate == pytest.approx(length, rel=1e-9)


def test_distances_to_curves_match_brute_force():
    rng = np.random.default_rng(2)
    curves = [
        ph_quintic_hermite(
            rng.normal(size=3), rng.normal(size=3), rng.normal(size=3), rng.normal(size=3), *rng.uniform(-1, 1, 2)
        )
        for _ in range(3)
    ]
    batch = PHQuintic(*(np.stack([getattr(c, k) for c in curves]) for k in ("p0", "A0", "A1", "A2")))
    points = batch.point(rng.uniform(0, 1, 4))  # (curve, 4, 3)
    points = points[:, :, None, :] + 0.05 * rng.normal(size=(3, 4, 5, 3))  # near the curves and off them
    points = points.reshape(3, 20, 3)
    dense = batch.point(np.linspace(0, 1, 200001))
    brute = np.min(np.linalg.norm(points[:, :, None, :] - dense[:, None, :, :], axis=-1), axis=-1)
    np.testing.assert_allclose(distances_to_curves(batch, points), brute, atol=1e-9)


def test_tube_length_function_equals_the_numpy_tubes():
    arm = CBHAArm()
    rec = recording_of("cbha-ph-ik", 3)
    layout = TubeLayout.cbha(arm.geometry)
    for free in (False, True):
        model = shared_model(EnergySettings(), free)
        f = tube_length_function(model, layout)
        for i in range(3):
            data = ShapeData.checked(
                rec.base_position[i],
                rec.base_direction[i],
                rec.tip_position[i],
                rec.tip_direction[i],
                length=rec.truth.backbone_length[i],
            )
            sol = model.solve_nlp(data)
            expected = tube_lengths(model.curve(sol, data), rec.base_normal[i], layout)
            np.testing.assert_allclose(
                np.asarray(f(sol.x, data.parameters(), rec.base_normal[i])).ravel(), expected, rtol=1e-13
            )


# -- the problem files on small settings -------------------------------------------------


def test_ph_shape_methods_agree_and_the_nlp_is_never_worse_than_the_grid(tmp_path):
    result = run_variant(tmp_path, "cbha-ph-shape", samples=6, baselines=["ph-ipopt", "ph-grid"])
    assert result.status == ["ok"] * 6
    E = {name: result.arrays[f"energy_{name}"] for name in ("ph-newton", "ph-ipopt", "ph-grid")}
    np.testing.assert_allclose(E["ph-newton"], E["ph-ipopt"], rtol=1e-9)
    assert np.all(E["ph-ipopt"] <= E["ph-grid"] * (1 + 1e-12))
    # distances recomputed from the stored curves by brute force
    curves = PHQuintic(result.arrays["ph_p0"], *np.moveaxis(result.arrays["ph_coefficients"], 1, 0))
    dense = curves.point(np.linspace(0, 1, 100001))
    markers = result.arrays["markers"]
    brute = np.min(np.linalg.norm(markers[:, :, None, :] - dense[:, None, :, :], axis=-1), axis=-1)
    np.testing.assert_allclose(result.arrays["marker_distance"], brute, atol=1e-8)
    # Honest bounds on the vertebra model (measured over 100 postures: mean 3.0 mm, worst vertebra 9.5 mm)
    assert np.all(result.arrays["marker_distance"] < 0.012)
    assert np.max(result.arrays["vertebra_distance"]) < 0.015
    rows = {row.method: row.metrics for row in result.comparison}
    assert rows["ph-grid"]["samples with relative gap > 1e-6"] >= rows["ph-ipopt"]["samples with relative gap > 1e-6"]


def test_recorded_csv_runs_through_the_same_problem_file(tmp_path):
    recording = recording_of("cbha-ph-shape", 5)
    write_marker_csv(recording, tmp_path / "recorded.csv")
    synthetic = run_variant(tmp_path / "a", "cbha-ph-shape", samples=5, baselines=[])
    recorded_file = problem_variant(
        "cbha-ph-shape", tmp_path, samples=5, baselines=[], data_params={"file": "recorded.csv"}
    )
    text = recorded_file.read_text().replace("source: synthetic", "source: csv")
    text = text.replace("    noise: 0.0003\n    rate: 240.0\n    stride: 24\n", "")
    recorded_file.write_text(text)
    recorded, _ = solve(str(recorded_file))
    np.testing.assert_allclose(recorded.arrays["marker_distance"], synthetic.arrays["marker_distance"], atol=1e-13)
    assert "vertebra_distance" not in recorded.arrays  # no ground truth in a recording


def test_newton_raphson_on_a_csv_recording_needs_its_marker_layout(tmp_path):
    """A CSV file does not say which vertebrae its markers are on: the comparator asks for
    ``data.params.intermediate``; given, it reproduces the synthetic run."""
    recording = recording_of("cbha-ph-ik", 3)
    write_marker_csv(recording, tmp_path / "recorded.csv")
    synthetic = run_variant(tmp_path / "a", "cbha-ph-ik", samples=3, baselines=["newton-raphson"])

    def recorded(params):
        file = problem_variant("cbha-ph-ik", tmp_path, samples=3, baselines=["newton-raphson"], data_params=params)
        text = file.read_text().replace("source: synthetic", "source: csv")
        file.write_text(text.replace("    noise: 0.0003\n    rate: 240.0\n    stride: 24\n", ""))
        return solve(str(file))[0]

    with pytest.raises(InputDataError) as err:
        recorded({"file": "recorded.csv"})
    assert err.value.field == "data.params.intermediate"
    result = recorded({"file": "recorded.csv", "intermediate": [5, 9, 13]})
    np.testing.assert_allclose(
        result.arrays["tube_lengths_newton_raphson"],
        synthetic.arrays["tube_lengths_newton_raphson"],
        rtol=0,
        atol=1e-12,
    )


def test_ph_ik_errors_and_frames(tmp_path):
    result = run_variant(tmp_path, "cbha-ph-ik", samples=8, baselines=["ph-ipopt"])
    assert result.status == ["ok"] * 8
    errors = np.abs(result.arrays["tube_lengths"] - result.arrays["reference_tube_lengths"])
    # measured over 100 postures: mean 1.6 mm, worst 4.7 mm (the PH shape, and its length from the end poses)
    assert np.max(errors) < 6e-3
    rows = {row.method: row.metrics for row in result.comparison}
    assert rows["ph-ipopt"]["mean |L error| [mm]"] == pytest.approx(rows["ph-newton"]["mean |L error| [mm]"], rel=1e-6)
    # the Euler-Rodrigues frame twists about the backbone: far worse than the rotation-minimising frame
    assert rows["ph-newton, euler_rodrigues frame"]["mean |L error| [mm]"] > rows["ph-newton"]["mean |L error| [mm]"]


def test_newton_raphson_row_reproduces_the_reference_tube_lengths_without_noise(tmp_path):
    """Newton-Raphson IK of noise-free section ends: the model's own legs summed, to rounding.

    The recording moves each leg as ``q_min + f (q_max - q_min)``, which is the affine elongation
    distribution the comparator imposes, and the two section ends fix the six tube lengths; so the
    root is the recorded configuration. Measured on the 100 noise-free postures of the problem:
    all ok, tube errors at most 1.5e-12 m; the tolerance is NR_TOLERANCE's 1e-9 m.
    """
    result = run_variant(tmp_path, "cbha-ph-ik", samples=6, baselines=["newton-raphson"], data_params={"noise": 0.0})
    rows = {row.method: row.metrics for row in result.comparison}
    nr = rows["newton-raphson"]
    status = result.arrays["status_newton_raphson"]
    assert len(status) == 6 and nr["failures"] == int(np.sum(status != "ok")) == 0  # every posture reported
    lengths = result.arrays["tube_lengths_newton_raphson"]
    np.testing.assert_allclose(lengths, result.arrays["reference_tube_lengths"], rtol=0, atol=1e-9)
    seconds = result.arrays["ik_seconds_newton-raphson"]
    assert np.all(seconds > 0) and nr["median IK time per sample [us]"] > 0


def test_newton_raphson_row_on_noisy_markers_and_its_marker_layout(tmp_path):
    """With the problem's 0.3 mm marker noise. Measured on its 100 postures: all ok, tube errors mean
    0.60 / 0.39 / 0.45 mm, at most 3.0 mm (the first 6: at most 1.5 mm); the linearised standard
    deviation of the tube errors is at most 1 mm per posture, so 3.5 mm bounds them at 3.5 sigma."""
    result = run_variant(tmp_path, "cbha-ph-ik", samples=6, baselines=["newton-raphson"])
    status = result.arrays["status_newton_raphson"]
    assert list(status) == ["ok"] * 6
    errors = np.abs(result.arrays["tube_lengths_newton_raphson"] - result.arrays["reference_tube_lengths"])
    assert 0 < np.max(errors) < 3.5e-3
    with pytest.raises(InputDataError, match=r"marker on vertebrae \[9\]"):
        run_variant(
            tmp_path, "cbha-ph-ik", samples=2, baselines=["newton-raphson"], data_params={"intermediate": [5, 13]}
        )


def test_pose_and_hybrid_comparators_report_every_posture(tmp_path):
    """The like-for-like Newton-Raphson (tip pose + distribution) and the hybrid networks, noise-free.

    Measured on the 100 noise-free postures: the pose row solves 93 (their tubes equal the
    recording's to 4e-12 m), the other roots leave Table I; with the problem's noise it solves
    41 of 100. The hybrid rows answer every posture: 21-28 mm mean error per tube with the
    networks of the Fig. 7 database (they extrapolate: the recording bends far more), 7-12 mm
    with those of the database whose sections bend as one.
    """
    result = run_variant(
        tmp_path,
        "cbha-ph-ik",
        samples=6,
        baselines=["newton-raphson-pose", "hybrid", "hybrid-coupled"],
        options={"coverage": False},
        data_params={"noise": 0.0},
    )
    rows = {row.method: row.metrics for row in result.comparison}
    reference = result.arrays["reference_tube_lengths"]
    status = result.arrays["status_newton_raphson_pose"]
    ok = status == "ok"
    assert ok.any() and rows["newton-raphson-pose"]["failures"] == int((~ok).sum())
    lengths = result.arrays["tube_lengths_newton_raphson_pose"]
    assert np.all(np.isnan(lengths[~ok]))
    np.testing.assert_allclose(lengths[ok], reference[ok], rtol=0, atol=1e-9)
    for name in ("hybrid", "hybrid_coupled"):
        hybrid = result.arrays[f"tube_lengths_{name}"]
        assert list(result.arrays[f"status_{name}"]) == ["ok"] * 6 and np.all(np.isfinite(hybrid))
        errors = np.abs(hybrid - reference) * 1e3
        assert rows[name.replace("_", "-")]["mean |L error| [mm]"] == pytest.approx(errors.mean(), rel=1e-12)
    assert not np.allclose(result.arrays["tube_lengths_hybrid"], result.arrays["tube_lengths_hybrid_coupled"])
    assert rows["hybrid"]["seed 002 Table III, hybrid: time per sample [us]"] == pytest.approx(12080)


def test_ph_ik_with_the_true_backbone_length_held(tmp_path):
    """Free end speeds with the model's backbone length (an oracle): tube errors drop below a millimetre."""
    result = run_variant(
        tmp_path, "cbha-ph-ik", samples=6, baselines=[], options={"length": "model", "free_speeds": True}
    )
    errors = np.abs(result.arrays["tube_lengths"] - result.arrays["reference_tube_lengths"])
    assert result.status == ["ok"] * 6
    assert np.mean(errors) < 1e-3


def test_rope_chain_links_meet_and_fit_their_markers(tmp_path):
    """C0 joints hold exactly and the rope keeps its length; marker distances are the PH shapes' own errors

    (measured over 40 postures: mean 3.9 / 4.7 / 4.5 mm for CBHA 1 / rope / CBHA 2; the
    rope's worst, up to about 30 mm, where it sags deepest, chord about half its length).
    """
    result = run_variant(tmp_path, "cbha-rope-chain", samples=4, baselines=[])
    assert result.status == ["ok"] * 4
    a = result.arrays
    np.testing.assert_allclose(a["arm1_ph_points"][:, -1], a["rope_ph_points"][:, 0], atol=1e-13)  # joint B
    np.testing.assert_allclose(a["rope_ph_points"][:, -1], a["arm2_ph_points"][:, 0], atol=1e-13)  # joint C
    rope_length = np.linalg.norm(np.diff(a["rope_ph_points"], axis=1), axis=2).sum(axis=1)
    np.testing.assert_allclose(rope_length, 0.65, rtol=1e-3)  # 100-segment polyline of a curve of length 0.65
    assert np.all(a["arm1_marker_distance"] < 0.015) and np.all(a["arm2_marker_distance"] < 0.015)
    assert np.all(a["rope_marker_distance"] < 0.05)


def test_bad_options_and_data_are_named(tmp_path):
    with pytest.raises(SpecError, match=r"options.length"):
        run_variant(tmp_path, "cbha-ph-shape", samples=2, baselines=[], options={"length": "guess"})
    with pytest.raises(SpecError, match=r"options.frame"):
        run_variant(tmp_path, "cbha-ph-ik", samples=2, baselines=[], options={"frame": "frenet"})
    with pytest.raises(SpecError, match=r"options.twist: unknown field"):
        run_variant(tmp_path, "cbha-ph-shape", samples=2, baselines=[], options={"twist": 1.0})
    with pytest.raises(SpecError, match=r"data.params.speed: unknown field"):
        run_variant(tmp_path, "cbha-ph-shape", samples=2, baselines=[], data_params={"speed": 1.0})
    # a recording without reference tube lengths cannot be scored by ph_ik
    rec = recording_of("cbha-ph-ik", 2)
    rec.tube_lengths = None
    write_marker_csv(rec, tmp_path / "no_lengths.csv")
    file = problem_variant("cbha-ph-ik", tmp_path, samples=2, baselines=[], data_params={"file": "no_lengths.csv"})
    file.write_text(
        file.read_text()
        .replace("source: synthetic", "source: csv")
        .replace("    noise: 0.0003\n    rate: 240.0\n    stride: 24\n", "")
    )
    with pytest.raises(InputDataError, match=r"L1: no reference tube lengths"):
        solve(str(file))
