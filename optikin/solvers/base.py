"""The contract every solver backend keeps: one :class:`Solution`, one protocol per family.

A backend is registered under the ``backend:`` name of a preset
(:func:`optikin.solvers.register_backend`) with its family, its options model
and a ``build(preset, options)`` that returns an adapter. The adapter of a
family offers the methods of that family's protocol below; whatever it solved,
it answers with :class:`Solution` objects (or a :class:`SolutionBatch` of many),
in the spirit of qpsolvers' ``Solution``: the point, how the solve went
(``status`` from :data:`optikin.results.STATUSES`), iterations, residual,
seconds, and backend-specific extras.

Families
--------
``evaluation``
    :class:`EvaluationBackend`: run an arm's CasADi Functions over a batch.
``nonlinear``
    :class:`NonlinearBackend`: bounded nonlinear least squares (inverse kinematics,
    platform forward kinematics); problems are
    :class:`optikin.solvers.nonlinear.LeastSquaresProblem`.
``ph``
    :class:`ShapeBackend`: minimum-energy PH backbones for a sequence of end poses.
``qp``
    :class:`QPBackend`: the per-step tracking QP; ``create(n, m)`` returns a
    :class:`QPStepSolver` that keeps the solver's state for one controller.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, Sequence, runtime_checkable

import numpy as np

from optikin.status import Status

if TYPE_CHECKING:
    from optikin.arms.base import ArmModel
    from optikin.solvers.nonlinear import LeastSquaresProblem


@dataclass
class Solution:
    """How one solve went.

    Attributes
    ----------
    x:
        The returned point, shape ``(n,)`` (NaN where the solver returned nothing).
    status:
        One of :data:`optikin.results.STATUSES`, decided by optikin from ``x``, not
        by the backend's own flag.
    iterations:
        Iterations the backend took; -1 where it does not say.
    residual:
        The family's measure of the answer: ``||r(x)||`` for least squares (units of
        ``r``), the bending energy for PH shapes, NaN where it has none.
    seconds:
        Wall time of the solve [s].
    message:
        Why a solve is not ``ok`` (empty when it is).
    extras:
        Backend-specific numbers (e.g. OSQP's primal residual), JSON-ready.
    """

    x: np.ndarray
    status: str
    iterations: int = -1
    residual: float = float("nan")
    seconds: float = 0.0
    message: str = ""
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == Status.OK


@dataclass
class SolutionBatch:
    """Many solves of one problem, as columns: row ``k`` of every field is sample ``k``.

    ``seconds`` is per sample [s]; a batched path (one call for all samples,
    ``batched=True``) reports its total divided by the number of samples.
    """

    x: np.ndarray
    status: list[str]
    iterations: np.ndarray
    residual: np.ndarray
    seconds: np.ndarray
    messages: list[str]
    batched: bool = False

    @classmethod
    def of(cls, solutions: Sequence[Solution], n: int) -> "SolutionBatch":
        """Stack single solutions of ``n``-vectors."""
        return cls(
            x=np.array([s.x for s in solutions]).reshape(len(solutions), n),
            status=[s.status for s in solutions],
            iterations=np.array([s.iterations for s in solutions], dtype=int),
            residual=np.array([s.residual for s in solutions]),
            seconds=np.array([s.seconds for s in solutions]),
            messages=[s.message for s in solutions],
        )

    def __len__(self) -> int:
        return len(self.status)

    def __getitem__(self, k: int) -> Solution:
        return Solution(
            self.x[k],
            self.status[k],
            int(self.iterations[k]),
            float(self.residual[k]),
            float(self.seconds[k]),
            self.messages[k],
        )


@runtime_checkable
class EvaluationBackend(Protocol):
    """Family ``evaluation``: ``evaluate(arm, name, Q) -> (N, rows, cols)`` for ``Q`` of shape ``(N, n_config)``."""

    def evaluate(self, arm: "ArmModel", name: str, Q: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class NonlinearBackend(Protocol):
    """Family ``nonlinear``: one solve from ``x0``, or many (optionally warm-started along a trajectory)."""

    def solve(
        self, problem: "LeastSquaresProblem", x0: np.ndarray, p: np.ndarray, x_ref: np.ndarray | None = None
    ) -> Solution: ...

    def solve_many(
        self,
        problem: "LeastSquaresProblem",
        X0: np.ndarray,
        P: np.ndarray,
        warm_start: bool = False,
        x_ref: np.ndarray | None = None,
    ) -> SolutionBatch: ...


@runtime_checkable
class ShapeBackend(Protocol):
    """Family ``ph``: the CasADi energy model of given settings, and one solution per sample in order."""

    def model(self, settings: Any, free_speeds: bool) -> Any: ...

    def solve(self, model: Any, samples: Sequence[Any]) -> Sequence[Solution]: ...


@runtime_checkable
class QPStepSolver(Protocol):
    """One controller's QP solver: ``solve(data) -> Solution`` with ``x`` the joint rates (NaN on failure)."""

    def solve(self, data: Any) -> Solution: ...


@runtime_checkable
class QPBackend(Protocol):
    """Family ``qp``: a fresh per-controller solver for ``n`` rates and ``m`` task rows."""

    def create(self, n: int, m: int) -> QPStepSolver: ...


Adapter = EvaluationBackend | NonlinearBackend | ShapeBackend | QPBackend
"""What a preset's ``build`` returns: an adapter keeping one family's protocol."""
