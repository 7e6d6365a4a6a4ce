"""Time per sample of the C-backed PH fast path (:mod:`optikin.native.ph`) against its peers, in one process.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_ph_native_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,max,rounds

The 100 samples of ``cbha-ph-shape`` (given end speeds) as one trajectory, each warm-started from the
previous solution. Contenders, interleaved round by round in this process and timed by this thread's
CPU clock (``time.thread_time``), each called twice in a row per round (``<name>_us``: the first call,
after the other contenders ran; ``<name>_again_us``: the second, with its code and data in the caches):

* ``c``: the C path on the problem's ``ph-newton`` adapter;
* ``compiled``: preset ``ph-newton-compiled``, Newton on the compiled CasADi Functions, the loop in Python;
* ``vm``: preset ``ph-newton``, CasADi's virtual machine, the reference of the C path;
* ``nelder_mead``: scipy's Nelder-Mead on the model's energy through a zero-copy compiled call
  (``xatol = fatol = 1e-10``), from the previous solution, on the first :data:`NM_SAMPLES` samples.

``extra_info`` holds each contender's median microseconds per sample, the ratios to ``c`` (first calls),
the load average, and, with valgrind on PATH, ``c_instructions``: instructions per sample of one C call
(callgrind on a small program that links the same generated C). The benchmarked callable is the C path.
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
from scipy.optimize import minimize

import optikin.native
from optikin.export.context import registered_preset
from optikin.export.ph_shape import ph_library, ph_setup
from optikin.fastcall import BufferedFunction
from optikin.native.ph import STEM, _DRIVER, native_solve

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler gcc on PATH")

ROUNDS = 9
NM_SAMPLES = 20

HARNESS = r"""
#include <stdio.h>
int main(int argc, char** argv) {
  long long n = atoll(argv[2]);
  double* P = malloc(sizeof(double) * n * OPTIKIN_NATIVE_PH_NP), *X = malloc(sizeof(double) * n * 2);
  double* EL = malloc(sizeof(double) * n * 2);
  int* it = malloc(sizeof(int) * n), *status = malloc(sizeof(int) * n), *notes = malloc(sizeof(int) * n);
  FILE* f = fopen(argv[1], "rb");
  if (!f || fread(P, sizeof(double), n * OPTIKIN_NATIVE_PH_NP, f) != (size_t)(n * OPTIKIN_NATIVE_PH_NP)) return 2;
  fclose(f);
  return optikin_native_ph_many(P, n, 0, 1, TOLERANCE, MAX_ITERATIONS, 1, 1, 0, X, EL, it, status, notes) == n ? 0 : 1;
}
"""


def c_instructions(folder: Path, setup) -> int | None:
    """Instructions per sample of one ``optikin_native_ph_many`` call on the samples (callgrind), or None."""
    if shutil.which("valgrind") is None:
        return None
    limits = setup.adapter.preset.limits
    library = ph_library("native", setup.model, setup.adapter, STEM)
    program = (
        library.translation_unit()
        + _DRIVER
        + f"\n#define TOLERANCE {float(limits.tolerance)!r}\n#define MAX_ITERATIONS {int(limits.max_iterations)}\n"
        + HARNESS
    )
    (folder / "harness.c").write_text(program)
    subprocess.run(
        ["gcc", *optikin.native.FLAGS, "harness.c", "-o", "harness", "-lm"], cwd=folder, check=True, capture_output=True
    )
    P = np.ascontiguousarray(setup.parameters, dtype=float)
    P.tofile(folder / "samples.bin")
    out = folder / "callgrind.out"
    command = ["valgrind", "--tool=callgrind", "--toggle-collect=optikin_native_ph_many", f"--callgrind-out-file={out}"]
    run = subprocess.run(
        [*command, "./harness", "samples.bin", str(len(P))], cwd=folder, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    refs = re.search(r"I\s+refs:\s+([\d,]+)", run.stderr)
    assert refs is not None, run.stderr
    return round(int(refs.group(1).replace(",", "")) / len(P))


def nelder_mead(model, samples, parameters: np.ndarray):
    """Nelder-Mead on the energy of each sample from the previous solution (the first from the coarse grid)."""
    energy = BufferedFunction(model.energy_function, compiled=True)

    def E(x, P):
        return float(energy(x, P)[0][0])

    previous = model.coarse_starts(parameters[0])[:, 0]
    out = []
    for P in parameters:
        result = minimize(E, previous, args=(P,), method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-10})
        out.append(result)
        previous = result.x
    return out


def test_ph_native(benchmark, tmp_path):
    setup = ph_setup("cbha-ph-shape")
    samples, model, adapter = setup.samples, setup.model, setup.adapter
    preset = registered_preset("ph-newton-compiled")
    assert preset is not None
    compiled = preset.build()
    compiled_model = compiled.model(model.settings, False)

    def c():
        return native_solve(adapter, model, samples)

    def python(adapter_, model_):
        def run():
            optikin.native.use_native(False)
            try:
                return adapter_.solve(model_, samples)
            finally:
                optikin.native.use_native(None)

        return run

    contenders = {
        "c": (c, len(samples)),
        "compiled": (python(compiled, compiled_model), len(samples)),
        "vm": (python(adapter, model), len(samples)),
        "nelder_mead": (lambda: nelder_mead(model, samples[:NM_SAMPLES], setup.parameters[:NM_SAMPLES]), NM_SAMPLES),
    }
    results = {name: run() for name, (run, _) in contenders.items()}  # build and compile outside the timing
    ours, reference = results["c"], results["vm"]
    assert ours is not None and ours.status == [s.status for s in reference]
    np.testing.assert_allclose(ours.x, [s.x for s in reference], rtol=0, atol=1e-12)
    gap = max(float(r.fun) - ours.energy[k] for k, r in enumerate(results["nelder_mead"]))
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
    benchmark.extra_info.update({f"{name}_over_c": round(us[name] / us["c"], 1) for name in us if name != "c"})
    benchmark.extra_info.update(
        {
            "samples": len(samples),
            "ok": ours.status.count("ok"),
            "nelder_mead_energy_above_c": gap,
            "load": os.getloadavg()[0],
        }
    )
    count = c_instructions(tmp_path, setup)
    if count is not None:
        benchmark.extra_info["c_instructions"] = count
    benchmark.group = "ph native, cbha-ph-shape trajectory"
    benchmark.pedantic(c, rounds=ROUNDS)
    assert us["c"] < us["compiled"]
