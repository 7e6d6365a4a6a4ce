"""Batched evaluation of a one-input CasADi Function over numpy arrays ``(N, n)``.

Converting numpy to ``DM`` and back costs more than the arithmetic, so the batch
is handed to CasADi with ``Function.buffer()``: no copies, the configurations
``(N, n)`` in C order *are* the column-major ``n x N`` input of ``f.map(N)``, and
the ``rows x (cols N)`` output lands directly in a numpy array ``(N, cols, rows)``.
Building ``f.map(n)`` costs time in proportion to ``n``, so big batches run in
chunks through cached maps of at most 4096 samples, fewer for a Function costly
enough that a chunk would take more than :data:`CHUNK_SECONDS` (:class:`BatchFunction`).
Timings: see ``BENCHMARKS.md``.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict

import casadi as ca
import numpy as np

from optikin.errors import SolverError
from optikin.interrupt import calls_casadi, check_interrupted

CHUNK_SECONDS = 0.2
"""Wall time a chunk of a batch aims at [s]."""
PROBE = 16
"""Samples of the first chunk of a Function whose cost per sample is not yet known."""


def _dense_indices(f: ca.Function) -> np.ndarray | None:
    """Column-major positions of output 0's nonzeros in its dense ``rows x cols`` block (None when dense)."""
    sp = f.sparsity_out(0)
    if sp.is_dense():
        return None
    return np.asarray(sp.row(), dtype=np.intp) + sp.size1() * np.asarray(sp.get_col(), dtype=np.intp)


def _as_batch(Q: np.ndarray, n: int, what: str) -> np.ndarray:
    """``Q`` as a C-contiguous float64 array ``(N, n)`` (copied only when needed)."""
    Q = np.ascontiguousarray(Q, dtype=np.float64)
    if Q.ndim == 1 and Q.shape[0] == n:
        Q = Q[None, :]
    if Q.ndim != 2 or Q.shape[1] != n:
        raise ValueError(f"{what}: expected configurations of shape (N, {n}), got {Q.shape}")
    return Q


class BatchFunction:
    """Zero-copy batched evaluation of a one-input CasADi Function over ``(N, n)`` arrays.

    ``batch(Q)`` returns ``(N, rows, cols)`` for output 0, the same numbers as
    ``f.map(N)(Q.T)``. Building ``f.map(n)`` the first time costs in proportion to
    ``n`` (see ``BENCHMARKS.md``), so large batches run as chunks of at most
    :attr:`chunk` samples through cached maps, plus one map for the remainder; the
    maps of the last ``max_sizes`` sizes are kept, that of the current chunk size
    always. A chunk is also kept short enough to take about :data:`CHUNK_SECONDS` at
    the cost per sample measured on the previous one (the first has :data:`PROBE`
    samples), because a stop request (:mod:`optikin.interrupt`) waits for the chunk
    running. Calls are serialised by a lock: a buffer holds raw pointers between
    ``set_arg`` and the call.
    """

    def __init__(self, f: ca.Function, chunk: int = 4096, max_sizes: int = 8):
        if f.n_in() != 1 or not f.sparsity_in(0).is_dense():
            raise ValueError(f"{f.name()}: batched evaluation needs one dense input")
        self.f = f
        self.chunk = int(chunk)
        self.n_in = f.nnz_in(0)
        self.rows, self.cols = f.size_out(0)
        self.nnz_out = f.nnz_out(0)
        self._scatter = _dense_indices(f)
        self._max_sizes = int(max_sizes)
        self._maps: OrderedDict[int, tuple] = OrderedDict()
        self._lock = threading.Lock()
        self._per_sample: float | None = None  # seconds per sample of the last chunk
        self._size = min(self.chunk, PROBE)  # samples of a full chunk, as last chosen

    def _chunk_size(self) -> int:
        """Samples of the next full chunk: :attr:`chunk`, or the largest power of two that takes at
        most :data:`CHUNK_SECONDS` at the last measured cost per sample (:data:`PROBE` before any)."""
        if self._per_sample is not None:
            fits = int(CHUNK_SECONDS / max(self._per_sample, 1e-12))
            self._size = min(self.chunk, 1 << max(fits.bit_length() - 1, 0))
        return self._size

    def _mapped(self, n: int) -> tuple:
        entry = self._maps.get(n)
        if entry is None:
            fm = self.f.map(n, "serial")
            buffer, call = fm.buffer()
            entry = self._maps[n] = (fm, buffer, call)
            while len(self._maps) > self._max_sizes:
                oldest = next(k for k in self._maps if k != self._size)
                del self._maps[oldest]
        else:
            self._maps.move_to_end(n)
        return entry

    @calls_casadi
    def _run(self, n: int, x: memoryview, y: memoryview) -> None:
        _, buffer, call = self._mapped(n)
        buffer.set_arg(0, x)
        buffer.set_res(0, y)
        call()
        status = buffer.ret()
        if status != 0:
            raise SolverError(f"evaluating {self.f.name()} over {n} samples failed (status {status})")

    def raw(self, Q: np.ndarray) -> np.ndarray:
        """Nonzeros of output 0 per sample, ``(N, nnz)`` (column-major within a sample)."""
        Q = _as_batch(Q, self.n_in, self.f.name())
        n = Q.shape[0]
        out = np.empty((n, self.nnz_out))
        if n == 0:
            return out
        x, y = Q.reshape(-1).data, out.reshape(-1).data
        a, b = self.n_in, self.nnz_out
        with self._lock:
            start = 0
            while start < n:
                size = min(self._chunk_size(), n - start)
                began = time.perf_counter()
                self._run(size, x[start * a : (start + size) * a], y[start * b : (start + size) * b])
                self._per_sample = (time.perf_counter() - began) / size
                check_interrupted()
                start += size
        return out

    def __call__(self, Q: np.ndarray) -> np.ndarray:
        return dense_output(self.raw(Q), self.rows, self.cols, self._scatter)


def dense_output(raw: np.ndarray, rows: int, cols: int, scatter: np.ndarray | None) -> np.ndarray:
    """``(N, nnz)`` nonzeros per sample -> ``(N, rows, cols)`` (a view when the output is dense)."""
    n = raw.shape[0]
    if scatter is not None:
        dense = np.zeros((n, rows * cols))
        dense[:, scatter] = raw
        raw = dense
    return raw.reshape(n, cols, rows).transpose(0, 2, 1)


_BATCH_CACHE: OrderedDict[int, BatchFunction] = OrderedDict()
_BATCH_CACHE_SIZE = 64
_BATCH_CACHE_LOCK = threading.Lock()


def batched(f: ca.Function) -> BatchFunction:
    """The (cached) :class:`BatchFunction` of ``f``; the cache holds ``f`` itself, so ids are not reused."""
    key = id(f)
    with _BATCH_CACHE_LOCK:
        entry = _BATCH_CACHE.get(key)
        if entry is None or entry.f is not f:
            entry = _BATCH_CACHE[key] = BatchFunction(f)
            while len(_BATCH_CACHE) > _BATCH_CACHE_SIZE:
                _BATCH_CACHE.popitem(last=False)
        else:
            _BATCH_CACHE.move_to_end(key)
        return entry


def _dm_batch_output(f: ca.Function, Q: np.ndarray) -> np.ndarray:
    """``f.map(N)`` through DM conversions; for Functions :class:`BatchFunction` does not handle."""
    rows, cols = f.size_out(0)
    if Q.shape[0] == 0:
        return np.empty((0, rows, cols))
    out = np.asarray(f.map(Q.shape[0], "serial")(Q.T))
    check_interrupted()
    return out.reshape(rows, cols, Q.shape[0], order="F").transpose(2, 0, 1)


def batch_evaluate(f: ca.Function, Q: np.ndarray) -> np.ndarray:
    """Output 0 of ``f`` on every row of ``Q (N, n)`` in one call into CasADi: ``(N, rows, cols)``.

    Zero-copy through ``Function.buffer()``, in chunks through cached maps of at
    most 4096 samples (see :class:`BatchFunction`); bit-identical to ``f.map(N)(Q.T)``.
    Functions with several or sparse inputs fall back to ``f.map(N)`` with DM
    conversions. ``ArmModel.evaluate`` can use this directly.
    """
    try:
        runner = batched(f)
    except ValueError:
        return _dm_batch_output(f, np.atleast_2d(np.asarray(Q, dtype=float)))
    return runner(Q)
