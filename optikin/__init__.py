"""optikin: continuum-robot kinematics in CasADi, with its hard problems posed as optimisation."""

__version__ = "0.2.0.dev0"


def __getattr__(name: str):
    """``optikin.solve_ik`` (and the modules ``api``, ``algebra``) without importing CasADi at ``import optikin``."""
    import importlib

    if name in ("solve_ik", "IkSolution"):
        return getattr(importlib.import_module("optikin.api"), name)
    if name in ("algebra", "api"):
        return importlib.import_module(f"optikin.{name}")
    raise AttributeError(f"module 'optikin' has no attribute {name!r}")
