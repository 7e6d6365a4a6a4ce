"""Solve a ``ph_ik`` problem: backbones, their tube lengths (both frames) and the comparators' lengths."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import cast

import casadi as ca
import numpy as np

from optikin.arms.cbha import CBHAArm
from optikin.baselines.ph_comparators import COMPARATORS, ComparatorRun, run_comparator
from optikin.curves import ShapeData, ShapeEnergyModel
from optikin.curves.tubes import CBHA_TUBE_ANGLES, TubeLayout, tube_lengths
from optikin.data.markers import MarkerRecording
from optikin.errors import InputDataError
from optikin.fastcall import BufferedFunction
from optikin.problems import ProblemContext
from optikin.problems.ph_ik.options import PHIkOptions
from optikin.problems.ph_shared import MethodRun, shape_samples, solve_methods, solver_name
from optikin.status import Status


@dataclass
class IkOutcome:
    """What a ``ph_ik`` run found (lengths in metres, times in seconds per posture).

    Attributes
    ----------
    recording, reference:
        The recording solved (base averaged with ``fixed_base``) and its tube lengths ``(N, 3)``.
    lengths, samples:
        Backbone length of each posture ``(N,)`` and its end data.
    runs:
        Every ``ph`` method (the solver first), by preset name.
    layout:
        The tubes around the backbone and the frame that carries them.
    tubes, ik_seconds:
        Per ``ph`` method, tube lengths ``(N, 3)``; per method and comparator, the time per posture.
    other_frame, other_tubes:
        The other frame and the solver's tube lengths carried by it.
    comparators:
        The comparators of Tables II-III listed in ``baselines``, by name.
    """

    recording: MarkerRecording
    reference: np.ndarray
    lengths: np.ndarray
    samples: list[ShapeData]
    runs: dict[str, MethodRun]
    layout: TubeLayout
    tubes: dict[str, np.ndarray]
    ik_seconds: dict[str, np.ndarray]
    other_frame: str
    other_tubes: np.ndarray
    comparators: dict[str, ComparatorRun]
    solver: str
    options: PHIkOptions

    @property
    def main(self) -> MethodRun:
        """The solver's run."""
        return self.runs[self.solver]


def tube_length_function(model: ShapeEnergyModel, layout: TubeLayout) -> ca.Function:
    """``(x, P, n0) -> (L_1, ..., L_M)``: the tubes of the model's curve at its free parameters ``x``.

    The curve is the model's own (:meth:`ShapeEnergyModel.symbols`), of the same
    ``x`` and parameter vector ``P`` as its energy; ``n0`` is the reference normal.
    """
    x, P, curve = model.symbols()
    n0 = ca.SX.sym("n0", 3)
    return ca.Function("ph_tube_lengths", [x, P, n0], [tube_lengths(curve, n0, layout)], ["x", "P", "n0"], ["L"])


def timed_tube_lengths(
    function: ca.Function, run: MethodRun, samples: list[ShapeData], normals: np.ndarray, compiled: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Tube lengths ``(N, M)`` of a method's solutions, one buffered call per sample, and each call's time."""
    f = BufferedFunction(function, compiled=compiled)
    x_in, p_in, n_in = f.inputs
    out = f.outputs[0]
    lengths, seconds = np.full((len(samples), out.size), np.nan), np.zeros(len(samples))
    for i, (sol, data) in enumerate(zip(run.solutions, samples)):
        if sol.status != Status.OK:
            continue
        tic = time.perf_counter()
        x_in[:] = sol.x
        p_in[:] = data.parameters()
        n_in[:] = normals[i]
        f()
        lengths[i] = out
        seconds[i] = time.perf_counter() - tic
    return lengths, seconds


def layout_of(ctx: ProblemContext, options: PHIkOptions) -> TubeLayout:
    """The tubes of ``options`` (the CBHA's radii by default)."""
    if options.tube_radius is None:
        if not isinstance(ctx.arm, CBHAArm):
            raise ctx.error("options.tube_radius", "required for an arm that is not a CBHA: [base, tip] in metres")
        return TubeLayout.cbha(ctx.arm.geometry, options.frame)
    r0, r1 = options.tube_radius
    return TubeLayout(float(r0), float(r1), CBHA_TUBE_ANGLES, options.frame)


def comparators_of(ctx: ProblemContext) -> list[str]:
    """The comparators listed in ``baselines``; they need a CBHA."""
    names = [n for n in COMPARATORS if n in ctx.spec.baselines]
    if names and not isinstance(ctx.arm, CBHAArm):
        raise ctx.error("baselines", f"{names[0]}: needs a cbha arm (CBHA inverse kinematics), not {ctx.arm_type!r}")
    return names


def method_tubes(
    runs: dict[str, MethodRun], samples: list[ShapeData], layout: TubeLayout, normals: np.ndarray
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per method: tube lengths, and time per posture (shape solve plus one tube-length call)."""
    tubes, ik_seconds = {}, {}
    for name, method in runs.items():
        function = tube_length_function(method.model, layout)
        tubes[name], tube_seconds = timed_tube_lengths(function, method, samples, normals, method.compiled)
        ik_seconds[name] = method.seconds + tube_seconds
    return tubes, ik_seconds


def run(ctx: ProblemContext) -> IkOutcome:
    """Backbones of every ``ph`` method, their tube lengths, and the comparators of Tables II-III."""
    options: PHIkOptions = ctx.options
    solver = solver_name(ctx)
    layout = layout_of(ctx, options)
    comparators = comparators_of(ctx)
    recording = ctx.load_data()
    source = f"{ctx.path.name}: data"
    if recording.tube_lengths is None:
        raise InputDataError(
            "no reference tube lengths: the recording needs columns L1, L2, L3", source=source, field="L1"
        )
    reference = recording.tube_lengths
    recording, lengths, samples = shape_samples(recording, options, source)
    runs = solve_methods(ctx, options.energy, options.free_speeds, samples, others=COMPARATORS)
    normals = recording.base_normal
    tubes, ik_seconds = method_tubes(runs, samples, layout, normals)
    other = "euler_rodrigues" if layout.frame == "rmf" else "rmf"
    other_tubes = tube_lengths(runs[solver].curves, normals, layout.with_frame(other))
    found = {name: run_comparator(cast(CBHAArm, ctx.arm), name, recording, source) for name in comparators}
    ik_seconds |= {name: c.seconds for name, c in found.items()}
    return IkOutcome(
        recording,
        reference,
        lengths,
        samples,
        runs,
        layout,
        tubes,
        ik_seconds,
        other,
        other_tubes,
        found,
        solver,
        options,
    )
