"""The ``ph`` backend family: minimum-energy PH quintic backbones for a sequence of end poses.

Every adapter of the family offers

* ``model(settings, free_speeds) -> ShapeEnergyModel``: the CasADi model of
  :mod:`optikin.curves.min_energy` (built once per settings and kept, so methods
  in one run share it);
* ``solve(model, samples) -> list[ShapeSolution]``: one solution per sample, in
  order, each with its status, energy, iterations and wall time. Samples are
  solved along the trajectory, each warm-started from the previous ``ok``
  solution when the backend's ``warm_start`` is on: this is the one warm-start
  loop of the PH solvers.

Backends (Singh et al. 2018, section II.A, posed as an NLP):

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

from typing import Sequence

import numpy as np
from pydantic import Field

from optikin.curves.min_energy import EnergySettings, ShapeData, ShapeEnergyModel, ShapeSolution
from optikin.interrupt import check_interrupted
from optikin.options import Options
from optikin.solvers import register_backend
from optikin.spec import SolverSpec
from optikin.status import Status

FAMILY = "ph"

_MODELS: dict[tuple, ShapeEnergyModel] = {}


def shared_model(
    settings: EnergySettings, free_speeds: bool, compile: bool = False, coarse_grid: int = 12
) -> ShapeEnergyModel:
    """The model of these settings, built once per process (compiled code is also cached on disk)."""
    key = (settings, free_speeds, compile, coarse_grid)
    if key not in _MODELS:
        _MODELS[key] = ShapeEnergyModel(settings, free_speeds=free_speeds, compile=compile, coarse_grid=coarse_grid)
    return _MODELS[key]


class NewtonOptions(Options):
    """Options of backend ``ph_newton``."""

    compile: bool = Field(False, strict=True, description="compile the Newton Functions to C (cached on disk)")
    warm_start: bool = Field(True, strict=True, description="start each sample from the previous ok solution")
    fallback: bool = Field(
        True, strict=True, description="coarse-grid restart, then IPOPT, when Newton does not converge"
    )
    basin_check: bool = Field(
        False,
        strict=True,
        description="also run Newton from the coarse grid on warm-started samples, keep the lower minimum",
    )
    coarse_grid: int = Field(12, ge=2, strict=True, description="points per angle of the coarse start grid")


class IpoptOptions(Options):
    """Options of backend ``ph_ipopt``."""

    warm_start: bool = Field(True, strict=True, description="start each sample from the previous ok solution")
    starts: int = Field(3, ge=1, strict=True, description="coarse-grid starts of a cold solve (best result kept)")


class GridOptions(Options):
    """Options of backend ``ph_grid``."""

    n: int = Field(64, ge=2, strict=True, description="points per free angle")
    n_ratio: int = Field(9, ge=2, strict=True, description="end-speed ratios in [1/3, 3] (free end speeds only)")


class PHAdapter:
    """The warm-start loop shared by the ``ph`` backends; subclasses solve one sample."""

    warm_start = False

    def __init__(self, preset: SolverSpec, options: Options):
        self.preset = preset
        self.options = options

    def model(self, settings: EnergySettings, free_speeds: bool) -> ShapeEnergyModel:
        """The shared model of these settings (module docstring)."""
        return shared_model(settings, free_speeds)

    def solve_one(self, model: ShapeEnergyModel, data: ShapeData, previous: np.ndarray | None) -> ShapeSolution:
        raise NotImplementedError

    def solve(self, model: ShapeEnergyModel, samples: Sequence[ShapeData]) -> Sequence[ShapeSolution]:
        """Solve ``samples`` in order, each from the previous ``ok`` solution when warm-starting."""
        out: list[ShapeSolution] = []
        previous = None
        for data in samples:
            check_interrupted()
            sol = self.solve_one(model, data, previous)
            out.append(sol)
            previous = sol.x if (self.warm_start and sol.status == Status.OK) else None
        return out


class NewtonAdapter(PHAdapter):
    """``ph_newton``: the fast path (module docstring)."""

    options: NewtonOptions

    def __init__(self, preset: SolverSpec, options: NewtonOptions):
        super().__init__(preset, options)
        self.warm_start = options.warm_start

    def model(self, settings: EnergySettings, free_speeds: bool) -> ShapeEnergyModel:
        return shared_model(settings, free_speeds, self.options.compile, self.options.coarse_grid)

    def solve(self, model: ShapeEnergyModel, samples: Sequence[ShapeData]) -> Sequence[ShapeSolution]:
        """:meth:`PHAdapter.solve` as one call of generated C where it applies (:mod:`optikin.native.ph`:
        the same answers to rounding), else sample by sample in Python."""
        from optikin.native.ph import native_solve

        batch = native_solve(self, model, samples)
        return batch if batch is not None else super().solve(model, samples)

    def solve_one(self, model: ShapeEnergyModel, data: ShapeData, previous: np.ndarray | None) -> ShapeSolution:
        limits = self.preset.limits
        return model.solve_newton(
            data,
            previous,
            tolerance=limits.tolerance,
            max_iterations=limits.max_iterations,
            fallback=self.options.fallback,
            basin_check=self.options.basin_check,
        )


class IpoptAdapter(PHAdapter):
    """``ph_ipopt``: the reference (module docstring)."""

    options: IpoptOptions

    def __init__(self, preset: SolverSpec, options: IpoptOptions):
        super().__init__(preset, options)
        self.warm_start = options.warm_start

    def solve_one(self, model: ShapeEnergyModel, data: ShapeData, previous: np.ndarray | None) -> ShapeSolution:
        return model.solve_nlp(data, previous, starts=self.options.starts)


class GridAdapter(PHAdapter):
    """``ph_grid``: the baseline (module docstring); no warm start."""

    options: GridOptions

    def solve_one(self, model: ShapeEnergyModel, data: ShapeData, previous: np.ndarray | None) -> ShapeSolution:
        return model.solve_grid(data, n=self.options.n, n_ratio=self.options.n_ratio)


register_backend(
    "ph_newton", FAMILY, "Newton on compiled CasADi derivatives, warm-started (PH fast path)", options=NewtonOptions
)(NewtonAdapter)
register_backend("ph_ipopt", FAMILY, "CasADi nlpsol IPOPT, warm or cold (PH reference)", options=IpoptOptions)(
    IpoptAdapter
)
register_backend("ph_grid", FAMILY, "dense grid over the free PH angles (and speed ratios)", options=GridOptions)(
    GridAdapter
)
