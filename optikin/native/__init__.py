"""Generated C called from Python once per batch, compiled once per model.

The batch paths of :mod:`optikin.native.ik` (damped Gauss-Newton IK, independent targets and
trajectories: the Python path's iteration in C around its own code-generated step Functions) and
:mod:`optikin.native.ph` (the minimum-energy PH backbones: the C of ``optikin export --what ph-shape``)
generate their C source, compile it into the per-user cache of :mod:`optikin.codegen` (keyed by
the hash of the source, the compiler and its version and the flags; loaded only when owned by the
user, private and matching its record) and call it through :mod:`ctypes` on numpy arrays: one C call
per batch (per chunk of :data:`CHUNK` samples, between which a stop request is honoured), no Python
object per sample. The Python/CasADi path stays the reference, and runs whenever the C does not
cover the model or the call.

The C path is taken when ``gcc`` is on ``PATH``; without it the reference path runs and one log line
says why. The environment variable :data:`ENVIRONMENT` set to ``0`` (or ``off``, ``false``, ``no``)
forces the reference path, as does :func:`use_native` ``(False)``.
"""

from __future__ import annotations

import ctypes
import logging
import os
import threading
from pathlib import Path

from optikin.errors import SolverError

logger = logging.getLogger(__name__)

ENVIRONMENT = "OPTIKIN_NATIVE"
"""Environment variable: ``0``, ``off``, ``false`` or ``no`` forces the Python reference paths."""

COMPILER = "gcc"
"""The compiler of the C paths (one of :data:`optikin.codegen.COMPILERS`)."""

FLAGS: tuple[str, ...] = ("-O3", "-ffp-contract=off")
"""Flags of the C paths: ``-O3`` without contraction into FMA, so the arithmetic is the export's."""

CHUNK = 4096
"""Samples per C call at most: a stop request waits for the call running."""

_OFF = {"0", "off", "false", "no"}
_override: bool | None = None
_reported: set[str] = set()
_lock = threading.Lock()


def use_native(enabled: bool | None) -> None:
    """Force the C paths on (``True``: still only where a compiler is there), off (``False``), or back to
    the environment's choice (``None``, :data:`ENVIRONMENT`)."""
    global _override
    _override = enabled


def native_enabled() -> bool:
    """Whether the C paths may run: :func:`use_native`'s choice, else :data:`ENVIRONMENT` is not off."""
    if _override is not None:
        return _override
    return os.environ.get(ENVIRONMENT, "").strip().lower() not in _OFF


def report_fallback(what: str, reason: str) -> None:
    """Log, once per process and ``what``, that the reference path runs instead of the C and why."""
    with _lock:
        if what in _reported:
            return
        _reported.add(what)
    logger.info("%s: the Python reference path runs instead of the compiled C: %s", what, reason)


def compiler_found(what: str) -> bool:
    """Whether :data:`COMPILER` is on ``PATH``; when not, :func:`report_fallback` says so for ``what``."""
    from optikin.codegen import find_compiler

    try:
        find_compiler(COMPILER)
    except SolverError as exc:
        report_fallback(what, str(exc))
        return False
    return True


def load_library(name: str, source: str) -> ctypes.CDLL | None:
    """The shared library of C ``source`` from the per-user cache (compiled there first if needed), or None
    when no compiler is there or compiling failed (logged once, :func:`report_fallback`).

    Parameters
    ----------
    name:
        The library's name stem in the cache (a C identifier).
    source:
        The whole translation unit (optikin's own generated code).
    """
    from optikin.codegen import source_library

    try:
        path: Path = source_library(name, source, FLAGS, COMPILER)
    except SolverError as exc:
        report_fallback(name, str(exc))
        return None
    return ctypes.CDLL(str(path))


def pointer(array) -> ctypes.c_void_p:
    """The address of a numpy array's data, for a ``c_void_p`` argument."""
    return ctypes.c_void_p(array.ctypes.data)
