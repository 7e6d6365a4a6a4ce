"""Results follow the evaluation budget, not the machine's load: the same problem solved on an idle
machine and while other processes keep every core busy gives the same statuses and answers."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np

from optikin.runner import solve

OVERRIDES = [("data.samples", 40), ("baselines", ["lm", "trf", "ipopt"])]


def spin(stop) -> None:
    while not stop.is_set():
        sum(i * i for i in range(10_000))


def statuses(result) -> dict[str, list[str]]:
    return {key: list(values) for key, values in result.arrays.items() if key.startswith("status_")}


def test_statuses_do_not_depend_on_the_load():
    quiet, _ = solve("cc-ik-pose", figures=False, overrides=OVERRIDES)
    stop = multiprocessing.Event()
    spinners = [multiprocessing.Process(target=spin, args=(stop,)) for _ in range(2 * (os.cpu_count() or 1))]
    for p in spinners:
        p.start()
    try:
        loaded, _ = solve("cc-ik-pose", figures=False, overrides=OVERRIDES)
    finally:
        stop.set()
        for p in spinners:
            p.join()
    assert statuses(quiet) == statuses(loaded)
    assert len(statuses(quiet)) == 4
    for key in statuses(quiet):
        solutions = key.replace("status_", "solutions_")
        assert np.array_equal(quiet.arrays[solutions], loaded.arrays[solutions], equal_nan=True)


def test_shipped_iterative_presets_use_wall_time_only_as_a_safety_net():
    from optikin.solvers import load_preset
    from optikin.spec import available

    for name in available("solvers"):
        preset = load_preset(name)
        if preset.backend.family == "nonlinear":
            # a solve here takes milliseconds; a limit of seconds would make statuses depend on the load
            assert preset.spec.limits.time_limit >= 30.0, name
