"""Baseline ``cosserat-wrench`` of ``ph_shape``: backbones by the physics instead of a PH quintic.

Each posture's backbone is the static Cosserat rod clamped at the measured base pose
whose tip, under the fitted tip force and couple (and the rod's own weight), reaches
the measured tip pose (:class:`optikin.physics.reconstruction.ShapeReconstructor`,
warm-started along the samples). The rod is one uniform, unactuated segment with the
stiffnesses of the kind's ``cosserat_wrench`` options; its reference length per
posture is the backbone length the PH methods use for it. A fit that does not reach
the tip pose (status ``not_converged``) has no backbone: its distances are NaN.

The fit has more than one exact solution: from the unloaded rod (the reconstructor's
cold start) the continuation, or a start carried over from another posture, can end on a
stretched, sheared, coiled rod under a tip force of hundreds of newtons that reaches the
same tip pose. So every posture starts from the clamp wrench of the circular arc of its end
poses (:meth:`~optikin.physics.reconstruction.ShapeReconstructor.arc_start`: the pure couple
``E I theta / L`` about ``t0 x t1`` that bends a weightless rod into the arc, plus the force
carrying the rod's weight); the previous posture's fit is only a second candidate, kept when
its shape has less elastic energy. A posture whose two candidates both reach the tip pose
with shapes more than ``ambiguity_distance`` apart is counted ``ambiguous``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from optikin.data.markers import MarkerRecording
from optikin.physics.model import RodArm
from optikin.physics.reconstruction import Reconstruction, ReconstructionOptions, ShapeReconstructor
from optikin.physics.rod import Rod
from optikin.problems.ph_shape.options import CosseratWrenchOptions

NAME = "cosserat-wrench"
"""The baseline's name in ``baselines``."""
MODULUS = 1.0e6
"""Young's modulus of the rod [Pa]: only the products E A, E I, G A, G J enter the equilibrium."""


@dataclass
class WrenchRun:
    """The ``cosserat-wrench`` fits of every posture.

    Attributes
    ----------
    fits:
        One reconstruction per posture.
    backbones:
        Backbone nodes per posture ``(N, S, 3)`` [m], NaN where the fit did not converge.
    build_seconds:
        Time to build the reconstructor [s].
    """

    fits: list[Reconstruction]
    backbones: np.ndarray
    build_seconds: float

    @property
    def status(self) -> list[str]:
        return [f.status for f in self.fits]

    @property
    def seconds(self) -> np.ndarray:
        return np.array([f.seconds for f in self.fits])

    @property
    def iterations(self) -> np.ndarray:
        return np.array([f.iterations for f in self.fits])

    @property
    def energies(self) -> np.ndarray:
        """Elastic energy of each kept shape [J]."""
        return np.array([f.energy for f in self.fits])

    @property
    def tip_forces(self) -> np.ndarray:
        """``|F|`` of each fitted tip force [N]."""
        return np.array([float(np.linalg.norm(f.wrench[:3])) for f in self.fits])

    @property
    def ambiguous(self) -> np.ndarray:
        """Per posture: other candidates reached the tip pose with another shape."""
        return np.array([f.ambiguous for f in self.fits])


def wrench_arm(options: CosseratWrenchOptions, length: float) -> RodArm:
    """One uniform unactuated rod of reference length ``length`` [m] with the stiffness and mass of ``options``."""
    area = options.EA / MODULUS
    shear = options.GA / area
    rod = Rod(
        length=length,
        area=area,
        second_moment=options.EI / MODULUS,
        polar_moment=options.GJ / shear,
        outer_radius=float(np.sqrt(area / np.pi)),
        youngs_modulus=MODULUS,
        shear_modulus=shear,
        density=options.mass_per_length / area,
        gravity=options.gravity,
    )
    return RodArm.single(rod)


def run_wrench(recording: MarkerRecording, lengths: np.ndarray, options: CosseratWrenchOptions) -> WrenchRun:
    """Fit every posture of ``recording`` from its arc, the previous fit as a candidate (module docstring).

    Parameters
    ----------
    recording:
        End poses (base already averaged when the kind's ``fixed_base`` is set).
    lengths:
        Reference length of each posture ``(N,)`` [m].
    options:
        The rod.
    """
    tic = time.perf_counter()
    arm = wrench_arm(options, float(np.median(lengths)))
    reconstructor = ShapeReconstructor(arm, ReconstructionOptions(steps_per_segment=options.steps))
    build = time.perf_counter() - tic
    base_poses = list(zip(recording.base_position, recording.base_orientation))
    tip_poses = list(zip(recording.tip_position, recording.tip_orientation))
    fits = reconstructor.reconstruct_sequence(base_poses, tip_poses, lengths)
    backbones = np.stack([f.solution.positions for f in fits])
    backbones[np.array([f.status != "ok" for f in fits])] = np.nan
    return WrenchRun(fits, backbones, build)


def distances_to_polylines(polylines: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point ``(N, K, 3)`` to polyline ``n`` ``(N, S, 3)``: ``(N, K)`` [m] (NaN for a NaN polyline).

    The closest point of each segment (projection clamped to the segment), the least over the segments.
    """
    a, b = polylines[:, None, :-1], polylines[:, None, 1:]  # (N, 1, S - 1, 3)
    p = points[:, :, None, :]  # (N, K, 1, 3)
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-300), 0.0, 1.0)
    d = np.linalg.norm(a + t[..., None] * ab - p, axis=-1)  # (N, K, S - 1)
    with np.errstate(invalid="ignore"):
        return np.min(d, axis=-1)
