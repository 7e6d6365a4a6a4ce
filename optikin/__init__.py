"""optikin: continuum-robot kinematics in CasADi, with its hard problems posed as optimisation."""

__version__ = "0.2.0.dev0"


API = ("solve_ik", "IkSolution", "reconstruct_backbone", "Backbone", "track", "Tracking")
"""The entry points of :mod:`optikin.api`, reachable as ``optikin.<name>``."""

__all__ = list(API)


def __getattr__(name: str):
    """``optikin.solve_ik``, ``reconstruct_backbone``, ``track`` (and the modules ``api``, ``algebra``) without
    importing CasADi at ``import optikin``."""
    import importlib

    if name in API:
        return getattr(importlib.import_module("optikin.api"), name)
    if name in ("algebra", "api"):
        return importlib.import_module(f"optikin.{name}")
    raise AttributeError(f"module 'optikin' has no attribute {name!r}")
