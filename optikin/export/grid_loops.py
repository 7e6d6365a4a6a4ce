"""A CasADi SX Function of two grid angles as C loops a compiler can vectorise (:func:`grid_source`).

Used by the PH shape export for the coarse grid of the minimum-energy search: every SX instruction
is written once as the one IEEE operation CasADi does, so the grid's values are CasADi's.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optikin.errors import SolverError

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
