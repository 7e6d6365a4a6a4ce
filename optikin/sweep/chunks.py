"""One large problem split in pieces: ``optikin solve NAME --jobs N`` or ``--dask local:N|ADDRESS``.

A kind that can be split (:attr:`optikin.problems.ProblemKind.run_chunked`) draws its samples once, in this
process, and hands slices of them to :meth:`Chunks.map`, which runs them on the sweep's engines
(:mod:`optikin.sweep.run`): joblib's loky worker processes or a Dask cluster. Every worker builds its own
:class:`~optikin.problems.ProblemContext` from the same problem file, preset and overrides (a
:class:`ProblemRef`: paths, names and values, picklable; no CasADi object crosses a process boundary) and keeps
it, with the models the kind builds on it, for the following pieces of the same run. Answers come back in the
order of the pieces, so the merged result equals the single-process run's sample for sample.

The workers read the same files as this process: on a remote Dask cluster, the problem file, the preset and
the data must be at the same paths (a shared file system).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from optikin.errors import SpecError
from optikin.problems import ChunkWork, ProblemContext, ProblemKind
from optikin.results import Result
from optikin.sweep.cell import cached_arm, worker_pool
from optikin.sweep.run import check_dask, check_jobs, dask_client

MIN_PIECE = 64
"""Fewest samples worth sending to a worker: a smaller batch is solved in this process."""
PIECES_PER_WORKER = 2
"""Pieces per worker of a large batch (a worker finishing early takes another)."""
RETRIES = 2
"""Worker deaths a piece survives on a ``local:N`` cluster (Dask reschedules it)."""
KEPT_CONTEXTS = 4
"""Problem contexts a worker process keeps (the most recently used)."""


@dataclass(frozen=True)
class ProblemRef:
    """What a worker needs to build a run's context: the problem file, the preset file, the overrides, and
    the digest of the two files' contents (a file edited between two runs is read again)."""

    path: str
    solver: str | None
    overrides: tuple[tuple[str, Any], ...]
    digest: str

    @property
    def key(self) -> str:
        """Canonical JSON of the reference (override values may be lists)."""
        return json.dumps([self.path, self.solver, self.overrides, self.digest], sort_keys=True, default=str)


_CONTEXTS: OrderedDict[str, tuple[ProblemContext, dict[str, Any]]] = OrderedDict()


def _context(ref: ProblemRef) -> tuple[ProblemContext, dict[str, Any]]:
    """This process's context of ``ref`` and its memo, built on first use (:func:`optikin.runner.prepare`)."""
    from optikin.runner import prepare

    key = ref.key
    if key not in _CONTEXTS:
        _, ctx = prepare(ref.path, ref.solver, overrides=ref.overrides, arms=cached_arm)
        _CONTEXTS[key] = (ctx, {})
        while len(_CONTEXTS) > KEPT_CONTEXTS:
            _CONTEXTS.popitem(last=False)
    _CONTEXTS.move_to_end(key)
    return _CONTEXTS[key]


def run_piece(ref: ProblemRef, work: ChunkWork, piece: Any) -> Any:
    """In a worker: ``work(ctx, memo, piece)`` on this process's context of ``ref``."""
    ctx, memo = _context(ref)
    return work(ctx, memo, piece)


class Chunks:
    """The engine of a split run: ``Chunks(jobs=N)`` (joblib, loky) or ``Chunks(dask="local:N" | ADDRESS)``.

    :func:`optikin.runner.solve` takes it as ``chunks`` and calls :meth:`run` (a Dask client, and a
    ``local:N`` cluster, live for that run).

    Parameters
    ----------
    jobs:
        joblib (loky) worker processes; ignored with ``dask``.
    dask:
        A Dask scheduler address, or ``local:N`` for a ``LocalCluster`` of N worker processes.
    """

    def __init__(self, jobs: int = 1, dask: str | None = None) -> None:
        check_dask(dask)
        self.jobs, self.dask = jobs if dask else check_jobs(jobs), dask
        self.workers = self.jobs
        self._client: Any = None
        self._ref: ProblemRef | None = None
        self._local: tuple[ProblemContext, dict[str, Any]] | None = None

    @property
    def parallel(self) -> bool:
        """Whether pieces go to worker processes (more than one joblib worker, or Dask)."""
        return self.dask is not None or self.jobs > 1

    def run(self, kind: ProblemKind, ctx: ProblemContext, overrides: Sequence[tuple[str, Any]]) -> Result:
        """Run ``kind`` on ``ctx`` split in pieces (with one joblib worker: :attr:`ProblemKind.run`).

        ``overrides`` are those :func:`optikin.runner.prepare` built ``ctx`` with; the workers build theirs
        from the same problem file and preset file with them.

        Raises
        ------
        SpecError
            On ``--jobs`` (or ``--dask``) for a kind that runs as one piece.
        """
        if not self.parallel:
            return kind.run(ctx)
        if kind.run_chunked is None:
            option = "--dask" if self.dask else "--jobs"
            raise SpecError(option, "", f"kind {kind.name!r} runs as one piece: solve {ctx.spec.name} without {option}")
        files = [Path(ctx.path).resolve()] + ([] if ctx.preset is None else [Path(ctx.preset.path).resolve()])
        digest = hashlib.sha256(b"".join(f.read_bytes() for f in files)).hexdigest()
        preset = None if ctx.preset is None else str(files[1])
        self._ref = ProblemRef(str(files[0]), preset, tuple((f, v) for f, v in overrides), digest)
        self._local = (ctx, {})
        if self.dask is None:
            return self._noted(kind.run_chunked(ctx, self))
        with dask_client(self.dask, retries=RETRIES) as client:
            self._client = client
            self.workers = max(1, len(client.scheduler_info().get("workers", {})))
            try:
                return self._noted(kind.run_chunked(ctx, self))
            finally:
                self._client = None

    def _noted(self, result: Result) -> Result:
        engine = f"Dask ({self.dask}, {self.workers} workers)" if self.dask else f"{self.jobs} joblib (loky) workers"
        result.notes.append(f"samples solved in pieces on {engine}; per-sample answers as in one process")
        return result

    def split(self, n: int) -> list[slice]:
        """Contiguous slices of ``n`` samples: :data:`PIECES_PER_WORKER` per worker, none smaller than
        :data:`MIN_PIECE` (a single slice when ``n`` is small: solved in this process)."""
        pieces = max(1, min(self.workers * PIECES_PER_WORKER, n // MIN_PIECE)) if self.parallel else 1
        size = math.ceil(n / pieces) if n else 0
        return [slice(k * size, min(n, (k + 1) * size)) for k in range(pieces) if k * size < n] or [slice(0, 0)]

    def map(self, work: ChunkWork, pieces: Sequence[Any]) -> list[Any]:
        """``work(ctx, memo, piece)`` of every piece, in order: here for a single piece, else on the workers."""
        assert self._ref is not None and self._local is not None, "map runs inside Chunks.run"
        if len(pieces) <= 1 or not self.parallel:
            ctx, memo = self._local
            return [work(ctx, memo, piece) for piece in pieces]
        if self._client is not None:
            futures = self._client.map(run_piece, [self._ref] * len(pieces), [work] * len(pieces), pieces, pure=False)
            return list(self._client.gather(futures))
        from joblib import delayed

        return list(worker_pool(self.jobs)(delayed(run_piece)(self._ref, work, p) for p in pieces))


def chunks_of(jobs: int, dask: str | None) -> Chunks | None:
    """The engine of ``optikin solve --jobs N`` / ``--dask ADDRESS``; None for one process (``--jobs 1``)."""
    check_dask(dask)
    jobs = jobs if dask else check_jobs(jobs)
    return Chunks(jobs, dask) if dask is not None or jobs > 1 else None
