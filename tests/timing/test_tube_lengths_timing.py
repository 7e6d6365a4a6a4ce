"""Exact CBHA tube lengths per posture against seed 004's hybrid networks, interleaved in one process.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest -o addopts="" tests/timing/test_tube_lengths_timing.py --benchmark-only -s

The data: the recording of ``problems/cbha-ph-shape.yaml`` (100 postures of the CBHA vertebra
model driven by its tubes, 0.3 mm marker noise, base pose averaged), the section ends measured
relative to the base (the tip rigid body and the marker on vertebra 9) as the ``newton-raphson``
comparator of ``cbha-ph-ik`` reads them, the tip alone for the networks. Per posture, in turn:

``exact``
    :class:`optikin.baselines.exact_tubes.ExactTubeLengths` (block-eliminated Newton on the
    48 x 48 system, compiled step), ``track``: from the linear extrapolation of the two previous
    solutions (the first posture of a pass from the straight configuration);
``exact-rootfinder``
    the path it replaces, :func:`optikin.baselines.ph_comparators.newton_raphson_step` (CasADi
    rootfinder on the same system, ``newton`` preset, then ``arm.tube_lengths``), from the
    previous solution;
``gauss-newton``, ``gauss-newton-compiled``
    the same system through the ``gauss_newton`` backend (its step Function: residual and
    Jacobian in SX, the linear solve numeric), from the previous solution; it stops at
    ``||r|| <= 1e-10`` rather than ``max |r| <= 1e-12``, so its lengths agree to 1e-9;
``hybrid``, ``hybrid-coupled``
    the shipped networks NN1-NN4 (of ``cbha-nn-ikm``, seed 004's Fig. 7 database, and of
    ``cbha-nn-ikm-coupled``) from the tip, then the legs summed
    (:func:`optikin.baselines.hybrid_tubes.hybrid_tube_lengths`, one posture per call as there);
``hybrid-ends``
    the networks of ``cbha-nn-ikm`` given the measured end of section 1 instead of NN1's
    prediction: the same inputs as ``exact``.

Each round passes over the 100 postures once per contender, every posture timed with the wall
clock and the thread's CPU clock; interleaved by ``pass`` (each contender's 100 postures in a
row, then the next contender's: the code and data of the one running stay in the caches) or by
``posture`` (every contender on posture ``k`` before posture ``k + 1``: each call finds the caches
filled by the others, as a solver called between other work does) or ``cold`` (as ``posture``, and
a sweep over 64 MB of memory before every timed call). ``extra_info`` holds, per
contender, the medians over all timed postures [us], the mean |tube-length error| against the
recording's [mm] and the postures not ok. The first round (untimed) builds and compiles.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from optikin.arms.cbha import CBHAArm
from optikin.baselines.exact_tubes import ExactTubeLengths
from optikin.baselines.hybrid_tubes import SHIPPED_STORES, hybrid_tube_lengths, load_hybrid_models
from optikin.baselines.nn_models import hybrid_inverse_configurations
from optikin.baselines.ph_comparators import (
    NR_PRESET,
    newton_raphson_problem,
    newton_raphson_step,
    relative_section_ends,
    section_end_markers,
)
from optikin.ik.formulation import rest_configuration
from optikin.problems.ph_shared import recording_of
from optikin.solvers import build_preset

ROUNDS = 5
SWEEP_BYTES = 64 * 2**20
"""Memory swept before every timed call of the ``cold`` runs."""


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield


@pytest.mark.parametrize("interleave", ["pass", "posture", "cold"])
def test_exact_tube_lengths_against_hybrid_networks(benchmark, interleave):
    arm = CBHAArm()
    recording = recording_of("cbha-ph-shape").with_fixed_base()
    ends = relative_section_ends(recording, section_end_markers(arm, recording, "timing"))
    tips = relative_section_ends(recording, [])
    truth = recording.tube_lengths
    n = len(ends)
    exact = ExactTubeLengths(arm)
    problem, newton = newton_raphson_problem(arm), build_preset(NR_PRESET)
    rest = rest_configuration(arm)
    networks = {name: load_hybrid_models(arm, SHIPPED_STORES[store]) for name, store in HYBRID.items()}
    n_platforms = arm.geometry.n_platforms

    def hybrid(models, section1=None):
        def one(k):
            Q = hybrid_inverse_configurations(
                models, tips[k : k + 1], None if section1 is None else section1[k : k + 1]
            )
            return arm.evaluate("leg_lengths", Q).reshape(n_platforms, 3).sum(axis=0), "ok"

        return one

    state = {"exact-rootfinder": rest, **{name: rest for name in GAUSS_NEWTON}}

    def exact_one(k):
        if k == 0:
            exact.reset()
        posture = exact.track(ends[k])
        return posture.lengths, posture.status

    def rootfinder_one(k):
        report, lengths, _ = newton_raphson_step(
            arm, newton, problem, rest if k == 0 else state["exact-rootfinder"], ends[k]
        )
        if report.status == "ok":
            state["exact-rootfinder"] = report.x
        return lengths, report.status

    def adapter_one(name, adapter):
        def one(k):
            report, lengths, _ = newton_raphson_step(arm, adapter, problem, rest if k == 0 else state[name], ends[k])
            if report.status == "ok":
                state[name] = report.x
            return lengths, report.status

        return one

    contenders = {"exact": exact_one, "exact-rootfinder": rootfinder_one}
    contenders |= {name: adapter_one(name, build_preset(name)) for name in GAUSS_NEWTON}
    contenders |= {name: hybrid(models) for name, models in networks.items()}
    contenders["hybrid-ends"] = hybrid(networks["hybrid"], ends[:, :3])
    lengths = {name: np.full((n, 3), np.nan) for name in contenders}
    status = {name: [""] * n for name in contenders}
    wall = {name: [] for name in contenders}
    cpu = {name: [] for name in contenders}

    sweep = np.ones(SWEEP_BYTES // 8) if interleave == "cold" else None

    def timed(name, k):
        if sweep is not None:
            np.add(sweep, 1.0, out=sweep)  # evicts the caches
        began, began_cpu = time.perf_counter(), time.thread_time()
        lengths[name][k], status[name][k] = contenders[name](k)
        spent_cpu, spent = time.thread_time() - began_cpu, time.perf_counter() - began
        wall[name].append(spent * 1e6)
        cpu[name].append(spent_cpu * 1e6)

    def one_round():
        if interleave in ("posture", "cold"):
            for k in range(n):
                for name in contenders:
                    timed(name, k)
        else:
            for name in contenders:
                for k in range(n):
                    timed(name, k)

    one_round()  # builds, compiles, warms caches
    for name in contenders:
        wall[name].clear()
        cpu[name].clear()
    benchmark.group = f"CBHA tube lengths, {n} recorded postures, all contenders per round, interleaved by {interleave}"
    benchmark.pedantic(one_round, rounds=ROUNDS, warmup_rounds=0, iterations=1)

    for name, models in networks.items():  # the per-posture calls are hybrid_tube_lengths' own
        np.testing.assert_array_equal(hybrid_tube_lengths(arm, tips, models)[0], lengths[name])
    np.testing.assert_array_equal(
        hybrid_tube_lengths(arm, tips, networks["hybrid"], ends[:, :3])[0], lengths["hybrid-ends"]
    )
    for name in ("exact-rootfinder", *GAUSS_NEWTON):
        np.testing.assert_allclose(lengths["exact"], lengths[name], rtol=0, atol=1e-9)
    rows = []
    for name in contenders:
        error = float(np.nanmean(np.abs(lengths[name] - truth)) * 1e3)
        info = {
            "wall median [us]": float(np.median(wall[name])),
            "thread CPU median [us]": float(np.median(cpu[name])),
            "mean |L error| [mm]": error,
            "not ok": sum(s != "ok" for s in status[name]),
        }
        benchmark.extra_info[name] = info
        rows.append(f"{name:18s} " + "  ".join(f"{k} {v:9.3f}" for k, v in info.items()))
    ratio = np.median(cpu["hybrid"]) / np.median(cpu["exact"])
    benchmark.extra_info["hybrid / exact, thread CPU medians"] = float(ratio)
    print(f"\ninterleaved by {interleave}\n" + "\n".join(rows) + f"\nhybrid / exact (thread CPU medians): {ratio:.2f}")
    assert status["exact"].count("ok") == n


HYBRID = {"hybrid": "cbha-nn-ikm", "hybrid-coupled": "cbha-nn-ikm-coupled"}
"""The hybrid contenders and the shipped networks each uses."""
GAUSS_NEWTON = ("gauss-newton", "gauss-newton-compiled")
"""The ``gauss_newton`` presets timed on the same system."""
