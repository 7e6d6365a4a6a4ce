"""``optikin export``: a problem's kinematics or its inverse-kinematics solver as a self-contained C library.

What is exported (``--what``):

``fk``
    the arm's ``fk_dq`` (unit dual quaternion of the tip, 8), ``fk_position`` (3) and
    ``backbone`` (``3 x K`` points), CasADi code generation behind checked entry points.
``ik-step``, ``ik-trajectory``
    the problem's inverse kinematics (an ``ik`` problem whose least-squares problem has no
    constraints: the constant-curvature position, pose and point targets; fixed variables,
    e.g. inextensible sections, are substituted as
    :attr:`~optikin.solvers.nonlinear.LeastSquaresProblem.reduced` does)
    solved by the damped projected Gauss-Newton iteration of
    :mod:`optikin.solvers.gauss_newton`, written in C in ``templates/ik.c`` (same damping
    rule ``lam = mu ||r||^2 + 1e-10 tr(J D^-1 J^T)/m``, same acceptance, same switch to the
    Newton model on a stalled large residual, the options and limits of the
    ``gauss-newton`` preset), with ``r``, ``J`` and the Hessian of ``1/2 ||r||^2`` generated
    by CasADi. The step's linear system is solved by LU with partial pivoting in C (CasADi's
    symbolic QR in Python), so iterates agree to rounding; where the Jacobian has a null
    direction at the solution (pose targets of a two-section CC arm, rank 5) rounding sets
    where along it either path lands, and along a trajectory each path continues from its own
    previous solution. ``ik-step`` solves each target from
    the problem's start; ``ik-trajectory`` warm-starts each from the previous solution.
``ph-shape``
    the minimum-energy PH quintic backbones of a ``ph_shape`` problem (given end speeds), a
    whole trajectory of samples in one call: warm starts, modified Newton, coarse-grid restart
    and basin check as the ``ph_newton`` fast path (:mod:`optikin.export.ph_shape`).
``qp-step``
    one step of the tracking QP controller of a ``tracking`` problem: Jacobian, rate box,
    optional rows ``A qdot >= b``, the QP solved by a dense dual active-set method in C, and the
    controller's fallback (:mod:`optikin.export.qp_step`).

Every piece of text of a generated file that optikin does not write as a constant goes through
:mod:`optikin.export._escape` (comments, string literals, identifiers, ``Makefile`` and CMake
values); the problem is named by its file stem only. The output folder is checked before anything
is generated (:func:`check_output_folder`) and a failed write leaves none of the files behind.

The folder written holds ``<stem>.c`` (the generated code and the template), ``<stem>.h``
(the documented API: sizes, work structure, status codes), ``main.c`` (an example that runs
the problem's first samples or a file of them and times the calls), a ``Makefile``, a
``CMakeLists.txt``, a ``README.md`` (building with make or CMake, running the example, what its
input file holds) and the example's input file (:data:`INPUT_FILES`: ``targets.txt`` for IK), which
holds the samples compiled into ``main.c``, so ``./example targets.txt`` prints what ``./example``
does. The problem is read importing only its own kind (:mod:`optikin.export.context`).
The library depends on libm only and allocates nothing: the caller owns the work structure.
:func:`build` compiles the example with a compiler of :data:`optikin.codegen.COMPILERS` and
flags checked against :data:`optikin.codegen.ALLOWED_FLAGS`.
"""

from __future__ import annotations

import argparse
import os
import secrets
import subprocess
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from string import Template
from typing import Any, Iterable, Sequence

import casadi as ca
import numpy as np

from optikin.codegen import check_flags, find_compiler
from optikin.errors import SolverError, SpecError
from optikin.export._escape import (
    c_comment,
    c_identifier,
    c_string,
    cmake_value,
    make_word,
    problem_comment,
)
from optikin.results import OutputError

WHATS = ("fk", "ik-step", "ik-trajectory", "ph-shape", "qp-step")
"""What ``optikin export`` writes (module docstring)."""

EXAMPLE_SAMPLES = 20
"""Samples of the problem compiled into the example ``main.c``."""

MAX_FILE_SAMPLES = 20000
"""Samples the example reads from a file at most."""

FK_FUNCTIONS = ("fk_dq", "fk_position", "backbone")


@dataclass(frozen=True)
class Export:
    """The files :func:`export` wrote.

    ``samples`` are the inputs compiled into the example (targets ``(k, NP)`` for IK,
    configurations ``(k, N)`` for FK); ``start`` the IK start configuration (None for FK).
    """

    what: str
    folder: Path
    stem: str
    samples: np.ndarray
    start: np.ndarray | None = None

    @property
    def source(self) -> Path:
        return self.folder / f"{self.stem}.c"

    @property
    def header(self) -> Path:
        return self.folder / f"{self.stem}.h"

    @property
    def files(self) -> tuple[Path, ...]:
        return tuple(self.folder / name for name in file_names(self.stem, self.what))


INPUT_FILES = {
    "fk": "configurations.txt",
    "ik-step": "targets.txt",
    "ik-trajectory": "targets.txt",
    "ph-shape": "samples.txt",
    "qp-step": "steps.txt",
}
"""The example's input file of each ``--what``: the inputs compiled into ``main.c``, one per line."""


def file_names(stem: str, what: str | None = None) -> tuple[str, ...]:
    """The names of the files an export of ``stem`` writes, in the order :func:`main` lists them.

    With ``what`` (one of :data:`WHATS`), also ``README.md`` and the example's input file
    (:data:`INPUT_FILES`); without, the code and build files only.
    """
    names = (f"{stem}.c", f"{stem}.h", "main.c", "Makefile", "CMakeLists.txt")
    return names if what is None else (*names, "README.md", INPUT_FILES[what])


def check_output_folder(out: Path | str, stem: str | None = None, what: str | None = None) -> Path:
    """The folder of ``--out`` ``out`` if an export can write into it; creates nothing.

    Parameters
    ----------
    out:
        The folder; a string may not be empty (``--out ''``, which ``Path`` would read as the
        current folder).
    stem:
        The export's stem: its files (:func:`file_names`) may not be symlinks or folders.
    what:
        What is exported (:data:`WHATS`), which adds the README and the input file to the files checked.

    Raises
    ------
    OutputError
        ``out`` is empty, is (or lies under) a file or a dangling symlink, its nearest existing
        folder is not writable, or a file of the export is a symlink or not a regular file.
    """
    if isinstance(out, str) and not out.strip():
        raise OutputError("--out: an empty output folder is not accepted (give a folder, e.g. c_export)")
    folder = Path(out)
    existing = folder
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    if existing.is_symlink() and not existing.exists():
        raise OutputError(f"{existing}: a symlink to nothing (dangling or a loop), not an output folder")
    if not existing.is_dir():
        raise OutputError(f"{existing}: not a folder, cannot hold the export")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"{existing}: cannot write the export there: permission denied")
    if existing == folder and stem is not None:
        for name in file_names(stem, what):
            path = folder / name
            if path.is_symlink() or (os.path.lexists(path) and not path.is_file()):
                raise OutputError(f"{path}: a symlink or folder is where the export writes a file")
    return folder


def _template(name: str) -> Template:
    return Template(resources.files("optikin.export").joinpath("templates", name).read_text())


def _numbers(values: Iterable[float]) -> str:
    """C initialiser of doubles, each printed so that it parses back to the same double."""
    text = []
    for v in values:
        v = float(v)
        if not np.isfinite(v):
            raise SolverError(f"cannot export the non-finite constant {v}")
        text.append(repr(v))
    return ", ".join(text)


def _rows(array: np.ndarray) -> str:
    return ", ".join("{" + _numbers(row) + "}" for row in np.atleast_2d(array))


def _common(stem: str, problem: str) -> dict[str, str]:
    """What every template of export ``stem`` takes: ``stem`` (also ``prefix``), ``PREFIX``, the problem's name."""
    stem = c_identifier(stem, "stem")
    return dict(stem=stem, prefix=stem, PREFIX=stem.upper(), problem=problem_comment(problem))


def _generated(functions: list[ca.Function], stem: str) -> tuple[str, dict[str, int]]:
    """CasADi's C code of ``functions`` (no header, no export macros) and the largest work sizes.

    CasADi writes the names of each Function and of its inputs and outputs into comments and string
    literals as they are: each must be a C identifier (:func:`~optikin.export._escape.c_identifier`).
    """
    for f in functions:
        c_identifier(f.name(), "Function name")
        for name in (*f.name_in(), *f.name_out()):
            c_identifier(name, f"input or output name of {f.name()}")
    generator = ca.CodeGenerator(f"{stem}.c", {"with_header": False, "with_export": False})
    for f in functions:
        generator.add(f)
    sizes = {
        "sz_arg": max(max(f.sz_arg() for f in functions), 1),
        "sz_res": max(max(f.sz_res() for f in functions), 1),
        "sz_iw": max(max(f.sz_iw() for f in functions), 1),
        "sz_w": max(max(f.sz_w() for f in functions), 1),
    }
    return generator.dump(), sizes


@dataclass(frozen=True)
class ExampleText:
    """What the README says of an export's example, and the example's input file.

    ``what`` is one of :data:`WHATS`; ``title`` a phrase naming the library; ``inputs`` the text of the
    input file (:data:`INPUT_FILES`), one input per line, the inputs compiled into ``main.c``;
    ``count`` how many; ``input_format`` what a line holds; ``usage`` the example's command line;
    ``output_format`` what it prints; ``max_inputs`` how many inputs the example reads at most.
    """

    what: str
    title: str
    inputs: str
    count: int
    input_format: str
    usage: str
    output_format: str
    max_inputs: int = MAX_FILE_SAMPLES


def _readme(example: ExampleText, stem: str, problem: str) -> str:
    """The ``README.md`` of export ``stem`` of problem ``problem`` (named by its file stem, made plain text)."""
    name = problem_comment(problem).replace("`", "_")
    return _template("README.md.in").substitute(
        stem=stem,
        title=example.title,
        problem_name=name,
        what=example.what,
        input=INPUT_FILES[example.what],
        n_samples=example.count,
        input_format=example.input_format,
        max_inputs=example.max_inputs,
        usage=example.usage,
        output_format=example.output_format,
    )


def _lines(rows: np.ndarray) -> str:
    """One line per row of ``rows``, each number printed so that it parses back to the same double."""
    return "".join(" ".join(repr(float(v)) for v in row) + "\n" for row in np.atleast_2d(rows))


def _write(
    folder: Path, stem: str, code: str, header: str, source: str, main: str, problem: str, example: ExampleText
) -> None:
    """Write the files of export ``stem`` of ``problem`` into ``folder`` (created): code, header, example,
    build files, README and the example's input file (:func:`file_names`).

    Each file is written under a temporary name first and all are then renamed into place, so an
    error while writing (a full disk) leaves none of them, whole or half-written: the temporaries
    and the folders this call created are removed.

    Raises
    ------
    OutputError
        The folder cannot take the files (:func:`check_output_folder`), or writing failed.
    """
    stem = c_identifier(stem, "stem")
    word = make_word(stem, "stem")
    texts = dict(
        zip(
            file_names(stem, example.what),
            (
                f"/* {stem}.c: written by optikin export */\n{code}\n{source}",
                header,
                main,
                _template("Makefile.in").substitute(stem=word),
                _template("CMakeLists.txt.in").substitute(
                    project=cmake_value(stem, "stem"),
                    target=cmake_value(stem, "stem"),
                    source=cmake_value(f"{stem}.c", "stem"),
                ),
                _readme(example, stem, problem),
                example.inputs,
            ),
        )
    )
    check_output_folder(folder, stem, example.what)
    created: list[Path] = []
    staged: list[tuple[Path, Path]] = []
    try:
        missing = [p for p in (folder, *folder.parents) if not os.path.lexists(p)]
        for parent in reversed(missing):
            parent.mkdir()
            created.append(parent)
        for name, text in texts.items():
            temporary = folder / f".{name}.{os.getpid()}-{secrets.token_hex(4)}.tmp"
            staged.append((temporary, folder / name))
            temporary.write_text(text, encoding="ascii")
        for temporary, final in staged:
            os.replace(temporary, final)
    except BaseException as exc:
        for temporary, _ in staged:
            temporary.unlink(missing_ok=True)
        for parent in reversed(created):
            try:
                parent.rmdir()
            except OSError:
                pass
        if isinstance(exc, OSError):
            raise OutputError(f"{folder}: cannot write the export: {exc.strerror or exc}") from None
        raise


# --------------------------------------------------------------------------- forward kinematics
def export_fk(problem: str, arm, folder: Path, samples: np.ndarray) -> Export:
    """Write the FK library of ``arm`` (module docstring); ``samples`` ``(k, N)`` go into the example."""
    common: dict[str, Any] = _common("optikin_fk", problem)
    prefix, PREFIX = common["prefix"], common["PREFIX"]
    q = ca.SX.sym("q", arm.n_config)
    functions, outputs, declarations, definitions, defines = [], [], [], [], []
    for name in FK_FUNCTIONS:
        c_identifier(name, "FK function")
        value = ca.densify(getattr(arm, name)(q))
        rows, cols = value.shape
        functions.append(ca.Function(f"{prefix}_{name}_cg", [q], [value]))
        size = f"{PREFIX}_{name.upper()}_SIZE"
        defines.append(f"#define {size} {rows * cols}")
        outputs.append(f"     {prefix}_{name}: {rows} x {cols}, {size} doubles")
        declarations.append(
            f"/* {name} of q into out ({size} doubles). Returns an enum {prefix}_status. */\n"
            f"int {prefix}_{name}({prefix}_work* work, const double* q, double* out);\n"
        )
        definitions.append(
            f"int {prefix}_{name}({prefix}_work* work, const double* q, double* out) {{\n"
            f"  return evaluate({prefix}_{name}_cg, work, q, out);\n}}\n"
        )
    code, sizes = _generated(functions, common["stem"])
    common.update(n=arm.n_config, **sizes)
    header = _template("fk.h").substitute(
        common,
        arm=c_comment(arm.name),
        variables=c_comment(", ".join(arm.config_names)),
        output_list="\n".join(outputs) + "\n",
        size_defines="\n".join(defines),
        declarations="\n".join(declarations),
    )
    source = _template("fk.c").substitute(common, definitions="\n".join(definitions))
    main = _template("fk_main.c").substitute(
        common,
        n_samples=len(samples),
        samples=_rows(samples),
        max_targets=MAX_FILE_SAMPLES,
        max_out=max(f.nnz_out(0) for f in functions),
        n_functions=len(functions),
        function_list=", ".join(f"{prefix}_{name}" for name in FK_FUNCTIONS),
        name_list=", ".join(c_string(name) for name in FK_FUNCTIONS),
        size_list=", ".join(str(f.nnz_out(0)) for f in functions),
    )
    example = ExampleText(
        "fk",
        "forward kinematics",
        _lines(samples),
        len(samples),
        f"one configuration per line, {arm.n_config} numbers ({c_comment(', '.join(arm.config_names))}).",
        "`./example [configurations.txt]`.",
        "For each configuration and function, a line `<name> <status> <values...>` (status 0: ok); then, on "
        "standard error, `per_call_us <name> <microseconds>` per function from a 0.1 s timing loop.",
    )
    _write(folder, common["stem"], code, header, source, main, problem, example)
    return Export("fk", folder, common["stem"], samples)


# --------------------------------------------------------------------------- inverse kinematics
@dataclass(frozen=True)
class IkLibrary:
    """The C of an IK library: CasADi's code, the header, the solver (``#include``-ing the header) and
    the template values (``common``: ``stem``, ``prefix``, ``PREFIX``, sizes)."""

    code: str
    header: str
    source: str
    common: dict[str, Any]

    def translation_unit(self) -> str:
        """Code, header and solver as one C file (the header in place of its ``#include``)."""
        include = f'#include "{self.common["stem"]}.h"'
        return f"{self.code}\n{self.source.replace(include, self.header)}"


def ik_library(problem_name: str, problem, adapter, start: np.ndarray, stem: str) -> IkLibrary:
    """The C of the IK library ``stem`` of least-squares ``problem`` solved as ``adapter`` (a GaussNewton) would.

    Parameters
    ----------
    problem_name:
        How comments name the problem (its file stem is kept).
    problem:
        :class:`~optikin.solvers.nonlinear.LeastSquaresProblem` without constraints.
    adapter:
        The :class:`~optikin.solvers.gauss_newton.GaussNewton` whose options and limits are exported.
    start:
        ``(N,)`` start configuration of independent targets and of a trajectory's first one.
    stem:
        The library's name and prefix (a C identifier).

    Raises
    ------
    SolverError
        The problem has constraints, or every variable is fixed.
    """
    from optikin.solvers.gauss_newton import LAMBDA_FLOOR, SLOW_PROGRESS, SLOW_STEPS

    if problem.constraints is not None:
        raise SolverError(f"{problem.name}: export handles problems without constraints only")
    full = problem
    problem = full.reduced  # the variables solved for (fixed ones substituted), as the Python adapters do
    if problem.n == 0:
        raise SolverError(f"{full.name}: every variable is fixed, nothing to solve")
    common: dict[str, Any] = _common(stem, problem_name)
    stem, prefix = common["stem"], common["prefix"]
    x, p, r, J = problem.symbols
    hessian = ca.hessian(0.5 * ca.sumsqr(r), x)[0]
    functions = [
        ca.Function(f"{prefix}_rj", [x, p], [r, ca.densify(J)]),
        ca.Function(f"{prefix}_hess", [x, p], [ca.densify(hessian)]),
    ]
    code, sizes = _generated(functions, stem)
    n, m, n_p = problem.n, problem.m, problem.n_data
    span = problem.upper - problem.lower
    scaling = np.ones(n) if problem.weights is None else problem.weights**2
    options, limits = adapter.options, adapter.limits
    fixed = full.fixed
    common.update(n=full.n, n_free=n, m=m, n_p=n_p, k=max(n, m))
    tolerance = repr(float(problem.tolerance))
    header = _template("ik.h").substitute(
        common,
        **sizes,
        variables=c_comment(", ".join(full.variable_names)),
        fixed_note=c_comment(
            ", ".join(f"{v} = {float(x)!r}" for v, x, f in zip(full.variable_names, full.lower, fixed) if f) or "none"
        ),
        target_kind=c_comment(problem.residual.name_in(1)),
        tolerance=tolerance,
        ok_note="" if problem.exact else ", or a stationary point (the problem is a minimisation)",
        stationarity_tolerance=repr(float(problem.stationarity_tolerance)),
        max_iterations=int(limits.max_iterations),
    )
    source = _template("ik.c").substitute(
        common,
        start=_numbers(start),
        free_index=", ".join(str(i) for i in np.flatnonzero(~fixed)),
        fixed_value=_numbers(np.where(fixed, full.lower, 0.0)),
        lower=_numbers(problem.lower),
        upper=_numbers(problem.upper),
        span=_numbers(span),
        lower_margin=_numbers(problem.lower + 1e-12 * span),
        upper_margin=_numbers(problem.upper - 1e-12 * span),
        periodic=", ".join(str(int(v)) for v in problem.periodic),
        scaling=_numbers(scaling),
        tolerance=tolerance,
        stop_tolerance=repr(float(min(problem.tolerance, limits.tolerance))),
        stationarity_tolerance=repr(float(problem.stationarity_tolerance)),
        exact=int(problem.exact),
        damping=repr(float(options.damping)),
        damping_min=repr(float(options.damping_min)),
        damping_max=repr(float(options.damping_max)),
        max_iterations=int(limits.max_iterations),
        second_order=int(options.second_order),
        lambda_floor=repr(LAMBDA_FLOOR),
        slow_progress=repr(SLOW_PROGRESS),
        slow_steps=int(SLOW_STEPS),
    )
    return IkLibrary(code, header, source, common)


def export_ik(what: str, problem_name: str, problem, adapter, start: np.ndarray, folder: Path, samples: np.ndarray):
    """Write the IK library of least-squares ``problem`` solved as ``adapter`` (a GaussNewton) would.

    Parameters
    ----------
    what:
        ``ik-step`` (independent targets) or ``ik-trajectory`` (warm-started), for the example.
    problem:
        :class:`~optikin.solvers.nonlinear.LeastSquaresProblem` without constraints.
    adapter:
        The :class:`~optikin.solvers.gauss_newton.GaussNewton` whose options and limits are exported.
    start:
        ``(N,)`` start configuration of independent targets and of a trajectory's first one.
    samples:
        ``(k, NP)`` targets compiled into the example.
    """
    library = ik_library(problem_name, problem, adapter, start, f"optikin_{what.replace('-', '_')}")
    code, header, source, common = library.code, library.header, library.source, library.common
    stem, n_p = common["stem"], common["n_p"]
    trajectory = what == "ik-trajectory"
    main = _template("ik_main.c").substitute(
        common,
        n_samples=len(samples),
        samples=_rows(samples),
        max_targets=MAX_FILE_SAMPLES,
        mode="trajectory" if trajectory else "independent",
        trajectory=int(trajectory),
    )
    example = ExampleText(
        what,
        "inverse kinematics, " + ("warm-started along a trajectory" if trajectory else "independent targets"),
        _lines(samples),
        len(samples),
        f"one target per line, {n_p} numbers ({c_comment(problem.residual.name_in(1))}).",
        "`./example [targets.txt [rounds]]` (rounds: repeat the whole set that many times; 0: no timing loop).",
        "One line per target: `status iterations ||r|| x[0] ... x[N-1]` (status 0: ok, 1: unreachable, "
        "2: not converged, 3: invalid input, 4: failed; see the header). Then, on standard error, "
        "`per_call_us` (wall microseconds per target) and `cpu_us` (process CPU microseconds per target) "
        "from repeating the whole set for 0.2 s.",
    )
    _write(folder, stem, code, header, source, main, problem_name, example)
    return Export(what, folder, stem, samples, np.asarray(start, dtype=float))


@dataclass(frozen=True)
class IkExportSetup:
    """What an IK export is made of: the least-squares problem, the Gauss-Newton adapter, start and targets."""

    problem: object
    adapter: object
    start: np.ndarray
    targets: np.ndarray


def ik_setup(problem: str, overrides: Sequence[tuple[str, Any]] = ()) -> IkExportSetup:
    """The least-squares problem of ``ik`` problem ``problem``, its ``gauss-newton`` adapter, start and targets.

    ``overrides`` are ``(dotted field, value)`` pairs set in the problem file before it is validated.

    Raises
    ------
    SpecError
        The problem is not of kind ``ik``, or its formulation is one per CBHA platform.
    """
    from optikin.export.context import context, registered_preset
    from optikin.ik.formulation import build_problem
    from optikin.problems.ik.run import load_targets, setup_of
    from optikin.solvers.gauss_newton import GaussNewton

    ctx = context(problem, ("ik",), "--what ik-step/ik-trajectory", overrides, ("optikin.solvers.gauss_newton",))
    setup = setup_of(ctx)
    least_squares = build_problem(ctx.arm, setup.formulation)
    if isinstance(least_squares, list):
        raise SpecError(ctx.path, "options.target", "leg-length targets (one problem per platform) are not exported")
    adapter = ctx.adapter
    if not isinstance(adapter, GaussNewton):
        preset = registered_preset("gauss-newton")
        assert preset is not None  # optikin.solvers.gauss_newton, imported above, registers it
        adapter = preset.build()
    targets = load_targets(ctx, setup)
    return IkExportSetup(least_squares, adapter, np.asarray(setup.start, dtype=float), targets.values)


def export(
    problem: str,
    what: str,
    folder: Path | str,
    samples: int = EXAMPLE_SAMPLES,
    overrides: Sequence[tuple[str, Any]] = (),
) -> Export:
    """Write the C library ``what`` (one of :data:`WHATS`) of named problem ``problem`` into ``folder``.

    Parameters
    ----------
    problem:
        A problem name or file, as for ``optikin solve``.
    what:
        ``fk``, ``ik-step``, ``ik-trajectory``, ``ph-shape`` or ``qp-step`` (module docstring).
    folder:
        Where the files go (created; files of the same names are overwritten).
    samples:
        How many of the problem's samples the example compiles in (IK: its first targets; FK:
        configurations drawn uniformly inside the bounds with the problem's seed; PH: its first
        samples; QP: steps spread along the reference).
    overrides:
        ``(dotted field, value)`` pairs set in the problem file before it is validated, e.g.
        ``("arm.params.section_lengths", [0.18] * 4)``.

    Returns
    -------
    Export
        The files written.

    Raises
    ------
    SpecError
        ``what`` does not fit the problem.
    SolverError
        The problem has constraints (not exported) or every variable is fixed.
    OutputError
        ``folder`` cannot take the files (:func:`check_output_folder`) or writing them failed.
    """
    if what not in WHATS:
        raise ValueError(f"--what {what!r}: one of {', '.join(WHATS)}")
    folder = check_output_folder(folder)
    if what == "fk":
        from optikin.export.context import context

        ctx = context(problem, None, "--what fk", overrides)
        Q = ctx.arm.sample_configurations(samples, ctx.rng(0))
        return export_fk(problem, ctx.arm, folder, Q)
    if what == "ph-shape":
        from optikin.export.ph_shape import export_ph_shape, ph_setup

        return export_ph_shape(problem, ph_setup(problem, overrides), folder, samples)
    if what == "qp-step":
        from optikin.export.qp_step import export_qp_step, qp_setup

        return export_qp_step(problem, qp_setup(problem, overrides), folder, samples)
    setup = ik_setup(problem, overrides)
    return export_ik(what, problem, setup.problem, setup.adapter, setup.start, folder, setup.targets[:samples])


def build(exported: Export, flags: Iterable[str] = ("-O2",), compiler: str = "cc") -> Path:
    """Compile the example of ``exported`` (``main.c`` and the library) into ``<folder>/example``.

    ``flags`` are checked against :data:`optikin.codegen.ALLOWED_FLAGS` and ``compiler`` is one of
    :data:`optikin.codegen.COMPILERS`, as for the compiled backends.

    Raises
    ------
    ValueError
        A flag or the compiler is not allowed.
    SolverError
        The compiler is missing or compiling failed.
    """
    checked = check_flags(flags)
    path = find_compiler(compiler)
    executable = exported.folder / "example"
    command = [path, *checked, "-std=c99", "-Wall", "main.c", exported.source.name, "-lm", "-o", executable.name]
    run = subprocess.run(command, cwd=exported.folder, capture_output=True, text=True)
    if run.returncode != 0:
        raise SolverError(f"compiling {exported.stem} with {compiler} failed: {run.stderr.strip()[:800]}")
    return executable


def main(args: argparse.Namespace) -> int:
    """``optikin export PROBLEM --what WHAT --out DIR``: write the files and list them."""
    exported = export(args.problem, args.what, args.out)
    for path in exported.files:
        print(path)
    return 0
