"""Two Cosserat-rod CBHAs holding a hanging rope: seed 002's closed chain on a physical truth.

The source ``synthetic`` of family ``rope_chains`` (:func:`optikin.data.markers.synthetic_rope_chain`)
holds the rope with two CBHA vertebra models, kinematic arms the rope cannot load. The
source ``cosserat`` of the same family holds it with two arms of
:mod:`optikin.data.cosserat_markers` (the real-size pneumatic Cosserat CBHA under gravity),
and the rope's weight loads them:

* **arms**: two arms of :func:`~optikin.data.cosserat_markers.cosserat_cbha_arm` (the
  params of :class:`~optikin.data.cosserat_markers.CosseratMarkerParams`), CBHA 1 clamped at
  the origin, CBHA 2 at ``(base_distance, 0, 0)`` turned half a turn about the vertical,
  facing it; each driven by its own seeded tube pressures (arm 1 draws from stream
  ``[seed, 0]`` exactly as the ``cosserat`` marker source does, arm 2 from ``[seed, 1]``);
* **rope**: a perfectly flexible, inextensible rope of ``rope_length`` and
  ``rope_mass_per_length`` hanging under gravity between the two true tips: the exact
  catenary (:func:`optikin.curves.catenary.catenary`). A rope is a rod whose bending
  stiffness is negligible at its length: a Cosserat rod of a real rope's ``E I`` between two
  points is the catenary up to boundary layers of width ``sqrt(E I / T)`` at its ends
  (millimetres), which a shooting solver resolves poorly (the problem gets stiff as
  ``E I -> 0``) and which no marker 20 mm from an end sees. What a rope does to the arms is
  kept: its end tensions (:meth:`~optikin.curves.catenary.Catenary.end_forces`: along the
  rope's end tangents, their vertical parts adding up to its weight) are the arms' tip
  forces (with the ``payload``'s weight);
* **coupling**: tips, rope and tip forces are made consistent per posture by fixed-point
  iteration: arms solved under the rope's forces (compiled shooting, warm-started), the
  catenary hung between the new tips, its end forces, until no tip moves by more than
  ``coupling_tolerance`` [m]. A posture that does not settle within ``coupling_iterations``,
  whose tips are farther apart than the rope is long, or whose equilibrium is not found is an
  :class:`~optikin.errors.InputDataError` naming it;
* **markers**: each arm recorded as the ``cosserat`` marker source records one (rigid bodies
  at its ends, five markers on each tube, their centroids as backbone markers, potentiometers,
  noise), the rope as the ``synthetic`` chain records it
  (:func:`optikin.data.markers.recorded_rope`: three intermediate markers, one ``end_offset``
  along the rope from each end giving its end directions; stream ``[seed, 2]``).

With ``rope_mass_per_length: 0`` the arms carry no rope and arm 1 is the ``cosserat`` marker
source's recording of the same seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import Field

from optikin.algebra import quat_from_axis_angle, quat_multiply
from optikin.arms.base import ArmModel
from optikin.curves.catenary import Catenary, catenary
from optikin.data.cosserat_markers import (
    CosseratMarkerParams,
    actuation,
    cosserat_cbha_arm,
    record_arm,
)
from optikin.data.markers import RopeChainRecording, recorded_rope, tube_fractions
from optikin.data.sources import register_source
from optikin.errors import InputDataError, SpecError
from optikin.physics import Loads, RodSolution, ShootingOptions, ShootingSolver
from optikin.spec import DataSpec

HALF_TURN = quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi)
"""CBHA 2's base frame relative to CBHA 1's: turned half a turn about the vertical, facing it."""


class CosseratRopeParams(CosseratMarkerParams):
    """``data.params`` of source ``cosserat`` (family ``rope_chains``): both arms (as the ``cosserat``
    marker source's params), the rope and the coupling."""

    rope_length: float = Field(
        0.8,
        gt=0,
        description="rope length [m]; assumed: longer than the two tips get apart along 200 postures of the default "
        "motion and seed (0.36-0.48 m arms bending up to about 90 degrees, 0.22-0.78 m apart)",
    )
    base_distance: float = Field(0.4, gt=0, description="distance between the two arm bases [m]; assumed")
    rope_mass_per_length: float = Field(
        0.05, ge=0, description="rope mass per length [kg/m]; assumed: a PVC skipping rope of 4-5 mm"
    )
    end_offset: float = Field(0.02, gt=0, description="rope marker distance from each end, along the rope [m]")
    rope_markers: tuple[float, ...] = Field(
        (0.25, 0.5, 0.75), min_length=1, description="rope markers, as fractions of its length [-]"
    )
    coupling_tolerance: float = Field(
        1e-9, gt=0, description="largest tip motion [m] between two coupling iterations at the fixed point"
    )
    coupling_iterations: int = Field(60, ge=1, le=1000, description="largest number of coupling iterations [-]")


@dataclass
class CosseratRopeChain(RopeChainRecording):
    """A :class:`~optikin.data.markers.RopeChainRecording` of two Cosserat arms loaded by their rope.

    ``arm1``, ``arm2`` are :class:`~optikin.data.cosserat_markers.CosseratRecording` s in the
    world frame; ``tip_forces`` ``(N, 2, 3)`` [N] the rope's pull on each tip at the fixed point
    (the payload's weight not included); ``coupling_iterations`` the iterations the fixed point took
    (the postures are iterated together).
    """

    tip_forces: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    coupling_iterations: int = 0


def hanging_ropes(tips: np.ndarray, params: CosseratRopeParams, source: str) -> tuple[list[Catenary], np.ndarray]:
    """The catenary between the tips ``(N, 2, 3)`` [m] of each posture and its pull on them ``(N, 2, 3)`` [N]."""
    gravity = np.asarray(params.gravity, dtype=float)
    weight = params.rope_mass_per_length * float(np.linalg.norm(gravity))
    if not np.linalg.norm(gravity) > 0:
        raise InputDataError("a rope hangs only under gravity: it is zero", source=source, field="gravity")
    ropes, forces = [], np.zeros_like(tips)
    for i, (B, C) in enumerate(tips):
        distance = float(np.linalg.norm(C - B))
        if distance >= params.rope_length * (1.0 - 1e-9):
            raise InputDataError(
                f"the tips are {distance:.4g} m apart, the rope is {params.rope_length:.4g} m long",
                source=source,
                sample=i,
                field="rope_length",
            )
        rope = catenary(B, C, params.rope_length, gravity, source=source)
        forces[i] = np.stack(rope.end_forces(weight))
        ropes.append(rope)
    return ropes, forces


def cosserat_rope_chain(
    params: CosseratRopeParams, samples: int, seed: int, source: str = "cosserat rope chain"
) -> CosseratRopeChain:
    """Record ``samples`` postures of two Cosserat CBHAs holding a rope (module docstring).

    Parameters
    ----------
    params:
        The arms, the rope, the coupling and the recorder.
    samples:
        Postures.
    seed:
        Seeds the streams ``[seed, 0]`` (arm 1's motion, then its noise), ``[seed, 1]`` (arm 2's)
        and ``[seed, 2]`` (the rope's noise).
    source:
        Names the recording (and the data in errors).

    Raises
    ------
    optikin.errors.InputDataError
        Naming the posture whose equilibrium is not found, whose tips the rope cannot reach, or
        when the coupling does not settle.
    """
    if not 0 < params.end_offset < params.rope_length / 2 or not all(0 < f < 1 for f in params.rope_markers):
        raise ValueError("need 0 < end_offset < rope_length / 2 and rope marker fractions within (0, 1)")
    rngs = [np.random.default_rng([seed, k]) for k in range(3)]
    n_sections = len(params.section_lengths)
    t = np.arange(samples) * params.stride / params.rate
    low, high = params.pressure_range
    pressures = [
        low + tube_fractions(n_sections, t, rng, params.frequency, params.amplitude) * (high - low) for rng in rngs[:2]
    ]
    q_base = np.asarray(params.base_orientation, dtype=float)
    placements = [
        ((0.0, 0.0, 0.0), params.base_orientation),
        ((params.base_distance, 0.0, 0.0), tuple(float(v) for v in quat_multiply(HALF_TURN, q_base))),
    ]
    solvers = []
    for position, orientation in placements:
        arm = cosserat_cbha_arm(params).model_copy(update={"base_position": position, "base_orientation": orientation})
        solvers.append(ShootingSolver(arm, ShootingOptions(steps_per_segment=params.steps_per_segment, compiled=True)))
    payload = params.payload * np.asarray(params.gravity, dtype=float)
    actuations = [actuation(params, p) for p in pressures]
    forces = np.zeros((samples, 2, 3))
    previous: list[list[RodSolution]] = []
    tips = np.full((samples, 2, 3), np.nan)
    for iteration in range(1, params.coupling_iterations + 1):
        solutions = []
        for k, solver in enumerate(solvers):
            loads = [
                Loads(tip_force=tuple(float(v) for v in payload + forces[i, k]), actuation=tuple(actuations[k][i]))
                for i in range(samples)
            ]
            if previous:
                solutions.append([solver.solve(load, old.base_wrench) for load, old in zip(loads, previous[k])])
            else:
                solutions.append(solver.solve_sequence(loads))
            for i, sol in enumerate(solutions[k]):
                if not sol.ok:
                    raise InputDataError(
                        f"no equilibrium of Cosserat CBHA {k + 1} under the rope: {sol.message}",
                        source=source,
                        sample=i,
                    )
        new_tips = np.stack([[sol.positions[-1] for sol in arm] for arm in solutions], axis=1)  # (N, 2, 3)
        moved = float(np.max(np.abs(new_tips - tips))) if np.all(np.isfinite(tips)) else np.inf
        tips, previous = new_tips, solutions
        ropes, new_forces = hanging_ropes(tips, params, source)
        if moved <= params.coupling_tolerance or np.array_equal(new_forces, forces):
            break
        forces = new_forces
    else:
        raise InputDataError(
            f"arms and rope did not settle within {params.coupling_iterations} coupling iterations (last tip motion "
            f"{moved:.3g} m; data.params.coupling_iterations)",
            source=source,
        )
    arms = [
        record_arm(params, solutions[k], solvers[k].s, t, pressures[k], rngs[k], f"{source}: CBHA {k + 1}")
        for k in range(2)
    ]
    chain = recorded_rope(arms[0], arms[1], ropes, params.rope_markers, params.end_offset, params.noise, rngs[2])
    return CosseratRopeChain(
        chain.arm1,
        chain.arm2,
        chain.rope_length,
        chain.rope_markers,
        chain.rope_directions,
        chain.rope_truth,
        chain.rope_marker_truth,
        tip_forces=forces,
        coupling_iterations=iteration,
    )


@register_source(
    "rope_chains",
    "cosserat",
    "two pneumatic Cosserat-rod CBHAs (real size, gravity) holding a hanging rope (exact catenary) whose weight "
    "loads their tips",
    params=CosseratRopeParams,
)
def cosserat_rope_source(arm: ArmModel, data: DataSpec, params: CosseratRopeParams, path: Path) -> CosseratRopeChain:
    """:func:`cosserat_rope_chain` of ``data.samples`` postures seeded by ``data.seed``.

    The recorded arms are those of ``params``; the problem's ``arm`` is not used.
    """
    try:
        return cosserat_rope_chain(params, data.samples, data.seed, source=f"{Path(path).name}: cosserat")
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
