"""Static Cosserat-rod models of continuum arms: the physical ground truth of optikin's comparisons.

==========================  ==========================================================
:mod:`.rod`                 rod parameters (:class:`Rod`) and the equations it obeys
:mod:`.tendons`             tendon routing and its loads (Rucker & Webster 2011)
:mod:`.pneumatic`           pressurised chambers as axial forces at an offset
:mod:`.model`               segments, arms, loads; the equations as CasADi Functions
:mod:`.shooting`            the BVP by shooting (RK4 + Newton), load derivatives (IFT)
:mod:`.collocation`         the same BVP by Gauss-Legendre collocation and IPOPT
:mod:`.reconstruction`      a shape from its end poses (the fitted tip wrench)
:mod:`.comparison`          backbones from end poses: PH, arc and tip-wrench fit against a relaxed rod
:mod:`.solution`            :class:`RodSolution`, what both solvers return
:mod:`.dynamics_equations`  the rod with inertia and damping, one BDF-alpha time step as a BVP in ``s``
:mod:`.dynamics`            time steps by multiple shooting (:class:`RodDynamics`), their derivatives
==========================  ==========================================================

Example
-------
>>> from optikin.physics import Loads, Rod, RodArm, ShootingSolver
>>> rod = Rod(length=0.3, radius=0.01, youngs_modulus=1e6, poisson_ratio=0.5, density=1000.0)
>>> solver = ShootingSolver(RodArm.single(rod))
>>> solution = solver.solve(Loads(tip_force=(0.01, 0.0, 0.0)))
>>> solution.status
'ok'
"""

from optikin.physics.collocation import CollocationOptions, CollocationSolver
from optikin.physics.dynamics import (
    Damping,
    DynamicsOptions,
    DynamicState,
    RodDynamics,
    StepDerivatives,
    StepError,
    Trajectory,
)
from optikin.physics.model import LOAD_NAMES, ArmEquations, Loads, RodArm, Segment, load_vector
from optikin.physics.pneumatic import Chamber, cbha_chambers
from optikin.physics.reconstruction import Reconstruction, ReconstructionOptions, ShapeReconstructor, reconstruct_shape
from optikin.physics.rod import Rod
from optikin.physics.shooting import LoadSensitivity, ShootingOptions, ShootingSolver
from optikin.physics.solution import RodSolution
from optikin.physics.tendons import Tendon

__all__ = [
    "LOAD_NAMES",
    "ArmEquations",
    "Chamber",
    "CollocationOptions",
    "CollocationSolver",
    "Damping",
    "DynamicState",
    "DynamicsOptions",
    "LoadSensitivity",
    "Loads",
    "Reconstruction",
    "ReconstructionOptions",
    "Rod",
    "RodArm",
    "RodDynamics",
    "RodSolution",
    "Segment",
    "ShootingOptions",
    "ShapeReconstructor",
    "ShootingSolver",
    "StepDerivatives",
    "StepError",
    "Tendon",
    "Trajectory",
    "cbha_chambers",
    "load_vector",
    "reconstruct_shape",
]
