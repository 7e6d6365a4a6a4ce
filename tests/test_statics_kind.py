"""Kind ``statics``: Cosserat equilibria from problem files, checked against closed forms, a second method and
the actuations that made the targets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.cli import main
from optikin.errors import InputDataError, SpecError
from optikin.runner import prepare, solve

L, RADIUS, E, OFFSET, T_MAX = 0.3, 0.01, 1e6, 0.005, 5.0
EI = E * np.pi * RADIUS**4 / 4

ARM = {
    "type": "cosserat",
    "params": {
        "youngs_modulus": E,
        "model": "kirchhoff",
        "steps_per_segment": 40,
        "segments": [{"length": L, "radius": RADIUS}],
        "tendons": [
            {"offset": OFFSET, "angle": 0.0, "max_tension": T_MAX},
            {"offset": OFFSET, "angle": float(np.pi / 2), "max_tension": T_MAX},
        ],
    },
}
"""One inextensible segment, two straight tendons at 90 degrees: reachable tip positions have one actuation."""


def problem(tmp_path: Path, name: str = "statics-test", **changes) -> Path:
    """A ``statics`` problem file in ``tmp_path`` on :data:`ARM`, without gravity, with ``changes`` applied."""
    spec = {
        "name": name,
        "title": "test",
        "kind": "statics",
        "arm": yaml.safe_load(yaml.safe_dump(ARM)),
        "data": {"source": "grid", "seed": 3, "samples": 3, "params": {"actuators": ["tendons.0"], "points": 3}},
        "options": {"mode": "forward", "loads": {"gravity": False}},
    }
    for key, value in changes.items():
        spec[key] = value
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def arc(s: np.ndarray, radius: float) -> np.ndarray:
    """Circular arc in the x-z plane from the origin along +z, bending towards +x."""
    angle = s / radius
    return np.stack([radius * (1 - np.cos(angle)), 0 * s, radius * np.sin(angle)], axis=1)


def test_a_straight_tendon_bends_a_kirchhoff_rod_into_the_arc_of_curvature_T_r_over_EI(tmp_path):
    result, _ = solve(str(problem(tmp_path)))
    assert result.status == ["ok", "ok", "ok"]
    tensions = result.arrays["actuation"][:, 0]
    assert tensions.tolist() == [0.0, T_MAX / 2, T_MAX]
    s = result.arrays["s"]
    for tension, backbone in zip(tensions, result.arrays["backbone"]):
        if tension == 0.0:
            expected = np.stack([0 * s, 0 * s, s], axis=1)
        else:
            expected = arc(s, EI / (tension * OFFSET))
        # RK4's O(h^4) error on 40 steps: 1.4e-8 m at kappa L = 0.95 rad (T_MAX), 16 times less per halved step
        assert np.abs(backbone - expected).max() < 3e-8


def test_shooting_and_collocation_agree_below_a_micrometre(tmp_path):
    data = {"source": "trajectory", "seed": 1, "samples": 4, "params": {"rate": 2.0}}
    options = {"mode": "forward", "loads": {"gravity": False}, "collocation_intervals": 20}
    path = problem(tmp_path, data=data, baselines=["collocation"], options=options)
    result, _ = solve(str(path))
    assert result.status == ["ok"] * 4 and all(s == "ok" for s in result.arrays["status_collocation"])
    assert result.metrics["max tip distance shooting-collocation [mm]"] < 1e-3
    rows = {row.method: row.metrics for row in result.comparison}
    assert rows["collocation"]["max |backbone - shooting| [mm]"] < 1e-3
    assert rows["shooting (compiled)"]["median time per equilibrium [ms]"] > 0


@pytest.mark.parametrize("solver,baseline", [("gauss-newton", "lm")])
def test_inverse_statics_recovers_the_actuation_of_reachable_targets(tmp_path, solver, baseline):
    path = problem(
        tmp_path,
        data={"source": "random", "seed": 7, "samples": 4},
        solver=solver,
        baselines=[baseline],
        options={"mode": "inverse", "loads": {"gravity": False}, "target_tolerance": 1e-10},
    )
    result, _ = solve(str(path))
    truth = result.arrays["target_actuation"]
    for method in (solver, baseline):
        assert all(s == "ok" for s in result.arrays[f"status_{method}"]), method
        assert result.arrays[f"tip_error_{method}"].max() < 1e-6
        assert np.abs(result.arrays[f"actuation_{method}"] - truth).max() < 1e-5 * T_MAX
    assert result.status == ["ok"] * 4


def test_a_bvp_that_does_not_converge_is_failed_with_its_residual(tmp_path):
    options = {"mode": "forward", "loads": {"gravity": False}, "tolerance": 1e-300}
    path = problem(tmp_path, data={"source": "random", "seed": 2, "samples": 3}, options=options)
    result, _ = solve(str(path))
    assert result.status == ["failed"] * 3
    assert np.all(np.isfinite(result.arrays["residual"])) and np.all(result.arrays["residual"] > 0)
    assert "equilibria failed" in result.notes[0]


@pytest.mark.parametrize(
    "where,value,field",
    [
        ("youngs_modulus", 0.0, "arm.params.youngs_modulus"),
        ("youngs_modulus", -1.0, "arm.params.youngs_modulus"),
        ("radius", 0.0, "arm.params.segments.0.radius"),
        ("offset", 0.02, "arm.params.tendons.0.offset"),
    ],
)
def test_bad_arm_parameters_name_the_field(tmp_path, where, value, field):
    arm = yaml.safe_load(yaml.safe_dump(ARM))
    if where == "youngs_modulus":
        arm["params"]["youngs_modulus"] = value
    elif where == "radius":
        arm["params"]["segments"][0]["radius"] = value
    else:
        arm["params"]["tendons"][0]["offset"] = value
    with pytest.raises(SpecError) as err:
        prepare(str(problem(tmp_path, arm=arm)))
    assert err.value.field == field


def test_a_negative_tension_names_the_sample_and_the_tendon(tmp_path):
    (tmp_path / "tensions.csv").write_text("tendons.0,tendons.1\n0.01,0.0\n-0.02,0.01\n")
    path = problem(tmp_path, data={"source": "csv", "params": {"file": "tensions.csv"}})
    with pytest.raises(InputDataError) as err:
        solve(str(path))
    assert err.value.sample == 1 and err.value.field == "tendons.0" and "negative" in str(err.value)


@pytest.mark.parametrize(
    "section,content,field",
    [
        ("options", {"mode": "forwards"}, "options.mode"),
        ("options", {"loads": {"payloadd": 1.0}}, "options.loads.payloadd"),
        ("data", {"source": "grid", "params": {"pointz": 3}}, "data.params.pointz"),
        ("data", {"source": "trajectory", "params": {"rat": 3.0}}, "data.params.rat"),
    ],
)
def test_typos_name_the_dotted_field(tmp_path, section, content, field):
    with pytest.raises(SpecError) as err:
        prepare(str(problem(tmp_path, **{section: content})))
    assert err.value.field == field


def test_baselines_are_checked_against_the_mode(tmp_path):
    kind_baseline = problem(tmp_path, baselines=["lm"])
    with pytest.raises(SpecError) as err:
        solve(str(kind_baseline))
    assert err.value.field == "baselines.0"


def test_figures_are_redrawn_from_a_written_result(tmp_path):
    _, folder = solve(str(problem(tmp_path)), out=tmp_path / "out")
    drawn = sorted(p.name for p in folder.glob("*.png"))
    assert drawn == ["backbones.png", "time.png", "tip.png"]
    for png in folder.glob("*.png"):
        png.unlink()
    assert main(["plot", str(folder)]) == 0
    assert sorted(p.name for p in folder.glob("*.png")) == drawn


def test_a_grid_too_large_is_refused_naming_its_points(tmp_path):
    data = {"source": "grid", "params": {"points": 5000}}
    with pytest.raises(SpecError) as err:
        solve(str(problem(tmp_path, data=data)))
    assert err.value.field == "data.params.points"


@pytest.mark.slow
def test_equilibria_from_zero_load_survive_the_jacobian_kept_from_other_loads():
    # Along this arm's tension trajectory, solves without a start (ramped from zero load) began
    # with the Jacobian of the previous, far-away loads and ended non-finite after a few dozen.
    from optikin.problems.statics.run import fixed_loads, shooting_solver

    _, ctx = prepare("cosserat-tendon-ik")
    solver = shooting_solver(ctx.arm, ctx.options)
    samples = ctx.data_source.load(ctx.arm, ctx.spec.data, ctx.data_params, ctx.path)
    fixed = fixed_loads(ctx.arm, ctx.options.loads)
    assert all(solver.solve(np.concatenate([fixed, a])).ok for a in samples.values[:60])


def test_the_continued_equilibrium_and_its_ift_jacobian_match_cold_solves_and_finite_differences(tmp_path):
    # TipEquilibrium reaches a new actuation by an IFT predictor and a simplified-Newton corrector from the
    # stored equilibrium nearest it; the pose must be the one solved from zero load, and dy/da the central
    # differences of such cold solves.
    from optikin.problems.statics.equilibrium import TipEquilibrium
    from optikin.problems.statics.run import fixed_loads, shooting_solver

    path = problem(tmp_path, options={"mode": "inverse", "loads": {"gravity": False}, "target_tolerance": 1e-10})
    _, ctx = prepare(str(path))
    solver = shooting_solver(ctx.arm, ctx.options)
    fixed = fixed_loads(ctx.arm, ctx.options.loads)
    equilibrium = TipEquilibrium(solver, fixed, ctx.options.flags)

    def cold(a: np.ndarray) -> np.ndarray:
        s = solver.solve(np.concatenate([fixed, a]))
        assert s.ok
        return np.concatenate([s.positions[-1], s.orientations[-1]])

    a = np.array([1.0, 0.5])
    equilibrium.evaluate(a)
    for step in (np.array([0.05, -0.02]), np.array([0.1, 0.08])):
        a = a + step
        y, dy = equilibrium.evaluate(a)
        assert np.abs(y - cold(a)).max() < 1e-10  # both roots within the tolerance 1e-10 N of the residual
        h = 1e-4
        fd = np.column_stack([(cold(a + h * e) - cold(a - h * e)) / (2 * h) for e in np.eye(2)])
        assert np.abs(dy - fd).max() < 1e-7 * np.abs(fd).max()
    assert equilibrium.equilibria == 3
