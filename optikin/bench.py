"""``optikin bench``: forward-kinematics throughput of every evaluation path against vectorised numpy.

For each arm (the two-section constant-curvature arm and, when
:mod:`optikin.arms.cbha` is present, the CBHA) the tip pose ``fk_dq`` is
evaluated on the same ``N`` configurations by

``numpy``            the baseline: the arm's own ``section_frames`` on a numpy
                     batch ``(N, n_config)`` followed by
                     ``dq_from_rotation_translation`` (``numpy_tip_dq`` of the
                     ``fk`` problem kind);
``casadi call``      one Python call per sample (on ``--call-samples`` samples);
``casadi map via DM`` ``f.map(N)`` called with numpy in, ``DM`` out (the naive batch);
``casadi map``       the ``casadi_map`` backend (zero-copy ``buffer()``, chunked map);
``compiled``         the ``casadi_compiled`` backend (generated C + gcc, one C call).

Every path is run once to build it (``first call``), then ``--repeats`` rounds
run every path once each, interleaved, so that load from other processes hits
all paths alike. Reported: the median time, the median time per sample, the
speed-up against numpy (numpy's time per sample over the path's; above 1 is
faster than numpy) and the largest difference from numpy's result. A path that
differs from numpy by more than ``--tolerance`` makes the command exit with 1.

The configurations are uniform within the arm's bounds
(``ArmModel.sample_configurations``); forward kinematics needs no other
feasibility, and the CBHA's own rejection sampler is far slower than the FK.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np

EXIT_OK, EXIT_DISAGREE = 0, 1
ARM_NAMES = ("cc", "cbha")
PATH_NAMES = ("numpy", "casadi call", "casadi map via DM", "casadi map", "compiled")


@dataclass
class PathResult:
    """Figures of one evaluation path on one arm."""

    path: str
    samples: int
    median_ms: float | None = None
    per_sample_ns: float | None = None
    speedup_vs_numpy: float | None = None
    max_abs_diff: float | None = None
    agrees: bool | None = None
    first_call_s: float | None = None
    times_ms: list[float] = field(default_factory=list)
    skipped: str = ""


# --------------------------------------------------------------------------- arms


def _load_arm(name: str):
    """``(arm, "")`` or ``(None, reason)`` when the arm cannot be benchmarked."""
    if name == "cc":
        from optikin.arms.constant_curvature import ConstantCurvatureArm

        arm = ConstantCurvatureArm()
    elif name == "cbha":
        try:
            module = importlib.import_module("optikin.arms.cbha")
        except ImportError as exc:
            return None, f"optikin.arms.cbha is not available ({exc})"
        if not hasattr(module, "CBHAArm"):
            return None, "optikin.arms.cbha has no CBHAArm"
        try:
            arm = module.CBHAArm()
        except Exception as exc:  # noqa: BLE001 - a module under construction may fail in any way
            return None, f"CBHAArm() failed: {type(exc).__name__}: {exc}"
    else:
        return None, f"unknown arm {name!r}; known: {', '.join(ARM_NAMES)}"
    for needed in ("section_frames", "fk_dq", "lower", "upper", "n_config"):
        if not hasattr(arm, needed):
            return None, f"{type(arm).__name__} lacks {needed}"
    try:  # the numpy baseline needs section_frames to accept a numpy batch
        from optikin.problems.fk import numpy_tip_dq

        probe = np.asarray(numpy_tip_dq(arm, _configurations(arm, 2, np.random.default_rng(0))))
        if probe.shape != (2, 8):
            return None, f"{type(arm).__name__}.section_frames on a numpy batch gave tip shape {probe.shape}"
    except Exception as exc:  # noqa: BLE001
        return None, f"{type(arm).__name__}.section_frames fails on a numpy batch: {type(exc).__name__}: {exc}"
    return arm, ""


def _configurations(arm, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` configurations uniform within the bounds (C-contiguous float64)."""
    return np.ascontiguousarray(rng.uniform(arm.lower, arm.upper, size=(n, arm.n_config)))


# --------------------------------------------------------------------------- paths


def _paths(
    arm, Q: np.ndarray, Q_call: np.ndarray, with_compiled: bool, flags: tuple[str, ...], compiler: str
) -> tuple[dict[str, tuple[Callable[[], np.ndarray], int]], dict[str, str]]:
    """Path name -> (run() returning tip dual quaternions (n, 8), n); and skipped path -> reason."""
    import casadi as ca

    from optikin.problems.fk import numpy_tip_dq
    from optikin.solvers.evaluation import CallEvaluator, CompiledEvaluator, CompiledOptions, MapEvaluator
    from optikin.spec import SolverSpec

    n, f = Q.shape[0], arm.fk_dq
    call = CallEvaluator(SolverSpec(name="bench-call", backend="casadi_call"))
    mapped = MapEvaluator(SolverSpec(name="bench-map", backend="casadi_map"))
    fm_dm: list[ca.Function] = []

    def map_via_dm() -> np.ndarray:
        if not fm_dm:
            fm_dm.append(f.map(n, "serial"))
        return np.asarray(fm_dm[0](Q.T)).T

    paths: dict[str, tuple[Callable[[], np.ndarray], int]] = {
        "numpy": (lambda: numpy_tip_dq(arm, Q), n),
        "casadi call": (lambda: call.evaluate(arm, "fk_dq", Q_call)[:, :, 0], Q_call.shape[0]),
        "casadi map via DM": (map_via_dm, n),
        "casadi map": (lambda: mapped.evaluate(arm, "fk_dq", Q)[:, :, 0], n),
    }
    skipped = {}
    if with_compiled:
        options = CompiledOptions.model_validate({"flags": list(flags), "compiler": compiler})
        compiled = CompiledEvaluator(SolverSpec(name="bench-compiled", backend="casadi_compiled"), options)
        paths["compiled"] = (lambda: compiled.evaluate(arm, "fk_dq", Q)[:, :, 0], n)
    else:
        skipped["compiled"] = "disabled by --no-compiled"
    return paths, skipped


def bench_arm(
    arm,
    samples: int,
    call_samples: int,
    repeats: int,
    seed: int,
    tolerance: float,
    with_compiled: bool = True,
    flags: tuple[str, ...] = ("-O3",),
    compiler: str = "gcc",
    advance: Callable[[int], None] | None = None,
) -> list[PathResult]:
    """Time every path on ``arm``; the first result is numpy's."""
    from optikin.errors import OptikinError

    if advance is None:

        def advance(k: int = 1) -> None:
            return None

    rng = np.random.default_rng(seed)
    Q = _configurations(arm, samples, rng)
    Q_call = Q[: min(call_samples, samples)]
    paths, skipped = _paths(arm, Q, Q_call, with_compiled, flags, compiler)

    results: dict[str, PathResult] = {}
    reference = None
    for name, (run, n) in list(paths.items()):
        start = time.perf_counter()
        try:
            value = np.asarray(run())
        except OptikinError as exc:  # e.g. no working C compiler
            skipped[name] = str(exc)
            del paths[name]
            continue
        result = results[name] = PathResult(name, n, first_call_s=time.perf_counter() - start)
        if name == "numpy":
            reference = value
        else:
            assert reference is not None  # numpy is the first path
            result.max_abs_diff = float(np.abs(value - reference[:n]).max()) if n else 0.0
            result.agrees = bool(result.max_abs_diff <= tolerance)
        advance(1)

    for _ in range(repeats):
        for name, (run, _n) in paths.items():
            start = time.perf_counter()
            run()
            results[name].times_ms.append((time.perf_counter() - start) * 1e3)
            advance(1)

    for r in results.values():
        median = float(np.median(r.times_ms)) if r.times_ms else None
        r.median_ms = median
        r.per_sample_ns = median * 1e6 / r.samples if median is not None and r.samples else None
    base = results["numpy"].per_sample_ns
    for r in results.values():
        if base and r.per_sample_ns:
            r.speedup_vs_numpy = base / r.per_sample_ns
    ordered = [
        results[p] if p in results else PathResult(p, 0, skipped=skipped.get(p, "not run"))
        for p in PATH_NAMES
        if p in results or p in skipped
    ]
    return ordered


# --------------------------------------------------------------------------- machine and output


def machine_info() -> dict:
    import casadi

    info = {
        "nproc": os.cpu_count(),
        "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "python": platform.python_version(),
        "casadi": casadi.CasadiMeta.version(),
        "numpy": np.__version__,
        "machine": platform.machine(),
        "system": f"{platform.system()} {platform.release()}",
    }
    try:
        info["gcc"] = subprocess.run(
            ["gcc", "--version"], capture_output=True, text=True, timeout=10
        ).stdout.splitlines()[0]
    except (OSError, IndexError, subprocess.SubprocessError):
        info["gcc"] = None
    return info


def _command(args: argparse.Namespace) -> str:
    parts = [
        "optikin bench",
        f"--samples {args.samples}",
        f"--call-samples {args.call_samples}",
        f"--repeats {args.repeats}",
    ]
    parts += [f"--arm {a}" for a in args.arm or []]
    if args.no_compiled:
        parts.append("--no-compiled")
    if args.json:
        parts.append("--json")
    return " ".join(parts)


def _fmt(value, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def print_tables(report: dict, console=None) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    if console is None:
        console = Console()
        if not console.is_terminal:  # a file or pipe: wide enough that no row wraps
            console = Console(width=120)
    m = report["machine"]
    console.print(f"[bold]{escape(report['command'])}[/bold]")
    console.print(
        f"{m['nproc']} cores ({m['usable_cpus']} usable), Python {m['python']}, casadi {m['casadi']}, "
        f"numpy {m['numpy']}, {m['gcc'] or 'no gcc'}; load average {report['load_average_before']} "
        f"-> {report['load_average_after']}"
    )
    for arm_name, entry in report["arms"].items():
        table = Table(
            title=f"{arm_name}: tip pose fk_dq, {entry['n_config']} configuration variables, "
            f"medians of {report['repeats']} interleaved repeats"
        )
        for col in ("path", "samples", "median ms", "ns/sample", "vs numpy", "max |diff|", "first call s"):
            table.add_column(col, justify="left" if col == "path" else "right")
        for r in entry["paths"]:
            if r["skipped"]:
                table.add_row(r["path"], "-", "-", "-", "-", "-", f"skipped: {escape(r['skipped'])}")
                continue
            diff = "reference" if r["path"] == "numpy" else _fmt(r["max_abs_diff"], ".1e")
            if r["agrees"] is False:
                diff = f"[red]{diff} > {report['tolerance']:g}[/red]"
            speed = _fmt(r["speedup_vs_numpy"], ".2f") + "x" if r["speedup_vs_numpy"] else "-"
            table.add_row(
                r["path"],
                str(r["samples"]),
                _fmt(r["median_ms"], ".2f"),
                _fmt(r["per_sample_ns"], ".0f"),
                speed,
                diff,
                _fmt(r["first_call_s"], ".3f"),
            )
        console.print(table)
    for s in report["skipped"]:
        console.print(f"[yellow]skipped {s['arm']}:[/yellow] {escape(s['reason'])}")
    console.print(
        "vs numpy = numpy's time per sample / the path's (above 1: faster than numpy); "
        "max |diff| = largest difference from numpy's tip dual quaternions. "
        "Medians on a shared machine: compare ratios, not absolute times."
    )


# --------------------------------------------------------------------------- command


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = "Forward-kinematics throughput of the evaluation paths against vectorised numpy."
    parser.add_argument("--samples", type=int, default=100_000, help="configurations per batch (default 100000)")
    parser.add_argument(
        "--call-samples", type=int, default=2_000, help="configurations for the one-call-per-sample path (default 2000)"
    )
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats of every path (default 7)")
    parser.add_argument("--arm", action="append", choices=ARM_NAMES, help="arm to measure (repeatable; default: all)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the configurations")
    parser.add_argument(
        "--tolerance", type=float, default=1e-12, help="largest accepted difference from numpy's result (default 1e-12)"
    )
    parser.add_argument("--no-compiled", action="store_true", help="skip the code-generated path")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON instead of tables")


def run_bench(args: argparse.Namespace, progress=None) -> dict:
    """Run the benchmark described by ``args``; returns the report (what ``--json`` prints)."""
    from optikin.progress import SILENT

    if args.samples < 1 or args.call_samples < 1 or args.repeats < 1:
        raise ValueError("--samples, --call-samples and --repeats must be positive")
    progress = progress or SILENT
    arm_names = list(dict.fromkeys(args.arm or ARM_NAMES))
    report = {
        "command": _command(args),
        "machine": machine_info(),
        "samples": args.samples,
        "call_samples": min(args.call_samples, args.samples),
        "repeats": args.repeats,
        "seed": args.seed,
        "tolerance": args.tolerance,
        "load_average_before": _load(),
        "arms": {},
        "skipped": [],
    }
    arms = []
    for name in arm_names:
        arm, reason = _load_arm(name)
        if arm is None:
            report["skipped"].append({"arm": name, "reason": reason})
        else:
            arms.append((name, arm))
    steps = len(PATH_NAMES) * (args.repeats + 1)
    with progress.task(f"bench: {len(arms)} arm(s), {args.samples} samples", total=steps * len(arms)) as advance:
        for name, arm in arms:
            results = bench_arm(
                arm,
                args.samples,
                args.call_samples,
                args.repeats,
                args.seed,
                args.tolerance,
                with_compiled=not args.no_compiled,
                advance=advance,
            )
            report["arms"][name] = {"n_config": arm.n_config, "paths": [asdict(r) for r in results]}
    report["load_average_after"] = _load()
    report["ok"] = all(r["agrees"] is not False for entry in report["arms"].values() for r in entry["paths"])
    return report


def _load() -> list[float] | None:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return None


def main(args: argparse.Namespace) -> int:
    from optikin.progress import Progress

    try:
        report = run_bench(args, Progress(enabled=not args.json))
    except ValueError as exc:
        print(f"optikin bench: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print_tables(report)
    return EXIT_OK if report["ok"] else EXIT_DISAGREE
