"""The wheel works on its own: built from the checkout, installed outside it, run from an unrelated folder.

The wheel is installed with ``pip install --no-deps --target`` and put first on ``PYTHONPATH``, so
the interpreter of the test environment supplies the dependencies while optikin itself comes from
the wheel alone (the test checks that it does).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("wheel")
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(work / "dist"), str(ROOT)],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    (wheel,) = (work / "dist").glob("optikin-*.whl")
    target = work / "site"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
        capture_output=True,
        text=True,
    )
    assert install.returncode == 0, install.stderr
    return target


def run(site: Path, folder: Path, *args: str) -> subprocess.CompletedProcess:
    env = os.environ | {"PYTHONPATH": str(site), "MPLBACKEND": "Agg"}
    env.pop("OPTIKIN_PATH", None)
    code = "import sys; from optikin.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", code, *args], cwd=folder, env=env, capture_output=True, text=True)


def test_the_wheel_carries_the_catalog_licence_and_types(installed):
    package = installed / "optikin"
    assert (package / "catalog" / "problems" / "cc-two-section-fk.yaml").is_file()
    assert (package / "catalog" / "solvers" / "casadi-map.yaml").is_file()
    assert (package / "catalog" / "sweeps" / "ph-noise.yaml").is_file()
    assert (package / "catalog" / "examples" / "track-my-demo.yaml").is_file()
    assert (package / "catalog" / "examples" / "data" / "demo-pose.csv").is_file()
    assert (package / "export" / "templates" / "ik.c").is_file()
    assert (package / "py.typed").is_file()
    (info,) = installed.glob("optikin-*.dist-info")
    assert "BSD 3-Clause" in (info / "licenses" / "LICENSE").read_text()
    shipped = {p.relative_to(ROOT / "problems") for p in (ROOT / "problems").rglob("*") if p.is_file()}
    catalog = package / "catalog" / "problems"
    assert {p.relative_to(catalog) for p in catalog.rglob("*") if p.is_file()} == shipped


def test_an_installed_wheel_lists_and_solves_from_an_unrelated_folder(installed, tmp_path):
    where = run(installed, tmp_path, "--version")
    assert where.returncode == 0 and where.stdout.startswith("optikin "), where.stderr
    listed = run(installed, tmp_path, "list")
    assert listed.returncode == 0, listed.stderr
    assert all(name in listed.stdout for name in ("cc-two-section-fk", "cc-ik-pose", "track-dmp"))
    solved = run(installed, tmp_path, "solve", "cc-two-section-fk", "--out", "out", "--no-figures", "--json")
    assert solved.returncode == 0, solved.stderr
    assert json.loads(solved.stdout)["problem"] == "cc-two-section-fk"
    assert (tmp_path / "out" / "cc-two-section-fk" / "result.json").is_file()
    origin = run(installed, tmp_path, "show", "--solver", "casadi-map")
    assert origin.returncode == 0, origin.stderr
    example = installed / "optikin" / "catalog" / "examples" / "dmp-my-demo.yaml"
    learned = run(installed, tmp_path, "solve", str(example), "--out", "out", "--no-figures", "--json")
    assert learned.returncode == 0, learned.stderr


def test_the_installed_package_is_the_wheel_not_the_checkout(installed, tmp_path):
    env = os.environ | {"PYTHONPATH": str(installed)}
    out = subprocess.run(
        [sys.executable, "-c", "import optikin, optikin.spec as s; print(optikin.__file__, s.shipped_dir('problems'))"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    module, problems = out.stdout.split()
    assert Path(module).is_relative_to(installed) and Path(problems).is_relative_to(installed)


def test_optikin_examples_copies_them_out_of_the_wheel_and_they_solve_there(installed, tmp_path):
    copied = run(installed, tmp_path, "examples", "mine")
    assert copied.returncode == 0, copied.stderr
    assert "optikin solve mine/track-my-demo.yaml" in copied.stdout
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for problem in ("dmp-my-demo.yaml", "track-my-demo.yaml"):
        solved = run(installed, elsewhere, "solve", str(tmp_path / "mine" / problem), "--out", "out", "--no-figures")
        assert solved.returncode == 0, solved.stderr
    again = run(installed, tmp_path, "examples", "mine")
    assert again.returncode == 2 and "already exists" in again.stderr
