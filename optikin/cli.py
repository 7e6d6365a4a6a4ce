"""The ``optikin`` command line: ``list``, ``show``, ``solve``, ``sweep``, ``plot``, ``view``, ``export``, ``bench``.

Exit status, one meaning each:

0
    the run finished and every sample is ``ok``;
1
    the run finished but some samples failed, or the run missed a criterion of its
    kind (e.g. a tracking run did not converge; a note says by how much);
2
    bad input (a malformed file, an unknown name or field, bad data): one line
    naming the file, field or sample;
3
    an internal error: one line, and the traceback with ``--debug``;
130
    interrupted (Ctrl-C or SIGTERM).
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys
import traceback
from pathlib import Path
from typing import Any, Callable, Literal

from optikin import __version__
from optikin.errors import OptikinError

EXIT_OK, EXIT_FAILED_SAMPLES, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
INTERRUPTED = "optikin: interrupted; nothing was written"
"""What an interrupted run says."""
INTERRUPTED_SWEEP = "optikin: interrupted; the finished cells are kept (the same command resumes)"
"""What a sweep stopped inside a long CasADi call says (its finished cells are on disk)."""


def _listing(
    kind: Literal["problems", "solvers"],
    load: Callable[[str], tuple[Any, Path]],
    describe: Callable[[Any], tuple[str, ...]],
) -> tuple[list[tuple[str, ...]], list[str]]:
    """Rows ``(name, *describe(spec))`` of every named file of ``kind``, and the errors of those that fail."""
    from optikin.spec import available

    rows, broken = [], []
    for name in available(kind):
        try:
            rows.append((name, *describe(load(name)[0])))
        except OptikinError as exc:
            broken.append(str(exc))
    return rows, broken


def _cmd_list(args: argparse.Namespace) -> int:
    from rich.markup import escape

    from optikin.report import print_listing, wide_console
    from optikin.spec import load_problem, load_solver

    console = wide_console()
    rows, broken = _listing("problems", load_problem, lambda spec: (spec.kind, spec.title))
    print_listing("problems", rows, ("name", "kind", "title"), console)
    if args.solvers:
        from optikin.registry import BACKENDS
        from optikin.solvers import load_backends

        load_backends()

        def describe(spec):
            where = BACKENDS.get(spec.backend).module if spec.backend in BACKENDS else "unknown backend"
            return (spec.backend, where, spec.title) if args.where else (spec.backend, spec.title)

        columns = ("name", "backend", "module", "title") if args.where else ("name", "backend", "title")
        solver_rows, solver_broken = _listing("solvers", load_solver, describe)
        print_listing("solvers", solver_rows, columns, console)
        broken += solver_broken
    if args.kinds:
        _print_kinds(console)
    for message in broken:
        console.print(f"[red]invalid:[/red] {escape(message)}")
    return EXIT_BAD_INPUT if broken else EXIT_OK


def _print_kinds(console) -> None:
    """Each problem kind with its backend families, data sources and options (field, type, default, meaning)."""
    from optikin.data.sources import DATA_SOURCES
    from optikin.options import describe_options
    from optikin.problems import load_kinds
    from optikin.registry import PROBLEM_KINDS
    from optikin.report import print_listing

    load_kinds()
    for name in PROBLEM_KINDS.names():
        kind = PROBLEM_KINDS.get(name)
        sources = DATA_SOURCES[kind.data_family].names() if kind.data_family in DATA_SOURCES else []
        console.print(
            f"[bold]{name}[/bold]: {kind.summary}; solved by {', '.join(kind.backend_families) or 'itself'}"
            f"; data sources ({kind.data_family}): {', '.join(sources)}"
        )
        print_listing(
            f"options of kind {name}",
            describe_options(kind.options),
            ("field", "type", "default", "description"),
            console,
        )


def _cmd_show(args: argparse.Namespace) -> int:
    import yaml

    from optikin.options import describe_options
    from optikin.report import print_listing, wide_console

    if args.solver:
        from optikin.solvers import load_preset

        preset = load_preset(args.name)
        path = preset.path
        model, title = preset.backend.options, f"options of backend {preset.spec.backend}"
        data = preset.spec.model_dump(mode="json")
        data["options"] = preset.options.model_dump(mode="json")
    else:
        from optikin.runner import prepare

        kind, ctx = prepare(args.name)
        path = ctx.path
        model, title = kind.options, f"options of kind {kind.name}"
        data = ctx.spec.model_dump(mode="json")
        data["options"] = ctx.options.model_dump(mode="json")
        data["data"]["params"] = ctx.data_params.model_dump(mode="json")
        if getattr(ctx.data_params, "file", None) is not None:
            for field in ("samples", "seed"):  # defaults that mean nothing for a file read whole
                if field not in ctx.spec.data.model_fields_set:
                    data["data"].pop(field, None)
    print(f"# {path}")
    print(json.dumps(data, indent=2) if args.json else yaml.safe_dump(data, sort_keys=False), end="")
    if not args.json:
        print_listing(title, describe_options(model), ("field", "type", "default", "description"), wide_console())
    return EXIT_OK


def _cmd_solve(args: argparse.Namespace) -> int:
    from optikin.progress import Progress
    from optikin.report import print_result
    from optikin.runner import solve

    from optikin.errors import SpecError
    from optikin.spec import parse_override

    if not args.out.strip():
        raise SpecError("--out", "", "an empty output folder is not accepted (give a folder, e.g. results)")
    overrides = [parse_override(text) for text in args.set or []]
    _headless_figures()
    result, written = solve(
        args.problem,
        solver=args.solver,
        out=Path(args.out),
        figures=not args.no_figures,
        progress=Progress(enabled=not args.json),
        notify=logging.getLogger("optikin.cli").info,
        overrides=overrides,
        chunks=_solve_chunks(args),
    )
    try:
        if args.json:
            print(json.dumps(result.summary(), indent=2))
        else:
            print_result(result, wide=args.wide, verbose=args.verbose)
            print(f"written to {written}")
    except KeyboardInterrupt:
        print(f"optikin: interrupted; the result was written to {written}", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK if result.succeeded else EXIT_FAILED_SAMPLES


def _solve_chunks(args: argparse.Namespace) -> Any:
    from optikin.sweep.chunks import chunks_of

    return chunks_of(args.jobs, args.dask)


def _cmd_plot(args: argparse.Namespace) -> int:
    from optikin.errors import InputDataError
    from optikin.results import read_result, redraw, result_kind

    _headless_figures()
    folder = Path(args.result)
    summary, arrays = read_result(folder)
    kind = result_kind(folder, summary)
    if kind.figures is None:
        print(f"kind {kind.name} draws no figures")
        return EXIT_OK
    if not arrays:
        raise InputDataError("the result holds no arrays: no figures to draw from", source=str(folder))
    for path in redraw(folder, kind.figures, summary, arrays):
        print(f"drew {path}")
    return EXIT_OK


def _cmd_view(args: argparse.Namespace) -> int:
    from optikin.view import open_in_browser, write_view

    page = write_view(Path(args.result), Path(args.out) if args.out else None)
    print(f"wrote {page}")
    if args.open and not open_in_browser(page):
        print(f"optikin: no web browser could be started; open {page.resolve().as_uri()}", file=sys.stderr)
    return EXIT_OK


def _headless_figures() -> None:
    """Figures from the command line are files: draw with the Agg backend, whatever the machine has."""
    import matplotlib

    matplotlib.use("Agg")


class _CommandParser(argparse.ArgumentParser):
    """A subcommand's parser; :meth:`defer` leaves a module's arguments and ``main`` until the subcommand is used."""

    _module: str | None = None

    def defer(self, module: str) -> None:
        """Add ``module.add_arguments`` when this parser first parses or prints its help, and run ``module.main``,
        so that ``optikin --help`` and the other subcommands do not import ``module``."""
        self._module = module
        self.set_defaults(run=lambda args: importlib.import_module(module).main(args))

    def _add_deferred(self) -> None:
        if self._module is not None:
            module, self._module = self._module, None
            importlib.import_module(module).add_arguments(self)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> tuple[Any, list[str]]:
        self._add_deferred()
        return super().parse_known_args(args, namespace)

    def format_help(self) -> str:
        self._add_deferred()
        return super().format_help()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="optikin",
        description=__doc__.splitlines()[0],
        epilog="exit status: 0 all samples ok, 1 some samples failed, 2 bad input "
        "(file, field or sample named), 3 internal error, 130 interrupted",
    )
    parser.add_argument("--version", action="version", version=f"optikin {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an internal error")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_CommandParser)

    p = sub.add_parser("list", help="named problems (and solver presets) with title and kind")
    p.add_argument("--solvers", action="store_true", help="also list solver presets")
    p.add_argument("--where", action="store_true", help="with --solvers: the module of each preset's backend")
    p.add_argument("--kinds", action="store_true", help="also list problem kinds with their options")
    p.set_defaults(run=_cmd_list)

    p = sub.add_parser("show", help="the validated spec of a named problem (or solver preset)")
    p.add_argument("name", help="problem name or path to a problem file")
    p.add_argument("--solver", action="store_true", help="NAME is a solver preset")
    p.add_argument("--json", action="store_true", help="print JSON instead of YAML")
    p.set_defaults(run=_cmd_show)

    p = sub.add_parser("solve", help="solve a named problem and write its results")
    p.add_argument("problem", help="problem name or path to a problem file")
    p.add_argument("--solver", help="solver preset name or path (default: the problem's)")
    p.add_argument("--out", default="results", help="output folder (default: ./results)")
    p.add_argument("--json", action="store_true", help="print the result summary as JSON")
    p.add_argument("--no-figures", action="store_true", help="skip drawing figures")
    p.add_argument("--wide", action="store_true", help="print every column of the comparison (-v: every metric too)")
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a field of the problem file (dotted, e.g. data.seed=3 or options.noise=0.001; "
        "the value is YAML); validated like the file; repeatable",
    )
    p.add_argument("--jobs", type=int, default=1, help="split the samples across N joblib (loky) worker processes")
    p.add_argument("--dask", metavar="ADDRESS", help="split the samples on a Dask scheduler, or local:N (LocalCluster)")
    p.set_defaults(run=_cmd_solve)

    p = sub.add_parser("plot", help="redraw the figures of a written result from its arrays, without solving")
    p.add_argument("result", help="a result folder (holding result.json and arrays.npz)")
    p.set_defaults(run=_cmd_plot)

    p = sub.add_parser("view", help="an interactive 3-D HTML page of a written result (self-contained)")
    p.add_argument("result", help="a result folder (holding result.json and arrays.npz)")
    p.add_argument("--out", help="the HTML file to write (default: RESULT/view.html)")
    p.add_argument("--open", action="store_true", help="open the page in the web browser")
    p.set_defaults(run=_cmd_view)

    p = sub.add_parser("sweep", help="solve a problem over axes of overrides (joblib or Dask workers), one table")
    p.defer("optikin.sweep.run")

    p = sub.add_parser("bench", help="forward-kinematics throughput of every evaluation path against numpy")
    p.defer("optikin.bench")

    p = sub.add_parser("examples", help="copy the shipped example problems and the data they read into a new folder")
    p.add_argument("folder", nargs="?", help="the new folder, which must not exist (default: ./optikin-examples)")
    p.set_defaults(run=_cmd_examples)

    p = sub.add_parser("export", help="a problem's kinematics, IK, PH shape or QP step as a self-contained C library")
    p.add_argument("problem", help="problem name or path to a problem file")
    p.add_argument(
        "--what",
        required=True,
        choices=("fk", "ik-step", "ik-trajectory", "ph-shape", "qp-step"),
        help="fk: fk_dq, fk_position, backbone; ik-step / ik-trajectory: the damped Gauss-Newton IK; "
        "ph-shape: minimum-energy PH backbones along a trajectory; qp-step: one tracking QP step",
    )
    p.add_argument("--out", required=True, help="output folder (.c, .h, main.c, Makefile, CMakeLists.txt)")
    p.set_defaults(run=_cmd_export)

    from optikin.progress import add_verbosity_arguments

    add_verbosity_arguments(parser, sub)
    return parser


def _cmd_examples(args: argparse.Namespace) -> int:
    from optikin.examples import DEFAULT_FOLDER, copy_examples, example_problems

    folder = copy_examples(DEFAULT_FOLDER if args.folder is None else args.folder)
    print(f"copied the examples into {folder}; try:")
    for problem in example_problems(folder):
        print(f"  optikin solve {folder / problem.name}")
    print(f"(the data files and the columns and units each reader expects: {folder / 'README.md'})")
    if (folder / "plugin").is_dir():
        print(f"your own arm as a plugin, worked through: {folder / 'plugin' / 'README.md'}")
    return EXIT_OK


def _cmd_export(args: argparse.Namespace) -> int:
    from optikin import export

    return export.main(args)


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default: the program's arguments); returns the exit status.

    Run as the program (``argv`` None), an interrupted run ends at once (:func:`optikin.interrupt.exit_now`):
    the interpreter's own teardown of a run's CasADi graphs and models can take seconds; and a signal
    arriving inside a long CasADi call ends the process after :data:`optikin.interrupt.STOP_GRACE`
    seconds if the call has not returned by then.
    """
    from optikin.interrupt import deferred_interrupts, exit_now
    from optikin.progress import command_line_logging

    args = build_parser().parse_args(argv)
    stopped = INTERRUPTED_SWEEP if args.command == "sweep" else INTERRUPTED
    try:
        with deferred_interrupts(stopped if argv is None else None), command_line_logging(args.verbose, args.quiet):
            code = args.run(args)
    except OptikinError as exc:
        print(f"optikin: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(INTERRUPTED, file=sys.stderr)
        code = EXIT_INTERRUPTED
    except Exception as exc:
        if args.debug:
            traceback.print_exc()
        else:
            print(
                f"optikin: internal error: {type(exc).__name__}: {exc}; run with --debug for the traceback",
                file=sys.stderr,
            )
        return EXIT_INTERNAL
    if code == EXIT_INTERRUPTED and argv is None:
        exit_now(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
