"""The whole-CBHA inverse problem of seed 004: the elongation distribution of section IV, and checks of answers.

Seed 004, section IV-A: "since the length of an inter-vertebra is a fraction of
the tube length, the elongation of each inter-vertebra at any time represents a
percentage of the total length of the tube. This percentage can be obtained by
considering the minimum and the maximum elongations of each inter-vertebra
listed in Table I." The percentages themselves (Fig. 6) are not in the text, and
the sentence reads two ways; both are offered (:data:`DISTRIBUTIONS`), each an
affine rule ``q_{m,k} = a_k + b_k L_{m,s}`` with ``L_{m,s} = sum_{j in s} q_{m,j}``
the length of tube ``m`` along section ``s`` (the quantity the wire
potentiometers measure and the pressures set):

``distributed``: a fixed share of the tube, the share of the mid-range lengths,

    q_{m,k} = c_k L_{m,s},    c_k = (q_min,k + q_max,k) / sum_{j in s} (q_min,j + q_max,j).

The shares at the minimum and at the maximum of Table I differ from ``c_k`` by at
most 0.5 percentage points. A leg lies within Table I exactly when its tube length
lies in ``[max_k q_min,k / c_k, min_k q_max,k / c_k]``: 67.2-147.8 mm for section 1
(Table I's sums: 65-150 mm) and 59.2-145.8 mm for section 2 (58-147 mm).

``affine``: the elongation above the minimum shared in proportion to the Table I ranges,

    q_{m,k} = q_min,k + (q_max,k - q_min,k) / sum_{j in s} (q_max,j - q_min,j) * (L_{m,s} - sum_{j in s} q_min,j),

so every leg sits at the same fraction of its own range: all at ``q_min`` when the
tube is shortest, all at ``q_max`` when it is longest. Every leg lies within Table I
exactly when the tube length does (65-150 mm and 58-147 mm). This is how the
synthetic recording moves the legs (:func:`optikin.data.markers.configurations_from_fractions`:
``q_min,k + f (q_max,k - q_min,k)`` with one ``f`` per section and tube), so its
configurations satisfy this rule exactly and the mid-range one only to about 0.1 mm.

As residual rows of the inverse problem (:mod:`optikin.ik.formulation`)
the distribution is ``q_{m,k}(q) - a_k - b_k L_{m,s}(q)`` for every platform but the
last of each section (whose row follows: the ``b_k`` add up to one and the ``a_k`` to
zero): 42 rows of full rank, leaving the 48 platform variables the 6 degrees of
freedom of the 6 tube lengths.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.arms.cbha import CBHAArm, CBHAGeometry, printed_leg_lengths

DISTRIBUTIONS = ("distributed", "affine")
"""Readings of seed 004's elongation distribution (module docstring)."""


def section_slices(geometry: CBHAGeometry) -> list[slice]:
    """Platform indices (0-based) of each section."""
    ends = np.cumsum((0,) + geometry.platforms_per_section)
    return [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]


def elongation_fractions(geometry: CBHAGeometry) -> np.ndarray:
    """``c_k``, one per platform: its share of its section's mid-range length (module docstring)."""
    mid = np.add(geometry.leg_min, geometry.leg_max)
    return np.concatenate([mid[s] / mid[s].sum() for s in section_slices(geometry)])


def distribution_coefficients(geometry: CBHAGeometry, elongation: str = "distributed") -> tuple[np.ndarray, np.ndarray]:
    """``(a_k, b_k)``, one per platform: leg ``q_{m,k} = a_k + b_k L_{m,s}`` (module docstring)."""
    if elongation == "distributed":
        c = elongation_fractions(geometry)
        return np.zeros_like(c), c
    if elongation != "affine":
        raise ValueError(f"elongation must be one of {', '.join(DISTRIBUTIONS)}, got {elongation!r}")
    lo, hi = np.asarray(geometry.leg_min, dtype=float), np.asarray(geometry.leg_max, dtype=float)
    b = np.concatenate([(hi[s] - lo[s]) / (hi[s] - lo[s]).sum() for s in section_slices(geometry)])
    a = lo - b * np.concatenate([np.full(s.stop - s.start, lo[s].sum()) for s in section_slices(geometry)])
    return a, b


def distributed_tube_range(geometry: CBHAGeometry, elongation: str = "distributed") -> tuple[np.ndarray, np.ndarray]:
    """Per section, the tube lengths ``[lower, upper]`` [m] whose distributed legs are all within Table I."""
    a, b = distribution_coefficients(geometry, elongation)
    lo, hi = np.asarray(geometry.leg_min), np.asarray(geometry.leg_max)
    slices = section_slices(geometry)
    return (
        np.array([np.max((lo[s] - a[s]) / b[s]) for s in slices]),
        np.array([np.min((hi[s] - a[s]) / b[s]) for s in slices]),
    )


def distribution_rows(arm: CBHAArm, q: ca.SX, elongation: str = "distributed") -> ca.SX:
    """``q_{m,k}(q) - a_k - b_k L_{m,s}(q)`` for all platforms but the last of each section, metres
    (module docstring)."""
    a, b = distribution_coefficients(arm.geometry, elongation)
    legs = ca.reshape(arm.leg_length_expressions(q), 3, arm.geometry.n_platforms)  # tube x platform
    rows = []
    for s in section_slices(arm.geometry):
        tube = ca.sum2(legs[:, s])
        rows += [legs[:, k] - a[k] - b[k] * tube for k in range(s.start, s.stop - 1)]
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


def distribution_deviation(arm: CBHAArm, X: np.ndarray, elongation: str = "distributed") -> np.ndarray:
    """Per configuration, ``max |q_{m,k} - a_k - b_k L_{m,s}|`` [m]: how far its legs are from the distribution."""
    legs = legs_of(arm, X).reshape(len(np.atleast_2d(X)), -1, 3)  # sample, platform, tube
    a, b = distribution_coefficients(arm.geometry, elongation)
    deviation = np.empty_like(legs)
    for s in section_slices(arm.geometry):
        tube = legs[:, s].sum(axis=1, keepdims=True)
        deviation[:, s] = legs[:, s] - a[s, None] - b[s, None] * tube
    return np.abs(deviation).max(axis=(1, 2))


def leg_checks(arm: CBHAArm, targets: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest leg-length error against the targets per sample (printed eqs. (7)-(9)), and whether every
    leg lies within Table I."""
    legs = legs_of(arm, X)
    lo, hi = arm.leg_limits()
    return np.abs(legs - targets).max(axis=1), np.all((legs >= lo - 1e-12) & (legs <= hi + 1e-12), axis=1)
