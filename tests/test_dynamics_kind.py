"""Kind ``dynamics``: Cosserat-rod arms in time from problem files, checked against closed forms and the statics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.cli import main
from optikin.errors import InputDataError, SpecError
from optikin.runner import solve

L, RADIUS, E, RHO = 0.3, 0.01, 1e6, 1000.0
EI = E * np.pi * RADIUS**4 / 4
RHO_A = RHO * np.pi * RADIUS**2

ARM = {
    "type": "cosserat",
    "params": {
        "youngs_modulus": E,
        "poisson_ratio": 0.5,
        "density": RHO,
        "gravity": [0.0, 0.0, 0.0],
        "steps_per_segment": 12,
        "segments": [{"length": L, "radius": RADIUS}],
        "tendons": [{"offset": 0.008, "angle": 0.0, "max_tension": 2.0}],
    },
}
"""The soft rod of the PyElastica comparisons with one straight tendon, without gravity, 13 points."""


def problem(tmp_path: Path, name: str = "dynamics-test", data: dict | None = None, **options) -> Path:
    """A ``dynamics`` problem file in ``tmp_path`` on :data:`ARM`: 10 ms steps, a tip-force release by default."""
    spec = {
        "name": name,
        "title": "test",
        "kind": "dynamics",
        "arm": yaml.safe_load(yaml.safe_dump(ARM)),
        "data": data
        or {
            "source": "step",
            "samples": 60,
            "params": {"tip_force_initial": [0.005, 0.0, 0.0], "tip_force_final": [0.0, 0.0, 0.0]},
        },
        "options": {"dt": 0.01, "gravity": False, **options},
    }
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def test_release_starts_from_the_cantilever_deflection_and_swings_through_zero(tmp_path):
    result, folder = solve(str(problem(tmp_path)), out=tmp_path / "out")
    assert result.status == ["ok"] * 60
    tip = result.arrays["tip_position"]
    assert tip.shape == (61, 3) and result.arrays["t"][-1] == pytest.approx(0.6)
    # at rest under 5 mN: Euler-Bernoulli F L^3 / (3 E I) = 5.7 mm, within 2 % (shear, 13 points)
    assert tip[0, 0] == pytest.approx(0.005 * L**3 / (3 * EI), rel=0.02)
    # half a period of the first mode (0.51 s by Euler-Bernoulli) after the release, the tip is on the other side
    assert tip[:, 0].min() < -0.5 * tip[0, 0]
    assert result.metrics["first bending period, Euler-Bernoulli [s]"] == pytest.approx(
        2 * np.pi / (1.8751**2 * np.sqrt(EI / (RHO_A * L**4))), rel=1e-4
    )
    assert result.arrays["backbone"].shape == (61, 13, 3)
    assert {"tip.png", "energy.png", "backbones.png", "step_time.png"} <= {p.name for p in folder.iterdir()}
    assert main(["plot", str(folder)]) == 0


def test_a_damped_tendon_ramp_settles_to_the_static_equilibrium(tmp_path):
    data = {"source": "ramp", "samples": 300, "params": {"initial": [0.0], "final": [0.3], "duration": 0.2}}
    omega1 = 1.8751**2 * np.sqrt(EI / (RHO_A * L**4))
    result, _ = solve(str(problem(tmp_path, data=data, damping={"viscosity": float(E / omega1)})))
    assert result.succeeded
    assert result.arrays["actuation"][-1, 0] == 0.3
    assert np.linalg.norm(result.arrays["tip_position"][-1] - [0, 0, L]) > 0.01
    # the tendons' RK4 errors of the two formulations differ by about 1e-5 m at 13 points
    assert result.metrics["final distance to the static equilibrium [mm]"] < 0.05


def test_sine_commands_follow_their_formula(tmp_path):
    data = {"source": "sine", "samples": 20, "params": {"mean": [0.5], "amplitude": [0.2], "frequency": 5.0}}
    result, _ = solve(str(problem(tmp_path, data=data)))
    t = result.arrays["t"]
    expected = 0.5 + 0.2 * np.sin(2 * np.pi * 5.0 * t[1:])
    np.testing.assert_allclose(result.arrays["actuation"][1:, 0], expected, atol=1e-15)
    assert result.arrays["actuation"][0, 0] == 0.5


def test_a_step_that_does_not_converge_stops_with_a_labelled_partial_trajectory(tmp_path, capsys):
    data = {"source": "step", "samples": 10, "params": {"initial": [0.0], "tip_force_final": [0.0, 0.0, -2.0]}}
    path = problem(tmp_path, data=data, max_iterations=1)
    assert main(["solve", str(path), "--out", str(tmp_path / "out"), "--no-figures", "-q"]) == 1
    result, _ = solve(str(path))
    assert result.status == ["failed"] * 10
    assert result.metrics["partial"] is True and result.arrays["t"].size == 1
    assert any("time step 1 (t = 0.01 s)" in note and "partial trajectory" in note for note in result.notes)


def test_bad_input_names_the_field(tmp_path):
    with pytest.raises(SpecError, match=r"options.dt: .*first bending period"):
        solve(str(problem(tmp_path, dt=0.5)))
    with pytest.raises(SpecError, match=r"options.dt: .*too short for shooting"):
        solve(str(problem(tmp_path, dt=1e-7)))
    with pytest.raises(SpecError, match=r"options.damping.viscosity"):
        solve(str(problem(tmp_path, damping={"viscosity": -1.0})))
    data = {"source": "step", "samples": 5, "params": {"final": [1.0, 2.0]}}
    with pytest.raises(InputDataError, match="data.params.final"):
        solve(str(problem(tmp_path, data=data)))
    data = {"source": "step", "samples": 5, "params": {"final": [-1.0]}}
    with pytest.raises(InputDataError, match="sample 1.*tendons.0"):
        solve(str(problem(tmp_path, data=data)))


@pytest.mark.parametrize("name", ["cosserat-cantilever-vibration", "cosserat-tendon-step", "cbha-pneumatic-dynamics"])
def test_shipped_problems_run(name, tmp_path):
    result, _ = solve(name, overrides=[("data.samples", 15)], figures=False)
    assert result.succeeded and result.samples == 15


def test_chamber_pressures_lag_their_commands_by_the_first_order_closed_form(tmp_path):
    arm = yaml.safe_load(yaml.safe_dump(ARM))
    arm["params"]["tendons"] = []
    arm["params"]["chambers"] = [{"offset": 0.005, "area": 1e-5, "pressure_range": [0.0, 1e5]}]
    data = {"source": "step", "samples": 30, "params": {"initial": [0.0], "final": [2.0e4]}}
    path = problem(tmp_path, data=data, pressure_time_constant=0.05)
    spec = yaml.safe_load(path.read_text())
    spec["arm"] = arm
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    result, _ = solve(str(path))
    assert result.succeeded
    t = result.arrays["t"]
    np.testing.assert_allclose(result.arrays["command"][1:, 0], 2.0e4)
    np.testing.assert_allclose(result.arrays["actuation"][:, 0], 2.0e4 * (1 - np.exp(-t / 0.05)), rtol=1e-12)
    spec["options"]["pressure_time_constant"] = 0.0
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    with pytest.raises(SpecError, match="options.pressure_time_constant"):
        solve(str(path))


def test_a_recorded_command_file_is_interpolated_linearly(tmp_path):
    (tmp_path / "commands.csv").write_text("t,tendons.0\n0.0,0.0\n0.05,0.2\n0.1,0.1\n")
    data = {"source": "csv", "samples": 15, "params": {"file": "commands.csv"}}
    result, _ = solve(str(problem(tmp_path, data=data)))
    assert result.succeeded
    t = result.arrays["t"]
    np.testing.assert_allclose(result.arrays["actuation"][:, 0], np.interp(t, [0.0, 0.05, 0.1], [0.0, 0.2, 0.1]))
    (tmp_path / "commands.csv").write_text("tendons.0\n0.0\n")
    with pytest.raises(InputDataError, match="t column"):
        solve(str(problem(tmp_path, data=data)))


def test_a_payload_weighs_on_the_rest_shape(tmp_path):
    """50 g at the tip under a weak transverse gravity (0.01 m/s^2, linear range): the tip moves by the
    cantilever's m g L^3 / (3 E I) more than without it, within 3 % (shear, 13 points)."""
    spec = {"source": "step", "samples": 3, "params": {"initial": [0.0]}}
    tips = []
    for payload in (0.0, 0.05):
        path = problem(tmp_path, data=spec, gravity=True, payload=payload)
        doc = yaml.safe_load(path.read_text())
        doc["arm"]["params"]["gravity"] = [-0.01, 0.0, 0.0]
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        result, _ = solve(str(path))
        assert result.succeeded
        tips.append(result.arrays["tip_position"][0, 0])
    assert tips[0] - tips[1] == pytest.approx(0.05 * 0.01 * L**3 / (3 * EI), rel=0.03)
