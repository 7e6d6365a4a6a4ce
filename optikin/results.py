"""The outcome of one solve of a problem file, and how it is written to disk.

A :class:`Result` holds per-sample status, iterations, residuals and timings
(every solve reports how it went), the arrays the problem produced, summary
metrics, and one row per compared method. :func:`write_result` writes
``result.json`` + ``arrays.npz`` + figures into ``OUT/<problem name>/``
atomically: everything goes to a temporary folder first, which then replaces
the old one in a single rename, so a failed run never leaves half a result.

Figures are drawn by the kind's :data:`FigureBuilder` from the arrays and the
summary alone, so :func:`redraw` can draw them again from a written folder.
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
from typing import Any, Callable, Mapping

import numpy as np

from optikin import __version__

STATUSES = ("ok", "unreachable", "failed", "not_converged", "timeout")
"""Per-sample statuses a problem kind may report."""

Drawer = Callable[[Path], None]
"""Draws one figure into the PNG file it is given."""

FigureBuilder = Callable[[Mapping[str, np.ndarray], Mapping[str, Any]], dict[str, Drawer]]
"""``figures(arrays, summary) -> {name: drawer}``: a kind's figures from a result's arrays and its
JSON summary (:meth:`Result.summary`) alone. A figure whose arrays are missing is left out."""


@dataclass
class MethodRow:
    """One compared method (the solver under study or a baseline) and its summary metrics."""

    method: str
    role: str  # "solver", "baseline" or "variant" (another formulation solved by the same solver)
    metrics: dict[str, Any]


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


def write_result(
    result: Result,
    out_dir: Path,
    figures: bool = True,
    arrays: list[str] | None = None,
    figure_builder: FigureBuilder | None = None,
) -> Path:
    """Write ``result`` under ``out_dir/<problem>/`` atomically; returns that folder.

    ``arrays`` restricts which arrays go into ``arrays.npz`` (all when None);
    ``figure_builder`` draws the kind's figures from all of the result's arrays.
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
            np.savez_compressed(staging / "arrays.npz", **kept)  # type: ignore[arg-type]
        if figures:
            drawers = figure_builder(result.arrays, summary) if figure_builder is not None else {}
            for name, draw in drawers.items():
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


def read_result(folder: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The summary (``result.json``) and arrays (``arrays.npz``, empty if absent) of a written result."""
    from optikin.errors import InputDataError

    folder = Path(folder)
    try:
        summary = json.loads((folder / "result.json").read_text())
    except OSError as exc:
        raise InputDataError(f"not a result folder: {exc.strerror or exc}", source=str(folder)) from None
    except json.JSONDecodeError as exc:
        raise InputDataError(f"result.json is not JSON: {exc.msg} (line {exc.lineno})", source=str(folder)) from None
    if not isinstance(summary, dict) or "kind" not in summary:
        raise InputDataError("result.json names no problem kind", source=str(folder))
    arrays: dict[str, np.ndarray] = {}
    if (folder / "arrays.npz").is_file():
        with np.load(folder / "arrays.npz", allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    return summary, arrays


def redraw(
    folder: Path, figure_builder: FigureBuilder, summary: Mapping[str, Any], arrays: Mapping[str, np.ndarray]
) -> list[Path]:
    """Draw a written result's figures again into ``folder``; each PNG replaces the old one atomically."""
    written = []
    for name, draw in figure_builder(arrays, summary).items():
        final = Path(folder) / f"{name}.png"
        fd, temporary = tempfile.mkstemp(prefix=f".{name}-", suffix=".png", dir=folder)
        os.close(fd)
        try:
            draw(Path(temporary))
            os.replace(temporary, final)
        except BaseException:
            Path(temporary).unlink(missing_ok=True)
            raise
        written.append(final)
    return written
