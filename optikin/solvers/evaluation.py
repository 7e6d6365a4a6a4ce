"""Evaluation backends: how an arm's CasADi Functions are run over a batch of configurations.

``casadi_map``      one ``Function.map`` call over the batch, zero-copy (the default).
``casadi_call``     one Python call per configuration (what a naive loop costs).
``casadi_compiled`` the Function turned into C by CasADi's code generator,
                    compiled with the system C compiler together with a small
                    batch loop, and called once for the whole batch.

Every backend offers ``evaluate(arm, name, Q) -> (N, rows, cols)`` with ``Q`` of
shape ``(N, n_config)``, and all three return the same numbers. How the batched
paths work: :mod:`optikin.batch` and :mod:`optikin.codegen`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.batch import batch_evaluate
from optikin.codegen import CompiledFunction
from optikin.solvers import register_backend
from optikin.spec import SolverSpec

class MapEvaluator:
    """Evaluate with one ``Function.map`` call per batch (zero-copy, mapped Function cached per size)."""

    def __init__(self, preset: SolverSpec):
        self.preset = preset

    def function(self, arm, name: str) -> ca.Function:
        return arm.function(name)

    def evaluate(self, arm, name: str, Q: np.ndarray) -> np.ndarray:
        return batch_evaluate(self.function(arm, name), Q)


class CallEvaluator(MapEvaluator):
    """Evaluate with one Python call per configuration (the naive loop, kept naive on purpose)."""

    def evaluate(self, arm, name: str, Q: np.ndarray) -> np.ndarray:
        f = arm.function(name)
        rows, cols = f.size_out(0)
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        if Q.shape[0] == 0:
            return np.empty((0, rows, cols))
        return np.stack([np.asarray(f(q)).reshape(rows, cols) for q in Q])


class CompiledEvaluator(MapEvaluator):
    """Evaluate code-generated, compiled Functions: one C call per batch."""

    def __init__(self, preset: SolverSpec):
        super().__init__(preset)
        self.flags = tuple(preset.options.get("flags", ["-O3"]))
        self.compiler = str(preset.options.get("compiler", "gcc"))
        # Keyed by the arm's id; the arm is kept so the id cannot be reused by another arm.
        self._cache: dict[tuple[int, str], tuple[object, CompiledFunction]] = {}

    def compiled(self, arm, name: str) -> CompiledFunction:
        key = (id(arm), name)
        entry = self._cache.get(key)
        if entry is None or entry[0] is not arm:
            entry = self._cache[key] = (arm, CompiledFunction(arm.function(name), self.flags, self.compiler))
        return entry[1]

    def function(self, arm, name: str) -> ca.Function:
        return self.compiled(arm, name).external

    def evaluate(self, arm, name: str, Q: np.ndarray) -> np.ndarray:
        return self.compiled(arm, name)(Q)


register_backend("casadi_map", "evaluation", "CasADi Function.map over the batch", options=None)(MapEvaluator)
register_backend("casadi_call", "evaluation", "one CasADi call per sample from Python", options=None)(CallEvaluator)
register_backend("casadi_compiled", "evaluation", "CasADi code generation + C compiler, one C call per batch", options=None)(
    CompiledEvaluator)
