"""Start-up: a problem imports its own kind and the modules of its presets' backends, not every kind and backend."""

from __future__ import annotations

import json
import subprocess
import pkgutil
import sys

from optikin import problems
from optikin.registry import BACKENDS
from optikin.solvers import BACKEND_MODULES, load_backends

# Run in a fresh interpreter: what an export's context, then a solve's prepare, import; an ik problem whose
# source (targets "cosserat") optikin.data.cosserat_sensors registers, which the statics kind imports; the
# messages of an unknown kind (a module of optikin.problems that registers none) and of an unknown backend.
SCRIPT = """
import json, sys
from pathlib import Path
from optikin.errors import SpecError
from optikin.registry import BACKENDS, PROBLEM_KINDS
from optikin.export.context import context
from optikin.runner import prepare

def imported():
    return {
        "kinds": PROBLEM_KINDS.names(),
        "backends": BACKENDS.names(),
        "modules": sorted(m for m in sys.modules if m.startswith("optikin.solvers.")),
        "heavy": sorted(m for m in ("matplotlib.pyplot", "cvxpy", "sklearn") if m in sys.modules),
    }

out = {}
context("cc-ik-position", None, "--what fk")
out["context"] = imported()
prepare("cc-ik-position")
out["prepare"] = imported()
folder = Path(sys.argv[1])
out["source"] = prepare(str(folder / "source.yaml"))[1].data_source.name
for name in ("kind", "backend"):
    try:
        prepare(str(folder / f"{name}.yaml"))
    except SpecError as exc:
        out[name] = str(exc)
print(json.dumps(out))
"""

PROBLEM = """\
name: {name}
title: a small test problem
{line}arm:
  type: constant_curvature
  params: {{section_lengths: [0.18, 0.18]}}
data:
  source: {source}
  samples: 4
"""


def test_backend_table_is_every_registration():
    """BACKEND_MODULES names each backend that importing every solver module registers, and where."""
    load_backends()
    assert BACKEND_MODULES == {name: BACKENDS.get(name).module for name in BACKENDS.names()}


def test_a_problem_imports_its_own_kind_and_backends_only(tmp_path):
    """An fk export of an ik problem and its solve import the ik kind and the backends of its presets alone (and
    neither matplotlib's pyplot, cvxpy nor scikit-learn); a
    data source another kind's module registers is found; an unknown kind or backend still lists every one."""
    (tmp_path / "kind.yaml").write_text(PROBLEM.format(name="kind", line="kind: ph_shared\n", source="random"))
    (tmp_path / "source.yaml").write_text(PROBLEM.format(name="source", line="kind: ik\n", source="cosserat"))
    (tmp_path / "warp.yaml").write_text("name: warp\nbackend: warp_drive\n")
    line = f"kind: fk\nsolver: {tmp_path}/warp.yaml\n"
    (tmp_path / "backend.yaml").write_text(PROBLEM.format(name="backend", line=line, source="random"))
    run = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True, check=True)
    out = json.loads(run.stdout)
    assert out["context"]["kinds"] == ["ik"]
    assert out["context"]["backends"] == ["gauss_newton"]
    # cc-ik-position: gauss-newton, baselines gauss-newton-compiled, newton, ipopt, sqpmethod, lm, trf
    assert out["prepare"]["kinds"] == ["ik"]
    assert out["prepare"]["backends"] == ["gauss_newton", "ipopt", "lm", "newton", "sqpmethod", "trf"]
    assert out["context"]["heavy"] == out["prepare"]["heavy"] == []  # figures and fits import theirs when used
    for modules in (out["context"]["modules"], out["prepare"]["modules"]):
        assert not any(m.startswith(("optikin.solvers.qp", "optikin.solvers.ph_backends")) for m in modules)
    assert out["source"] == "cosserat"
    kinds = ", ".join(sorted(m.name for m in pkgutil.iter_modules(problems.__path__) if m.ispkg))
    assert "kind.yaml: kind: unknown problem kind 'ph_shared'; " in out["kind"]
    assert out["kind"].endswith(f" known: {kinds}")
    backends = ", ".join(sorted(BACKEND_MODULES))
    assert "warp.yaml: backend: unknown solver backend 'warp_drive'; " in out["backend"]
    assert out["backend"].endswith(f" known: {backends}")


def test_the_command_line_parser_imports_no_subcommand_module():
    """``optikin --help`` imports neither numpy nor the sweep and bench modules; ``optikin sweep`` still has its
    arguments (fresh interpreter)."""
    script = (
        "import sys; from optikin.cli import build_parser; parser = build_parser(); "
        "print(sorted(m for m in ('numpy', 'optikin.sweep.run', 'optikin.bench') if m in sys.modules)); "
        "print(parser.parse_args(['sweep', 'grid', '--jobs', '2']).jobs)"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert run.stdout.split("\n")[:2] == ["[]", "2"]


def test_plot_imports_the_result_kind_only(tmp_path, capsys):
    """``optikin plot`` redraws with the result's own kind alone (fresh interpreter); an unknown kind exits 2."""
    from optikin.cli import EXIT_BAD_INPUT, main

    out = tmp_path / "out"
    assert main(["solve", "cc-two-section-fk", "--set", "data.samples=4", "--out", str(out), "-q"]) == 0
    folder = out / "cc-two-section-fk"
    script = (
        "import sys; from optikin.cli import main; from optikin.registry import PROBLEM_KINDS; "
        f"code = main(['plot', {str(folder)!r}]); print(code, PROBLEM_KINDS.names())"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert run.stdout.splitlines()[-1] == "0 ['fk']"
    summary = json.loads((folder / "result.json").read_text())
    (folder / "result.json").write_text(json.dumps({**summary, "kind": "teleport"}))
    capsys.readouterr()
    assert main(["plot", str(folder)]) == EXIT_BAD_INPUT
    assert "result.json: kind: unknown problem kind 'teleport'" in capsys.readouterr().err


def test_the_network_kinds_import_scikit_learn_only_to_train():
    """The nn and ph_ik kinds, and a stored model's metadata, need no scikit-learn import (fresh interpreter)."""
    script = (
        "import sys; import optikin.problems.nn_fkm, optikin.problems.nn_ikm, optikin.problems.ph_ik; "
        "import optikin.baselines.nn_store; print('sklearn' in sys.modules)"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "False"
