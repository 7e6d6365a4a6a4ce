"""CasADi Functions compiled to C, with a batch loop so a whole batch is one C call.

A ``Map`` over an ``external`` Function pays CasADi's per-call dispatch for every
sample, about as much as the compiled arithmetic itself, so the generated code
gets a C loop over the samples (``optikin_batch_<name>``) called through
``ctypes`` (which releases the GIL). ``-O3`` without ``-ffast-math`` or
``-march=native`` keeps the results bit-identical to CasADi's virtual machine
(FMA contraction would change the last bit).

What reaches the compiler is fixed here, not by the files a user runs: the
compiler is one of :data:`COMPILERS`, found on ``PATH``, and its flags come from
the allow-list :data:`ALLOWED_FLAGS` of optimisation flags (:func:`check_flags`),
so a preset cannot pass ``-wrapper``, ``-B``, ``-specs``, ``@file`` or plugins.
Libraries are cached per user in ``$XDG_CACHE_HOME/optikin`` (else
``~/.cache/optikin``, mode 0700), each beside a JSON record of the hash of its
generated source, compiler (path and version) and flags and of the library's own
bytes. A library is loaded only if both files belong to the current user, are not
group- or world-writable and the record matches; otherwise it is rebuilt (into a
temporary name in the cache, then renamed into place).
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import json
import os
import re
import shutil
import signal
import socket
import stat
import subprocess
import tempfile
from pathlib import Path
from typing import Annotated, Iterable, Literal, get_args

import casadi as ca
import numpy as np
from pydantic import AfterValidator
from pydantic_core import PydanticCustomError

from optikin.batch import _as_batch, _dense_indices, batch_evaluate, dense_output
from optikin.errors import SolverError

_DRIVER_VERSION = "batch-v1"

CompilerName = Literal["cc", "gcc", "clang"]
"""The C compilers optikin calls, by name (resolved on ``PATH``)."""

COMPILERS: tuple[str, ...] = get_args(CompilerName)

ALLOWED_FLAGS: frozenset[str] = frozenset(
    {
        "-O0",
        "-O1",
        "-O2",
        "-O3",
        "-Os",
        "-Og",
        "-Ofast",
        "-march=native",
        "-mtune=native",
        "-ffast-math",
        "-fno-fast-math",
        "-funroll-loops",
        "-fno-unroll-loops",
        "-fno-math-errno",
        "-fno-trapping-math",
        "-ffp-contract=off",
        "-ffp-contract=fast",
        "-fomit-frame-pointer",
        "-fno-strict-aliasing",
    }
)
"""Compiler flags a preset may pass: optimisation flags only, nothing that names a file or a program."""

_DRIVER = r"""
/* ---- optikin: one call evaluates output 0 of {name} on n samples ---- */
#include <stdlib.h>
CASADI_SYMBOL_EXPORT long long optikin_batch_{name}(const casadi_real* x, casadi_real* y, long long n) {{
  casadi_int sz_arg = 0, sz_res = 0, sz_iw = 0, sz_w = 0;
  long long i, status = 0;
  int mem;
  const casadi_real** arg;
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
  if ({name}_work(&sz_arg, &sz_res, &sz_iw, &sz_w)) return -1;
  arg = (const casadi_real**) calloc(sz_arg > 1 ? sz_arg : 1, sizeof(*arg));
  res = (casadi_real**) calloc(sz_res > 1 ? sz_res : 1, sizeof(*res));
  iw = (casadi_int*) calloc(sz_iw > 1 ? sz_iw : 1, sizeof(*iw));
  w = (casadi_real*) calloc(sz_w > 1 ? sz_w : 1, sizeof(*w));
  if (!arg || !res || !iw || !w) {{ free(arg); free(res); free(iw); free(w); return -1; }}
  {name}_incref();
  mem = {name}_checkout();
  for (i = 0; i < n; ++i) {{
    arg[0] = x + i * {n_in};
    res[0] = y + i * {n_out};
    if ({name}(arg, res, iw, w, mem)) {{ status = i + 1; break; }}
  }}
  {name}_release(mem);
  {name}_decref();
  free(arg); free(res); free(iw); free(w);
  return status;
}}
"""


# --------------------------------------------------------------------------- what reaches the compiler


def check_flag(flag: str) -> str:
    """``flag`` if it is in :data:`ALLOWED_FLAGS`.

    Raises
    ------
    ValueError
        Naming the flag and the allowed ones.
    """
    if not isinstance(flag, str) or flag not in ALLOWED_FLAGS:
        raise ValueError(f"compiler flag {flag!r} is not allowed; allowed: {', '.join(sorted(ALLOWED_FLAGS))}")
    return flag


def check_flags(flags: Iterable[str]) -> tuple[str, ...]:
    """``flags`` as a tuple, each checked by :func:`check_flag`.

    Raises
    ------
    ValueError
        Naming the position of the first flag refused (``flags.1: ...``).
    """
    if isinstance(flags, str):
        raise ValueError(f"expected a list of compiler flags, got the string {flags!r}")
    checked = []
    for i, flag in enumerate(flags):
        try:
            checked.append(check_flag(flag))
        except ValueError as exc:
            raise ValueError(f"flags.{i}: {exc}") from None
    return tuple(checked)


def _validate_flag(flag: str) -> str:
    try:
        return check_flag(flag)
    except ValueError as exc:
        raise PydanticCustomError("compiler_flag", str(exc)) from None


CompilerFlag = Annotated[str, AfterValidator(_validate_flag)]
"""A compiler flag in an options model (``list[CompilerFlag]``), checked against :data:`ALLOWED_FLAGS`."""


def find_compiler(name: str) -> str:
    """The path of compiler ``name`` (one of :data:`COMPILERS`) on ``PATH``.

    Raises
    ------
    ValueError
        ``name`` is not one of :data:`COMPILERS`.
    SolverError
        It is not installed.
    """
    if name not in COMPILERS:
        raise ValueError(f"compiler {name!r} is not allowed; allowed: {', '.join(COMPILERS)}")
    found = shutil.which(name)
    if found is None:
        raise SolverError(f"C compiler {name!r} not found on PATH: use the casadi_map backend instead")
    return found


@functools.lru_cache(maxsize=None)
def _compiler_version(compiler: str) -> str:
    try:
        run = subprocess.run([compiler, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise SolverError(f"cannot run {compiler} --version: {exc}") from None
    return run.stdout.strip()


# --------------------------------------------------------------------------- the per-user cache


def cache_dir() -> Path:
    """The per-user folder of compiled libraries, created with mode 0700.

    ``$XDG_CACHE_HOME/optikin`` when ``XDG_CACHE_HOME`` is an absolute path, else
    ``~/.cache/optikin``.

    Raises
    ------
    SolverError
        The folder is a symbolic link, not a folder, or belongs to another user.
    """
    base = os.environ.get("XDG_CACHE_HOME", "")
    root = Path(base) if base and os.path.isabs(base) else Path.home() / ".cache"
    cache = root / "optikin"
    root.mkdir(parents=True, exist_ok=True)
    try:
        cache.mkdir(mode=0o700)
    except FileExistsError:
        pass
    st = os.lstat(cache)
    if not stat.S_ISDIR(st.st_mode):
        raise SolverError(f"compiled-code cache {cache} is not a folder")
    if st.st_uid != os.getuid():
        raise SolverError(f"compiled-code cache {cache} belongs to another user")
    if stat.S_IMODE(st.st_mode) != 0o700:
        os.chmod(cache, 0o700)
    return cache


def _owned_and_private(path: Path) -> bool:
    """A regular file of the current user that neither group nor others may write."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _source(f: ca.Function) -> str:
    """The C code of ``f`` plus the batch loop (for a Function with an input and an output).

    The names of ``f`` and of its inputs and outputs, which CasADi and the batch loop write into
    comments, string literals and symbols as they are, must be C identifiers.

    Raises
    ------
    SpecError
        A name is not a C identifier (:func:`optikin.export._escape.c_identifier`).
    """
    from optikin.export._escape import c_identifier

    c_identifier(f.name(), "Function name", "compiled code")
    for name in (*f.name_in(), *f.name_out()):
        c_identifier(name, f"input or output name of {f.name()}", "compiled code")
    generator = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False})
    generator.add(f)
    source = generator.dump()
    if f.n_in() >= 1 and f.n_out() >= 1:
        source += _DRIVER.format(name=f.name(), n_in=f.nnz_in(0), n_out=f.nnz_out(0))
    return source


def _record(source: str, compiler: str, flags: tuple[str, ...]) -> dict[str, object]:
    """What a library is built from, and its hash."""
    version = _compiler_version(compiler)
    record: dict[str, object] = {
        "driver": _DRIVER_VERSION,
        "casadi": ca.CasadiMeta.version(),
        "compiler": compiler,
        "compiler_version": version,
        "flags": list(flags),
    }
    material = json.dumps({**record, "source": source}, sort_keys=True)
    record["hash"] = hashlib.sha256(material.encode()).hexdigest()
    return record


def _is_valid(library: Path, sidecar: Path, key: str) -> bool:
    """The cached library may be loaded: owned, private, recorded hash and library bytes match."""
    if not (_owned_and_private(library) and _owned_and_private(sidecar)):
        return False
    try:
        record = json.loads(sidecar.read_text())
        return (
            isinstance(record, dict)
            and record.get("hash") == key
            and record.get("library_sha256") == _sha256_file(library)
        )
    except (OSError, ValueError):
        return False


def _build(
    name: str,
    source: str,
    compiler: str,
    flags: tuple[str, ...],
    record: dict[str, object],
    library: Path,
    sidecar: Path,
) -> None:
    """Compile ``source`` into a temporary name in the cache folder, then rename it and its record into place.

    The compiler runs in a process group of its own; when the build is interrupted (Ctrl-C, SIGTERM, any
    exception) the whole group (the driver, ``cc1``, ``as``, ``ld``) is killed and waited for before the
    temporary folder ``.NAME-build-HOST-PID-RANDOM`` is removed, so nothing keeps running and nothing
    half-built reaches the cache. The folders that killed builds left behind are removed first.
    """
    _remove_dead_builds(library.parent)
    with tempfile.TemporaryDirectory(dir=library.parent, prefix=f".{name}-build-{_host()}-{os.getpid()}-") as work:
        c_file = Path(work) / f"{name}.c"
        c_file.write_text(source)
        partial = Path(work) / library.name
        process = subprocess.Popen(
            [compiler, "-shared", "-fPIC", *flags, str(c_file), "-o", str(partial), "-lm"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        try:
            _, stderr = process.communicate()
        except BaseException:
            _kill_group(process)
            raise
        if process.returncode != 0:
            raise SolverError(f"compiling {name} with {compiler} failed: {stderr.strip()[:500]}")
        os.chmod(partial, 0o700)
        partial_record = Path(work) / sidecar.name
        partial_record.write_text(json.dumps({**record, "library_sha256": _sha256_file(partial)}, indent=1))
        os.chmod(partial_record, 0o600)
        os.replace(partial, library)
        os.replace(partial_record, sidecar)


_BUILD = re.compile(r"\.[A-Za-z_][A-Za-z0-9_]*-build-(?P<host>[A-Za-z0-9.]+)-(?P<pid>\d+)-[A-Za-z0-9_]+")
"""A build folder in the cache: ``.NAME-build-HOST-PID-RANDOM``."""


def _host() -> str:
    """This machine's name as build folders carry it (a cache on a shared home may serve several)."""
    return re.sub(r"[^A-Za-z0-9.]", "_", socket.gethostname()) or "host"


def _remove_dead_builds(cache: Path) -> None:
    """Remove the build folders in ``cache`` of this host's processes that are gone (killed mid-build, even by
    SIGKILL, which no clean-up survives); they are never loaded, but would pile up."""
    try:
        entries = list(cache.iterdir())
    except OSError:
        return
    for entry in entries:
        match = _BUILD.fullmatch(entry.name)
        if match is None or match["host"] != _host() or not entry.is_dir() or entry.is_symlink():
            continue
        try:
            os.kill(int(match["pid"]), 0)
        except ProcessLookupError:
            shutil.rmtree(entry, ignore_errors=True)
        except PermissionError:
            continue


def _kill_group(process: subprocess.Popen) -> None:
    """Kill the process group ``process`` leads (SIGKILL), then reap its leader and close its pipes."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.communicate()


def cached_library(f: ca.Function, flags: Iterable[str] = ("-O3",), compiler: str = "gcc") -> Path:
    """The shared library of ``f`` in the per-user cache, compiled unless a valid one is there.

    Parameters
    ----------
    f:
        The Function to compile.
    flags:
        Compiler flags, each in :data:`ALLOWED_FLAGS`.
    compiler:
        One of :data:`COMPILERS`, found on ``PATH``.

    Returns
    -------
    Path
        ``<cache>/<name>_<hash>.so``, beside its record ``<name>_<hash>.json``.

    Raises
    ------
    ValueError
        A flag or the compiler is not allowed.
    SolverError
        No such compiler, or compiling failed.
    """
    return source_library(f.name(), _source(f), check_flags(flags), compiler)


def source_library(name: str, source: str, flags: tuple[str, ...], compiler: str = "gcc", build: bool = True) -> Path:
    """The shared library of the C ``source`` in the per-user cache, compiled unless a valid one is there.

    The library is keyed, like :func:`cached_library`'s, by a hash of the source, the compiler and its
    version, the flags and CasADi's version, and loaded only if its recorded hash and bytes match.

    Parameters
    ----------
    name:
        The library's name stem (a C identifier).
    source:
        The whole C translation unit.
    flags:
        Compiler flags. Not checked against :data:`ALLOWED_FLAGS`: this is for optikin's own generated
        sources and flags; user-given flags go through :func:`cached_library`.
    compiler:
        One of :data:`COMPILERS`, found on ``PATH``.
    build:
        Compile when no valid library is cached; otherwise raise :class:`SolverError`.

    Returns
    -------
    Path
        ``<cache>/<name>_<hash>.so``, beside its record ``<name>_<hash>.json``.

    Raises
    ------
    SolverError
        No such compiler, compiling failed, or (``build=False``) no valid library is cached.
    SpecError
        ``name``, which names files in the cache, is not a C identifier.
    """
    from optikin.export._escape import c_identifier

    c_identifier(name, "library name", "compiled code")
    path = find_compiler(compiler)
    record = _record(source, path, flags)
    key = str(record["hash"])
    cache = cache_dir()
    stem = f"{name}_{key[:16]}"
    library, sidecar = cache / f"{stem}.so", cache / f"{stem}.json"
    if not _is_valid(library, sidecar, key):
        if not build:
            raise SolverError(f"{stem} is not built yet")
        _build(name, source, path, flags, record, library, sidecar)
    return library


def compile_function(f: ca.Function, flags: tuple[str, ...] = ("-O3",), compiler: str = "gcc") -> ca.Function:
    """C code of ``f`` compiled into a shared library (cached by content) and loaded back with ``external``."""
    return CompiledFunction(f, flags, compiler).external


class CompiledFunction:
    """A one-input Function compiled to C, with one C call per batch.

    ``batch(Q)`` -> ``(N, rows, cols)`` like :class:`BatchFunction`;
    :attr:`external` is the same code as a CasADi Function (``casadi.external``).
    The shared library is cached per user (:func:`cached_library`) by the hash of
    its generated source, compiler and flags.

    Parameters
    ----------
    f:
        The Function.
    flags:
        Compiler flags, each in :data:`ALLOWED_FLAGS` (:func:`check_flags`).
    compiler:
        One of :data:`COMPILERS`.

    Raises
    ------
    SolverError
        A flag or the compiler is not allowed, the compiler is missing, or compiling failed.
    """

    def __init__(self, f: ca.Function, flags: Iterable[str] = ("-O3",), compiler: str = "gcc"):
        self.f = f
        self.name = f.name()
        try:
            self.library = cached_library(f, flags, compiler)
        except ValueError as exc:
            raise SolverError(f"compiling {self.name}: {exc}") from None
        self.external = ca.external(self.name, str(self.library))
        self._driver = None
        if f.n_in() == 1 and f.n_out() >= 1 and f.sparsity_in(0).is_dense():
            self.n_in = f.nnz_in(0)
            self.rows, self.cols = f.size_out(0)
            self.nnz_out = f.nnz_out(0)
            self._scatter = _dense_indices(f)
            driver = getattr(ctypes.CDLL(str(self.library)), f"optikin_batch_{self.name}")
            driver.argtypes = (ctypes.c_void_p, ctypes.c_void_p, ctypes.c_longlong)
            driver.restype = ctypes.c_longlong
            self._driver = driver

    def raw(self, Q: np.ndarray) -> np.ndarray:
        """Nonzeros of output 0 per sample, ``(N, nnz)``."""
        Q = _as_batch(Q, self.n_in, self.name)
        n = Q.shape[0]
        out = np.empty((n, self.nnz_out))
        if n == 0:
            return out
        assert self._driver is not None
        status = self._driver(Q.ctypes.data, out.ctypes.data, n)
        if status < 0:
            raise SolverError(f"compiled {self.name}: could not allocate its work arrays")
        if status > 0:
            raise SolverError(f"compiled {self.name} failed on sample {status - 1}")
        return out

    def __call__(self, Q: np.ndarray) -> np.ndarray:
        if self._driver is None:
            return batch_evaluate(self.external, Q)
        return dense_output(self.raw(Q), self.rows, self.cols, self._scatter)
