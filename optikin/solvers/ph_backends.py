"""The ``ph`` backend family: minimum-energy PH quintic backbones for a sequence of end poses.

Every adapter of the family offers

* ``model(settings, free_speeds) -> ShapeEnergyModel``: the CasADi model of
  :mod:`optikin.curves.min_energy` (built once per settings and kept, so methods
  in one run share it);
* ``solve(model, samples) -> list[ShapeSolution]``: one solution per sample, in
  order, each with its status, energy, iterations and wall time.

Backends (seed 002 section II.A posed as an NLP; issue 3 item 2):

``ph_newton``  the fast path: Newton on the compiled (``compile: true``) or
               virtual-machine CasADi gradient and Hessian, warm-started from the
               previous sample (``warm_start``), coarse-grid restart and IPOPT
               fallback (``fallback``), optionally also from the coarse grid on
               every warm-started sample, keeping the lower minimum (``basin_check``,
               for free end speeds); ``limits.tolerance`` and
               ``limits.max_iterations`` are Newton's.
``ph_ipopt``   the reference: CasADi ``nlpsol('ipopt')`` (tolerance 1e-12), warm
               from the previous solution (``warm_start: true``) or cold from the
               ``starts`` best points of a coarse grid.
``ph_grid``    the baseline: the best point of an ``n x n`` grid over the two free
               angles (times ``n_ratio`` end-speed ratios with free speeds).
"""

from __future__ import annotations

from typing import Any

from optikin.curves.min_energy import EnergySettings, ShapeData, ShapeEnergyModel, ShapeSolution
from optikin.errors import SpecError
from optikin.solvers import register_backend
from optikin.spec import SolverSpec, available

FAMILY = "ph"

_MODELS: dict[tuple, ShapeEnergyModel] = {}


def shared_model(settings: EnergySettings, free_speeds: bool, compile: bool = False,
                 coarse_grid: int = 12) -> ShapeEnergyModel:
    """The model of these settings, built once per process (compiled code is also cached on disk)."""
    key = (settings, free_speeds, compile, coarse_grid)
    if key not in _MODELS:
        _MODELS[key] = ShapeEnergyModel(settings, free_speeds=free_speeds, compile=compile, coarse_grid=coarse_grid)
    return _MODELS[key]


def preset_path(preset: SolverSpec) -> str:
    """The file a preset most likely came from, for error messages."""
    return str(available("solvers").get(preset.name, f"solver preset {preset.name!r}"))


class PHAdapter:
    """Common option checking; subclasses set :attr:`method` and :attr:`defaults`."""

    method = ""
    defaults: dict[str, Any] = {}

    def __init__(self, preset: SolverSpec):
        self.preset = preset
        unknown = sorted(set(preset.options) - set(self.defaults))
        if unknown:
            raise SpecError(preset_path(preset), f"options.{unknown[0]}",
                            f"unknown option of backend {preset.backend!r}; known: {', '.join(self.defaults)}")
        self.options = {**self.defaults, **preset.options}
        for key, default in self.defaults.items():
            value = self.options[key]
            if isinstance(default, bool) and not isinstance(value, bool):
                raise SpecError(preset_path(preset), f"options.{key}", f"must be true or false, got {value!r}")
            if isinstance(default, int) and not isinstance(default, bool) and not (
                    isinstance(value, int) and not isinstance(value, bool) and value >= 2):
                raise SpecError(preset_path(preset), f"options.{key}", f"must be an integer >= 2, got {value!r}")

    def model(self, settings: EnergySettings, free_speeds: bool) -> ShapeEnergyModel:
        return shared_model(settings, free_speeds)

    def solve(self, model: ShapeEnergyModel, samples: list[ShapeData]) -> list[ShapeSolution]:
        raise NotImplementedError


class NewtonAdapter(PHAdapter):
    method = "newton"
    defaults = {"compile": False, "warm_start": True, "fallback": True, "basin_check": False, "coarse_grid": 12}

    def model(self, settings: EnergySettings, free_speeds: bool) -> ShapeEnergyModel:
        return shared_model(settings, free_speeds, self.options["compile"], self.options["coarse_grid"])

    def solve(self, model: ShapeEnergyModel, samples: list[ShapeData]) -> list[ShapeSolution]:
        limits = self.preset.limits
        out, previous = [], None
        for data in samples:
            sol = model.solve_newton(data, previous, tolerance=limits.tolerance,
                                     max_iterations=limits.max_iterations, fallback=self.options["fallback"],
                                     basin_check=self.options["basin_check"])
            out.append(sol)
            previous = sol.x if (self.options["warm_start"] and sol.status == "ok") else None
        return out


class IpoptAdapter(PHAdapter):
    method = "nlp"
    defaults = {"warm_start": True, "starts": 3}

    def solve(self, model: ShapeEnergyModel, samples: list[ShapeData]) -> list[ShapeSolution]:
        out, previous = [], None
        for data in samples:
            if previous is not None:
                sol = model.solve_nlp(data, previous)
            else:
                sol = model.solve_nlp(data, starts=self.options["starts"])
            out.append(sol)
            previous = sol.x if (self.options["warm_start"] and sol.status == "ok") else None
        return out


class GridAdapter(PHAdapter):
    method = "grid"
    defaults = {"n": 64, "n_ratio": 9}

    def solve(self, model: ShapeEnergyModel, samples: list[ShapeData]) -> list[ShapeSolution]:
        return [model.solve_grid(data, n=self.options["n"], n_ratio=self.options["n_ratio"]) for data in samples]


register_backend("ph_newton", FAMILY, "Newton on compiled CasADi derivatives, warm-started (PH fast path)", options=None)(
    NewtonAdapter)
register_backend("ph_ipopt", FAMILY, "CasADi nlpsol IPOPT, warm or cold (PH reference)", options=None)(IpoptAdapter)
register_backend("ph_grid", FAMILY, "dense grid over the free PH angles (and speed ratios)", options=None)(GridAdapter)
