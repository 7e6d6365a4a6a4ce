"""A pneumatic Cosserat rod as the tracked plant, actuated through the controller's constant-curvature model.

The controller keeps its constant-curvature (CC) model of a multi-section arm
(:class:`~optikin.arms.constant_curvature.ConstantCurvatureArm`); the simulated arm is a
static Cosserat rod (:mod:`optikin.physics`) with three pressurised chambers per
section, 120 degrees apart (a CBHA-like trunk, :func:`optikin.physics.cbha_chambers`).
A section's CC configuration ``(S, theta, phi)`` is turned into its three chamber
pressures by the nominal map: the pressures whose equilibrium, without gravity and
payload, is that CC section.

The nominal map. Without external loads the section wrench of rod and chambers is
zero along the whole arm (free tip; :mod:`optikin.physics.pneumatic`), so inside
section ``k`` the rod carries ``n = sum_i p_i a d3`` and
``m = sum_i p_i a (R r_i) x d3``: a uniform extension ``v3 = 1 + sum_i p_i a / (E A)``
and a uniform curvature ``u = (a r / (E I)) sum_i p_i (sin a_i, -cos a_i, 0)`` in the
material frame, whatever the other sections do (chambers act inside their own
section only). A uniform ``u = (theta / L0) (-sin phi, cos phi, 0)`` over the rest
length ``L0`` is the rotation ``Rz(phi) Ry(theta) Rz(-phi)`` of the CC convention and
the stretched length is ``S = L0 v3``, so the CC section is reproduced exactly by

    sum_i p_i = (E A / a) (S / L0 - 1),    sum_i p_i (cos a_i, sin a_i) = -(E I theta / (a r L0)) (cos phi, sin phi),

whose solution for three chambers at ``a_i = 0, 2 pi / 3, 4 pi / 3`` is

    p_i = (E A / (3 a)) (S / L0 - 1) - (2 E I theta / (3 a r L0)) cos(phi - a_i).

(The rod bends away from the pressurised side.) With a rest length below the
shortest CC length every command stretches the rod; a chamber on the inside of a
strong bend may still need a pressure below ambient, which the map gives as it is
(the plant model has no pressure limits). Gravity (the rod's weight ``rho A g``) and
the payload's weight at the tip are then the only difference between plant and
model: with neither the plant's tip is the CC tip up to the RK4 discretisation error.

The equilibrium of each control step is solved by shooting (compiled Newton by
default), warm-started from the previous steps' base wrenches; a solve without a
usable start ramps the loads from zero (:class:`~optikin.physics.ShootingSolver`).
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from optikin.algebra import dq_from_rotation_translation
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.task import Task
from optikin.physics import Rod, RodArm, RodSolution, Segment, ShootingOptions, ShootingSolver, cbha_chambers
from optikin.physics.pneumatic import CBHA_ANGLES


@dataclass(frozen=True)
class PneumaticRod:
    """Parameters of the CBHA-like rod plant (SI units), one entry per section where a sequence.

    Attributes
    ----------
    youngs_modulus, poisson_ratio, density:
        Material of the whole rod [Pa, -, kg/m^3].
    radius:
        Radius of each section's solid equivalent cross-section [m].
    chamber_offset:
        Distance of each section's three chambers from the backbone [m].
    chamber_area:
        Pressurised area of every chamber [m^2].
    rest_length:
        Unpressurised length of each section [m].
    gravity:
        Gravitational acceleration in the base frame [m/s^2]; zeros for none.
    payload:
        Mass hanging at the tip [kg]; its weight is ``payload * gravity``.
    steps_per_segment:
        RK4 steps per section of the shooting grid.
    compiled:
        Newton on C-compiled residual and Jacobian (about 0.1 ms per warm solve) instead of the VM.
    """

    youngs_modulus: float
    poisson_ratio: float
    density: float
    radius: tuple[float, ...]
    chamber_offset: tuple[float, ...]
    chamber_area: float
    rest_length: tuple[float, ...]
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    payload: float = 0.0
    steps_per_segment: int = 20
    compiled: bool = True

    def rods(self) -> list[Rod]:
        """One :class:`~optikin.physics.Rod` per section."""
        return [
            Rod(
                length=length,
                radius=radius,
                youngs_modulus=self.youngs_modulus,
                poisson_ratio=self.poisson_ratio,
                density=self.density,
                gravity=self.gravity,
            )
            for length, radius in zip(self.rest_length, self.radius)
        ]

    def rod_arm(self) -> RodArm:
        """The arm: each section's rod with its three chambers (the first along ``d1``)."""
        return RodArm(
            segments=tuple(
                Segment(rod=rod, chambers=cbha_chambers(offset, self.chamber_area))
                for rod, offset in zip(self.rods(), self.chamber_offset)
            )
        )


def nominal_pressures(q: np.ndarray, rod: PneumaticRod) -> np.ndarray:
    """The chamber pressures ``(3 m,)`` [Pa] whose equilibrium without gravity and payload is the CC ``q``.

    Parameters
    ----------
    q:
        ``(3 m,)`` ``(S_1, theta_1, phi_1, ..., S_m, theta_m, phi_m)`` [m, rad, rad].
    rod:
        The plant (module docstring for the map and its derivation).

    Returns
    -------
    numpy.ndarray
        Per section its three gauge pressures, in the order of :func:`optikin.physics.cbha_chambers`.
    """
    q = np.asarray(q, dtype=float)
    out = np.empty(q.size)
    angles = np.asarray(CBHA_ANGLES)
    E, a = rod.youngs_modulus, rod.chamber_area
    for k, (R, r, L0) in enumerate(zip(rod.radius, rod.chamber_offset, rod.rest_length)):
        S, theta, phi = q[3 * k : 3 * k + 3]
        area, second_moment = np.pi * R**2, np.pi * R**4 / 4.0
        axial = E * area / (3.0 * a) * (S / L0 - 1.0)
        bending = 2.0 * E * second_moment * theta / (3.0 * a * r * L0)
        out[3 * k : 3 * k + 3] = axial - bending * np.cos(phi - angles)
    return out


class RodPlantSimulator:
    """The rod plant along one run: CC configuration -> pressures -> warm-started equilibrium -> tip.

    Parameters
    ----------
    arm:
        The controller's CC arm (its number of sections sizes the rod).
    rod:
        The plant's parameters.

    Attributes
    ----------
    failures:
        Steps whose equilibrium did not converge since :meth:`reset` (even ramped from zero load);
        their tip is the last converged one (the rod model has no answer there).
    iterations:
        Newton iterations since :meth:`reset`.
    pressure_range:
        Lowest and highest pressure commanded since :meth:`reset` [Pa].

    Raises
    ------
    ValueError
        When ``arm`` is not a constant-curvature arm with one rod section per CC section.
    """

    def __init__(self, arm: ArmModel, rod: PneumaticRod):
        if not isinstance(arm, ConstantCurvatureArm):
            raise ValueError(f"a Cosserat plant is actuated through a constant_curvature model, not {arm.name}")
        m = arm.n_sections
        for name in ("radius", "chamber_offset", "rest_length"):
            if len(getattr(rod, name)) != m:
                raise ValueError(f"{name} needs {m} values (one per section), got {len(getattr(rod, name))}")
        self.rod = rod
        self.solver = ShootingSolver(
            rod.rod_arm(), ShootingOptions(steps_per_segment=rod.steps_per_segment, compiled=rod.compiled)
        )
        self._fixed = np.zeros(12)  # tip force, tip couple, distributed force, gravity
        self._fixed[0:3] = rod.payload * np.asarray(rod.gravity)
        self._fixed[9:12] = rod.gravity
        self.reset()

    def reset(self) -> None:
        """Forget the warm start and the counters (a new run)."""
        self._wrenches: list[np.ndarray] = []  # the last two converged base wrenches
        self.failures, self.iterations = 0, 0
        self.pressure_range = (np.inf, -np.inf)
        self.solution: RodSolution | None = None
        self._tip: tuple[np.ndarray, np.ndarray] | None = None  # the last converged tip (quaternion, position)

    def equilibrium(self, q: np.ndarray) -> RodSolution:
        """The rod's equilibrium for the CC configuration ``q``.

        The solve starts from the last converged base wrench, linearly extrapolated from the
        two before (as :meth:`optikin.physics.ShootingSolver.solve_sequence` does).
        """
        pressures = nominal_pressures(q, self.rod)
        self.pressure_range = (
            min(self.pressure_range[0], float(pressures.min())),
            max(self.pressure_range[1], float(pressures.max())),
        )
        guess = None
        if self._wrenches:
            guess = self._wrenches[-1] if len(self._wrenches) == 1 else 2 * self._wrenches[-1] - self._wrenches[-2]
        solution = self.solution = self.solver.solve(np.concatenate([self._fixed, pressures]), guess)
        self.iterations += solution.iterations
        if solution.ok:
            self._wrenches = [*self._wrenches[-1:], solution.base_wrench]
        else:
            self.failures += 1
        return solution

    def tip(self, q: np.ndarray, task: Task) -> np.ndarray:
        """The plant's tip for ``q``: position ``(3,)`` or dual quaternion ``(8,)`` of the tip frame."""
        solution = self.equilibrium(q)
        if solution.ok or self._tip is None:
            self._tip = (solution.orientations[-1].copy(), solution.tip_position.copy())
        orientation, position = self._tip
        if task == "position":
            return position.copy()
        return dq_from_rotation_translation(orientation, position, check=False)
