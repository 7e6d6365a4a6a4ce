"""Solve a ``ph_chain`` problem: every link of the chain CBHA 1, rope, CBHA 2 with every method."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optikin.curves import ShapeData
from optikin.curves.chain import check_joints
from optikin.data.markers import MarkerRecording, RopeChainRecording
from optikin.problems import ProblemContext
from optikin.problems.ph_chain.options import PHChainOptions
from optikin.problems.ph_shared import MethodRun, backbone_lengths, end_data, solve_methods, solver_name

LINKS = ("CBHA 1", "rope", "CBHA 2")
"""The links of the chain, from the base of CBHA 1 to the base of CBHA 2."""


@dataclass
class ChainOutcome:
    """What a ``ph_chain`` run found.

    Attributes
    ----------
    chain:
        The recording (both arms, the rope).
    arm1, arm2:
        The arms' recordings solved (base averaged with ``fixed_base``).
    links:
        Per link, the end data of each posture (CBHA 2 traversed from its tip).
    runs:
        Per link, every method (the solver first), by preset name.
    solver, options:
        The solver's preset name and the kind's options.
    """

    chain: RopeChainRecording
    arm1: MarkerRecording
    arm2: MarkerRecording
    links: dict[str, list[ShapeData]]
    runs: dict[str, dict[str, MethodRun]]
    solver: str
    options: PHChainOptions

    @property
    def main(self) -> dict[str, MethodRun]:
        """The solver's run of each link."""
        return {name: self.runs[name][self.solver] for name in LINKS}

    @property
    def markers(self) -> dict[str, np.ndarray]:
        """Per link, the markers ``(N, K, 3)`` [m] its curve is checked against."""
        return {"CBHA 1": self.arm1.markers, "rope": self.chain.rope_markers, "CBHA 2": self.arm2.markers}

    @property
    def truths(self) -> dict[str, np.ndarray]:
        """Per link, the ground truth ``(N, M, 3)`` [m]: the arms' backbones (vertebra centres, or the Cosserat
        backbone at every solver node), dense catenary points."""
        assert self.arm1.truth is not None and self.arm2.truth is not None, "a simulated chain has its ground truth"
        return {"CBHA 1": self.arm1.truth.vertebrae, "rope": self.chain.rope_truth, "CBHA 2": self.arm2.truth.vertebrae}


def reversed_data(data: ShapeData) -> ShapeData:
    """The same backbone traversed from its end (CBHA 2 runs from its tip C to its base D)."""
    return ShapeData(
        data.p1, -data.t1, data.p0, -data.t0, None if data.speeds is None else data.speeds[::-1], data.length
    )


def chain_links(
    chain: RopeChainRecording, arm1: MarkerRecording, arm2: MarkerRecording, length: str | float, source: str
) -> dict[str, list[ShapeData]]:
    """End data of every link and posture; the joints are checked (C0, Singh et al. 2018, eqs. 19-22)."""
    n = len(chain)
    links = {
        "CBHA 1": end_data(arm1, backbone_lengths(arm1, length, source), source),
        "rope": [
            ShapeData.checked(
                arm1.tip_position[i],
                chain.rope_directions[i, 0],
                arm2.tip_position[i],
                chain.rope_directions[i, 1],
                length=chain.rope_length,
                source=source,
                sample=i,
            )
            for i in range(n)
        ],
        "CBHA 2": [reversed_data(d) for d in end_data(arm2, backbone_lengths(arm2, length, source), source)],
    }
    for i in range(n):
        check_joints([links[name][i] for name in LINKS], "C0", source=f"{source}: sample {i}")
    return links


def run(ctx: ProblemContext) -> ChainOutcome:
    """Every link of every posture with every method."""
    options: PHChainOptions = ctx.options
    chain: RopeChainRecording = ctx.load_data()
    arm1, arm2 = chain.arm1, chain.arm2
    if options.fixed_base:
        arm1, arm2 = arm1.with_fixed_base(), arm2.with_fixed_base()
    links = chain_links(chain, arm1, arm2, options.length, f"{ctx.path.name}: data")
    free = {name: options.rope_free_speeds if name == "rope" else options.free_speeds for name in LINKS}
    runs = {name: solve_methods(ctx, options.energy, free[name], links[name], f" ({name})") for name in LINKS}
    return ChainOutcome(chain, arm1, arm2, links, runs, solver_name(ctx), options)
