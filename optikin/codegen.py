"""CasADi Functions compiled to C, with a batch loop so a whole batch is one C call.

A ``Map`` over an ``external`` Function pays CasADi's per-call dispatch for every
sample, about as much as the compiled arithmetic itself, so the generated code
gets a C loop over the samples (``optikin_batch_<name>``) called through
``ctypes`` (which releases the GIL). ``-O3`` without ``-ffast-math`` or
``-march=native`` keeps the results bit-identical to CasADi's virtual machine
(FMA contraction would change the last bit).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from optikin.batch import _as_batch, _dense_indices, batch_evaluate, dense_output
from optikin.errors import SolverError


_DRIVER_VERSION = "batch-v1"

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


def _library_path(f: ca.Function, flags: tuple[str, ...], compiler: str) -> Path:
    source = f.serialize()
    tag = " ".join([_DRIVER_VERSION, ca.__version__, compiler, *flags])
    key = hashlib.sha1((source + tag).encode()).hexdigest()[:16]
    cache = Path(tempfile.gettempdir()) / "optikin-codegen"
    cache.mkdir(exist_ok=True)
    return cache / f"{f.name()}_{key}.so"


def _build_library(f: ca.Function, library: Path, flags: tuple[str, ...], compiler: str) -> None:
    """Generate C for ``f`` plus the batch loop and compile it; atomic against concurrent builds."""
    if shutil.which(compiler) is None:
        raise SolverError(f"C compiler {compiler!r} not found: use the casadi_map backend instead")
    name = f.name()
    with tempfile.TemporaryDirectory(dir=library.parent, prefix=f".{name}-") as work:
        c_name = f"{name}.c"
        generator = ca.CodeGenerator(c_name, {"with_header": False})
        generator.add(f)
        generator.generate(work + os.sep)
        c_file = Path(work) / c_name
        if f.n_in() >= 1 and f.n_out() >= 1:
            with open(c_file, "a") as handle:
                handle.write(_DRIVER.format(name=name, n_in=f.nnz_in(0), n_out=f.nnz_out(0)))
        partial = Path(work) / library.name
        run = subprocess.run([compiler, "-shared", "-fPIC", *flags, str(c_file), "-o", str(partial), "-lm"],
                             capture_output=True, text=True)
        if run.returncode != 0:
            raise SolverError(f"compiling {name} with {compiler} failed: {run.stderr.strip()[:500]}")
        os.replace(partial, library)


def compile_function(f: ca.Function, flags: tuple[str, ...] = ("-O3",), compiler: str = "gcc") -> ca.Function:
    """C code of ``f`` compiled into a shared library (cached by content) and loaded back with ``external``."""
    return CompiledFunction(f, flags, compiler).external


class CompiledFunction:
    """A one-input Function compiled to C, with one C call per batch.

    ``batch(Q)`` -> ``(N, rows, cols)`` like :class:`BatchFunction`;
    :attr:`external` is the same code as a CasADi Function (``casadi.external``).
    The shared library is cached in ``$TMPDIR/optikin-codegen`` by the content of
    the Function, the flags and the CasADi version (build: ~0.2 s for a tip pose).
    """

    def __init__(self, f: ca.Function, flags: tuple[str, ...] = ("-O3",), compiler: str = "gcc"):
        self.f = f
        self.name = f.name()
        self.library = _library_path(f, tuple(flags), compiler)
        if not self.library.exists():
            _build_library(f, self.library, tuple(flags), compiler)
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
