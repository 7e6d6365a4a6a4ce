"""Baseline ``cosserat-wrench`` of ``ph_shape``: backbones by the physics instead of a PH quintic.

Each posture's backbone is the static Cosserat rod clamped at the measured base pose
whose tip, under the fitted tip force and couple (and the rod's own weight), reaches
the measured tip pose (:class:`optikin.physics.reconstruction.ShapeReconstructor`,
warm-started along the samples). The rod is one uniform, unactuated segment with the
stiffnesses of the kind's ``cosserat_wrench`` options; its reference length per
posture is the backbone length the PH methods use for it. A fit that does not reach
the tip pose (status ``not_converged``) has no backbone: its distances are NaN.

The fit has more than one exact solution: from the unloaded rod (the reconstructor's
cold start) the continuation can end on a stretched, sheared, coiled rod under a
tip force of hundreds of newtons that reaches the same tip pose. So the first
posture, and every posture after a failed fit, starts from the clamp wrench of the
circular arc of the end poses (:func:`arc_guess`: the pure couple ``E I theta / L``
about ``t0 x t1`` that bends a weightless rod into the arc, plus the force carrying
the rod's weight); every other posture from the previous posture's fit.
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


def arc_guess(options: CosseratWrenchOptions, t0: np.ndarray, t1: np.ndarray, length: float) -> np.ndarray:
    """Clamp wrench ``(n(0) [N], m(0) [N m])`` of the circular arc from tangent ``t0`` to ``t1`` of length ``length``.

    A pure couple ``E I kappa`` with ``kappa = theta / L`` (``theta`` the angle between the
    unit tangents) about ``t0 x t1`` bends the rod into that arc (Euler's elastica under an
    end couple); ``n(0) = (rho A L) g`` carries the rod's weight (``n' + f = 0`` with ``f = rho A g``
    and a free tip, ``n(L) = 0``).
    """
    axis = np.cross(t0, t1)
    sine = float(np.linalg.norm(axis))
    theta = float(np.arctan2(sine, float(np.dot(t0, t1))))
    couple = options.EI * theta / length * axis / sine if sine > 1e-12 else np.zeros(3)
    force = options.mass_per_length * length * np.asarray(options.gravity, dtype=float)
    return np.concatenate([force, couple])


def run_wrench(recording: MarkerRecording, lengths: np.ndarray, options: CosseratWrenchOptions) -> WrenchRun:
    """Fit every posture of ``recording`` in order, each started from the previous fit (module docstring).

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
    t0, t1 = recording.base_direction, recording.tip_direction
    fits: list[Reconstruction] = []
    guess: np.ndarray | None = None
    for i in range(len(recording)):
        if guess is None:
            guess = arc_guess(options, t0[i], t1[i], float(lengths[i]))
        base = (recording.base_position[i], recording.base_orientation[i])
        tip = (recording.tip_position[i], recording.tip_orientation[i])
        fit, z = reconstructor.reconstruct(base, tip, float(lengths[i]), guess)
        fits.append(fit)
        guess = z if fit.status == "ok" and np.all(np.isfinite(z)) else None
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
