"""The outcome of one solve of a problem file, and how it is written to disk.

A :class:`Result` holds per-sample status, iterations, residuals and timings
(DESIGN.md: every solve reports how it went), the arrays the problem produced,
summary metrics, and one row per compared method. :func:`write_result` writes
``result.json`` + ``arrays.npz`` + figures into ``OUT/<problem name>/``
atomically: everything goes to a temporary folder first, which then replaces
the old one in a single rename, so a failed run never leaves half a result.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable

import numpy as np

from optikin import __version__

STATUSES = ("ok", "unreachable", "failed", "not_converged", "timeout")
"""Per-sample statuses a problem kind may report."""


@dataclass
class MethodRow:
    """One compared method (the solver under study or a baseline) and its summary metrics."""

    method: str
    role: str  # "solver", "baseline" or "variant" (another formulation solved by the same solver)
    metrics: dict[str, float | int | str]


@dataclass
class Result:
    problem: str
    kind: str
    solver: str | None
    title: str
    arm: dict[str, Any]
    status: list[str]
    iterations: np.ndarray | None = None
    residuals: np.ndarray | None = None
    timings: dict[str, float] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    comparison: list[MethodRow] = field(default_factory=list)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    figures: dict[str, Callable[[Path], None]] = field(default_factory=dict, repr=False)
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.status) - set(STATUSES))
        if unknown:
            raise ValueError(f"unknown sample status {unknown}; allowed: {STATUSES}")

    @property
    def samples(self) -> int:
        return len(self.status)

    def status_counts(self) -> dict[str, int]:
        return {s: self.status.count(s) for s in STATUSES if s in self.status}

    @property
    def succeeded(self) -> bool:
        return all(s == "ok" for s in self.status)

    def summary(self) -> dict[str, Any]:
        """Everything but the arrays and figures, as JSON-ready data."""
        failed = [i for i, s in enumerate(self.status) if s != "ok"]
        out = {
            "optikin": __version__,
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "problem": self.problem,
            "title": self.title,
            "kind": self.kind,
            "solver": self.solver,
            "arm": self.arm,
            "samples": self.samples,
            "status_counts": self.status_counts(),
            "failed_samples": failed[:100],
            "timings": self.timings,
            "metrics": self.metrics,
            "comparison": [row.__dict__ for row in self.comparison],
            "notes": self.notes,
        }
        if self.iterations is not None:
            out["iterations"] = _stats(self.iterations)
        if self.residuals is not None:
            out["residuals"] = _stats(self.residuals)
        return _json_ready(out)


def _stats(x: np.ndarray) -> dict[str, float]:
    x = np.asarray(x, dtype=float)
    finite = x[np.isfinite(x)]
    if finite.size == 0:
        return {"median": math.nan, "max": math.nan}
    return {"median": float(np.median(finite)), "max": float(finite.max()), "min": float(finite.min())}


def _json_ready(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _json_ready(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_ready(v) for v in x]
    if isinstance(x, np.ndarray):
        return _json_ready(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def write_result(result: Result, out_dir: Path, figures: bool = True, arrays: list[str] | None = None) -> Path:
    """Write ``result`` under ``out_dir/<problem>/`` atomically; returns that folder.

    ``arrays`` restricts which arrays go into ``arrays.npz`` (all when None).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    final = out_dir / result.problem
    staging = Path(tempfile.mkdtemp(prefix=f".{result.problem}-", dir=out_dir))
    try:
        kept = result.arrays if arrays is None else {k: v for k, v in result.arrays.items() if k in arrays}
        summary = result.summary()
        summary["arrays"] = {k: list(np.shape(v)) for k, v in kept.items()}
        summary["figures"] = []
        if kept:
            np.savez_compressed(staging / "arrays.npz", **kept)
        if figures:
            for name, draw in result.figures.items():
                draw(staging / f"{name}.png")
                summary["figures"].append(f"{name}.png")
        (staging / "result.json").write_text(json.dumps(summary, indent=2) + "\n")
        _replace_dir(staging, final)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return final


def _replace_dir(staging: Path, final: Path) -> None:
    """Swap ``staging`` into ``final``; the old folder is removed only after the rename."""
    old = None
    if final.exists():
        old = final.with_name(f".{final.name}-old-{os.getpid()}")
        final.rename(old)
    staging.rename(final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
