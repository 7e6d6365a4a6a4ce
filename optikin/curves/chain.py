"""Chains of PH quintics: links joined with C1 or C0 continuity (seed 002, section III, eqs. 15-22).

A chain is a list of links, each a PH quintic Hermite interpolant chosen by
minimum energy (:class:`optikin.curves.min_energy.ShapeEnergyModel`):

* **C1** (eqs. 15-18): ``r_k(1) = r_{k+1}(0)`` and ``r_k'(1) = r_{k+1}'(0)``; the
  joints carry one point and one derivative (direction and speed), shared by the
  two links that meet there. Build the links with :func:`c1_links`.
* **C0** (eqs. 19-22): only ``r_k(1) = r_{k+1}(0)``; each link has its own end
  directions (e.g. an arm tip holding a rope at an angle), as in the closed chain
  of seed 002 section IV.B (CBHA 1, rope, CBHA 2).

:func:`solve_chain` checks the joints (naming the link at fault) and solves each
link; links are independent given their end data, so they are solved one by one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from optikin.curves.min_energy import ShapeData, ShapeEnergyModel, ShapeSolution
from optikin.curves.ph_quintic import PHQuintic
from optikin.errors import InputDataError

JOINT_TOLERANCE = 1e-9
"""Largest mismatch at a joint, relative to the chain's size."""


@dataclass
class ChainLink:
    """One link of a chain: its end data, its minimum-energy solution and its curve."""

    data: ShapeData
    solution: ShapeSolution
    curve: PHQuintic


def c1_links(points: np.ndarray, directions: np.ndarray, speeds: np.ndarray, *, source: str = "") -> list[ShapeData]:
    """End data of a C1 chain through ``points`` (``m+1 x 3``) with joint ``directions`` and ``speeds`` (eqs. 15-18).

    Link ``k`` runs from joint ``k`` to ``k+1`` with ``r_k'(0) = speeds[k] t_k`` and
    ``r_k'(1) = speeds[k+1] t_{k+1}``, so adjacent links share the derivative.
    """
    points, directions = np.asarray(points, dtype=float), np.asarray(directions, dtype=float)
    speeds = np.asarray(speeds, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 2:
        raise InputDataError(
            f"expected joint points of shape (m+1, 3), m >= 1, got {points.shape}", source=source, field="points"
        )
    if directions.shape != points.shape or speeds.shape != points.shape[:1]:
        raise InputDataError(
            f"need one direction and one speed per joint ({points.shape[0]}), got "
            f"{directions.shape} and {speeds.shape}",
            source=source,
            field="directions",
        )
    return [
        ShapeData.checked(
            points[k],
            directions[k],
            points[k + 1],
            directions[k + 1],
            speeds=(speeds[k], speeds[k + 1]),
            source=source,
            sample=k,
        )
        for k in range(points.shape[0] - 1)
    ]


def check_joints(links: Sequence[ShapeData], continuity: str, *, source: str = "") -> None:
    """Raise :class:`InputDataError` naming the first link whose start does not meet the previous link's end."""
    if continuity not in ("C0", "C1"):
        raise ValueError(f"continuity must be 'C0' or 'C1', got {continuity!r}")
    if not links:
        raise InputDataError("a chain needs at least one link", source=source)
    size = max(max(float(np.linalg.norm(d.p1 - d.p0)), d.length or 0.0) for d in links)
    for k in range(1, len(links)):
        before, after = links[k - 1], links[k]
        gap = np.linalg.norm(after.p0 - before.p1)
        if gap > JOINT_TOLERANCE * size:
            raise InputDataError(
                f"link starts {gap:.3g} away from the end of link {k - 1} (C0 needs r_k(1) = "
                f"r_k+1(0), seed 002 eqs. 17, 21)",
                source=source,
                sample=k,
                field="p0",
            )
        if continuity == "C1":
            if before.speeds is None or after.speeds is None:
                raise InputDataError(
                    "a C1 chain needs the end speeds of every link", source=source, sample=k, field="speeds"
                )
            d_end = before.speeds[1] * before.t1
            d_start = after.speeds[0] * after.t0
            if np.linalg.norm(d_start - d_end) > JOINT_TOLERANCE * max(float(np.linalg.norm(d_end)), size):
                raise InputDataError(
                    f"start derivative differs from the end derivative of link {k - 1} "
                    f"(C1 needs r_k'(1) = r_k+1'(0), seed 002 eqs. 16, 18)",
                    source=source,
                    sample=k,
                    field="t0",
                )


def solve_chain(
    links: Sequence[ShapeData],
    model: ShapeEnergyModel,
    continuity: str = "C0",
    *,
    method: str = "newton",
    source: str = "",
) -> list[ChainLink]:
    """Minimum-energy PH quintic for every link, after checking the joints for ``continuity``."""
    check_joints(links, continuity, source=source)
    if continuity == "C1" and model.free_speeds:
        raise ValueError("a C1 chain fixes the speeds at its joints: use a model with given speeds")
    solvers: dict[str, Callable[[ShapeData], ShapeSolution]] = {
        "newton": model.solve_newton,
        "nlp": model.solve_nlp,
        "grid": model.solve_grid,
    }
    if method not in solvers:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(solvers)}")
    links_out = []
    for data in links:
        solution = solvers[method](data)
        links_out.append(ChainLink(data, solution, model.curve(solution, data)))
    return links_out
