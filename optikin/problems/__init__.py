"""Problem kinds: each reads a validated problem spec, builds its problem, solves it, returns a Result.

A kind registers a :class:`ProblemKind` under the name used in the ``kind``
field of problem files. The runner hands it a :class:`ProblemContext` holding
the spec, the solver preset, the arm model and a progress reporter.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from optikin.arms.base import ArmModel
from optikin.errors import SpecError
from optikin.progress import Progress
from optikin.registry import PROBLEM_KINDS
from optikin.results import Result
from optikin.spec import ProblemSpec, SolverSpec


@dataclass
class ProblemContext:
    spec: ProblemSpec
    path: Path
    arm: ArmModel
    solver: SolverSpec | None
    solver_path: Path | None
    progress: Progress
    adapter: Any = None

    def rng(self, stream: int = 0) -> np.random.Generator:
        """A generator seeded from ``data.seed`` (``stream`` separates independent draws)."""
        return np.random.default_rng([self.spec.data.seed, stream])

    def option(self, key: str, default: Any) -> Any:
        return self.spec.options.get(key, default)

    def error(self, field_path: str, message: str) -> SpecError:
        return SpecError(self.path, field_path, message)


@dataclass(frozen=True)
class ProblemKind:
    """What a kind accepts and how it runs."""

    name: str
    summary: str
    run: Callable[[ProblemContext], Result]
    backend_families: tuple[str, ...]
    default_solver: str | None
    baselines: tuple[str, ...] = ()
    options: dict[str, Any] = field(default_factory=dict)


def register_kind(kind: ProblemKind) -> ProblemKind:
    PROBLEM_KINDS.register(kind.name)(kind)
    return kind


def load_kinds() -> None:
    """Import every problem-kind module in this package so it is registered."""
    from optikin.solvers import _import_all

    _import_all(__name__, __path__)
