"""Time per target of the C-backed Gauss-Newton IK batch (:mod:`optikin.native.ik`) against its peers, in one process.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_ik_native_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,max,rounds

Cases: ``trajectory`` (the 1000 targets of ``cc-ik-trajectory``, 10 s at 100 Hz, warm-started),
``cold`` (the 1000 independent targets of ``cc-ik-position`` from its start) and ``pose-trajectory``
(1000 targets of ``cc-ik-pose-trajectory``, warm-started). Contenders, interleaved round by round in
this process and timed by this thread's CPU clock (``time.thread_time``), each called twice in a row
per round (``<name>_us``: the first call, after the other contenders ran; ``<name>_again_us``: the second,
with its code and data in the caches): ``c`` (the C path),
``python`` (``GaussNewton.solve_many`` with the C path off, the reference) and scipy ``lm`` (preset
``lm``, on the first :data:`LM_TARGETS` targets, warm-started the same way). ``extra_info`` holds each
contender's median microseconds per target, the ratios ``lm / c`` and ``python / c``, the load average,
and, with valgrind on PATH, ``c_instructions``: instructions per target of one C call (callgrind on a
small program that links the same generated C). The benchmarked callable is the C path.
"""

from __future__ import annotations

import os
import re
import shutil
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

import optikin.native
from optikin.export import ik_setup
from optikin.native.ik import native_solve_many, source
from optikin.solvers import build_preset

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler gcc on PATH")

ROUNDS = 9
LM_TARGETS = 100
CASES = {
    "trajectory": ("cc-ik-trajectory", True),
    "cold": ("cc-ik-position", False),
    "pose-trajectory": ("cc-ik-pose-trajectory", True),
}

HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
int main(int argc, char** argv) {
  long long n = atoll(argv[2]);
  double* P = malloc(sizeof(double) * n * NP), *X = malloc(sizeof(double) * n * NX);
  double* info = malloc(sizeof(double) * n * 3), previous[NX];
  int* calls = malloc(sizeof(int) * n), have = 0;
  FILE* f = fopen(argv[1], "rb");
  if (!f || fread(P, sizeof(double), n * NP, f) != (size_t)(n * NP)) return 2;
  fclose(f);
  return (int) optikin_native_ik_many(START, 0, P, n, WARM, previous, &have, X, info, calls);
}
"""


def c_instructions(folder: Path, adapter, problem, start: np.ndarray, P: np.ndarray, warm: bool) -> int | None:
    """Instructions per target of one ``optikin_native_ik_many`` call on ``P`` (callgrind), or None without valgrind."""
    if shutil.which("valgrind") is None:
        return None
    start_values = ", ".join(repr(float(v)) for v in start)
    program = (
        source(adapter, problem)
        + f"\nstatic const double START[{len(start)}] = {{{start_values}}};\n#define WARM {int(warm)}\n"
        + HARNESS
    )
    (folder / "harness.c").write_text(program)
    subprocess.run(
        ["gcc", *optikin.native.FLAGS, "harness.c", "-o", "harness", "-lm"], cwd=folder, check=True, capture_output=True
    )
    np.ascontiguousarray(P, dtype=float).tofile(folder / "targets.bin")
    out = folder / "callgrind.out"
    command = ["valgrind", "--tool=callgrind", "--toggle-collect=optikin_native_ik_many", f"--callgrind-out-file={out}"]
    run = subprocess.run(
        [*command, "./harness", "targets.bin", str(len(P))], cwd=folder, capture_output=True, text=True
    )
    refs = re.search(r"I\s+refs:\s+([\d,]+)", run.stderr)
    assert refs is not None, run.stderr
    return round(int(refs.group(1).replace(",", "")) / len(P))


@pytest.mark.parametrize("case", list(CASES))
def test_ik_native(benchmark, tmp_path, case):
    problem_name, warm = CASES[case]
    setup = ik_setup(problem_name, [("data.samples", 1000)] if warm else [])
    adapter, problem, start, P = setup.adapter, setup.problem, setup.start, setup.targets[:1000]
    lm = build_preset("lm")

    def c():
        return native_solve_many(adapter, problem, start, P, warm)

    def python():
        optikin.native.use_native(False)
        try:
            return adapter.solve_many(problem, start, P, warm_start=warm)
        finally:
            optikin.native.use_native(None)

    def scipy_lm():
        return lm.solve_many(problem, start, P[:LM_TARGETS], warm_start=warm)

    contenders = {"c": (c, len(P)), "python": (python, len(P)), "lm": (scipy_lm, LM_TARGETS)}
    results = {name: run() for name, (run, _) in contenders.items()}  # build and compile outside the timing
    assert results["c"] is not None
    assert results["c"].status == results["python"].status
    np.testing.assert_allclose(results["c"].x, results["python"].x, rtol=0, atol=1e-12)
    times: dict[str, list[float]] = {name: [] for name in contenders}
    again: dict[str, list[float]] = {name: [] for name in contenders}
    for _ in range(ROUNDS):
        for name, (run, count) in contenders.items():
            for record in (times[name], again[name]):
                began = time.thread_time()
                run()
                record.append((time.thread_time() - began) / count)
    us = {name: 1e6 * statistics.median(t) for name, t in times.items()}
    benchmark.extra_info.update({f"{name}_us": round(value, 3) for name, value in us.items()})
    benchmark.extra_info.update({f"{name}_again_us": round(1e6 * statistics.median(t), 3) for name, t in again.items()})
    benchmark.extra_info.update(
        {
            "lm_over_c": round(us["lm"] / us["c"], 1),
            "python_over_c": round(us["python"] / us["c"], 1),
            "targets": len(P),
            "ok": results["c"].status.count("ok"),
            "median iterations": float(np.median(results["c"].iterations)),
            "load": os.getloadavg()[0],
        }
    )
    count = c_instructions(tmp_path, adapter, problem.reduced, problem.free_part(start), P, warm)
    if count is not None:
        benchmark.extra_info["c_instructions"] = count
    benchmark.group = f"ik native {case}"
    benchmark.pedantic(c, rounds=ROUNDS)
    assert us["c"] < us["python"]
