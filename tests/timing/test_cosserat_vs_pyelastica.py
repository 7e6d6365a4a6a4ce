"""One Cosserat-rod equilibrium: PyElastica's damped relaxation against optikin's compiled shooting (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts, and without pyelastica); run with

    OPENBLAS_NUM_THREADS=1 pytest -o addopts="" tests/timing/test_cosserat_vs_pyelastica.py --benchmark-only

Case ``tip_force_small`` of tests/data/pyelastica (0.3 m rod, r = 10 mm, E = 1 MPa,
G = E/3, rho = 1000 kg/m^3, dead tip force 0.01 N along +x, no gravity), in one process:

* PyElastica (Gazzola et al., R. Soc. open sci. 5:171628, 2018) relaxing 50 elements to
  rest with ``relax`` of tools/pyelastica_reference.py (PositionVerlet, the script's time
  step, damping, load ramp and stop test), numba compiled beforehand;
* optikin's compiled shooting (RK4 on the same 51 nodes, Newton on the base wrench)
  from zero load (``cold``: the load ramped from the straight rod) and from the
  equilibrium of a tip force 5 % larger (``warm``).

``extra_info`` holds the median wall and thread-CPU seconds per equilibrium, optikin's
speed-up over PyElastica's medians of the same run (wall and thread CPU), and the
largest node distance [mm] of each shape from the reference file's
``continuum_positions`` (the linear-law continuum solution at the same arc lengths).
optikin's shear stiffness is ``G A``; the continuum field uses PyElastica's
``(27/28) G A``, which moves this tip by about 1 um.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from optikin.errors import SolverError
from optikin.physics import Loads, Rod, RodArm, ShootingOptions, ShootingSolver

ROOT = Path(__file__).resolve().parents[2]
CASE = "tip_force_small"
ELEMENTS = 50
ROUNDS, WARMUP = 200, 5
"""Rounds of each optikin solve, and untimed rounds before them."""
NEARBY = 1.05
"""The warm start is the equilibrium of the tip force times this factor."""

_pyelastica: dict[str, float] = {}
"""PyElastica's medians of this run [s], for the speed-ups."""


@pytest.fixture(scope="module")
def reference() -> dict[str, Any]:
    path = ROOT / "tests" / "data" / "pyelastica" / f"{CASE}_n{ELEMENTS}.npz"
    if not path.exists():
        pytest.skip(f"{path.name} not shipped")
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def script() -> Any:
    pytest.importorskip("elastica")
    spec = importlib.util.spec_from_file_location("pyelastica_reference", ROOT / "tools" / "pyelastica_reference.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def solver(reference) -> ShootingSolver:
    rod = Rod(
        length=float(reference["length"]),
        radius=float(reference["radius"]),
        youngs_modulus=float(reference["youngs_modulus"]),
        shear_modulus=float(reference["shear_modulus"]),
        density=float(reference["density"]),
        gravity=(0.0, 0.0, 0.0),
    )
    try:
        return ShootingSolver(RodArm.single(rod), ShootingOptions(steps_per_segment=ELEMENTS, compiled=True))
    except SolverError as exc:
        pytest.skip(str(exc))


def _distance_mm(positions: np.ndarray, reference: dict[str, Any]) -> float:
    """Largest node distance [mm] from the reference's continuum solution."""
    return float(np.linalg.norm(positions - reference["continuum_positions"], axis=1).max() * 1e3)


def _timed(fn, walls: list[float], cpus: list[float]):
    """``fn`` wrapped to append its wall and thread-CPU seconds to ``walls`` and ``cpus``."""

    def run():
        wall, cpu = time.perf_counter(), time.thread_time()
        out = fn()
        cpus.append(time.thread_time() - cpu)
        walls.append(time.perf_counter() - wall)
        return out

    return run


def test_pyelastica_relaxation(benchmark, reference, script):
    case = script.CASES[CASE]
    dt = script.time_step(ELEMENTS)
    assert np.isclose(dt, float(reference["dt"]))
    script.relax(case, ELEMENTS, dt, n_steps=10)  # numba compiles (or loads its cache) outside the timing
    walls: list[float] = []
    cpus: list[float] = []
    results: list[dict[str, Any]] = []
    benchmark.group = f"one equilibrium of {CASE}, {ELEMENTS} elements"
    benchmark.pedantic(
        _timed(lambda: results.append(script.relax(case, ELEMENTS, dt)), walls, cpus),
        rounds=3,
        warmup_rounds=0,
        iterations=1,
    )
    _pyelastica.update(wall=float(np.median(walls)), cpu=float(np.median(cpus)))
    last = results[-1]
    benchmark.extra_info.update(
        {
            "median wall per equilibrium [s]": round(_pyelastica["wall"], 3),
            "median thread CPU per equilibrium [s]": round(_pyelastica["cpu"], 3),
            "median relaxation loop only, wall / process CPU [s]": (
                round(float(np.median([r["wall_time"] for r in results])), 3),
                round(float(np.median([r["cpu_time"] for r in results])), 3),
            ),
            "steps": int(last["steps"]),
            "max distance from continuum [mm]": round(_distance_mm(last["positions"], reference), 4),
            "max distance from shipped file [mm]": float(
                np.linalg.norm(last["positions"] - reference["positions"], axis=1).max() * 1e3
            ),
        }
    )
    assert int(last["steps"]) == int(reference["steps"])
    assert np.abs(last["positions"] - reference["positions"]).max() < 1e-6


@pytest.mark.parametrize("start", ["cold", "warm"])
def test_optikin_compiled_shooting(benchmark, reference, solver, start):
    force = tuple(float(f) for f in reference["tip_force"])
    target = Loads(tip_force=force)
    nearby = Loads(tip_force=tuple(NEARBY * f for f in force))
    guess = solver.solve(nearby).base_wrench
    solver.solve(target)  # the first calls of the compiled Functions outside the timing

    def setup():
        if start == "warm":  # the solver as it is after the nearby equilibrium (its Newton Jacobian kept)
            solver.solve(nearby, guess)

    walls: list[float] = []
    cpus: list[float] = []
    solutions = []
    solve = _timed(lambda: solutions.append(solver.solve(target, guess if start == "warm" else None)), walls, cpus)
    benchmark.group = f"one equilibrium of {CASE}, {ELEMENTS} elements"
    benchmark.pedantic(solve, setup=setup, rounds=ROUNDS, warmup_rounds=WARMUP, iterations=1)
    wall, cpu = float(np.median(walls[-ROUNDS:])), float(np.median(cpus[-ROUNDS:]))
    last = solutions[-1]
    benchmark.extra_info.update(
        {
            "median wall per equilibrium [ms]": round(wall * 1e3, 4),
            "median thread CPU per equilibrium [ms]": round(cpu * 1e3, 4),
            "Newton iterations": last.iterations,
            "max distance from continuum [mm]": round(_distance_mm(last.positions, reference), 4),
            "max distance from PyElastica's shipped shape [mm]": round(
                float(np.linalg.norm(last.positions - reference["positions"], axis=1).max() * 1e3), 4
            ),
        }
    )
    if _pyelastica:
        benchmark.extra_info["speed-up vs PyElastica, wall (median)"] = round(_pyelastica["wall"] / wall, 1)
        benchmark.extra_info["speed-up vs PyElastica, thread CPU (median)"] = round(_pyelastica["cpu"] / cpu, 1)
    assert all(s.ok for s in solutions)
    assert _distance_mm(last.positions, reference) < 0.01
