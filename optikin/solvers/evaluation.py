"""Evaluation backends: how an arm's CasADi Functions are run over a batch of configurations.

``casadi_map``      one ``Function.map`` call over the batch, zero-copy (the default).
``casadi_call``     one Python call per configuration (what a naive loop costs).
``casadi_compiled`` the Function turned into C by CasADi's code generator,
                    compiled with the system C compiler together with a small
                    batch loop, and called once for the whole batch.

Every backend offers ``evaluate(arm, name, Q) -> (N, rows, cols)`` with ``Q`` of
shape ``(N, n_config)``, and all three return the same numbers. How the batched
paths work: :mod:`optikin.batch` and :mod:`optikin.codegen`.

Preset options: ``casadi_map`` and ``casadi_call`` take none; ``casadi_compiled``
takes ``compiler`` (``cc``, ``gcc`` or ``clang``, found on ``PATH``) and ``flags``
(optimisation flags from :data:`optikin.codegen.ALLOWED_FLAGS`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from pydantic import Field

from optikin.arms.base import ArmModel
from optikin.batch import batch_evaluate
from optikin.codegen import CompiledFunction, CompilerFlag, CompilerName
from optikin.options import NoOptions, Options
from optikin.solvers import register_backend
from optikin.spec import SolverSpec


class CompiledOptions(Options):
    """Preset options of backend ``casadi_compiled``."""

    compiler: CompilerName = Field("gcc", description="C compiler, found on PATH by name")
    flags: list[CompilerFlag] = Field(
        default_factory=lambda: ["-O3"],
        description="compiler flags, optimisation flags only (e.g. -O2, "
        "-march=native); -O3 alone keeps results bit-identical",
    )


class MapEvaluator:
    """Evaluate with one ``Function.map`` call per batch (zero-copy, mapped Function cached per size).

    Parameters
    ----------
    preset:
        The solver preset.
    options:
        Its options (none).
    """

    def __init__(self, preset: SolverSpec, options: Options = NoOptions()):
        self.preset = preset
        self.options = options

    def function(self, arm: ArmModel, name: str) -> ca.Function:
        """The Function ``name`` of ``arm`` this backend evaluates."""
        return arm.function(name)

    def evaluate(self, arm: ArmModel, name: str, Q: np.ndarray) -> np.ndarray:
        """Output 0 of Function ``name`` at each configuration of ``Q`` ``(N, n_config)``: ``(N, rows, cols)``."""
        return batch_evaluate(self.function(arm, name), Q)


class CallEvaluator(MapEvaluator):
    """Evaluate with one Python call per configuration (the naive loop, kept naive on purpose)."""

    def evaluate(self, arm: ArmModel, name: str, Q: np.ndarray) -> np.ndarray:
        """Output 0 of Function ``name`` at each configuration of ``Q`` ``(N, n_config)``: ``(N, rows, cols)``."""
        f = arm.function(name)
        rows, cols = f.size_out(0)
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        if Q.shape[0] == 0:
            return np.empty((0, rows, cols))
        return np.stack([np.asarray(f(q)).reshape(rows, cols) for q in Q])


class CompiledEvaluator(MapEvaluator):
    """Evaluate code-generated, compiled Functions: one C call per batch.

    Parameters
    ----------
    preset:
        The solver preset.
    options:
        Compiler and flags.
    """

    def __init__(self, preset: SolverSpec, options: CompiledOptions = CompiledOptions()):
        super().__init__(preset, options)
        self.flags = tuple(options.flags)
        self.compiler = options.compiler
        # Keyed by the arm's id; the arm is kept so the id cannot be reused by another arm.
        self._cache: dict[tuple[int, str], tuple[object, CompiledFunction]] = {}

    def compiled(self, arm: ArmModel, name: str) -> CompiledFunction:
        """Function ``name`` of ``arm`` compiled (once per arm and name)."""
        key = (id(arm), name)
        entry = self._cache.get(key)
        if entry is None or entry[0] is not arm:
            entry = self._cache[key] = (arm, CompiledFunction(arm.function(name), self.flags, self.compiler))
        return entry[1]

    def function(self, arm: ArmModel, name: str) -> ca.Function:
        """The compiled Function ``name`` of ``arm`` (a CasADi ``external``)."""
        return self.compiled(arm, name).external

    def evaluate(self, arm: ArmModel, name: str, Q: np.ndarray) -> np.ndarray:
        """Output 0 of Function ``name`` at each configuration of ``Q`` ``(N, n_config)``: ``(N, rows, cols)``."""
        return self.compiled(arm, name)(Q)


register_backend("casadi_map", "evaluation", "CasADi Function.map over the batch", options=NoOptions)(MapEvaluator)
register_backend("casadi_call", "evaluation", "one CasADi call per sample from Python", options=NoOptions)(
    CallEvaluator
)
register_backend(
    "casadi_compiled",
    "evaluation",
    "CasADi code generation + C compiler, one C call per batch",
    options=CompiledOptions,
)(CompiledEvaluator)
