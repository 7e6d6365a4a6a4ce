"""Evaluate an arm's forward kinematics over the configurations of ``data:``, and the baselines on the same ones."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, TypeVar

import numpy as np

from optikin.algebra import dq_from_rotation_translation, dq_norm_residual
from optikin.arms.base import ArmModel
from optikin.problems import ProblemContext
from optikin.solvers import build_preset
from optikin.solvers.base import EvaluationBackend

T = TypeVar("T")

FUNCTIONS = ("fk_dq", "section_dq", "backbone")
"""The arm Functions evaluated for every sample: tip pose, section end poses, backbone points."""


@dataclass
class BaselineRun:
    """One baseline on the same configurations: its name, wall time [s] and tip dual quaternions ``(N, 8)``."""

    name: str
    seconds: float
    tip_dq: np.ndarray


@dataclass
class FkOutcome:
    """What an ``fk`` run computed.

    Attributes
    ----------
    configurations, t:
        The samples ``(N, n_config)`` and their times ``(N,)`` [s] (None unless a trajectory).
    tip_dq, section_dq, backbone:
        Tip dual quaternions ``(N, 8)``, section end dual quaternions ``(N, m, 8)`` and
        backbone points ``(N, K, 3)`` [m], from the solver's backend.
    unit_error:
        ``max(|norm residual|, |dot residual|)`` of each tip dual quaternion ``(N,)``.
    build_seconds, tip_seconds:
        Building (and compiling) the Functions on one sample, and evaluating ``fk_dq`` on all.
    baselines:
        The baselines run, in the order of the problem file.
    skipped_rows:
        Rows of a file source left out because ``data.samples`` asked for fewer.
    """

    configurations: np.ndarray
    t: np.ndarray | None
    tip_dq: np.ndarray
    section_dq: np.ndarray
    backbone: np.ndarray
    unit_error: np.ndarray
    build_seconds: float
    tip_seconds: float
    baselines: list[BaselineRun] = field(default_factory=list)
    skipped_rows: int = 0


def timed(fn: Callable[[], T], repeats: int = 1) -> tuple[T, float]:
    """Run ``fn`` ``repeats`` times; return the last value and the median wall time in seconds."""
    times, value = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - start)
    assert value is not None
    return value, float(np.median(times))


def numpy_tip_dq(arm: ArmModel, Q: np.ndarray) -> np.ndarray:
    """Tip dual quaternions ``(N, 8)`` of configurations ``Q`` ``(N, n_config)`` by the arm's formulas on
    numpy arrays (the ``numpy`` baseline)."""
    quat, pos = arm.section_frames(Q)[-1]
    return dq_from_rotation_translation(quat, pos, check=False)


def unit_error(tip: np.ndarray) -> np.ndarray:
    """``max(|norm residual|, |dot residual|)`` of dual quaternions ``(N, 8)``: 0 for unit ones."""
    norm_err, dot_err = dq_norm_residual(tip)
    return np.maximum(np.abs(norm_err), np.abs(dot_err))


def evaluate_all(
    ctx: ProblemContext, evaluator: EvaluationBackend, Q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Tip ``(N, 8)``, sections ``(N, m, 8)``, backbone ``(N, K, 3)`` and the time of the tip evaluation [s]."""
    arm = ctx.arm
    with ctx.progress.task(f"fk: {Q.shape[0]} samples", total=3) as advance:
        tip, t_tip = timed(lambda: evaluator.evaluate(arm, "fk_dq", Q)[:, :, 0])
        advance()
        sections = evaluator.evaluate(arm, "section_dq", Q).transpose(0, 2, 1)
        advance()
        backbone = evaluator.evaluate(arm, "backbone", Q).transpose(0, 2, 1)
        advance()
    return tip, sections, backbone, t_tip


def run_baseline(
    arm: ArmModel, name: str, Q: np.ndarray, evaluators: dict[str, EvaluationBackend] | None = None
) -> BaselineRun:
    """Baseline ``name`` on ``Q``: ``numpy``, or an evaluation preset (built once on one sample, then timed;
    kept in ``evaluators`` when given)."""
    if name == "numpy":
        tip, seconds = timed(lambda: numpy_tip_dq(arm, Q))
        return BaselineRun(name, seconds, tip)
    evaluators = {} if evaluators is None else evaluators
    if name not in evaluators:
        evaluators[name] = build_preset(name)
    evaluator = evaluators[name]
    evaluator.evaluate(arm, "fk_dq", Q[:1])
    tip, seconds = timed(lambda: evaluator.evaluate(arm, "fk_dq", Q)[:, :, 0])
    return BaselineRun(name, seconds, tip)


def evaluate(ctx: ProblemContext, Q: np.ndarray, evaluators: dict[str, EvaluationBackend] | None = None) -> FkOutcome:
    """The solver's backend and every baseline on configurations ``Q`` ``(N, n_config)`` (checked)."""
    arm = ctx.arm
    evaluator = ctx.backend(EvaluationBackend)
    # Build the Functions (and compile them, for compiled backends) before timing.
    t_build = timed(lambda: [evaluator.evaluate(arm, name, Q[:1]) for name in FUNCTIONS])[1]
    tip, sections, backbone, t_tip = evaluate_all(ctx, evaluator, Q)
    baselines = [run_baseline(arm, name, Q, evaluators) for name in ctx.spec.baselines]
    return FkOutcome(Q, None, tip, sections, backbone, unit_error(tip), t_build, t_tip, baselines)


def load_configurations(ctx: ProblemContext) -> tuple[np.ndarray, np.ndarray | None, int]:
    """The configurations of ``data:`` ``(N, n_config)``, checked against the arm; their times; the rows
    of a file left out."""
    samples = ctx.load_data()
    Q = ctx.arm.validate(samples.values, source=f"{ctx.path.name}: data ({ctx.spec.data.source})")
    return Q, samples.t, samples.skipped_rows


def run(ctx: ProblemContext) -> FkOutcome:
    """Evaluate the solver's backend and every baseline on the configurations of ``data:``."""
    Q, t, skipped_rows = load_configurations(ctx)
    outcome = evaluate(ctx, Q)
    outcome.t, outcome.skipped_rows = t, skipped_rows
    return outcome
