"""The README and the example's input file of every ``optikin export --what``.

The input file holds the samples compiled into ``main.c``, so the example run on it prints what it
prints without an argument; the README names the file and the commands that build and run it.
"""

from __future__ import annotations

import shutil
import subprocess

import pytest

from optikin.export import INPUT_FILES, build, export

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler cc on PATH")

CASES = [
    ("cc-ik-position", "fk"),
    ("cc-ik-position", "ik-step"),
    ("cc-ik-trajectory", "ik-trajectory"),
    ("cbha-ph-shape", "ph-shape"),
    ("track-nominal", "qp-step"),
]


@pytest.mark.parametrize("problem, what", CASES, ids=[what for _, what in CASES])
def test_the_example_reads_its_input_file_as_the_readme_says(tmp_path, problem, what):
    exported = export(problem, what, tmp_path, samples=5)
    name = INPUT_FILES[what]
    readme = (tmp_path / "README.md").read_text()
    for text in (f"./example {name}", f"./build/example {name}", "make", "cmake -S . -B build", problem):
        assert text in readme, text
    lines = (tmp_path / name).read_text().splitlines()
    assert len(lines) == len(exported.samples) == 5
    assert {p.name for p in exported.files} >= {"README.md", name}
    executable = build(exported)
    compiled_in = subprocess.run([str(executable)], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    from_file = subprocess.run([str(executable), name], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert compiled_in.returncode == from_file.returncode == 0, from_file.stderr
    printed = from_file.stdout.splitlines()
    assert printed == compiled_in.stdout.splitlines()
    assert len(printed) == 5 * (3 if what == "fk" else 1)


def test_a_shortened_input_file_runs_fewer_samples(tmp_path):
    """The example reads the file, not its compiled-in samples: two lines give two answers."""
    exported = export("cc-ik-position", "ik-step", tmp_path, samples=5)
    data = tmp_path / "targets.txt"
    data.write_text("".join(data.read_text().splitlines(keepends=True)[:2]))
    run = subprocess.run([str(build(exported)), "targets.txt", "0"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0 and len(run.stdout.splitlines()) == 2
