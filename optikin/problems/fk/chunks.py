"""An ``fk`` run with its configurations split across worker processes (``optikin solve NAME --jobs N`` /
``--dask``).

The configurations are drawn (or read) once, here; every worker evaluates the solver's backend and the
baselines on a contiguous slice of them (:func:`evaluate_piece`, the same code as one process); the slices
are merged in order, so every per-sample array equals the single-process run's. Times: the evaluation
times of the pieces add up (the time per sample the comparison reports is the backend's, not the split's
wall time, which is in the result's provenance); the build time is the longest of the workers' builds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems import ChunkEngine, ProblemContext
from optikin.problems.fk.report import report
from optikin.problems.fk.run import BaselineRun, FkOutcome, evaluate, load_configurations
from optikin.results import Result


def run_chunked(ctx: ProblemContext, engine: ChunkEngine) -> Result:
    """The ``fk`` run with the configurations evaluated in pieces on ``engine``."""
    Q, t, skipped_rows = load_configurations(ctx)
    outcome = merge(engine.map(evaluate_piece, [Q[s] for s in engine.split(len(Q))]))
    outcome.t, outcome.skipped_rows = t, skipped_rows
    return report(ctx, outcome)


def evaluate_piece(ctx: ProblemContext, memo: dict[str, Any], Q: np.ndarray) -> FkOutcome:
    """In a worker: :func:`~optikin.problems.fk.run.evaluate` on one slice (baseline presets kept in ``memo``)."""
    return evaluate(ctx, Q, memo.setdefault("evaluators", {}))


def merge(pieces: list[FkOutcome]) -> FkOutcome:
    """The outcomes of consecutive slices as one, in order."""

    def joined(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in pieces])

    baselines = [
        BaselineRun(
            run.name,
            sum(p.baselines[k].seconds for p in pieces),
            np.concatenate([p.baselines[k].tip_dq for p in pieces]),
        )
        for k, run in enumerate(pieces[0].baselines)
    ]
    return FkOutcome(
        configurations=joined("configurations"),
        t=None,
        tip_dq=joined("tip_dq"),
        section_dq=joined("section_dq"),
        backbone=joined("backbone"),
        unit_error=joined("unit_error"),
        build_seconds=max(p.build_seconds for p in pieces),
        tip_seconds=sum(p.tip_seconds for p in pieces),
        baselines=baselines,
    )
