"""Time per sample of minimum-energy PH shape reconstruction along a 100-posture trajectory (pytest-benchmark).

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_ph_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,max,rounds

The data: the recording of ``problems/cbha-ph-shape.yaml`` (100 postures of the CBHA
vertebra model driven by its tubes, end poses from motion-capture rigid bodies with
0.3 mm marker noise, the base pose averaged), end speeds set to the arc-length
estimate of the end poses (the seed's setting; group "given speeds") or left free
with the model's backbone length held (group "free speeds"). Each benchmarked path
solves the samples in trajectory order, one round per sample (the first sample of a
pass is a cold start, every later one is warm-started from the previous solution
where the method warm-starts), after one untimed pass that builds and compiles; the
median is the time per sample. ``extra_info``: the largest energy gap to a cold,
three-start IPOPT reference solved once per sample, the number of samples whose
relative gap exceeds 1e-6, and the speed-up over the grid (given speeds). The
compiled Newton paths take about 8 s (given speeds) and 25-60 s (free speeds) to
compile the first time; the libraries are cached on disk afterwards.

``ph-ik`` adds the tube lengths (one call of the compiled tube-length Function) to
the compiled given-speed Newton: the time per sample of the PH inverse kinematics
of seed 002 Table III (0.27 ms there). ``newton-raphson`` is that table's comparator
(233 ms there) as ``cbha-ph-ik`` runs it
(:func:`optikin.baselines.ph_comparators.newton_raphson_tube_lengths`):
per posture, Newton on the 48 x 48 system of the section ends and the affine elongation
distribution, started from the last posture it solved (the first of a pass from the
straight configuration), plus the tube lengths of the solution, on the same 100 postures
in the same run (given-speed group); ``extra_info`` has the postures not ok, the mean
tube-length error against the recording's and the ratio of its median to ``ph-ik``'s.
``compiled-basin-check`` also runs Newton from the best coarse-grid point on every
warm-started sample and keeps the lower minimum (``basin_check``), against the worse
branch a warm start can follow with free speeds.
The grid of the free-speed group is 24 x 24 angles x 5 speed ratios (the 64 x 64 x 9
of ``ph-grid`` costs about 3 s per sample there).
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.arms.cbha import CBHAArm
from optikin.curves import EnergySettings, ShapeEnergyModel
from optikin.curves.tubes import TubeLayout
from optikin.fastcall import BufferedFunction
from optikin.problems.ph_shared import backbone_lengths, end_data, recording_of
from optikin.ik.formulation import rest_configuration
from optikin.baselines.ph_comparators import (
    NR_PRESET,
    newton_raphson_problem,
    newton_raphson_step,
    relative_section_ends,
    section_end_markers,
)
from optikin.problems.ph_ik import tube_length_function
from optikin.solvers import build_preset

GROUPS = {
    False: "PH shape, 100-posture CBHA trajectory, given speeds (seed setting): time per sample",
    True: "PH shape, 100-posture CBHA trajectory, free speeds, length held: time per sample",
}
_grid_median: dict[bool, float] = {}
_ph_ik_median: list[float] = []


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


@pytest.fixture(scope="module")
def recording():
    return recording_of("cbha-ph-shape").with_fixed_base()


@pytest.fixture(scope="module", params=[False, True], ids=["given-speeds", "free-speeds"])
def case(request, recording):
    free = request.param
    lengths = backbone_lengths(recording, "model" if free else "arc", "timing")
    samples = end_data(recording, lengths, "timing")
    reference = ShapeEnergyModel(EnergySettings(), free_speeds=free)
    energies = np.array([reference.solve_nlp(d, starts=3).energy for d in samples])
    return free, samples, energies, recording.base_normal


def _bench(benchmark, case, name, solve_one, warm=True):
    free, samples, reference, _ = case
    n = len(samples)
    solutions = [None] * n
    state = {"k": 0, "previous": None}

    def step():
        k = state["k"] % n
        state["k"] += 1
        sol = solve_one(samples[k], state["previous"] if (warm and k > 0) else None)
        state["previous"] = sol.x if sol.status == "ok" else None
        solutions[k] = sol

    for _ in range(n):  # builds, compiles, warms caches
        step()
    benchmark.group = GROUPS[free]
    benchmark.pedantic(step, rounds=n, iterations=1, warmup_rounds=0)
    energies = np.array([s.energy for s in solutions])
    gap = energies - reference
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(
        {
            "median per sample [us]": median * 1e6,
            "max energy gap": float(np.max(gap)),
            "samples with relative gap > 1e-6": int(np.sum(gap > 1e-6 * np.abs(reference))),
            "not ok": int(sum(s.status != "ok" for s in solutions)),
            "newton fallbacks": int(sum(bool(s.notes) and s.method == "newton" for s in solutions)),
        }
    )
    if name == "grid":
        _grid_median[free] = median
    elif free in _grid_median:
        benchmark.extra_info["speed-up over grid"] = _grid_median[free] / median
    assert np.all(np.isfinite(energies))
    return solutions


def test_grid(benchmark, case):
    model = ShapeEnergyModel(EnergySettings(), free_speeds=case[0])
    n, n_ratio = (64, 9) if not case[0] else (24, 5)  # free speeds: 24 x 24 x 5 with a secant on the length
    _bench(benchmark, case, "grid", lambda d, x0: model.solve_grid(d, n=n, n_ratio=n_ratio), warm=False)


def test_ipopt_cold(benchmark, case):
    model = ShapeEnergyModel(EnergySettings(), free_speeds=case[0])
    _bench(benchmark, case, "ipopt cold", lambda d, x0: model.solve_nlp(d, starts=3), warm=False)


def test_ipopt_warm(benchmark, case):
    model = ShapeEnergyModel(EnergySettings(), free_speeds=case[0])
    _bench(
        benchmark,
        case,
        "ipopt warm",
        lambda d, x0: model.solve_nlp(d, x0) if x0 is not None else model.solve_nlp(d, starts=3),
    )


@pytest.mark.parametrize(
    "compiled, basin_check",
    [(False, False), (True, False), (True, True)],
    ids=["vm", "compiled", "compiled-basin-check"],
)
def test_newton(benchmark, case, compiled, basin_check):
    model = ShapeEnergyModel(EnergySettings(), free_speeds=case[0], compile=compiled)
    _bench(
        benchmark,
        case,
        f"newton {'compiled' if compiled else 'vm'}",
        lambda d, x0: model.solve_newton(d, x0, basin_check=basin_check),
    )


def test_ph_ik_compiled(benchmark, case):
    """Compiled Newton plus the compiled tube-length Function: PH inverse kinematics per sample (given speeds)."""
    free, samples, _, normals = case
    if free:
        pytest.skip("the seed's setting (given speeds) only")
    model = ShapeEnergyModel(EnergySettings(), compile=True)
    tubes = BufferedFunction(tube_length_function(model, TubeLayout()), compiled=True)
    index = {id(d): i for i, d in enumerate(samples)}

    def solve_one(data, x0):
        sol = model.solve_newton(data, x0)
        tubes.inputs[0][:] = sol.x
        tubes.inputs[1][:] = data.parameters()
        tubes.inputs[2][:] = normals[index[id(data)]]
        tubes()
        return sol

    _bench(benchmark, case, "ph-ik", solve_one)
    _ph_ik_median.append(benchmark.stats.stats.median)


def test_newton_raphson_ik(benchmark, case, recording):
    """The Newton-Raphson comparator of Table II on the same postures, one round per posture (given speeds)."""
    if case[0]:
        pytest.skip("the seed's setting (given speeds) only")
    arm = CBHAArm()
    problem, newton = newton_raphson_problem(arm), build_preset(NR_PRESET)
    targets = relative_section_ends(recording, section_end_markers(arm, recording, "timing"))
    n, rest = len(targets), rest_configuration(arm)
    lengths, status = np.full((n, 3), np.nan), [""] * n
    state = {"k": 0, "start": rest}

    def step():
        k = state["k"] % n
        state["k"] += 1
        start = rest if k == 0 else state["start"]
        report, lengths[k], _ = newton_raphson_step(arm, newton, problem, start, targets[k])
        status[k] = report.status
        if report.status == "ok":
            state["start"] = report.x

    for _ in range(n):  # builds the rootfinder, warms caches
        step()
    benchmark.group = GROUPS[False]
    benchmark.pedantic(step, rounds=n, iterations=1, warmup_rounds=0)
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(
        {
            "median per sample [us]": median * 1e6,
            "not ok": sum(s != "ok" for s in status),
            "mean |L error| [mm]": float(np.nanmean(np.abs(lengths - recording.tube_lengths)) * 1e3),
        }
    )
    if _ph_ik_median:
        benchmark.extra_info["ratio to ph-ik"] = median / _ph_ik_median[-1]
    assert len(status) == n and all(status)
