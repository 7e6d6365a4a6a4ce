"""A real-coded genetic algorithm: the gain tuner of Seleem et al. (2020, sec. III-C-5, Figs. 5-6), as a baseline.

Seleem et al. (2020) tune their DMP gains with MATLAB's GA; this is a small, seeded,
dependency-free equivalent for box-bounded minimisation:

* tournament selection (``tournament`` contestants),
* blend crossover BLX-alpha (Eshelman & Schaffer 1993) with probability ``crossover``,
* Gaussian mutation of each gene with probability ``mutation``, its scale
  shrinking linearly from ``0.1`` to ``0.01`` of the box width over the run,
* elitism (the ``elite`` best survive unchanged), offspring clipped to the box.

The objective is evaluated on a whole population at once,
``objective(X (pop, n)) -> (pop,)``; non-finite values count as ``+inf``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from optikin.interrupt import check_interrupted


@dataclass(frozen=True)
class GeneticResult:
    """The best point of a run.

    Attributes
    ----------
    x:
        ``(n,)`` best point found.
    value:
        Its objective.
    history:
        ``(generations + 1,)`` best objective after each generation (0: the initial population).
    evaluations:
        Objective evaluations.
    seconds:
        Wall time [s].
    """

    x: np.ndarray
    value: float
    history: np.ndarray
    evaluations: int
    seconds: float


def minimise(
    objective: Callable[[np.ndarray], np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    population: int = 30,
    generations: int = 40,
    seed: int = 0,
    elite: int = 2,
    crossover: float = 0.9,
    mutation: float = 0.2,
    tournament: int = 3,
    blend: float = 0.5,
    initial: np.ndarray | None = None,
) -> GeneticResult:
    """Minimise ``objective`` over the box ``[lower, upper]``.

    Parameters
    ----------
    objective:
        ``X (pop, n) -> (pop,)`` values; non-finite ones count as ``+inf``.
    lower, upper:
        ``(n,)`` bounds, ``lower < upper``.
    population:
        Individuals per generation (> ``elite``).
    generations:
        Generations after the initial population (>= 0).
    seed:
        Seed of every random draw.
    elite:
        Best individuals kept unchanged each generation.
    crossover:
        Probability of the blend crossover (BLX-``blend``).
    mutation:
        Probability of mutating each gene.
    tournament:
        Contestants per tournament.
    blend:
        ``alpha`` of BLX-alpha.
    initial:
        ``(k, n)`` or ``(n,)`` points placed in the first population (clipped into the box).

    Returns
    -------
    GeneticResult

    Raises
    ------
    ValueError
        Inconsistent bounds or sizes.
    """
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if lower.shape != upper.shape or lower.ndim != 1 or np.any(upper <= lower):
        raise ValueError("lower and upper must be 1-D arrays of equal length with lower < upper")
    if population < 2 or not 0 <= elite < population or generations < 0:
        raise ValueError(
            f"need population >= 2, 0 <= elite < population, generations >= 0 "
            f"(got {population}, {elite}, {generations})"
        )
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    width = upper - lower
    n = lower.size

    def evaluate(X: np.ndarray) -> np.ndarray:
        values = np.asarray(objective(X), dtype=float).reshape(-1)
        return np.where(np.isfinite(values), values, np.inf)

    X = lower + rng.random((population, n)) * width
    if initial is not None:
        seeds = np.clip(np.atleast_2d(np.asarray(initial, dtype=float)), lower, upper)[:population]
        X[: len(seeds)] = seeds
    values = evaluate(X)
    evaluations = population
    history = [values.min()]

    for generation in range(generations):
        check_interrupted()
        order = np.argsort(values)
        X, values = X[order], values[order]
        contestants = rng.integers(0, population, (population - elite, 2, tournament))
        parents = X[contestants.min(axis=2)]  # sorted, so the lowest index is the fittest
        a, b = parents[:, 0], parents[:, 1]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        spread = hi - lo
        children = lo - blend * spread + rng.random(a.shape) * (1 + 2 * blend) * spread
        keep = rng.random(len(a)) >= crossover
        children[keep] = a[keep]
        scale = (0.1 - 0.09 * generation / max(generations - 1, 1)) * width
        mutate = rng.random(children.shape) < mutation
        children = children + mutate * rng.normal(size=children.shape) * scale
        children = np.clip(children, lower, upper)
        child_values = evaluate(children)
        evaluations += len(children)
        X = np.vstack([X[:elite], children])
        values = np.concatenate([values[:elite], child_values])
        history.append(values.min())

    best = int(np.argmin(values))
    return GeneticResult(
        x=X[best],
        value=float(values[best]),
        history=np.array(history),
        evaluations=evaluations,
        seconds=time.perf_counter() - start,
    )
