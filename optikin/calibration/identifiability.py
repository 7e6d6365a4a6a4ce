"""What the postures of a calibration can determine: an identifiability report from the Jacobian.

At a point ``(X, beta)`` (the start or the solution) :func:`analyse` takes the information on the free
geometry (section lengths, base pose, marker offsets) with every posture's own configuration eliminated, the
Schur complement ``S`` of :func:`optikin.calibration.solver.information` (an actuator map's coefficients are
eliminated the same way, by pseudo-inverse: they are nuisance parameters here, their rank is reported).

To compare lengths with angles, every parameter is put on one scale: lengths, positions and offsets in metres,
angles so that one degree counts as one millimetre (``z = c omega``, ``c =`` :data:`ANGLE_SCALE`). With
``C = diag(1 or c)``, the scaled information is ``H = C^-1 S C^-1`` and its eigen-decomposition
``H = V diag(s^2) V^T`` gives:

* the **singular values** ``s`` of the whitened Jacobian of the geometry [m of marker motion per scaled unit
  of parameter];
* the **weakly determined combinations**: eigenvectors ``v`` whose standard deviation ``noise / s`` exceeds
  :data:`MAX_STD` (or whose ``s`` is below :data:`RANK_TOLERANCE` times the largest, numerically none), named
  by their parameters of weight at least :data:`NAMED_WEIGHT`;
* the **standard deviations** of each parameter, ``noise sqrt(diag H^-1)`` (infinite on a null combination),
  against :data:`MAX_STD`, and the **correlations** above :data:`MAX_CORRELATION`.

``noise`` is the larger of the fit's residual standard deviation per coordinate and the expected marker noise:
a noise-free recording of identical postures has zero residual, yet cannot determine its geometry, and must
not be reported with a standard deviation of zero.

A calibration is ``not_identifiable`` when it has fewer measured coordinates than unknowns, a null or weak
combination, a parameter whose standard deviation exceeds :data:`MAX_STD`, or a parameter on its bound. The
report names the parameters and the option that would determine them (:func:`remedies`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from optikin.calibration.solver import Problem, information
from optikin.status import Status

MAX_STD = 1e-3
"""The standard deviation [m] above which a parameter or combination is weakly determined: 1 mm for lengths,
positions and offsets, 1 degree for angles (:data:`ANGLE_SCALE`)."""
ANGLE_SCALE = 1e-3 / np.radians(1.0)
"""Metres per radian on the common scale: one degree counts as one millimetre."""
MAX_CORRELATION = 0.95
"""Correlations above this (in absolute value) are listed."""
RANK_TOLERANCE = 1e-7
"""A singular value below this times the largest is zero: the combination is not determined at all."""
NAMED_WEIGHT = 0.2
"""A parameter is named in a combination where its weight (of a unit vector) reaches this."""
BOUND_TOLERANCE = 1e-9
"""A parameter within this [m, rad] of a bound is on it."""

Verdict = Literal[Status.OK, Status.NOT_IDENTIFIABLE]


@dataclass(frozen=True)
class Combination:
    """A direction of the scaled geometry: its singular value, standard deviation and weights by parameter."""

    singular_value: float
    std: float
    weights: dict[str, float]

    def describe(self) -> str:
        """``0.71 L1 - 0.70 base_z`` (weights of at least :data:`NAMED_WEIGHT`), its std in mm."""
        terms = sorted(self.weights.items(), key=lambda kv: -abs(kv[1]))
        text = " ".join(f"{'-' if w < 0 else '+'} {abs(w):.2f} {n}" for n, w in terms).lstrip("+ ")
        std = "undetermined" if not np.isfinite(self.std) else f"std {self.std * 1e3:.3g} mm or deg"
        return f"{text} ({std})"


@dataclass(eq=False)
class Identifiability:
    """The identifiability report of one point of a calibration (module docstring).

    Attributes
    ----------
    names : list of str
        The free geometry parameters analysed.
    singular_values : numpy.ndarray
        Of the whitened, scaled Jacobian, descending [m/m].
    std : numpy.ndarray
        Per parameter, in its own unit [m or rad] (inf: undetermined).
    scaled_std : numpy.ndarray
        Per parameter on the common scale [m; angles: 1 degree as 1 mm].
    weak : list of Combination
        The weakly determined or undetermined combinations.
    correlations : list of tuple
        ``(name, name, rho)`` with ``|rho|`` above the threshold.
    at_bounds : list of tuple
        ``(name, "lower" or "upper", value)``.
    measurements, unknowns : int
        Measured coordinates, and unknowns (per-posture and shared).
    noise : float
        The noise level used [m per coordinate].
    map_rank : tuple of int or None
        ``(rank, size)`` of an actuator map's information.
    max_std : float
        The threshold used [m].
    """

    names: list[str]
    singular_values: np.ndarray
    std: np.ndarray
    scaled_std: np.ndarray
    weak: list[Combination]
    correlations: list[tuple[str, str, float]]
    at_bounds: list[tuple[str, str, float]]
    measurements: int
    unknowns: int
    noise: float
    max_std: float = MAX_STD
    map_rank: tuple[int, int] | None = None
    reasons: list[str] = field(default_factory=list)

    @property
    def verdict(self) -> Verdict:
        return Status.NOT_IDENTIFIABLE if self.reasons else Status.OK

    @property
    def weak_parameters(self) -> list[str]:
        """Every parameter named in a weak combination, above the threshold or on a bound, in parameter order."""
        named = {n for c in self.weak for n in c.weights}
        named |= {n for n, s in zip(self.names, self.scaled_std) if not s <= self.max_std}
        named |= {n for n, _, _ in self.at_bounds}
        return [n for n in self.names if n in named]

    def summary(self) -> dict[str, Any]:
        """JSON-ready: verdict, reasons, singular values, weak combinations, stds, correlations, bounds."""
        return {
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "remedies": remedies(self),
            "measured coordinates": self.measurements,
            "unknowns": self.unknowns,
            "noise level per coordinate [mm]": self.noise * 1e3,
            "std threshold [mm or deg]": self.max_std * 1e3,
            "singular values": [float(f"{s:.4g}") for s in self.singular_values],
            "weak combinations": [c.describe() for c in self.weak],
            "std [mm or deg]": {n: _finite(s * 1e3) for n, s in zip(self.names, self.scaled_std)},
            f"correlations above {MAX_CORRELATION}": [f"{a} ~ {b}: {r:+.3f}" for a, b, r in self.correlations],
            "at bounds": [f"{n} at its {side} bound {v:.6g}" for n, side, v in self.at_bounds],
            **({"actuator map rank": f"{self.map_rank[0]} of {self.map_rank[1]}"} if self.map_rank else {}),
        }


def _finite(x: float) -> float | str:
    return float(f"{x:.4g}") if np.isfinite(x) else "undetermined"


def parameter_scales(names: list[str]) -> np.ndarray:
    """``C``: 1 for lengths, positions and offsets [m], :data:`ANGLE_SCALE` for rotation components [rad]."""
    return np.array([ANGLE_SCALE if n.startswith("base_r") else 1.0 for n in names])


def analyse(
    problem: Problem,
    X: np.ndarray,
    beta: np.ndarray,
    names: list[str],
    noise: float,
    max_std: float = MAX_STD,
) -> Identifiability:
    """The identifiability report at ``(X, beta)`` (module docstring).

    Parameters
    ----------
    problem : Problem
        The calibration problem (what is free, the priors, the bounds).
    X, beta : numpy.ndarray
        The point: per-posture configurations ``(N, n_x)`` and shared parameters ``(n_beta,)``.
    names : list of str
        The names of the shared parameters (:meth:`optikin.calibration.model.Layout.beta_names`).
    noise : float
        Noise per coordinate [m] (module docstring: the larger of the residual and the expected one).
    max_std : float
        The threshold of weakly determined [m].

    Returns
    -------
    Identifiability
    """
    lay = problem.model.layout
    free = np.flatnonzero(problem.free)
    is_map = np.zeros(lay.n_beta, dtype=bool)
    is_map[lay.actuator_map] = True
    geometry = np.array([i for i, k in enumerate(free) if not is_map[k]], dtype=int)
    nuisance = np.array([i for i, k in enumerate(free) if is_map[k]], dtype=int)
    measurements = 3 * int(problem.seen.sum())
    unknowns = len(X) * lay.n_x + len(free)
    gnames = [names[free[i]] for i in geometry]
    reasons: list[str] = []
    if measurements < unknowns:
        reasons.append(
            f"{measurements} measured coordinates for {unknowns} unknowns ({len(X)} postures x {lay.n_x} "
            f"configuration variables + {len(free)} shared parameters)"
        )
    map_rank = None
    if len(free) == 0 or len(geometry) == 0:
        empty = np.zeros(0)
        report = Identifiability(gnames, empty, empty, empty, [], [], [], measurements, unknowns, noise, max_std)
        report.reasons.extend(reasons)
        return report
    S, _ = information(problem, X, beta)
    if len(nuisance):
        Saa = S[np.ix_(nuisance, nuisance)]
        Sga = S[np.ix_(geometry, nuisance)]
        pinv = np.linalg.pinv(Saa, rcond=1e-10, hermitian=True)
        map_rank = (int(np.linalg.matrix_rank(Saa, hermitian=True)), len(nuisance))
        S = S[np.ix_(geometry, geometry)] - Sga @ pinv @ Sga.T
    scale = parameter_scales(gnames)
    H = S / np.outer(scale, scale)
    eigenvalues, V = np.linalg.eigh(0.5 * (H + H.T))
    order = np.argsort(eigenvalues)[::-1]
    eigenvalues, V = np.maximum(eigenvalues[order], 0.0), V[:, order]
    singular = np.sqrt(eigenvalues)
    null = singular <= RANK_TOLERANCE * max(float(singular[0]), 1e-300)
    with np.errstate(divide="ignore"):
        combination_std = np.where(null, np.inf, noise / np.where(null, 1.0, singular))
    weak = []
    for k in np.flatnonzero(~(combination_std <= max_std)):
        v = V[:, k] * (1.0 if V[np.argmax(np.abs(V[:, k])), k] >= 0 else -1.0)
        weights = {n: float(w) for n, w in zip(gnames, v) if abs(w) >= NAMED_WEIGHT}
        weak.append(Combination(float(singular[k]), float(combination_std[k]), weights))
    inverse = np.where(null, 0.0, 1.0 / np.where(null, 1.0, eigenvalues))
    covariance = noise**2 * (V * inverse) @ V.T
    in_null = np.any(np.abs(V[:, null]) >= 1e-3, axis=1) if null.any() else np.zeros(len(gnames), dtype=bool)
    scaled_std = np.where(in_null, np.inf, np.sqrt(np.maximum(np.diag(covariance), 0.0)))
    correlations = []
    determined = np.flatnonzero(~in_null)
    for a_i, a in enumerate(determined):
        for b in determined[a_i + 1 :]:
            denominator = np.sqrt(covariance[a, a] * covariance[b, b])
            rho = covariance[a, b] / denominator if denominator > 0 else 0.0
            if abs(rho) > MAX_CORRELATION:
                correlations.append((gnames[a], gnames[b], float(rho)))
    at_bounds = []
    for i, k in enumerate(free[geometry]):
        for side, bounds in (("lower", problem.lower), ("upper", problem.upper)):
            if bounds is not None and np.isfinite(bounds[k]) and abs(beta[k] - bounds[k]) <= BOUND_TOLERANCE:
                at_bounds.append((gnames[i], side, float(bounds[k])))
    if null.any():
        reasons.append(
            f"{int(null.sum())} combination(s) of the geometry not determined by the postures: "
            + "; ".join(c.describe() for c in weak if not np.isfinite(c.std))
        )
    finite_weak = [c for c in weak if np.isfinite(c.std)]
    if finite_weak:
        reasons.append(
            f"{len(finite_weak)} combination(s) weakly determined (std above {max_std * 1e3:g} mm or degrees): "
            + "; ".join(c.describe() for c in finite_weak)
        )
    above = [
        f"{n} ({s * 1e3:.3g} {'deg' if n.startswith('base_r') else 'mm'})"
        for n, s in zip(gnames, scaled_std)
        if np.isfinite(s) and s > max_std
    ]
    if above:
        reasons.append(f"standard deviation above {max_std * 1e3:g} mm or degrees: " + ", ".join(above))
    if at_bounds:
        reasons.append(
            "at a bound (the data pull it outside the bounds of the nominal): "
            + ", ".join(f"{n} at its {side} bound {v * 1e3:.4g} mm" for n, side, v in at_bounds)
        )
    std = scaled_std / scale
    return Identifiability(
        gnames,
        singular,
        std,
        scaled_std,
        weak,
        correlations,
        at_bounds,
        measurements,
        unknowns,
        noise,
        max_std,
        map_rank,
        reasons,
    )


def remedies(report: Identifiability) -> list[str]:
    """The options that would determine the weak parameters of ``report``, most specific first."""
    if report.verdict == Status.OK:
        return []
    weak = report.weak_parameters
    out = []
    if report.measurements < report.unknowns:
        out.append("more postures or more markers (each posture adds 3 coordinates per marker seen)")
    if any(n.startswith("base_") for n in weak):
        out.append(
            "hold the base: set options.base.plane and options.base.direction (the mount plane and the "
            "direction the backbone leaves it, in the recording's frame), or options.base.body with fix: "
            "[x, y, z, tilt] (a tracked base rigid body), or a fixed pose (options.base.position, orientation "
            "and fix: [x, y, z, tilt])"
        )
    if any(n.startswith("L") and n[1:].isdigit() for n in weak):
        out.append(
            "more varied postures (larger bends of every section, in several bending planes), or hold "
            "the section lengths (options.lengths: fixed) at measured values"
        )
    if any(n.startswith("marker") for n in weak):
        out.append("a prior on the marker offsets (options.offset_sigma) or no offsets (options.offsets: none)")
    if not weak and report.reasons and not out:
        out.append("more varied postures")
    if report.at_bounds:
        out.append(
            "check the nominal section lengths and arm.params.length_range: a length on its bound is not an estimate"
        )
    return out
