"""``optikin export PROBLEM --what ph-shape``: the minimum-energy PH quintic reconstruction of a trajectory in C.

The C library (``templates/ph.c``) runs, for a whole trajectory of samples in one call, what
:meth:`optikin.curves.min_energy.ShapeEnergyModel.solve_newton` does for each sample along the
warm-start loop of :class:`optikin.solvers.ph_backends.PHAdapter`: modified Newton from the
previous ``ok`` solution (:func:`optikin.curves.newton.modified_newton`, with its converging-step
rule), a coarse-grid restart when it fails, the optional basin check against Newton from the
coarse grid, the angles wrapped into ``[-pi, pi)``. Where the Python path would fall back to
IPOPT, the C library reports ``NOT_CONVERGED``. Given end speeds only (the seed's setting).

What is generated, by CasADi from the model's own expressions (:func:`newton_functions`):

* the data-only part of the Hermite family, once per sample (:func:`split_model`);
* the Newton outputs (:func:`optikin.curves.newton.modified_newton_outputs`) with the bending
  energy's gradient and Hessian through its 13 Bernstein coefficients
  (:func:`bending_derivatives`; with a twist term, CasADi's derivatives of the energy), and the
  energy, length and gradient alone for a step predicted to converge;
* the energy on the coarse grid, written as loops the compiler can vectorise (:func:`grid_source`),
  value for value the model's.

The answers agree with the Python fast path to rounding (1e-14 in the angles on ``cbha-ph-shape``),
with the same statuses and Newton steps.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from optikin.errors import SolverError

if TYPE_CHECKING:
    from optikin.curves.min_energy import ShapeEnergyModel
    from optikin.curves.ph_quintic import PHQuintic
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


FAMILY_FIELDS = ("A0_bar", "A2_bar", "center", "pole", "pole_root")
"""The fields of :class:`optikin.curves.ph_quintic.HermiteFamily` a member needs besides the angles."""


@dataclass(frozen=True)
class SplitModel:
    """A given-speeds model cut into its data-only part and the rest.

    ``family`` (an SX of the parameter vector ``P``) holds the :data:`FAMILY_FIELDS` of the
    Hermite family, one sample's constants; ``curve`` is the family member at the angles ``x``
    built on the symbols ``F`` that stand for them. The cut changes no operation: the energy of
    ``curve`` at ``(x, family(P))`` is the model's, rounding included.
    """

    x: ca.SX
    P: ca.SX
    F: ca.SX
    family: ca.SX
    curve: PHQuintic


def split_model(model: ShapeEnergyModel) -> SplitModel:
    """The model's curve ``hermite_family(p0, s0 t0, p1, s1 t1).member(phi0, phi2)`` cut after the family."""
    from optikin.curves.min_energy import ShapeParameters
    from optikin.curves.ph_quintic import hermite_family

    x, P, _ = model.symbols()
    p = ShapeParameters.of(P)
    family = hermite_family(p.p0, p.s0 * p.t0, p.p1, p.s1 * p.t1)
    values = [getattr(family, name) for name in FAMILY_FIELDS]
    offsets = np.cumsum([0] + [v.numel() for v in values]).tolist()
    F = ca.SX.sym("F", offsets[-1])
    fields = dict(zip(FAMILY_FIELDS, ca.vertsplit(F, offsets)))
    curve = replace(family, **fields).member(x[0], x[1], 0.0)
    return SplitModel(x, P, F, ca.vertcat(*values), curve)


def _mirrored(coefficients: list, degree: int) -> tuple[list, list]:
    """``(c_i + c_{d-i}, c_i - c_{d-i})`` for ``i < d/2`` (and the middle ``c_{d/2}`` among the sums)."""
    half = (degree + 1) // 2
    sums = [coefficients[i] + coefficients[degree - i] for i in range(half)]
    if degree % 2 == 0:
        sums.append(coefficients[degree // 2])
    return sums, [coefficients[i] - coefficients[degree - i] for i in range(half)]


def _pair_basis(degree: int, t: float) -> tuple[list[float], list[float]]:
    """Weights of the sums and differences of :func:`_mirrored` giving a polynomial at ``t`` and ``1 - t``."""
    from optikin.curves.bernstein import bernstein_basis

    b = [float(v) for v in bernstein_basis(degree, np.array(t))]
    half = (degree + 1) // 2
    even = [0.5 * (b[i] + b[degree - i]) for i in range(half)] + ([b[degree // 2]] if degree % 2 == 0 else [])
    return even, [0.5 * (b[i] - b[degree - i]) for i in range(half)]


def bending_derivatives(curve: PHQuintic, x: ca.SX, nodes: int) -> tuple[ca.SX, ...]:
    """``(E, S, g, h00, h01, h11)``: ``E = int kappa^2 ds``, the arc length, gradient (2) and Hessian.

    ``E = sum_n w_n f(u_n, v_n, s_n)`` with ``f = 4 (u^2 + v^2) / s^3`` at the Gauss-Legendre
    nodes, where ``u, v`` (cubic) and ``s = sigma`` (quartic) are Bernstein polynomials of the
    13 coefficients ``c(x)`` (:func:`optikin.curves.energy.bending_energy`). The derivatives go
    through ``c``: with ``J = dc/dx`` (forward mode twice, also for the second derivatives
    ``c_ab``) and the node values' derivatives ``D_n = B_n J`` (rows ``a, b, d`` for ``u, v, s``),

        g = J' G,   G = sum_n w_n B_n' grad f_n,
        H = sum_n 8 w_n r^3 (a~ a~' + b~ b~' - 3 q r^2 d d') + sum_i G_i c_i,xx,

    ``r = 1/s``, ``q = u^2 + v^2``, ``a~ = a - 3 r u d``, ``b~ = b - 3 r v d`` (the Hessian of
    ``f`` as a sum of squares). The nodes come in pairs ``t, 1 - t`` (equal weights), where the
    Bernstein basis is mirrored: each value at a pair is a sum and a difference of two half-length
    dot products (:func:`_mirrored`), and so is each entry of ``G``. Reverse mode through the whole
    graph costs about twice as much.
    """
    from optikin.curves.bernstein import gauss_legendre_unit
    from optikin.curves.energy import rotation_rate_coefficients

    t, w = gauss_legendre_unit(nodes)
    _, gj, gk = rotation_rate_coefficients(curve)
    sigma = curve.speed_coefficients()
    length = (sigma[0] + sigma[1] + sigma[2] + sigma[3] + sigma[4]) / 5.0
    c = ca.vertcat(*gj, *gk, *sigma)
    e = [ca.DM([1.0, 0.0]), ca.DM([0.0, 1.0])]
    dc = [ca.jtimes(c, x, e[0]), ca.jtimes(c, x, e[1])]
    ddc = {(a, b): ca.jtimes(dc[a], x, e[b]) for a, b in ((0, 0), (0, 1), (1, 1))}
    degrees, offsets = (3, 3, 4), (0, 4, 8, 13)

    def split(vector: Any) -> list[tuple[list, list]]:
        """The mirrored sums and differences of the three polynomials whose coefficients are ``vector``."""
        parts = ca.vertsplit(vector, list(offsets))
        return [_mirrored(ca.vertsplit(part, 1), d) for part, d in zip(parts, degrees)]

    values, slopes = split(c), [split(d) for d in dc]
    pairs = [(k, nodes - 1 - k, w[k]) for k in range(nodes // 2)]
    if nodes % 2:
        pairs.append((nodes // 2, nodes // 2, 0.5 * w[nodes // 2]))  # the middle node, half its weight twice
    energy: Any = 0.0
    H: dict[tuple[int, int], Any] = {ab: 0.0 for ab in ddc}
    G_sums: list[list] = [[0.0] * len(values[j][0]) for j in range(3)]
    G_differences: list[list] = [[0.0] * len(values[j][1]) for j in range(3)]
    for k, _, weight in pairs:
        bases = [_pair_basis(d, float(t[k])) for d in degrees]

        def at_pair(split_vector: list[tuple[list, list]], j: int) -> tuple[Any, Any]:
            (even, odd), (sums, differences) = bases[j], split_vector[j]
            ev = sum(ei * si for ei, si in zip(even, sums))
            od = sum(oi * di for oi, di in zip(odd, differences))
            return ev + od, ev - od

        node_values = [at_pair(values, j) for j in range(3)]  # (at t, at 1 - t) of u, v, s
        node_slopes = [[at_pair(slopes[a], j) for j in range(3)] for a in (0, 1)]
        weighted = [[0.0, 0.0] for _ in range(3)]  # w grad f at t, 1 - t
        for side in (0, 1):
            u, v, sv = (node_values[j][side] for j in range(3))
            r = 1.0 / sv
            q = u * u + v * v
            k1 = (8.0 * weight) * (r * r * r)
            energy = energy + 0.5 * k1 * q
            weighted[0][side], weighted[1][side], weighted[2][side] = k1 * u, k1 * v, -1.5 * k1 * q * r
            du, dv, ds = ([node_slopes[a][j][side] for a in (0, 1)] for j in range(3))
            a_t = [du[a] - 3.0 * r * u * ds[a] for a in (0, 1)]
            b_t = [dv[a] - 3.0 * r * v * ds[a] for a in (0, 1)]
            curvature = -3.0 * q * r * r
            for a, b in H:
                H[a, b] = H[a, b] + k1 * (a_t[a] * a_t[b] + b_t[a] * b_t[b] + curvature * ds[a] * ds[b])
        for j in range(3):
            (even, odd), total, difference = bases[j], weighted[j][0] + weighted[j][1], weighted[j][0] - weighted[j][1]
            G_sums[j] = [g + ei * total for g, ei in zip(G_sums[j], even)]
            G_differences[j] = [g + oi * difference for g, oi in zip(G_differences[j], odd)]
    G = []
    for j, d in enumerate(degrees):
        half = (d + 1) // 2
        low = [G_sums[j][i] + G_differences[j][i] for i in range(half)]
        high = [G_sums[j][i] - G_differences[j][i] for i in range(half)]
        G += low + ([G_sums[j][half]] if d % 2 == 0 else []) + high[::-1]
    Gv = ca.vertcat(*G)
    g = ca.vertcat(ca.dot(Gv, dc[0]), ca.dot(Gv, dc[1]))
    h = {ab: H[ab] + ca.dot(Gv, ddc[ab]) for ab in ddc}
    return energy, length, g, h[0, 0], h[0, 1], h[1, 1]


def newton_functions(model: ShapeEnergyModel, prefix: str) -> tuple[list[ca.Function], ca.Function]:
    """The generated Functions of ``model`` (a given-speeds ShapeEnergyModel), named for ``prefix``.

    ``[family: P -> F, newton: (x, F) -> (modified_newton_outputs), gradient: (x, F) -> (E, S, max|g|)]``
    and the grid energy ``(x, F) -> E`` (written as loops by :func:`grid_source`). Bending energy
    alone goes through :func:`bending_derivatives`; with twist, CasADi's gradient and Hessian of
    the energy. ``gradient`` shares the operations of the first three outputs of ``newton``.
    """
    from optikin.curves.energy import shape_energy
    from optikin.curves.newton import modified_newton_outputs

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


_C_OPERATIONS = {
    ca.OP_ASSIGN: "{0}",
    ca.OP_ADD: "{0} + {1}",
    ca.OP_SUB: "{0} - {1}",
    ca.OP_MUL: "{0} * {1}",
    ca.OP_DIV: "{0} / {1}",
    ca.OP_NEG: "-{0}",
    ca.OP_SQ: "{0} * {0}",
    ca.OP_TWICE: "{0} + {0}",
    ca.OP_INV: "1. / {0}",
    ca.OP_SQRT: "sqrt({0})",
    ca.OP_FABS: "fabs({0})",
    ca.OP_FMAX: "({0} > {1}) | ({1} != {1}) ? {0} : {1}",
    ca.OP_FMIN: "({0} < {1}) | ({1} != {1}) ? {0} : {1}",
    ca.OP_SIN: "sin({0})",
    ca.OP_COS: "cos({0})",
    ca.OP_EXP: "exp({0})",
    ca.OP_LOG: "log({0})",
    ca.OP_POW: "pow({0}, {1})",
    ca.OP_CONSTPOW: "pow({0}, {1})",
    ca.OP_LT: "{0} < {1}",
    ca.OP_LE: "{0} <= {1}",
    ca.OP_EQ: "{0} == {1}",
    ca.OP_NE: "{0} != {1}",
    ca.OP_NOT: "!{0}",
    ca.OP_AND: "{0} && {1}",
    ca.OP_OR: "{0} || {1}",
    ca.OP_IF_ELSE_ZERO: "{0} ? {1} : 0.",
}
"""C of the SX operations a grid energy may hold, each one IEEE operation as in CasADi's own code."""


def grid_source(fn: ca.Function, n: int, name: str) -> str:
    """C function ``void name(const double* F, double* E)``: ``fn(x, F)`` on the ``n x n`` angle grid.

    ``E[i n + j]`` is the value at ``x = (-pi + 2 pi i / n, -pi + 2 pi j / n)`` (the grid of
    :meth:`optikin.curves.min_energy.ShapeEnergyModel.coarse_starts`, ``phi0``-major). Each SX
    instruction of ``fn`` is written once, placed by what it depends on: ``F`` alone before the
    loops, ``phi2`` alone in a first loop over ``j`` (kept in arrays of ``n``), ``phi0`` alone in
    the loop over ``i``, the rest in loops over ``j`` inside it. Those hold arithmetic only (the
    trigonometry of the angles is hoisted) so that the compiler may run them in SIMD lanes; the
    square roots, which C's ``errno`` keeps out of vector code, get loops of their own (stages),
    the values passed between stages kept in arrays of ``n``. Every value is the one IEEE
    operation CasADi does, in its order (``fmax`` and ``fmin`` as selects with C99's NaN rule),
    so the energies are CasADi's.
    """
    nodes: list[tuple[int, str, list[int]]] = []  # (instruction, C template or constant text, argument instructions)
    depends: dict[int, int] = {}  # bit 1: phi0, bit 2: phi2
    stage: dict[int, int] = {}  # loops over j in the order written: even stages arithmetic, odd square roots
    kept: dict[int, int] = {}  # work slot -> the instruction whose value it holds
    result: int | None = None
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        inputs, outputs = fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_OUTPUT:
            result = kept[inputs[0]]
            continue
        args: list[int] = []
        if op == ca.OP_INPUT:
            which, entry = inputs
            depends[k] = (1 << entry) if which == 0 else 0
            text = f"-pi + two_pi * {'ij'[entry]} / {n}" if which == 0 else f"F[{entry}]"
        elif op == ca.OP_CONST:
            constant = float(fn.instruction_constant(k))
            depends[k] = 0
            text = (
                repr(constant)
                if np.isfinite(constant)
                else "NAN"
                if np.isnan(constant)
                else "-INFINITY"[constant > 0 :]
            )
        elif op in _C_OPERATIONS:
            args = [kept[i] for i in inputs]
            depends[k] = 0
            for a in args:
                depends[k] |= depends[a]
            text = _C_OPERATIONS[op]
        else:
            raise SolverError(f"--what ph-shape: the grid energy holds CasADi operation {op}, not written to C")
        latest = max([stage[a] for a in args if depends[a] == 3], default=0)
        if depends[k] == 3 and op == ca.OP_SQRT:
            stage[k] = latest + 1 if latest % 2 == 0 else latest + 2
        else:
            stage[k] = latest + latest % 2
        kept[outputs[0]] = k
        nodes.append((k, text, args))
    if result is None:
        raise SolverError("--what ph-shape: the grid energy has no output")
    arrays: set[int] = set()

    def ref(a: int, where: int) -> str:
        """The value of instruction ``a`` in a statement of class-3 stage ``where`` (-1: after the stages)."""
        if depends[a] == 2 or (depends[a] == 3 and stage[a] != where):
            arrays.add(a)
            return f"a{a}[j]"
        return f"t{a}"

    blocks: dict[tuple[int, int], list[str]] = {}
    for k, text, args in nodes:
        where = stage[k] if depends[k] == 3 else 0
        value = text.format(*(ref(a, where) if depends[k] == 3 else f"t{a}" for a in args)) if args else text
        blocks.setdefault((depends[k], where), []).append(f"const double t{k} = {value};")
    final = ref(result, -1) if depends[result] == 3 else f"t{result}"
    stages = sorted(w for d, w in blocks if d == 3)
    lines = [f"static void {name}(const double* F, double* E) {{", "  int i, j;"]
    lines += [f"  double a{k}[{n}];" for k in sorted(arrays)]
    lines += [f"  {c}" for c in blocks.get((0, 0), [])]
    lines += [f"  for (j = 0; j < {n}; ++j) {{"] + [f"    {c}" for c in blocks.get((2, 0), [])]
    lines += [f"    a{k}[j] = t{k};" for k in sorted(arrays) if depends[k] == 2] + ["  }"]
    lines += [f"  for (i = 0; i < {n}; ++i) {{"] + [f"    {c}" for c in blocks.get((1, 0), [])]
    for w in stages:
        lines += [f"    for (j = 0; j < {n}; ++j) {{"] + [f"      {c}" for c in blocks[3, w]]
        lines += [f"      a{k}[j] = t{k};" for k in sorted(arrays) if depends[k] == 3 and stage[k] == w] + ["    }"]
    lines += [f"    for (j = 0; j < {n}; ++j) E[i * {n} + j] = {final};", "  }", "}"]
    return "\n".join(lines) + "\n"


def export_ph_shape(problem: str, setup: PHExportSetup, folder: Path, samples: int) -> "Export":
    """Write the PH library of ``setup`` into ``folder``; its first ``samples`` samples go into the example."""
    from optikin.curves.min_energy import N_PARAMETERS
    from optikin.curves.newton import CURVATURE_SAFETY, ENERGY_NOISE, PREDICTION_SAFETY
    from optikin.export import MAX_FILE_SAMPLES, Export, _generated, _rows, _template, _write

    model, adapter = setup.model, setup.adapter
    if model.free_speeds:
        raise SolverError(f"{problem}: --what ph-shape exports given end speeds only")
    stem = prefix = "optikin_ph_shape"
    PREFIX = prefix.upper()
    functions, grid = newton_functions(model, prefix)
    code, sizes = _generated(functions, stem)
    options, limits = adapter.options, adapter.preset.limits
    settings = model.settings
    common = dict(stem=stem, prefix=prefix, PREFIX=PREFIX, problem=problem, n_p=N_PARAMETERS)
    header = _template("ph.h").substitute(
        common,
        **sizes,
        n_family=functions[0].nnz_out(0),
        twist_note=f" + {settings.twist_weight!r} int tau^2 ds" if settings.twist_weight else "",
        nodes=settings.nodes,
        coarse_grid=model.coarse_grid,
        preset=adapter.preset.name,
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
        coarse_grid=model.coarse_grid,
        grid_energy=grid_source(grid, model.coarse_grid, f"{prefix}_grid_energy"),
    )
    rows = setup.parameters[:samples]
    main = _template("ph_main.c").substitute(
        common, n_samples=len(rows), samples=_rows(rows), max_samples=MAX_FILE_SAMPLES
    )
    _write(folder, stem, code, header, source, main)
    return Export("ph-shape", folder, stem, rows)
