"""The contracts every layer keeps: typed options everywhere, errors naming file and dotted field,
exit codes with one meaning, figures redrawn from a written result, the caller's matplotlib backend kept."""

from __future__ import annotations

import subprocess
import sys
from typing import Any, Sequence

import pytest
import yaml

from optikin.cli import EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED, main
from optikin.data.sources import DATA_SOURCES
from optikin.errors import SpecError
from optikin.problems import load_kinds
from optikin.registry import BACKENDS, PROBLEM_KINDS
from optikin.runner import prepare, solve
from optikin.solvers import load_backends, load_preset
from optikin.spec import available, load_problem
from tests.conftest import write_variant

load_kinds()
load_backends()
TYPO = "not_a_field_of_anything"


def shipped_problem_of(kind: str) -> str:
    """The first shipped problem of ``kind``."""
    for name in sorted(available("problems")):
        if load_problem(name)[0].kind == kind:
            return name
    raise LookupError(kind)


def field_of_error(problem: str, overrides: Sequence[tuple[str, Any]]) -> str:
    with pytest.raises(SpecError) as err:
        prepare(problem, overrides=overrides)
    assert "unknown field" in str(err.value)
    return err.value.field


KINDS = PROBLEM_KINDS.names()
SOURCES = [(family, name) for family, registry in sorted(DATA_SOURCES.items()) for name in registry.names()]


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_declares_typed_options_and_figures(kind):
    declared = PROBLEM_KINDS.get(kind)
    assert declared.options is not None, f"kind {kind} checks its options by hand"
    assert declared.figures is not None, f"kind {kind} draws no figures from its arrays"


@pytest.mark.parametrize("backend", BACKENDS.names())
def test_every_backend_declares_typed_options(backend):
    assert BACKENDS.get(backend).options is not None, f"backend {backend} checks its options by hand"


@pytest.mark.parametrize("kind", KINDS)
def test_option_typo_names_file_and_dotted_field(kind, tmp_path, capsys):
    problem = shipped_problem_of(kind)
    assert field_of_error(problem, [(f"options.{TYPO}", 1)]) == f"options.{TYPO}"
    assert main(["solve", problem, "--set", f"options.{TYPO}=1", "--out", str(tmp_path / "out")]) == EXIT_BAD_INPUT
    message = capsys.readouterr().err
    assert str(load_problem(problem)[1]) in message and f"options.{TYPO}" in message
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("family,source", SOURCES)
def test_data_param_typo_names_the_dotted_field(family, source):
    kinds = [k for k in KINDS if PROBLEM_KINDS.get(k).data_family == family]
    assert kinds, f"no kind reads data family {family}"
    overrides = [("data.source", source), ("data.params", {TYPO: 1})]
    assert field_of_error(shipped_problem_of(kinds[0]), overrides) == f"data.params.{TYPO}"


@pytest.mark.parametrize("backend", BACKENDS.names())
def test_preset_option_typo_names_file_and_dotted_field(backend, tmp_path):
    preset = tmp_path / "solvers" / "typo.yaml"
    preset.parent.mkdir()
    preset.write_text(yaml.safe_dump({"name": "typo", "backend": backend, "options": {TYPO: 1}}))
    with pytest.raises(SpecError) as err:
        load_preset(str(preset))
    assert err.value.field == f"options.{TYPO}" and err.value.path == str(preset)


def test_unknown_data_source_lists_the_family():
    kind = next(k for k in KINDS if PROBLEM_KINDS.get(k).data_family)
    with pytest.raises(SpecError) as err:
        prepare(shipped_problem_of(kind), overrides=[("data.source", "nope")])
    known = DATA_SOURCES[PROBLEM_KINDS.get(kind).data_family].names()
    assert err.value.field == "data.source" and all(name in str(err.value) for name in known)


def test_unknown_output_array_is_named(tmp_path):
    overrides = [("data.samples", 4), ("outputs", {"arrays": ["tip_dq", "nope"]})]
    with pytest.raises(SpecError) as err:
        solve("cc-two-section-fk", out=tmp_path / "out", overrides=overrides)
    assert err.value.field == "outputs.arrays.1" and "tip_dq" not in str(err.value).split("known:")[0]
    assert not (tmp_path / "out").exists()


def test_plot_redraws_a_written_result(tmp_path, capsys):
    _, folder = solve("cc-two-section-fk", out=tmp_path / "out", overrides=[("data.samples", 8)])
    drawn = sorted(p.name for p in folder.glob("*.png"))
    assert drawn
    for png in folder.glob("*.png"):
        png.unlink()
    assert main(["plot", str(folder)]) == 0
    assert sorted(p.name for p in folder.glob("*.png")) == drawn
    assert all(p.stat().st_size > 1000 for p in folder.glob("*.png"))


def test_importing_the_package_keeps_the_callers_matplotlib_backend():
    code = (
        "import matplotlib; matplotlib.use('svg'); import optikin.problems; "
        "from optikin.problems import load_kinds; load_kinds(); print(matplotlib.get_backend())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "svg"


@pytest.mark.parametrize(
    "text,message",
    [
        ("a: 1\na: 2\n", "duplicate key 'a' (first on line 1)"),
        ("a: &x [1, 2]\nb: *x\n", "aliases (*x) are not accepted"),
        ("a: " + "[" * 2000 + "]" * 2000 + "\n", "nested too deeply"),
    ],
)
def test_yaml_that_cannot_be_trusted_is_refused(tmp_path, text, message, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert main(["show", str(path)]) == EXIT_BAD_INPUT
    assert message in capsys.readouterr().err


def test_binary_and_huge_files_are_refused(tmp_path, capsys):
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\xff\xfe\x00name: x")
    assert main(["show", str(binary)]) == EXIT_BAD_INPUT
    assert "not UTF-8" in capsys.readouterr().err
    huge = tmp_path / "huge.yaml"
    huge.write_text("a: [" + "1, " * 600_000 + "1]\n")
    assert main(["show", str(huge)]) == EXIT_BAD_INPUT
    assert "larger than" in capsys.readouterr().err


def test_negative_seed_is_a_field_error():
    with pytest.raises(SpecError) as err:
        prepare("cc-two-section-fk", overrides=[("data.seed", -5)])
    assert err.value.field == "data.seed"


def test_a_shadowing_preset_is_announced(tmp_path, monkeypatch, capsys):
    _, shipped = load_problem("cc-two-section-fk")
    (tmp_path / "solvers").mkdir()
    preset = (shipped.parent.parent / "solvers" / "casadi-map.yaml").read_text()
    (tmp_path / "solvers" / "casadi-map.yaml").write_text(preset)
    (tmp_path / "problems").mkdir()
    problem = write_variant(tmp_path / "problems", "cc-two-section-fk", lambda d: d["data"].update(samples=4))
    monkeypatch.chdir(tmp_path)
    assert main(["solve", "cc-two-section-fk", "--out", str(tmp_path / "out"), "--no-figures", "--json"]) == 0
    err = capsys.readouterr().err
    assert f"using solver file {tmp_path / 'solvers' / 'casadi-map.yaml'} (shadows the shipped solver" in err
    assert f"using problem file {problem} (shadows the shipped problem 'cc-two-section-fk')" in err
    assert (
        main(
            [
                "solve",
                str(problem),
                "--out",
                str(tmp_path / "out"),
                "--no-figures",
                "--json",
                "--solver",
                str(shipped.parent.parent / "solvers" / "casadi-map.yaml"),
            ]
        )
        == 0
    )
    assert "using" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "raised,code,words",
    [
        (RuntimeError("boom"), EXIT_INTERNAL, "internal error: RuntimeError: boom; run with --debug"),
        (KeyboardInterrupt(), EXIT_INTERRUPTED, "interrupted"),
    ],
)
def test_exit_codes_have_one_meaning(monkeypatch, capsys, raised, code, words):
    import optikin.runner

    def fail(*args, **kwargs):
        raise raised

    monkeypatch.setattr(optikin.runner, "solve", fail)
    assert main(["solve", "cc-two-section-fk"]) == code
    assert words in capsys.readouterr().err


def test_empty_out_is_refused(capsys):
    assert main(["solve", "cc-two-section-fk", "--out", ""]) == EXIT_BAD_INPUT
    assert "--out" in capsys.readouterr().err
