"""optikin: continuum-robot kinematics in CasADi, with its hard problems posed as optimisation."""

__version__ = "0.1.0"
