"""optikin: continuum-robot kinematics in CasADi, with its hard problems posed as optimisation."""

__version__ = "0.2.0.dev0"
