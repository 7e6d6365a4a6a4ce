"""Evaluation backends: how an arm's CasADi Functions are run over a batch of configurations.

``casadi_map``      one ``Function.map(N)`` call over the batch (the default).
``casadi_call``     one Python call per configuration (what a naive loop costs).
``casadi_compiled`` the Function turned into C by CasADi's code generator,
                    compiled with the system C compiler, loaded back with
                    ``casadi.external`` and mapped over the batch.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from optikin.errors import SolverError
from optikin.solvers import register_backend
from optikin.spec import SolverSpec


def _batch_output(f: ca.Function, Q: np.ndarray) -> np.ndarray:
    """``f.map(N)`` on ``Q (N, n)``; returns ``(N, rows, cols)``."""
    rows, cols = f.size_out(0)
    out = np.asarray(f.map(Q.shape[0])(Q.T))
    return out.reshape(rows, cols, Q.shape[0], order="F").transpose(2, 0, 1)


class MapEvaluator:
    """Evaluate with one ``Function.map`` call per batch."""

    def __init__(self, preset: SolverSpec):
        self.preset = preset

    def function(self, arm, name: str) -> ca.Function:
        return arm.function(name)

    def evaluate(self, arm, name: str, Q: np.ndarray) -> np.ndarray:
        return _batch_output(self.function(arm, name), Q)


class CallEvaluator(MapEvaluator):
    """Evaluate with one Python call per configuration."""

    def evaluate(self, arm, name: str, Q: np.ndarray) -> np.ndarray:
        f = arm.function(name)
        return np.stack([np.asarray(f(q)) for q in Q])


def compile_function(f: ca.Function, flags: tuple[str, ...] = ("-O3",), compiler: str = "gcc") -> ca.Function:
    """C code of ``f`` compiled into a shared library (cached by content) and loaded back."""
    if shutil.which(compiler) is None:
        raise SolverError(f"C compiler {compiler!r} not found: use the casadi_map backend instead")
    source = f.serialize()
    key = hashlib.sha1((source + " ".join(flags)).encode()).hexdigest()[:16]
    cache = Path(tempfile.gettempdir()) / "optikin-codegen"
    cache.mkdir(exist_ok=True)
    library = cache / f"{f.name()}_{key}.so"
    if not library.exists():
        c_name = f"{f.name()}_{key}.c"
        generator = ca.CodeGenerator(c_name, {"with_header": False})
        generator.add(f)
        generator.generate(str(cache) + "/")
        partial = library.with_suffix(".so.part")
        run = subprocess.run([compiler, "-shared", "-fPIC", *flags, str(cache / c_name), "-o", str(partial)],
                             capture_output=True, text=True)
        if run.returncode != 0:
            raise SolverError(f"compiling {f.name()} failed: {run.stderr.strip()[:500]}")
        partial.rename(library)
    return ca.external(f.name(), str(library))


class CompiledEvaluator(MapEvaluator):
    """Evaluate code-generated, compiled Functions, mapped over the batch."""

    def __init__(self, preset: SolverSpec):
        super().__init__(preset)
        self.flags = tuple(preset.options.get("flags", ["-O3"]))
        self.compiler = str(preset.options.get("compiler", "gcc"))
        self._cache: dict[tuple[int, str], ca.Function] = {}

    def function(self, arm, name: str) -> ca.Function:
        key = (id(arm), name)
        if key not in self._cache:
            self._cache[key] = compile_function(arm.function(name), self.flags, self.compiler)
        return self._cache[key]


register_backend("casadi_map", "evaluation", "CasADi Function.map over the batch")(MapEvaluator)
register_backend("casadi_call", "evaluation", "one CasADi call per sample from Python")(CallEvaluator)
register_backend("casadi_compiled", "evaluation", "CasADi code generation + C compiler, mapped")(CompiledEvaluator)
