"""The whole-CBHA inverse problem of seed 004: the elongation distribution of section IV, and checks of answers.

Seed 004, section IV-A: "since the length of an inter-vertebra is a fraction of
the tube length, the elongation of each inter-vertebra at any time represents a
percentage of the total length of the tube. This percentage can be obtained by
considering the minimum and the maximum elongations of each inter-vertebra
listed in Table I." The percentages themselves (Fig. 6) are not in the text;
here platform ``k`` of section ``s`` takes its share of the mid-range lengths,

    c_k = (q_min,k + q_max,k) / sum_{j in s} (q_min,j + q_max,j),

and every leg follows ``q_{m,k} = c_k L_{m,s}`` with ``L_{m,s} = sum_{j in s}
q_{m,j}`` the length of tube ``m`` along section ``s`` (the quantity the wire
potentiometers measure and the pressures set). The shares at the minimum and at
the maximum of Table I differ from ``c_k`` by at most 0.5 percentage points.
A distributed leg lies within Table I exactly when its tube length lies in
``[max_k q_min,k / c_k, min_k q_max,k / c_k]``: 67.2-147.8 mm for section 1
(Table I's sums: 65-150 mm) and 59.2-145.8 mm for section 2 (58-147 mm).

As residual rows of the inverse problem (:mod:`optikin.problems.ik_formulation`)
the distribution is ``q_{m,k}(q) - c_k L_{m,s}(q)`` for every platform but the
last of each section (whose row follows, the fractions adding up to one): 42
rows of full rank, leaving the 48 platform variables the 6 degrees of freedom of
the 6 tube lengths.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.arms.cbha import CBHAArm, CBHAGeometry, printed_leg_lengths


def section_slices(geometry: CBHAGeometry) -> list[slice]:
    """Platform indices (0-based) of each section."""
    ends = np.cumsum((0,) + geometry.platforms_per_section)
    return [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]


def elongation_fractions(geometry: CBHAGeometry) -> np.ndarray:
    """``c_k``, one per platform: its share of its section's mid-range length (module docstring)."""
    mid = np.add(geometry.leg_min, geometry.leg_max)
    return np.concatenate([mid[s] / mid[s].sum() for s in section_slices(geometry)])


def distributed_tube_range(geometry: CBHAGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Per section, the tube lengths ``[lower, upper]`` [m] whose distributed legs are all within Table I."""
    c = elongation_fractions(geometry)
    lo, hi = np.asarray(geometry.leg_min), np.asarray(geometry.leg_max)
    slices = section_slices(geometry)
    return (np.array([np.max(lo[s] / c[s]) for s in slices]), np.array([np.min(hi[s] / c[s]) for s in slices]))


def distribution_rows(arm: CBHAArm, q: ca.SX) -> ca.SX:
    """``q_{m,k}(q) - c_k L_{m,s}(q)`` for all platforms but the last of each section, metres (module docstring)."""
    c = elongation_fractions(arm.geometry)
    legs = ca.reshape(arm.leg_length_expressions(q), 3, arm.geometry.n_platforms)  # tube x platform
    rows = []
    for s in section_slices(arm.geometry):
        tube = ca.sum2(legs[:, s])
        rows += [legs[:, k] - c[k] * tube for k in range(s.start, s.stop - 1)]
    return ca.vertcat(*rows)


def legs_of(arm: CBHAArm, X: np.ndarray) -> np.ndarray:
    """Leg lengths ``(N, 3 (N_v - 1))`` [m] of configurations ``X``, by the printed eqs. (7)-(9) of seed 004.

    An independent transcription of the model's leg lengths (:func:`printed_leg_lengths`).
    Rows of ``X`` that are not finite give NaN.
    """
    X = np.atleast_2d(X)
    Z, theta, psi = np.moveaxis(X.reshape(len(X), -1, 3), 2, 0)
    radii = arm.geometry.radii
    return np.stack(printed_leg_lengths(Z, theta, psi, radii[:-1], radii[1:]), axis=2).reshape(len(X), -1)


def leg_margins(arm: CBHAArm, X: np.ndarray) -> np.ndarray:
    """Per configuration, the smallest distance [m] of a leg to its Table I limits; negative outside."""
    legs = legs_of(arm, X)
    lo, hi = arm.leg_limits()
    return np.min(np.minimum(legs - lo, hi - legs), axis=1)


def distribution_deviation(arm: CBHAArm, X: np.ndarray) -> np.ndarray:
    """Per configuration, ``max |q_{m,k} - c_k L_{m,s}|`` [m]: how far its legs are from the distribution."""
    legs = legs_of(arm, X).reshape(len(np.atleast_2d(X)), -1, 3)  # sample, platform, tube
    c = elongation_fractions(arm.geometry)
    deviation = np.empty_like(legs)
    for s in section_slices(arm.geometry):
        tube = legs[:, s].sum(axis=1, keepdims=True)
        deviation[:, s] = legs[:, s] - c[s, None] * tube
    return np.abs(deviation).max(axis=(1, 2))


def leg_checks(arm: CBHAArm, targets: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest leg-length error against the targets per sample (printed eqs. (7)-(9)), and whether every
    leg lies within Table I."""
    legs = legs_of(arm, X)
    lo, hi = arm.leg_limits()
    return np.abs(legs - targets).max(axis=1), np.all((legs >= lo - 1e-12) & (legs <= hi + 1e-12), axis=1)
