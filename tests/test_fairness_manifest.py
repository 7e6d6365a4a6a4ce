"""The fairness manifest: every comparison says what each method was given, and labels another arm.

The shipped comparison problems are checked statically (their files, no run); the old
``cbha-ph-ik-cosserat`` arm (Table I unscaled under a Cosserat arm 1.8 times its size) must
be caught; the coverage of a training set is checked against distances worked out by hand.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from optikin.problems.fairness import ArmSize, Given, Manifest, coverage, mismatch
from optikin.problems.nn_shared import method_names, nn_manifest, options as nn_options
from optikin.runner import prepare_spec
from optikin.spec import load_problem

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"
KINDS = ("ph_ik", "ph_shape", "nn_fkm", "nn_ikm")


def comparison_files() -> list[Path]:
    out = []
    for path in sorted(PROBLEMS.glob("*.yaml")):
        kind = (yaml.safe_load(path.read_text()) or {}).get("kind")
        if kind in KINDS:
            out.append(path)
    return out


def manifest_of(path: Path, overrides: dict | None = None) -> Manifest:
    spec, where = load_problem(str(path), tuple((overrides or {}).items()))
    _, ctx = prepare_spec(spec, where, run=False)
    if spec.kind == "ph_ik":
        from optikin.problems.ph_ik.report import manifest

        return manifest(ctx)
    if spec.kind == "ph_shape":
        from optikin.problems.ph_shape.report import manifest as shape_manifest

        return shape_manifest(ctx)
    o = nn_options(ctx)
    return nn_manifest(spec, ctx.arm, o, ctx.data_params, method_names(spec.kind, spec, o))


def test_the_network_rows_are_named_as_a_run_names_them():
    """The static names are the rows' (NetworkRun.label, the exact solvers, Table IV's), so each gets its entry."""
    found = manifest_of(PROBLEMS / "cbha-nn-ikm-cosserat.yaml")
    names = [g.method for g in found.given]
    assert names[:3] == ["mlp-seed", "mlp-seed-raw", "mlp-adam"] and "ipopt" in names and "true-lengths" in names
    network = found.of("mlp-adam")
    assert network.geometry == "measured" and "Adam" in network.training and network.arm.tube_range is not None
    assert found.of("direct-mlp").training == "the Cosserat training postures"
    fkm = manifest_of(PROBLEMS / "cbha-nn-fkm-cosserat.yaml")
    assert [g.method for g in fkm.given][:2] == ["mlp-seed-fig9", "mlp-seed-raw-fig9"]


def test_every_kind_has_a_shipped_comparison():
    kinds = {yaml.safe_load(p.read_text())["kind"] for p in comparison_files()}
    assert kinds == set(KINDS)


@pytest.mark.parametrize("path", comparison_files(), ids=lambda p: p.stem)
def test_shipped_comparisons_label_every_other_arm(path):
    found = manifest_of(path)
    assert found.given, f"{path.name}: no method in the manifest"
    assert found.violations() == [], f"{path.name}: {found.violations()}"
    # every method's row says where its geometry comes from, in the printed notes too
    assert len(found.notes()) == len(found.given)
    assert all("UNLABELLED" not in line for line in found.notes())


def test_the_unscaled_table_i_under_the_cosserat_arm_is_caught():
    """cbha-ph-ik-cosserat as it was: Table I's tubes (123-297 mm) cannot hold the 360 mm arm."""
    found = manifest_of(PROBLEMS / "cbha-ph-ik-cosserat.yaml", {"arm.params": {}})
    bad = found.violations()
    # every vertebra-model row: the hybrid networks' arm is then the problem's, so nothing labels it
    assert [line.split(":")[0] for line in bad] == ["newton-raphson", "newton-raphson-pose", "hybrid", "hybrid-coupled"]
    assert all("123-297 mm cannot hold the recorded arm's unpressurised 360 mm" in line for line in bad)
    # the PH rows get the recorded arm's tube offsets: nothing to label
    assert found.of("ph-newton").geometry == "measured" and not found.problems(found.of("ph-newton"))


def test_the_scaled_arm_holds_the_recorded_tube_lengths():
    found = manifest_of(PROBLEMS / "cbha-ph-ik-cosserat.yaml")
    newton = found.of("newton-raphson")
    assert newton.arm.tube_range == pytest.approx((0.2214, 0.5346))
    assert mismatch(newton.arm, found.truth, np.array([0.339, 0.492])) == ""
    assert "outside" in mismatch(newton.arm, found.truth, np.array([0.2, 0.339]))
    assert found.of("hybrid").geometry == "another arm" and found.of("hybrid").label


def test_labels_are_required_for_another_arm_and_the_generators_own():
    truth = ArmSize("truth", (0.04, 0.029), None, 0.36)
    same = ArmSize("model", (0.04, 0.029), (0.2, 0.5))
    small = ArmSize("model", (0.04, 0.029), (0.12, 0.3))
    wide = ArmSize("model", (0.05, 0.029), (0.2, 0.5))
    entries = (
        Given("a", "measured", same),
        Given("b", "measured", small),
        Given("c", "measured", wide),
        Given("d", "generator's own"),
        Given("e", "another arm"),
        Given("f", "another arm", small, label="reused networks"),
    )
    found = Manifest(truth, False, entries)
    assert [v.split(":")[0] for v in found.violations()] == ["b", "c", "d", "e"]
    assert "tube offsets 50-29 mm" in found.violations()[1]
    # on a truth the methods share, the generator's own model is fair
    assert [v.split(":")[0] for v in Manifest(truth, True, entries).violations()] == ["b", "c", "e"]
    with pytest.raises(ValueError, match="geometry 'guessed'"):
        Given("g", "guessed")


def test_coverage_distances_and_the_out_of_range_label():
    train = np.array([[0.0, 0.0], [0.001, 0.0], [0.002, 0.0]])  # spaced 1 mm
    test = np.array([[0.001, 0.0005], [0.0, 0.010]])  # 0.5 mm and 10 mm from the nearest
    found = coverage(train, test)
    assert found["test input to nearest training input, median [mm]"] == pytest.approx(5.25)
    assert found["test input to nearest training input, max [mm]"] == pytest.approx(10.0)
    assert found["training inputs' own spacing, 95th percentile [mm]"] == pytest.approx(1.0)
    assert found["test inputs beyond that spacing"] == 0.5 and found["outside training range"]
    manifest = Manifest(ArmSize("truth"), True, (Given("net", "none", training="db"),))
    labelled = manifest.with_coverage("net", found)
    assert labelled.of("net").label and labelled.violations() == []
    assert "tested outside its training range" in labelled.notes()[0]
    assert not coverage(train, train + 1e-5)["outside training range"]
