"""The nn_fkm and nn_ikm problem kinds on a small setting: exact-FK tip errors, test-split MSEs, store, bad input.

References: the chain of 4x4 matrices of eq. (5) written out in numpy, the printed
eqs. (7)-(9), Table I typed in again, and the database rebuilt from the problem's data.
"""

from __future__ import annotations

import typing

import numpy as np
import pytest
import yaml

from optikin.arms.cbha import CBHAArm, CBHAGeometry, printed_leg_lengths
from optikin.baselines.nn_database import DatabaseSpec, build_database
from optikin.errors import InputDataError, SpecError
from optikin.baselines.nn_models import SETTINGS
from optikin.problems import ProblemContext
from optikin.problems.nn_shared import SettingName, database_spec, options
from optikin.progress import SILENT
from optikin.registry import PROBLEM_KINDS
from optikin.results import read_result, redraw
from optikin.runner import solve
from optikin.spec import load_problem, project_root

Q_MIN_MM = np.array([8.5, 8.5, 8.5, 7, 7, 7, 8.5, 10, 6.5, 8, 8, 7.5, 7.5, 7, 7, 6.5])
Q_MAX_MM = np.array([19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5, 20.5, 19, 19, 18, 18, 16])
RADII = np.linspace(0.040, 0.029, 17)
CANDIDATES, SEED = 40_000, 2016


def chain_tips(Q: np.ndarray) -> np.ndarray:
    """Tip positions of configurations (n, 48): product of the eq. (5) matrices, numpy."""
    T = np.tile(np.eye(4), (len(Q), 1, 1))
    for Z, theta, psi in np.moveaxis(Q.reshape(len(Q), -1, 3), 1, 0).transpose(0, 2, 1):
        ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
        A = np.zeros((len(Q), 4, 4))
        A[:, 0, :3], A[:, 1, :3], A[:, 2] = (
            np.stack([ct, st * sp, st * cp], -1),
            np.stack([0 * ct, cp, -sp], -1),
            np.stack([-st, sp * ct, ct * cp, Z], -1),
        )
        A[:, 3, 3] = 1.0
        T = T @ A
    return T[:, :3, 3]


def small_problem(tmp_path, kind: str, **changes) -> str:
    data = yaml.safe_load((project_root() / "problems" / f"cbha-nn-{kind}.yaml").read_text())
    data["data"]["samples"] = CANDIDATES
    data["options"] |= {"setting": "small", "exact_samples": 3, "latency_repeats": 3}
    for key, value in changes.items():
        section, _, field = key.partition("__")
        if field:
            data[section][field] = value
        else:
            data[section] = value
    data["name"] = f"small-{kind}"
    path = tmp_path / f"small-{kind}.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


@pytest.fixture(scope="module")
def database():
    return build_database(CBHAGeometry(), DatabaseSpec(candidates=CANDIDATES, seed=SEED))


@pytest.fixture(scope="module")
def fkm_solved(tmp_path_factory):
    """The small nn_fkm problem's Result and the folder it was written to (figures drawn)."""
    folder = tmp_path_factory.mktemp("fkm")
    return solve(small_problem(folder, "fkm", options__variants=["seed", "adam"]), out=folder / "out")


@pytest.fixture(scope="module")
def ikm_solved(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ikm")
    return solve(small_problem(folder, "ikm", options__variants=["adam"]), out=folder / "out")


@pytest.fixture(scope="module")
def fkm(fkm_solved):
    return fkm_solved[0]


@pytest.fixture(scope="module")
def ikm(ikm_solved):
    return ikm_solved[0]


def test_fkm_tip_errors_go_through_the_exact_chain(fkm, database):
    a = fkm.arrays
    assert np.array_equal(a["test_rows"], database.test)
    np.testing.assert_allclose(a["tip"], chain_tips(database.configurations[database.test]), atol=1e-15)
    rows = {r.method: r.metrics for r in fkm.comparison}
    for variant in ("seed", "adam"):
        np.testing.assert_allclose(a[f"tip_{variant}"], chain_tips(a[f"configurations_{variant}"]), atol=1e-15)
        errors = np.linalg.norm(a[f"tip_{variant}"] - a["tip"], axis=1) * 1e3
        assert rows[f"mlp-{variant}"]["tip error mean [mm]"] == pytest.approx(errors.mean(), rel=1e-12)
        assert rows[f"mlp-{variant}"]["tip error max [mm]"] == pytest.approx(errors.max(), rel=1e-12)
    for solver in ("newton", "gauss-newton", "lm"):  # the problem file's IK presets, on the first 3 test arms
        row = rows[solver]
        assert row["samples"] == 3 and row["ok [%]"] == 100 and row["samples without a tip"] == 0
        assert row["tip error max [mm]"] < 1e-9 and row["max |platform variables - truth|"] < 1e-9
        np.testing.assert_allclose(a[f"tip_{solver}"], a["tip"][:3], atol=1e-12)
    assert rows["newton"]["batched"] and not rows["lm"]["batched"]
    assert fkm.succeeded
    # the fairness manifest: every row says what it was given; the networks their database and its coverage
    assert all("given" in r for r in rows.values()) and fkm.metrics["fairness"]["unlabelled"] == []
    given = rows["mlp-adam"]["given"]
    assert given["geometry"] == "generator's own" and "training rows" in given["training"]
    assert given["test input to nearest training input, median [mm]"] > 0
    assert rows["newton"]["given"]["limits"] == "Table I" and rows["newton"]["given"]["training"] == "none"


def test_fkm_reports_the_test_split_mse(fkm, database):
    a, rows = fkm.arrays, {r.method: r.metrics for r in fkm.comparison}
    truth = database.configurations[database.test]
    for variant in ("seed", "adam"):
        for s, cols in ((1, slice(0, 24)), (2, slice(24, 48))):
            mse = np.mean((a[f"configurations_{variant}"][:, cols] - truth[:, cols]) ** 2)
            assert rows[f"mlp-{variant}"][f"test MSE fkm_section{s}"] == pytest.approx(mse, rel=1e-9)


def test_ikm_realises_lengths_within_table_i_and_measures_through_exact_fk(ikm, database):
    a, rows = ikm.arrays, {r.method: r.metrics for r in ikm.comparison}
    np.testing.assert_allclose(a["targets"], chain_tips(database.configurations[database.test]), atol=1e-15)
    Q = a["configurations_adam"].reshape(len(a["targets"]), 16, 3)
    legs = np.stack([np.stack(printed_leg_lengths(*Q[:, k].T, RADII[k], RADII[k + 1]), -1) for k in range(16)], 1)
    lo, hi = np.repeat(Q_MIN_MM, 3) / 1e3, np.repeat(Q_MAX_MM, 3) / 1e3
    np.testing.assert_allclose(legs.reshape(len(Q), -1), np.clip(a["leg_lengths_adam"], lo, hi), atol=1e-12)
    np.testing.assert_allclose(a["tip_adam"], chain_tips(a["configurations_adam"]), atol=1e-15)
    errors = np.linalg.norm(a["tip_adam"] - a["targets"], axis=1) * 1e3
    assert rows["mlp-adam"]["tip error median [mm]"] == pytest.approx(np.median(errors), rel=1e-12)
    assert set(rows) == {"mlp-adam", "ipopt", "sqpmethod", "gauss-newton", "lm"}
    for solver in ("ipopt", "sqpmethod"):  # Table I imposed: realised tips reach the first 3 targets
        np.testing.assert_allclose(a[f"tip_{solver}"], a["targets"][:3], atol=1e-9)
        np.testing.assert_allclose(a[f"tip_{solver}"], chain_tips(a[f"configurations_{solver}"]), atol=1e-15)
        assert rows[solver]["ok [%]"] == 100 and rows[solver]["lengths clipped to Table I [%]"] == 0
    for solver in ("gauss-newton", "lm"):  # bounds only: a length outside Table I is clipped, and then misses
        reached = np.linalg.norm(a[f"tip_{solver}"] - a["targets"][:3], axis=1) < 1e-9
        assert rows[solver]["ok [%]"] == pytest.approx(100 * reached.mean())


def test_store_is_reused_and_refused_for_another_database(tmp_path):
    store = tmp_path / "models"
    path = small_problem(tmp_path, "fkm", options__variants=["adam"], options__store=str(store), baselines=["newton"])
    first, _ = solve(path)
    again, _ = solve(path)
    assert first.metrics["mlp-adam loaded from store"] is False
    assert again.metrics["mlp-adam loaded from store"] is True
    np.testing.assert_array_equal(again.arrays["tip_adam"], first.arrays["tip_adam"])
    other = small_problem(
        tmp_path,
        "fkm",
        options__variants=["adam"],
        options__store=str(store),
        baselines=["newton"],
        data__seed=SEED + 1,
    )
    with pytest.raises(InputDataError) as err:
        solve(other)
    assert err.value.field == "database.seed"


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"data__source": "random"}, "data.source"),
        ({"options__variants": ["sgd-fast"]}, "options.variants.0"),
        ({"options__penalty": -1.0}, "options.penalty"),
        ({"data__params": {"z_range_mm": [8, 25]}}, "data"),
        ({"data__params": {"grid": True}}, "data.params.grid"),
        ({"data__params": {"split": [0.7, 0.2, 0.2]}}, "data.params.split"),
        ({"data__params": {"coupling": "vertebra"}}, "data.params.coupling"),
        ({"options__setting": "medium"}, "options.setting"),
        ({"options__exact_samples": 0}, "options.exact_samples"),
        ({"baselines": ["qp-osqp"]}, "baselines.0"),
        ({"baselines": ["least_squares"]}, "baselines.0"),
        ({"solver": "newton"}, "solver"),
    ],
)
def test_bad_problem_files_name_the_field(tmp_path, changes, field):
    with pytest.raises(SpecError) as err:
        solve(small_problem(tmp_path, "fkm", **changes))
    assert err.value.field == field


@pytest.mark.parametrize("name", ["cbha-nn-fkm", "cbha-nn-ikm", "cbha-nn-fkm-coupled", "cbha-nn-ikm-coupled"])
def test_shipped_problem_files_are_valid(name):
    spec, path = load_problem(name)
    ctx = ProblemContext(spec=spec, path=path, arm_model=CBHAArm(**spec.arm.params), progress=SILENT)
    o, db_spec = options(ctx), database_spec(ctx)
    assert o.setting == "full" and db_spec.split == (0.70, 0.15, 0.15)
    assert db_spec.coupling == ("section" if name.endswith("coupled") else "platform")
    assert db_spec.z_range == (0.0, 0.025) and db_spec.angle_range == pytest.approx((-np.pi / 4, np.pi / 4))


@pytest.mark.parametrize("kind", ["fkm", "ikm"])
@pytest.mark.parametrize(
    "changes, field",
    [
        ({"options__exact_sampels": 3}, "options.exact_sampels"),
        ({"data__params": {"z_range_mm": [0, 25], "coupilng": "section"}}, "data.params.coupilng"),
    ],
)
def test_a_typo_in_options_or_data_params_is_an_unknown_field(tmp_path, kind, changes, field):
    with pytest.raises(SpecError) as err:
        solve(small_problem(tmp_path, kind, **changes))
    assert err.value.field == field and "unknown field" in str(err.value)


def test_the_setting_names_are_the_trained_settings():
    assert typing.get_args(SettingName) == tuple(SETTINGS)


@pytest.mark.parametrize("kind", ["fkm", "ikm"])
def test_figures_are_redrawn_from_the_written_result(request, tmp_path, kind):
    result, folder = request.getfixturevalue(f"{kind}_solved")
    summary, arrays = read_result(folder)
    assert summary["figures"] == ["search.png", "tip_errors.png"]
    builder = PROBLEM_KINDS.get(f"nn_{kind}").figures
    assert sorted(builder(arrays, summary)) == ["search", "tip_errors"]
    assert [p.name for p in redraw(folder, builder, summary, arrays)] == ["search.png", "tip_errors.png"]
    methods = [row.method for row in result.comparison]
    for method in methods:  # the figures' arrays are the rows' tip errors, the searches the models'
        np.testing.assert_array_equal(arrays[f"tip_errors_{method}"], result.arrays[f"tip_errors_{method}"])
    key = f"{methods[0]} {kind}_{'section1' if kind == 'fkm' else 'nn1'} validation criterion per width"
    search = arrays[f"search_{methods[0].removeprefix('mlp-')}_{kind}_{'section1' if kind == 'fkm' else 'nn1'}"]
    assert {str(int(n)): v for n, v in search} == pytest.approx(summary["metrics"][key])
    without = {k: v for k, v in arrays.items() if not k.startswith("tip_errors_")}
    assert sorted(builder(without, summary)) == ["search"]
