"""Per-call time of the exported C libraries (``optikin export``) against the Python paths, in one session.

Skipped in the normal run (``--benchmark-skip`` in pyproject's addopts); run with

    OPENBLAS_NUM_THREADS=1 pytest tests/timing/test_export_timing.py --benchmark-only \
        --benchmark-columns=median,iqr,min,max,rounds

The benchmarked callable is the Python path; the C example's own timing loop (``main.c``: the
whole input set repeated for 0.2 s, median of five runs, built with ``-O2``) goes into
``extra_info`` as ``c_wall_us`` and ``c_cpu_us`` (process CPU time) per call, with the machine's
load average.

* ``ph-shape``: the 100 samples of ``cbha-ph-shape`` as one trajectory (warm starts); Python:
  preset ``ph-newton-compiled`` (Newton on the compiled CasADi Function, the loop in Python), per
  sample; ``basin`` adds the basin check on every warm-started sample. With valgrind on PATH,
  ``c_instructions``: instructions per sample of one trajectory call (callgrind).
* ``qp-step``: ``track-nominal``'s controller on arms of 2, 4 and 8 sections (0.18 m each, the
  waypoints repeated per section), one step per call; steps along the reference (no constraint
  active) or ``active``: configurations up to 1.3 x beyond the limits with references from random
  nearby configurations (nearly every rate at a bound). Python: ``QPController.command`` with the
  ``qp-daqp`` preset.
"""

from __future__ import annotations

import os
import re
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from optikin.export import build, export

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_export_qp import line, random_steps  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler cc on PATH")


def c_times(executable: Path, data: Path, *args: str, runs: int = 5) -> dict[str, float]:
    """Median wall and CPU microseconds per call of the example's timing loop."""
    wall, cpu = [], []
    for _ in range(runs):
        out = subprocess.run([str(executable), str(data), *args], capture_output=True, text=True, check=True)
        times = dict(item.split() for item in out.stderr.splitlines())
        wall.append(float(times["per_call_us"]))
        cpu.append(float(times["cpu_us"]))
    return {"c_wall_us": statistics.median(wall), "c_cpu_us": statistics.median(cpu), "load": os.getloadavg()[0]}


def c_instructions(executable: Path, function: str, *args: str) -> int:
    """Instructions of the calls of ``function`` in one run of the example with ``args`` (valgrind's callgrind)."""
    out = executable.parent / "callgrind.out"
    command = ["valgrind", "--tool=callgrind", f"--toggle-collect={function}", f"--callgrind-out-file={out}"]
    run = subprocess.run([*command, str(executable), *args], capture_output=True, text=True, check=True)
    refs = re.search(r"I\s+refs:\s+([\d,]+)", run.stderr)
    assert refs is not None, run.stderr
    return int(refs.group(1).replace(",", ""))


@pytest.mark.parametrize("basin", [False, True], ids=["warm", "basin"])
def test_ph_shape_trajectory(benchmark, tmp_path, basin):
    """With valgrind on PATH, ``c_instructions``: instructions per sample of one ``optikin_ph_shape_trajectory``
    call (callgrind, no timing loop)."""
    from optikin.export.context import registered_preset
    from optikin.export.ph_shape import ph_setup

    setup = ph_setup("cbha-ph-shape")
    data = tmp_path / "samples.txt"
    np.savetxt(data, setup.parameters, fmt="%.17g")
    executable = build(export("cbha-ph-shape", "ph-shape", tmp_path))
    options = ("50", "1", "1" if basin else "0")
    benchmark.extra_info.update(c_times(executable, data, *options))
    if shutil.which("valgrind"):
        count = c_instructions(executable, "optikin_ph_shape_trajectory", str(data), *options, "0")
        benchmark.extra_info["c_instructions"] = round(count / len(setup.parameters))
    preset = registered_preset("ph-newton-compiled")
    assert preset is not None
    newton_options = preset.options.model_copy(update={"basin_check": basin})
    adapter = type(setup.adapter)(preset.spec, newton_options)
    model = adapter.model(setup.model.settings, False)
    adapter.solve(model, setup.samples[:2])  # compile (cached on disk) outside the timing
    benchmark.extra_info["samples"] = len(setup.samples)
    benchmark.pedantic(lambda: adapter.solve(model, setup.samples), rounds=5)


@pytest.mark.parametrize("active", [False, True], ids=["reference", "active"])
@pytest.mark.parametrize("sections", [2, 4, 8])
def test_qp_step(benchmark, tmp_path, sections, active):
    from optikin.control.qp import QPController
    from optikin.export.context import registered_preset
    from optikin.export.qp_step import qp_setup

    import optikin.solvers.qp.qp_qpsolvers  # noqa: F401  (registers qp_qpsolvers)

    overrides = [
        ("arm.params.section_lengths", [0.18] * sections),
        (
            "data.params.waypoints",
            [[0.180, 0.6, 0.3] * sections, [0.170, 1.0, 0.8] * sections, [0.185, 0.3, 1.5] * sections],
        ),
        ("options.start_offset", [0.003, 0.05, -0.05] * sections),
    ]
    setup = qp_setup("track-nominal", overrides, samples=1000)
    steps = random_steps(setup, 1000, seed=1, spread=1.3) if active else setup.steps
    data = tmp_path / "steps.txt"
    data.write_text("\n".join(line(s) for s in steps) + "\n")
    executable = build(export("track-nominal", "qp-step", tmp_path, overrides=overrides))
    benchmark.extra_info.update(c_times(executable, data))
    n = setup.arm.n_config
    m = (steps.shape[1] - n) // 3
    preset = registered_preset("qp-daqp")
    assert preset is not None
    controller = QPController(
        setup.arm,
        setup.dt,
        setup.task,
        setup.gain,
        setup.damping,
        solver=preset.build().create(n, m),
        rate_limits=setup.rate_limits,
        margin=setup.margin,
        limit_gain=setup.limit_gain,
        fallback=setup.fallback,
    )
    arguments = [(s[:n], s[n : n + m], s[n + m : n + 2 * m], s[n + 2 * m :]) for s in steps]
    position = iter(range(10**9))

    def step():
        controller.command(*arguments[next(position) % len(arguments)])

    benchmark(step)


@pytest.mark.parametrize("problem", ["cc-ik-trajectory", "cc-ik-pose-trajectory"])
def test_ik_trajectory(benchmark, tmp_path, problem):
    """``ik-trajectory``: 1000 targets of the problem's 10 s, 100 Hz trajectory (``data.samples``
    overridden), one C call for the whole chain. Python: ``GaussNewton.solve_many(warm_start=True)``
    (preset ``gauss-newton``), per target in ``python_us``. With valgrind on PATH, ``c_instructions``:
    instructions per target of one ``optikin_ik_trajectory_trajectory`` call (callgrind, no timing loop)."""
    from optikin.export import ik_setup

    overrides = [("data.samples", 1000)]
    setup = ik_setup(problem, overrides)
    data = tmp_path / "targets.txt"
    np.savetxt(data, setup.targets, fmt="%.17g")
    executable = build(export(problem, "ik-trajectory", tmp_path, overrides=overrides))
    benchmark.extra_info.update(c_times(executable, data))
    iterations = [
        int(line.split()[1])
        for line in subprocess.check_output([str(executable), str(data), "0"], text=True).splitlines()
    ]
    benchmark.extra_info.update({"targets": len(setup.targets), "median iterations": float(np.median(iterations))})
    if shutil.which("valgrind"):
        count = c_instructions(executable, "optikin_ik_trajectory_trajectory", str(data), "0")
        benchmark.extra_info["c_instructions"] = round(count / len(setup.targets))
    problem_, adapter, start, P = setup.problem, setup.adapter, setup.start, setup.targets
    adapter.solve_many(problem_, start, P[:3], warm_start=True)  # build the step Function outside the timing
    batch = benchmark.pedantic(lambda: adapter.solve_many(problem_, start, P, warm_start=True), rounds=5)
    benchmark.extra_info["python_us"] = round(1e6 * benchmark.stats.stats.median / len(P), 1)
    assert batch.status.count("ok") == len(P)
