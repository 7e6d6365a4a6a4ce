"""``optikin export``: the C library built with the system compiler against the Python path (CasADi's VM).

The C iteration (LU in C, CasADi-generated residual, Jacobian and Hessian) is compared with
:class:`optikin.solvers.gauss_newton.GaussNewton` (CasADi's symbolic QR inside one step
Function): statuses equal target by target, solved configurations within 1e-10.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from optikin.cli import main
from optikin.export import Export, build, export, ik_setup

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler cc on PATH")

STATUS = {0: "ok", 1: "unreachable", 2: "not_converged", 3: "invalid_input", 4: "failed"}


def run_example(exported: Export, rows: np.ndarray, tmp: Path) -> np.ndarray:
    """Build the example and run it on ``rows`` (one input per line); its printed lines as an array."""
    executable = build(exported)
    data = tmp / "inputs.txt"
    np.savetxt(data, np.atleast_2d(rows), fmt="%.17g")
    run = subprocess.run([str(executable), str(data)], capture_output=True, text=True, timeout=60, check=True)
    assert "per_call_us" in run.stderr
    return run.stdout


def numeric(stdout: str) -> np.ndarray:
    return np.array([[float(v) for v in line.split()] for line in stdout.splitlines()])


@pytest.fixture(scope="module")
def unreachable_setup():
    return ik_setup("cc-ik-unreachable")


def test_ik_step_agrees_with_gauss_newton_on_cc_ik_position(tmp_path):
    setup = ik_setup("cc-ik-position")
    P = setup.targets[:40]
    out = numeric(run_example(export("cc-ik-position", "ik-step", tmp_path), P, tmp_path))
    for row, p in zip(out, P):
        solution = setup.adapter.solve(setup.problem, setup.start, p)
        assert STATUS[int(row[0])] == solution.status
        if solution.status == "ok":
            np.testing.assert_allclose(row[3:], solution.x, rtol=0, atol=1e-10)
            assert row[2] <= setup.problem.tolerance
    assert (out[:, 0] == 0).sum() >= 35


def test_unreachable_targets_get_the_same_status_and_residual(tmp_path, unreachable_setup):
    """Targets beyond the reach bound end ``unreachable`` in C as in Python, at the same distance. The
    closest configuration of a redundant arm is not isolated, so it is compared more loosely."""
    setup = unreachable_setup
    outside = np.flatnonzero(np.linalg.norm(setup.targets, axis=1) > 0.396)[:8]
    inside = np.arange(8)
    P = setup.targets[np.concatenate([inside, outside])]
    out = numeric(run_example(export("cc-ik-unreachable", "ik-step", tmp_path), P, tmp_path))
    statuses = []
    for row, p in zip(out, P):
        solution = setup.adapter.solve(setup.problem, setup.start, p)
        statuses.append(solution.status)
        assert STATUS[int(row[0])] == solution.status
        assert abs(row[2] - solution.residual) <= 1e-10
        np.testing.assert_allclose(row[3:], solution.x, rtol=0, atol=1e-10 if solution.status == "ok" else 1e-6)
    assert statuses[8:] == ["unreachable"] * 8
    # independent of both solvers: the distance of a target beyond reach is at least |p| - reach
    reach = 0.396
    assert np.all(out[8:, 2] >= np.linalg.norm(P[8:], axis=1) - reach - 1e-12)


def test_trajectory_agrees_with_warm_started_gauss_newton(tmp_path):
    setup = ik_setup("cc-ik-trajectory")
    P = setup.targets[:200]
    out = numeric(run_example(export("cc-ik-trajectory", "ik-trajectory", tmp_path), P, tmp_path))
    batch = setup.adapter.solve_many(setup.problem, setup.start, P, warm_start=True)
    assert [STATUS[int(s)] for s in out[:, 0]] == list(batch.status)
    assert list(out[:, 1].astype(int)) == list(batch.iterations)
    np.testing.assert_allclose(out[:, 3:], batch.x, rtol=0, atol=1e-10)


def test_the_example_times_a_given_number_of_rounds(tmp_path):
    """``./example targets.txt ROUNDS``: the timing loop runs ROUNDS times (0: none, nothing timed)."""
    setup = ik_setup("cc-ik-trajectory")
    executable = build(export("cc-ik-trajectory", "ik-trajectory", tmp_path))
    data = tmp_path / "targets.txt"
    np.savetxt(data, setup.targets[:5], fmt="%.17g")
    for rounds, timed in (("0", False), ("2", True)):
        run = subprocess.run([str(executable), str(data), rounds], capture_output=True, text=True, check=True)
        assert len(run.stdout.splitlines()) == 5
        times = dict(line.split() for line in run.stderr.splitlines())
        assert set(times) == ({"per_call_us", "cpu_us"} if timed else set())


def test_invalid_input_is_a_status(tmp_path, unreachable_setup):
    P = unreachable_setup.targets[:2].copy()
    P[1, 1] = np.nan
    out = numeric(run_example(export("cc-ik-unreachable", "ik-step", tmp_path), P, tmp_path))
    assert STATUS[int(out[0, 0])] == "ok" and STATUS[int(out[1, 0])] == "invalid_input"


def test_fk_agrees_with_the_arm_functions(tmp_path):
    from optikin.runner import prepare

    _, ctx = prepare("cc-ik-position")
    arm = ctx.arm
    Q = arm.sample_configurations(5, np.random.default_rng(3))
    lines = run_example(export("cc-ik-position", "fk", tmp_path), Q, tmp_path).splitlines()
    assert len(lines) == 3 * len(Q)
    for k, q in enumerate(Q):
        for j, name in enumerate(("fk_dq", "fk_position", "backbone")):
            label, status, *values = lines[3 * k + j].split()
            assert label == name and status == "0"
            expected = np.asarray(getattr(arm, name)(q)).ravel(order="F")
            np.testing.assert_allclose(np.array(values, dtype=float), expected, rtol=0, atol=1e-14)
        # independent of CasADi: the tip of the backbone is the tip position
        np.testing.assert_allclose(
            np.array(lines[3 * k + 2].split()[-3:], dtype=float), arm.fk_position(q).full().ravel()
        )


@pytest.mark.parametrize(
    "problem, what",
    [
        ("cc-ik-position", "ik-step"),
        ("cc-ik-position", "fk"),
        ("cbha-ph-shape", "ph-shape"),
        ("track-nominal", "qp-step"),
    ],
)
def test_the_library_allocates_nothing_and_needs_only_libm(tmp_path, problem, what):
    exported = export(problem, what, tmp_path)
    for path in (exported.source, exported.header):
        text = path.read_text()
        assert not re.search(r"\b(malloc|calloc|realloc|free|alloca)\s*\(", text), path.name
        includes = set(re.findall(r"#include\s*([<\"][^>\"]+[>\"])", text))
        assert includes <= {"<math.h>", f'"{exported.stem}.h"'}, includes


def test_build_refuses_flags_outside_the_allow_list(tmp_path):
    exported = export("cc-ik-position", "fk", tmp_path)
    with pytest.raises(ValueError, match="not allowed"):
        build(exported, flags=("-O2", "-wrapper"))


def test_the_export_subcommand_writes_the_files(tmp_path, capsys):
    assert main(["export", "cc-ik-position", "--what", "ik-step", "--out", str(tmp_path)]) == 0
    written = capsys.readouterr().out.split()
    assert {Path(p).name for p in written} == {
        "optikin_ik_step.c",
        "optikin_ik_step.h",
        "main.c",
        "Makefile",
        "CMakeLists.txt",
        "README.md",
        "targets.txt",
    }
    assert main(["export", "cbha-fk", "--what", "ik-step", "--out", str(tmp_path / "x")]) == 2


@pytest.mark.parametrize("problem, what", [("cbha-ph-shape", "ph-shape"), ("track-nominal", "qp-step")])
def test_the_subcommand_exports_ph_shape_and_qp_step_and_refuses_other_kinds(tmp_path, problem, what):
    assert main(["export", problem, "--what", what, "--out", str(tmp_path)]) == 0
    assert (tmp_path / "CMakeLists.txt").exists()
    assert main(["export", "cc-ik-position", "--what", what, "--out", str(tmp_path / "x")]) == 2


@pytest.mark.skipif(shutil.which("make") is None or shutil.which("nm") is None, reason="needs make and nm")
def test_the_makefile_builds_a_library_that_needs_only_libm(tmp_path):
    exported = export("cc-ik-position", "ik-step", tmp_path)
    subprocess.run(["make", "-s", "CC=cc"], cwd=tmp_path, check=True, capture_output=True, timeout=120)
    assert (tmp_path / "example").exists()
    symbols = subprocess.run(["nm", "-u", f"{exported.stem}.o"], cwd=tmp_path, capture_output=True, text=True)
    names = {line.split()[-1] for line in symbols.stdout.splitlines() if line.strip()}
    undefined = {name for name in names if not name.startswith("_")}  # leaving out the compiler's runtime
    libm = {
        "sin",
        "cos",
        "sincos",
        "tan",
        "sqrt",
        "fmin",
        "fmax",
        "fmod",
        "floor",
        "fabs",
        "atan2",
        "exp",
        "log",
        "pow",
    }
    assert undefined <= libm, undefined - libm


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
@pytest.mark.parametrize("problem, what", [("cc-ik-position", "fk"), ("track-nominal", "qp-step")])
def test_cmake_builds_the_library_and_the_example(tmp_path, problem, what):
    """CMakeLists.txt beside the Makefile: the example it builds prints what the Makefile's does."""
    exported = export(problem, what, tmp_path)
    build_dir = tmp_path / "build"
    for command in (["cmake", "-S", str(tmp_path), "-B", str(build_dir)], ["cmake", "--build", str(build_dir)]):
        subprocess.run(command, check=True, capture_output=True, timeout=300)
    assert (build_dir / f"lib{exported.stem}.a").exists()
    ours = subprocess.run([str(build_dir / "example")], capture_output=True, text=True, timeout=60, check=True)
    theirs = subprocess.run([str(build(exported))], capture_output=True, text=True, timeout=60, check=True)
    words, expected = ours.stdout.split(), theirs.stdout.split()
    assert len(words) == len(expected) > 0
    for word, other in zip(words, expected):
        assert word == other or abs(float(word) - float(other)) <= 1e-12


def test_point_targets_with_fixed_lengths_agree_with_gauss_newton(tmp_path):
    """cc-ik-points: inextensible sections (lengths fixed, not solved for, returned at their value)."""
    setup = ik_setup("cc-ik-points")
    P = setup.targets[:15]
    out = numeric(run_example(export("cc-ik-points", "ik-step", tmp_path), P, tmp_path))
    fixed = setup.problem.fixed
    assert fixed.any()
    for row, p in zip(out, P):
        solution = setup.adapter.solve(setup.problem, setup.start, p)
        assert STATUS[int(row[0])] == solution.status == "ok"
        np.testing.assert_array_equal(row[3:][fixed], setup.problem.lower[fixed])
        np.testing.assert_allclose(row[3:], solution.x, rtol=0, atol=1e-10)


def test_pose_targets_reach_the_pose(tmp_path):
    """cc-ik-pose: the pose Jacobian of a two-section CC arm has rank 5, so the configuration along its
    null direction is set by rounding (the Python path itself moves by ~1e-3 when the start changes by
    1e-15): statuses are compared, and the pose reached against the target."""
    from optikin.runner import prepare

    setup = ik_setup("cc-ik-pose")
    P = setup.targets[:10]
    out = numeric(run_example(export("cc-ik-pose", "ik-step", tmp_path), P, tmp_path))
    arm = prepare("cc-ik-pose")[1].arm
    assert (out[:, 0] == 0).sum() >= 8
    for row, p in zip(out, P):
        solution = setup.adapter.solve(setup.problem, setup.start, p)
        assert STATUS[int(row[0])] == solution.status
        if solution.status == "ok":
            dq = np.asarray(arm.fk_dq(row[3:])).ravel()
            assert min(np.abs(dq - p).max(), np.abs(dq + p).max()) < 1e-9
