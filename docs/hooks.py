"""MkDocs hook: the pages generated from optikin itself, so they cannot drift from the code.

* ``reference/problem-file.md``: the problem-file and solver-preset schemas of :mod:`optikin.spec`;
* ``reference/kinds/<kind>.md``: each problem kind (:func:`optikin.problems.load_kinds`) with its
  options model, its data sources and their params models (:mod:`optikin.data.sources`) and the
  shipped problem files of that kind;
* ``reference/backends/<family>.md``: each backend family with its backends' options models and
  the shipped presets (``solvers/*.yaml``);
* ``benchmarks.md``: ``BENCHMARKS.md`` of the repository;
* ``notebooks/<name>.ipynb``: the notebooks of ``notebooks/``, rendered by mkdocs-jupyter.

Every table row is a field of a pydantic model as :func:`optikin.options.describe_options`
gives it (``optikin list --kinds`` and ``optikin show`` print the same rows): field, type,
default, and the description, which carries the unit.

The notebooks are rendered as stored (without outputs); ``OPTIKIN_DOCS_EXECUTE=1`` executes
them during the build on their small setting (``OPTIKIN_SMALL=1``), so the pages show the figures.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import textwrap
from pathlib import Path
from typing import Any, get_args

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.plugins import event_priority
from mkdocs.structure.files import File, Files

from optikin.errors import OptikinError

ROOT = Path(__file__).resolve().parent.parent
ROWS = ("field", "type", "default", "description")


def _cell(text: str, code: bool = False) -> str:
    """One table cell, newlines folded: inline code, or text with pipes and brackets escaped
    (``x, y, z [, t]`` is no link)."""
    text = " ".join(str(text).split())
    if code:
        return f"`{text}`" if text else ""  # a table splits no code span at its pipes
    return text.replace("[", "\\[").replace("]", "\\]").replace("|", "\\|")


def spec_rows(model: Any, prefix: str = "") -> list[tuple[str, str, str, str]]:
    """The rows of :func:`~optikin.options.describe_options` for the file schemas of :mod:`optikin.spec`,
    whose nested models (``outputs``, ``limits``) may have neither a description nor a docstring."""
    from pydantic import BaseModel

    from optikin.options import describe_options

    rows: list[tuple[str, str, str, str]] = []
    for name, info in model.model_fields.items():
        nested = info.annotation
        if isinstance(nested, type) and issubclass(nested, BaseModel):
            doc = (nested.__doc__ or "").strip().splitlines()
            rows.append((f"{prefix}{name}", nested.__name__, "", info.description or (doc[0] if doc else "")))
            rows += spec_rows(nested, f"{prefix}{name}.")
        else:
            leaf = type(model.__name__, (BaseModel,), {"__annotations__": {name: info.annotation}, name: info})
            rows += describe_options(leaf, prefix)
    return rows


def options_table(model: Any, rows: list[tuple[str, str, str, str]] | None = None) -> str:
    """A markdown table of every field of an options model (nested models flattened with dots)."""
    from optikin.options import describe_options

    rows = describe_options(model) if rows is None else rows
    if not rows:
        return "Takes no options.\n"
    lines = ["| " + " | ".join(ROWS) + " |", "| --- | --- | --- | --- |"]
    for field, type_name, default, description in rows:
        cells = (_cell(field, True), _cell(type_name, True), _cell(default, True), _cell(description))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _models_in(annotation: Any) -> list[type]:
    """The pydantic models inside a union, list or dict annotation (``X | None``, ``list[X]``)."""
    from pydantic import BaseModel

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in get_args(annotation) for m in _models_in(arg)]


def inner_models(model: Any, prefix: str = "") -> list[tuple[str, type]]:
    """``(dotted field, model)`` of every model behind a union or a list (``plant.physics: X | None``),
    which :func:`~optikin.options.describe_options` names but does not flatten; searched through
    the nested models it does flatten."""
    from pydantic import BaseModel

    found: list[tuple[str, type]] = []
    for name, info in model.model_fields.items():
        annotation, dotted = info.annotation, f"{prefix}{name}"
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            found += inner_models(annotation, f"{dotted}.")
            continue
        for inner in _models_in(annotation):
            found += [(dotted, inner), *inner_models(inner, f"{dotted}.")]
    return found


def model_tables(model: Any, rows: list[tuple[str, str, str, str]] | None = None) -> str:
    """The table of ``model`` followed by one table per model behind a union or list field."""
    parts = [options_table(model, rows)]
    for dotted, inner in inner_models(model):
        summary = _first_paragraph(inner.__doc__).replace("[", "\\[").replace("]", "\\]")
        parts += [f"`{dotted}` as `{inner.__name__}`: {summary}", ""]
        parts.append(options_table(inner, spec_rows(inner)))
    return "\n".join(parts)


def _first_paragraph(doc: str | None) -> str:
    """The first paragraph of a docstring on one line, Sphinx roles as plain code (``:mod:`x``` -> ```x```)."""
    text = (doc or "").strip().split("\n\n")[0].replace("\n", " ")
    return re.sub(r":[a-z]+:`~?([^`]+)`", r"`\1`", text)


def _problems_by_kind() -> dict[str, list[tuple[str, str]]]:
    from optikin.spec import available, load_problem

    by_kind: dict[str, list[tuple[str, str]]] = {}
    for name in available("problems"):
        try:
            spec, _ = load_problem(name)
        except OptikinError:  # an invalid file is listed by `optikin list` and failed by the tests
            continue
        by_kind.setdefault(spec.kind, []).append((name, spec.title))
    return by_kind


def _presets_by_backend() -> dict[str, list[Any]]:
    from optikin.spec import available, load_solver

    by_backend: dict[str, list[Any]] = {}
    for name in available("solvers"):
        try:
            spec, _ = load_solver(name)
        except OptikinError:
            continue
        by_backend.setdefault(spec.backend, []).append(spec)
    return by_backend


def kind_pages() -> dict[str, str]:
    """``{kind name: page}`` of every registered problem kind."""
    from optikin.data.sources import DATA_SOURCES
    from optikin.problems import load_kinds
    from optikin.registry import PROBLEM_KINDS

    load_kinds()
    problems = _problems_by_kind()
    pages = {}
    for name in PROBLEM_KINDS.names():
        kind = PROBLEM_KINDS.get(name)
        families = ", ".join(f"[{f}](../backends/{f}.md)" for f in kind.backend_families) or "itself"
        lines = [
            f"# Kind `{name}`",
            "",
            f"{_cell(kind.summary[:1].upper() + kind.summary[1:])}.",
            "",
            f"- solved by the backend families: {families}",
            f"- default solver preset: `{kind.default_solver}`" if kind.default_solver else "- no default preset",
            f"- baselines of the kind itself: {', '.join(f'`{b}`' for b in kind.baselines) or 'none'}",
            f"- data family (`data.source`): `{kind.data_family}`",
            f"- `arm:` {'may be left out' if kind.arm_optional else 'required'}",
            "",
            f"Module: [`optikin.problems.{name}`](#module-docstring); "
            f"`optikin show NAME` prints a file of this kind with every default filled in.",
            "",
            "## Options (`options:`)",
            "",
            model_tables(kind.options),
            "## Data sources (`data.source`, `data.params`)",
            "",
        ]
        registry = DATA_SOURCES.get(kind.data_family)
        for source in [registry.get(n) for n in registry.names()] if registry is not None else []:
            source_name = source.name
            lines += [f"### `{source_name}`", "", f"{_cell(source.summary)}.", "", model_tables(source.params)]
        lines += ["## Shipped problem files", ""]
        lines += [f"- `{p}`: {_cell(title)}" for p, title in problems.get(name, [])] or ["None."]
        lines += [
            "",
            "## Module docstring",
            "",
            f"::: optikin.problems.{name}",
            "    options:",
            "      members: false",
            "      show_submodules: false",
            "",
        ]
        pages[name] = "\n".join(lines)
    return pages


def backend_pages() -> dict[str, str]:
    """``{family: page}`` of every backend family, with each backend's options and presets."""
    from optikin.registry import BACKENDS
    from optikin.solvers import FAMILIES, load_backends

    load_backends()
    presets = _presets_by_backend()
    pages = {}
    for family in FAMILIES:
        lines = [
            f"# Backend family `{family}`",
            "",
            "A solver preset (`solvers/*.yaml`) names a backend and its `options:`, checked against the "
            "backend's model below; `limits:` (`max_iterations`, `time_limit`, `tolerance`) are common to "
            "all presets ([problem file reference](../problem-file.md)).",
            "",
        ]
        for name in BACKENDS.names():
            backend = BACKENDS.get(name)
            if backend.family != family:
                continue
            lines += [
                f"## `{name}`",
                "",
                f"{_cell(backend.summary)}. Module: `{backend.module}`.",
                "",
                model_tables(backend.options),
            ]
            for spec in presets.get(name, []):
                options = ", ".join(f"`{k}: {v}`" for k, v in spec.options.items()) or "defaults"
                lines.append(f"- preset `{spec.name}`: {_cell(spec.title)} (options: {options})")
            lines.append("")
        pages[family] = "\n".join(lines)
    return pages


def problem_file_page() -> str:
    """The schemas of a problem file and a solver preset, and the registered arms."""
    from optikin.registry import ARMS
    from optikin.spec import ProblemSpec, SolverSpec

    import optikin.arms  # noqa: F401  (registers the arms)

    arms = [f"- `{name}`: [`{ARMS.get(name).__name__}`](../api/arms.md)" for name in ARMS.names()]
    return "\n".join(
        [
            "# Problem files and solver presets",
            "",
            "A problem file (`problems/*.yaml`) names a [problem kind](kinds/index.md), an arm and its "
            "parameters, a data source with its seed, a solver preset and the baselines to compare. "
            "Unknown fields are errors; `options`, `data.params` and a preset's `options` are checked "
            "against the models of the kind, the data source and the backend.",
            "",
            "## Problem file",
            "",
            model_tables(ProblemSpec, spec_rows(ProblemSpec)),
            "## Arms (`arm.type`)",
            "",
            "`arm.params` are the constructor arguments of the arm's class ([API](../api/arms.md)); "
            "`arm: path.yaml` includes an `arm:` section written by `calibrate`.",
            "",
            *arms,
            "",
            "## Solver preset",
            "",
            model_tables(SolverSpec, spec_rows(SolverSpec)),
            "The backends and their options: [backend families](backends/index.md).",
            "",
        ]
    )


def _subcommands(parser: Any) -> dict[str, Any]:
    """``{name: parser}`` of every subcommand of ``parser``, deferred arguments added (by printing its help)."""
    import argparse

    found: dict[str, Any] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                sub.format_help()
                found[name] = sub
    return found


def _argument_rows(parser: Any) -> list[tuple[str, str, str]]:
    """``(argument, default, meaning)`` of every argument of ``parser`` but ``--help``."""
    import argparse

    rows = []
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if action.option_strings:
            metavar = "" if action.nargs == 0 else f" {action.metavar or action.dest.upper()}"
            name = ", ".join(action.option_strings) + metavar
        else:
            name = action.metavar or action.dest
        default = action.default
        shown = "" if default in (None, False, argparse.SUPPRESS) or action.nargs == 0 else repr(default)
        meaning = action.help or ""
        if action.choices and not isinstance(action.choices, dict):
            meaning += f" (one of: {', '.join(map(str, action.choices))})"
        if action.required and action.option_strings:
            meaning += " (required)"
        rows.append((name, shown, meaning))
    return rows


def _argument_table(parser: Any) -> list[str]:
    rows = _argument_rows(parser)
    if not rows:
        return ["Takes no arguments.", ""]
    lines = ["| argument | default | meaning |", "| --- | --- | --- |"]
    lines += [f"| {_cell(a, True)} | {_cell(d, True)} | {_cell(m)} |" for a, d, m in rows]
    return [*lines, ""]


def command_page() -> str:
    """Every subcommand of ``optikin`` with its usage and arguments, read from :func:`optikin.cli.build_parser`."""
    from optikin.cli import build_parser

    parser = build_parser()
    lines = [
        "# Commands",
        "",
        "Every subcommand and option of `optikin`, generated from its argument parser "
        "(`optikin COMMAND --help` prints the same). Options before the subcommand:",
        "",
        *_argument_table(parser),
        f"{_cell(parser.epilog or '')}.",
        "",
    ]
    for name, sub in _subcommands(parser).items():
        summary = next((a.help for a in parser._subparsers._group_actions[0]._choices_actions if a.dest == name), "")
        usage = " ".join(sub.format_usage().split())
        lines += [f"## `optikin {name}`", "", f"{_cell(summary or '')}.", "", "```text", usage, "```", ""]
        lines += _argument_table(sub)
    return "\n".join(lines)


def sweep_file_page() -> str:
    """The schema of a sweep file (``sweeps/*.yaml``), its annotated example, and the shipped sweeps."""
    from optikin.spec import shipped_dir
    from optikin.sweep import spec as sweep_spec

    example = (sweep_spec.__doc__ or "").split("A sweep file::", 1)[-1].split("\n\n")[1]
    shipped = [f"- `{path.stem}`" for path in sorted(shipped_dir("sweeps").glob("*.yaml"))]  # type: ignore[arg-type]
    return "\n".join(
        [
            "# Sweep files",
            "",
            "`optikin sweep NAME` solves a problem over axes of overrides and collects one table; "
            "the file is validated like a problem file (unknown fields are errors).",
            "",
            "```yaml",
            textwrap.dedent(example).rstrip(),
            "```",
            "",
            model_tables(sweep_spec.SweepSpec),
            "## Shipped sweeps",
            "",
            *(shipped or ["None."]),
            "",
        ]
    )


ROLE_RE = re.compile(r":(?:py:)?(?:mod|class|func|meth|data|attr|exc|obj|const):<code>(~?)([\w.]+)</code>")
"""A Sphinx role of a docstring as mkdocstrings renders it (``:class:<code>X</code>``)."""

PAGES: dict[str, str] = {}
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
NOTEBOOK_DIR: list[Path] = []
"""The temporary folder holding the notebooks' copies while they are executed (empty: not executing)."""


def on_config(config: MkDocsConfig) -> MkDocsConfig:
    """Generate the pages, put them in the navigation, and switch notebook execution on if asked."""
    PAGES.clear()
    kinds, families = kind_pages(), backend_pages()
    PAGES["reference/problem-file.md"] = problem_file_page()
    PAGES["reference/kinds/index.md"] = "\n".join(["# Problem kinds", "", *[f"- [`{k}`]({k}.md)" for k in kinds], ""])
    PAGES["reference/backends/index.md"] = "\n".join(
        ["# Backend families", "", *[f"- [`{f}`]({f}.md)" for f in families], ""]
    )
    PAGES.update({f"reference/kinds/{k}.md": page for k, page in kinds.items()})
    PAGES.update({f"reference/backends/{f}.md": page for f, page in families.items()})
    PAGES["benchmarks.md"] = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    PAGES["reference/commands.md"] = command_page()
    PAGES["reference/sweep-file.md"] = sweep_file_page()
    PAGES["reference/recordings.md"] = (ROOT / "examples" / "README.md").read_text(encoding="utf-8")

    generated = {
        "GENERATED_KINDS": [{"Problem kinds": "reference/kinds/index.md"}]
        + [{k: f"reference/kinds/{k}.md"} for k in kinds],
        "GENERATED_BACKENDS": [{"Backend families": "reference/backends/index.md"}]
        + [{f: f"reference/backends/{f}.md"} for f in families],
        "GENERATED_NOTEBOOKS": [{p.stem.replace("_", " "): f"notebooks/{p.name}"} for p in NOTEBOOKS],
    }
    config["nav"] = _expand(config["nav"], generated)

    NOTEBOOK_DIR.clear()
    if os.environ.get("OPTIKIN_DOCS_EXECUTE") == "1":
        os.environ.setdefault("OPTIKIN_SMALL", "1")
        # Figures shown inline (a notebook's last expression may be its figure), whatever the caller's backend.
        os.environ["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"
        config["plugins"]["mkdocs-jupyter"].config["execute"] = True
        # The kernel runs in the notebook's folder and a notebook may write there: run copies.
        NOTEBOOK_DIR.append(Path(tempfile.mkdtemp(prefix="optikin-docs-")))
        (NOTEBOOK_DIR[0] / "notebooks").mkdir()
        for path in NOTEBOOKS:
            shutil.copy2(path, NOTEBOOK_DIR[0] / "notebooks" / path.name)
    return config


def on_post_build(config: MkDocsConfig) -> None:
    """Remove the executed copies of the notebooks."""
    for folder in NOTEBOOK_DIR:
        shutil.rmtree(folder, ignore_errors=True)
    NOTEBOOK_DIR.clear()


def _expand(nav: Any, generated: dict[str, list[Any]]) -> Any:
    """The navigation with each placeholder page (``GENERATED_*``) replaced by its generated entries."""
    if isinstance(nav, list):
        out: list[Any] = []
        for item in nav:
            if isinstance(item, str) and item in generated:
                out += generated[item]
            else:
                out.append(_expand(item, generated))
        return out
    if isinstance(nav, dict):
        return {key: _expand(value, generated) for key, value in nav.items()}
    return nav


def on_page_content(html: str, **kwargs: Any) -> str:
    """Sphinx roles of the docstrings (``:func:`~optikin.api.solve_ik```) as cross-references to the API
    pages, resolved by mkdocs-autorefs (plain code where the object is not documented on the site), and
    the ``::`` that opens a reST literal block as one colon."""

    def reference(match: re.Match[str]) -> str:
        short, identifier = match.groups()
        title = identifier.rsplit(".", 1)[-1] if short else identifier
        return f'<autoref identifier="{identifier}" optional><code>{title}</code></autoref>'

    return ROLE_RE.sub(reference, html).replace("::</p>", ":</p>")  # a reST literal block's "::" ends the line


@event_priority(100)
def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add the generated pages and the notebooks (before mkdocs-jupyter wraps the notebooks)."""
    for src_uri, content in PAGES.items():
        files.append(File.generated(config, src_uri, content=content))
    source = NOTEBOOK_DIR[0] if NOTEBOOK_DIR else ROOT
    for path in NOTEBOOKS:
        # A real source folder (the repository, or the copies), not File.generated: mkdocs-jupyter's
        # wrapper finds the notebook from ``src_dir``.
        uri = path.relative_to(ROOT).as_posix()
        files.append(
            File(uri, src_dir=str(source), dest_dir=config.site_dir, use_directory_urls=config.use_directory_urls)
        )
    return files
