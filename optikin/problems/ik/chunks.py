"""An ``ik`` run with its targets split across worker processes (``optikin solve NAME --jobs N`` / ``--dask``).

The run is :func:`optikin.problems.ik.run.solve` itself: the targets are drawn once, here, and every
decision between the solves (which samples to retry, the start of each retry: the nearest solved target's
solution, or a seeded random configuration) is taken here on all samples, as in one process. Only the batch
solves go to the workers, in contiguous pieces of targets with their starts (:func:`solve_piece`); a
backend's batch solve treats every sample on its own, so the answers, merged in order, equal the
single-process run's sample for sample. Targets along a trajectory are solved in order, each from the
previous solution: they run as one piece.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin.problems import ChunkEngine, ProblemContext
from optikin.problems.ik.report import result_of
from optikin.problems.ik.run import Solve, methods_of, setup_of, solve, solver_of
from optikin.results import Result
from optikin.solvers.base import SolutionBatch

Piece = tuple[int, np.ndarray, np.ndarray, bool, "np.ndarray | None"]
"""``(method index, starts (n,) or (k, n), targets (k, d), warm start, x_ref)``."""


def run_chunked(ctx: ProblemContext, engine: ChunkEngine) -> Result:
    """The ``ik`` run with every batch of independent targets solved in pieces on ``engine``."""
    return result_of(ctx, solve(ctx, lambda index, local: split_solver(ctx, engine, index, local)))


def split_solver(ctx: ProblemContext, engine: ChunkEngine, index: int, local: Solve) -> Solve:
    """The batch solver of method ``index`` in pieces: each slice of :meth:`ChunkEngine.split` (with its
    starts) solved by :func:`solve_piece`; one slice is solved here by ``local``."""

    def solve_rows(X0: np.ndarray, P: np.ndarray, warm: bool, x_ref: np.ndarray | None) -> SolutionBatch:
        if warm:
            raise ctx.error(
                "data.source",
                f"targets along a trajectory ({ctx.spec.data.source}) are solved in order, each from the "
                "previous solution: they run as one piece (solve without --jobs/--dask)",
            )
        slices = engine.split(len(P))
        if len(slices) == 1:
            return local(X0, P, warm, x_ref)
        pieces = [(index, X0 if np.ndim(X0) == 1 else X0[s], P[s], warm, x_ref) for s in slices]
        return merge(engine.map(solve_piece, pieces))

    return solve_rows


def solve_piece(ctx: ProblemContext, memo: dict[str, Any], piece: Piece) -> SolutionBatch:
    """In a worker: method ``index`` of :func:`methods_of` (built once per process and run) on one piece."""
    index, X0, P, warm, x_ref = piece
    if "methods" not in memo:
        memo["methods"] = methods_of(ctx, setup_of(ctx))
    method = memo["methods"][index]
    return solver_of(method.adapter, method.problem)(X0, P, warm, x_ref)


def merge(batches: list[SolutionBatch]) -> SolutionBatch:
    """The batches of consecutive pieces as one, in order."""
    return SolutionBatch(
        x=np.concatenate([b.x for b in batches]),
        status=[s for b in batches for s in b.status],
        iterations=np.concatenate([b.iterations for b in batches]),
        residual=np.concatenate([b.residual for b in batches]),
        seconds=np.concatenate([b.seconds for b in batches]),
        messages=[m for b in batches for m in b.messages],
        batched=all(b.batched for b in batches),
    )
