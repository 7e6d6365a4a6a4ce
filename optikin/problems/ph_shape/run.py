"""Solve a ``ph_shape`` problem: every method's backbones and their distances to the markers."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from optikin.curves import ShapeData
from optikin.data.markers import MarkerRecording, estimated_tip, rotation_onto
from optikin.problems import ProblemContext
from optikin.problems.ph_shape import cc
from optikin.problems.ph_shape.c1 import SECTIONS, C1Chain, c1_chain_data, joint_poses, joint_tangents
from optikin.problems.ph_shape.options import PHShapeOptions
from optikin.problems.ph_shape.wrench import NAME, WrenchRun, distances_to_polylines, run_wrench
from optikin.problems.ph_shared import (
    MethodRun,
    backbone_lengths,
    distances_to_curves,
    end_data,
    shape_samples,
    solve_methods,
    solver_name,
)
from optikin.solvers.ph_backends import PHAdapter

OTHERS = (NAME, cc.NAME, cc.TWO_ARCS)
"""The baselines the kind runs itself (not ``ph`` presets)."""


@dataclass
class ShapeOutcome:
    """What a ``ph_shape`` run found.

    Attributes
    ----------
    recording:
        The recording solved (base pose averaged with ``fixed_base``).
    lengths:
        Backbone length of each posture ``(N,)`` [m].
    samples:
        End data of each posture.
    runs:
        Every method (the solver first), by preset name.
    distances:
        Per method, distance of each intermediate marker to its curve ``(N, K)`` [m] (``cosserat-wrench``
        ``cc-arc`` and ``cc-two-arcs`` included when listed).
    solver:
        The solver's preset name.
    options:
        The kind's options.
    wrench:
        The ``cosserat-wrench`` fits, when listed.
    chain:
        The C1 chain of every method, with ``c1_joint``.
    arcs:
        The ``cc-arc`` arcs, when listed.
    two_arcs:
        The ``cc-two-arcs`` arcs, when listed.
    held_out:
        Distance of each intermediate marker to the solver's backbone whose tip tangent did not use it
        ``(N, K)`` [m] (:func:`held_out_distances`), for a recording whose tip pose is estimated from its markers.
    """

    recording: MarkerRecording
    lengths: np.ndarray
    samples: list[ShapeData]
    runs: dict[str, MethodRun]
    distances: dict[str, np.ndarray]
    solver: str
    options: PHShapeOptions
    wrench: WrenchRun | None = None
    chain: C1Chain | None = None
    arcs: cc.CCRun | None = None
    two_arcs: cc.TwoArcs | None = None
    held_out: np.ndarray | None = None

    @property
    def main(self) -> MethodRun:
        """The solver's run."""
        return self.runs[self.solver]


def run(ctx: ProblemContext) -> ShapeOutcome:
    """Rebuild every posture's backbone with each method; marker distances per method."""
    options: PHShapeOptions = ctx.options
    source = f"{ctx.path.name}: data"
    recording, lengths, samples = shape_samples(tip_of(ctx, ctx.load_data(), options), options, source)
    runs = solve_methods(ctx, options.energy, options.free_speeds, samples, others=OTHERS)
    distances = {name: distances_to_curves(method.curves, recording.markers) for name, method in runs.items()}
    wrench = None
    if NAME in ctx.spec.baselines:
        used = np.array([s.length for s in samples], dtype=float)  # the PH methods' lengths (raised to the chord)
        with ctx.progress.task(f"{ctx.spec.kind}: {len(samples)} samples x {NAME}", total=1) as advance:
            wrench = run_wrench(recording, used, options.cosserat_wrench)
            advance()
        distances[NAME] = distances_to_polylines(wrench.backbones, recording.markers)
    arcs = None
    if cc.NAME in ctx.spec.baselines:
        arcs = cc.run_cc(recording)
        distances[cc.NAME] = arcs.distances(recording.markers)
    two_arcs = None
    if cc.TWO_ARCS in ctx.spec.baselines:
        two_arcs = cc.run_two_arcs(recording, source)
        distances[cc.TWO_ARCS] = two_arcs.distances(recording.markers)
    chain = c1_chain(ctx, recording, options, source) if options.c1_joint else None
    held_out = held_out_distances(ctx, recording, options, source)
    return ShapeOutcome(
        recording, lengths, samples, runs, distances, solver_name(ctx), options, wrench, chain, arcs, two_arcs, held_out
    )


def tip_of(ctx: ProblemContext, recording: MarkerRecording, options: PHShapeOptions) -> MarkerRecording:
    """``recording`` with ``options.tip``'s tip orientation: its own, or that of
    :func:`~optikin.data.markers.estimated_tip` (from the base point averaged with ``fixed_base``)."""
    if options.tip == "recorded":
        return recording
    try:
        return estimated_tip(recording.with_fixed_base() if options.fixed_base else recording)
    except ValueError as exc:
        raise ctx.error("options.tip", str(exc)) from None


def held_out_distances(
    ctx: ProblemContext, recording: MarkerRecording, options: PHShapeOptions, source: str
) -> np.ndarray | None:
    """Each intermediate marker's distance to the solver's backbone built without it ``(N, K)`` [m].

    For a recording whose tip tangent was estimated from its markers
    (:attr:`~optikin.data.markers.MarkerRecording.held_out_tip_directions`; None otherwise): marker ``k`` is
    scored on the minimum-energy PH quintic from the base pose to the tip point along the tangent estimated
    without it, its backbone length by ``options.length`` from the other markers.
    """
    directions = recording.held_out_tip_directions
    if directions is None:
        return None
    adapter = ctx.backend(PHAdapter)
    model = adapter.model(options.energy, options.free_speeds)
    n, K = recording.markers.shape[0], recording.markers.shape[1]
    out = np.empty((n, K))
    for k in range(K):
        tip = rotation_onto(recording.base_orientation, directions[:, k])
        others = replace(
            recording, tip_orientation=tip, markers=np.delete(recording.markers, k, axis=1), marker_vertebrae=()
        )
        samples = end_data(others, backbone_lengths(others, options.length, source), source)
        curves = model.curves(adapter.solve(model, samples), samples)
        out[:, k] = distances_to_curves(curves, recording.markers[:, k : k + 1])[:, 0]
    return out


def c1_chain(ctx: ProblemContext, recording: MarkerRecording, options: PHShapeOptions, source: str) -> C1Chain:
    """Both sections of every posture with every ``ph`` method (:mod:`optikin.problems.ph_shape.c1`)."""
    position, orientation, marker = joint_poses(recording, source)
    links = c1_chain_data(
        (recording.base_position, recording.base_direction),
        (position, joint_tangents(orientation)),
        (recording.tip_position, recording.tip_direction),
        source,
    )
    runs = {
        name: solve_methods(ctx, options.energy, False, links[name], f" (C1 {name})", others=OTHERS)
        for name in SECTIONS
    }
    return C1Chain(position, orientation, marker, links, runs)
