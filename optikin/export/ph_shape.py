"""``optikin export PROBLEM --what ph-shape``: the minimum-energy PH quintic reconstruction of a trajectory in C.

The C library (``templates/ph.c``) runs, for a whole trajectory of samples in one call, what
:meth:`optikin.curves.min_energy.ShapeEnergyModel.solve_newton` does for each sample along the
warm-start loop of :class:`optikin.solvers.ph_backends.PHAdapter`: modified Newton from the
previous ``ok`` solution (:func:`optikin.curves.newton.modified_newton`, with its converging-step
rule), a coarse-grid restart when it fails, the optional basin check against Newton from the
coarse grid, the angles wrapped into ``[-pi, pi)``. Where the Python path would fall back to
IPOPT, the C library reports ``NOT_CONVERGED``. Given end speeds only (the seed's setting).

What is generated, by CasADi from the model's own expressions (:func:`newton_functions`):

* the data-only part of the Hermite family, once per sample
  (:func:`~optikin.export.ph_derivatives.split_model`);
* the Newton outputs (:func:`optikin.curves.newton.modified_newton_outputs`) with the bending
  energy's gradient and Hessian through its 13 Bernstein coefficients
  (:func:`~optikin.export.ph_derivatives.bending_derivatives`; with a twist term, CasADi's
  derivatives of the energy), and the energy, length and gradient alone for a step predicted to
  converge;
* the energy on the coarse grid, written as loops the compiler can vectorise, value for value the
  model's (:func:`~optikin.export.grid_loops.grid_source`).

The answers agree with the Python fast path to rounding (1e-14 in the angles on ``cbha-ph-shape``),
with the same statuses and Newton steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from optikin.errors import SolverError

if TYPE_CHECKING:
    from optikin.curves.min_energy import ShapeEnergyModel
    from optikin.export import Export
    from optikin.solvers.ph_backends import NewtonAdapter


@dataclass(frozen=True)
class PHExportSetup:
    """A ``ph_shape`` problem's model, its ``ph_newton`` adapter and its samples' parameter vectors ``(k, NP)``."""

    model: ShapeEnergyModel
    adapter: NewtonAdapter
    samples: list
    parameters: np.ndarray


def ph_setup(problem: str, overrides=()) -> PHExportSetup:
    """The model, ``ph_newton`` adapter (the problem's solver, else preset ``ph-newton``) and samples of ``problem``.

    Raises
    ------
    SpecError
        The problem is not of kind ``ph_shape``.
    SolverError
        It frees the end speeds (not exported).
    """
    from optikin.export.context import context, registered_preset
    from optikin.problems.ph_shared import shape_samples
    from optikin.solvers.ph_backends import NewtonAdapter

    ctx = context(problem, ("ph_shape",), "--what ph-shape", overrides, ("optikin.solvers.ph_backends",))
    options = ctx.options
    if options.free_speeds:
        raise SolverError(f"{problem}: --what ph-shape exports given end speeds only (options.free_speeds: false)")
    _, _, samples = shape_samples(ctx.load_data(), options, f"{ctx.path.name}: data")
    adapter = ctx.adapter
    if not isinstance(adapter, NewtonAdapter):
        preset = registered_preset("ph-newton")
        assert preset is not None  # optikin.solvers.ph_backends, imported by context, registers it
        adapter = preset.build()
    model = adapter.model(options.energy, False)
    return PHExportSetup(model, adapter, samples, np.array([s.parameters() for s in samples]))


def newton_functions(model: ShapeEnergyModel, prefix: str) -> tuple[list[ca.Function], ca.Function]:
    """The generated Functions of ``model`` (a given-speeds ShapeEnergyModel), named for ``prefix``.

    ``[family: P -> F, newton: (x, F) -> (modified_newton_outputs), gradient: (x, F) -> (E, S, max|g|)]``
    and the grid energy ``(x, F) -> E`` (written as loops by :func:`~optikin.export.grid_loops.grid_source`).
    Bending energy alone goes through :func:`~optikin.export.ph_derivatives.bending_derivatives`; with
    twist, CasADi's gradient and Hessian of
    the energy. ``gradient`` shares the operations of the first three outputs of ``newton``.
    """
    from optikin.curves.energy import shape_energy
    from optikin.curves.newton import modified_newton_outputs
    from optikin.export.ph_derivatives import bending_derivatives, split_model

    split = split_model(model)
    x, F, curve = split.x, split.F, split.curve
    settings = model.settings
    energy = shape_energy(curve, settings.twist_weight, settings.nodes, settings.curvature_floor)
    derivatives: tuple[ca.SX, ...]
    if settings.twist_weight:
        length, g = curve.arc_length(), ca.gradient(energy, x)
        H = ca.hessian(energy, x)[0]
        derivatives = (energy, length, g, H[0, 0], H[0, 1], H[1, 1])
    else:
        derivatives = bending_derivatives(curve, x, settings.nodes)
    E, S, g = derivatives[:3]
    return [
        ca.Function(f"{prefix}_family", [split.P], [ca.cse(split.family)]),
        ca.Function(f"{prefix}_newton", [x, F], [ca.cse(modified_newton_outputs(*derivatives))]),
        ca.Function(f"{prefix}_gradient", [x, F], [ca.cse(ca.vertcat(E, S, ca.mmax(ca.fabs(g))))]),
    ], ca.Function(f"{prefix}_grid_energy", [x, F], [ca.cse(energy)])


@dataclass(frozen=True)
class PHLibrary:
    """The C of a PH library: CasADi's code, the header, the solver (``#include``-ing the header) and the
    template values (``common``)."""

    code: str
    header: str
    source: str
    common: dict[str, object]

    def translation_unit(self) -> str:
        """Code, header and solver as one C file (the header in place of its ``#include``)."""
        include = f'#include "{self.common["stem"]}.h"'
        return f"{self.code}\n{self.source.replace(include, self.header)}"


def ph_library(problem: str, model: ShapeEnergyModel, adapter: NewtonAdapter, stem: str) -> PHLibrary:
    """The C of the PH library ``stem`` of ``model`` (given end speeds) solved as ``adapter`` (``ph_newton``) would.

    Raises
    ------
    SolverError
        The model frees the end speeds.
    """
    from optikin.curves.min_energy import N_PARAMETERS
    from optikin.curves.newton import CURVATURE_SAFETY, ENERGY_NOISE, PREDICTION_SAFETY
    from optikin.export import _common, _generated, _template
    from optikin.export._escape import c_comment, c_identifier
    from optikin.export.grid_loops import grid_source

    if model.free_speeds:
        raise SolverError(f"{problem}: --what ph-shape exports given end speeds only")
    common: dict[str, object] = dict(_common(stem, problem), n_p=N_PARAMETERS)
    stem = prefix = str(common["stem"])
    functions, grid = newton_functions(model, prefix)
    code, sizes = _generated(functions, stem)
    options, limits = adapter.options, adapter.preset.limits
    settings = model.settings
    header = _template("ph.h").substitute(
        common,
        **sizes,
        n_family=functions[0].nnz_out(0),
        twist_note=f" + {float(settings.twist_weight)!r} int tau^2 ds" if settings.twist_weight else "",
        nodes=int(settings.nodes),
        coarse_grid=int(model.coarse_grid),
        preset=c_comment(adapter.preset.name),
    )
    source = _template("ph.c").substitute(
        common,
        energy_noise=repr(ENERGY_NOISE),
        prediction_safety=repr(PREDICTION_SAFETY),
        curvature_safety=repr(CURVATURE_SAFETY),
        tolerance=repr(float(limits.tolerance)),
        max_iterations=int(limits.max_iterations),
        warm_start=int(options.warm_start),
        restart=int(options.fallback),
        basin_check=int(options.basin_check),
        coarse_grid=int(model.coarse_grid),
        grid_energy=grid_source(grid, model.coarse_grid, c_identifier(grid.name(), "Function name")),
    )
    return PHLibrary(code, header, source, common)


def export_ph_shape(problem: str, setup: PHExportSetup, folder: Path, samples: int) -> "Export":
    """Write the PH library of ``setup`` into ``folder``; its first ``samples`` samples go into the example."""
    from optikin.curves.min_energy import N_PARAMETERS
    from optikin.export import MAX_FILE_SAMPLES, Export, ExampleText, _lines, _rows, _template, _write

    library = ph_library(problem, setup.model, setup.adapter, "optikin_ph_shape")
    code, header, source, common = library.code, library.header, library.source, library.common
    stem = str(common["stem"])
    rows = setup.parameters[:samples]
    main = _template("ph_main.c").substitute(
        common, n_samples=len(rows), samples=_rows(rows), max_samples=MAX_FILE_SAMPLES
    )
    example = ExampleText(
        "ph-shape",
        "minimum-energy PH quintic backbones along a trajectory",
        _lines(rows),
        len(rows),
        f"one sample per line, the {N_PARAMETERS} entries of its parameter vector P: base point p0 (3) [m], "
        "unit base tangent t0 (3), tip point p1 (3) [m], unit tip tangent t1 (3), end speeds s0, s1 [m] "
        "and the backbone length L [m] (see the header). The samples are solved as one trajectory.",
        "`./example [samples.txt [max_iterations restart basin_check [seconds]]]` (the options override the "
        "preset's; seconds: length of the timing loop, 0.2 unless given, 0 for none).",
        "One line per sample: `status iterations E S phi0 phi2` (status 0: ok; E the bending energy, S the "
        "length, phi0 and phi2 the angles in [-pi, pi)). Then, on standard error, `per_call_us` (wall "
        "microseconds per sample) and `cpu_us` (process CPU microseconds per sample).",
    )
    _write(folder, stem, code, header, source, main, problem, example)
    return Export("ph-shape", folder, stem, rows)
