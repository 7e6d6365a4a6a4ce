"""Sweep files (``sweeps/*.yaml``): a base problem, axes of overrides, the metrics to collect.

A sweep file::

    name: ph-noise                       # must match the file name
    title: Shape error against marker noise
    problem: cbha-ph-shape               # a problem name or a path (relative to the sweep file)
    solver: null                         # a preset for every cell (optional; an axis may set it)
    combine: product                     # product of the axes, or zip (equal lengths)
    axes:                                # dotted field of the problem file -> values
      data.params.noise: [0.0001, 0.0003, 0.001]
      data.seed: range(3)                # range(stop), range(start, stop[, step]), read without eval
    set: {data.samples: 20}              # overrides shared by every cell
    metrics: ["mean marker error [mm]"]  # keys of the result's metrics or comparison rows
    retries: 2                           # a cell is tried 1 + retries times before it is marked failed

Each cell is the base problem with one value of every axis set (:func:`optikin.spec.apply_overrides`),
validated in the worker like ``optikin solve --set``, so a bad value fails that cell alone.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, field_validator

from optikin import __version__
from optikin.errors import OptikinError, SpecError
from optikin.options import Options, validate_options
from optikin.spec import NAME_PATTERN, _read_yaml, is_path, resolve, shipped_dir

RANGE = re.compile(r"^\s*range\(\s*(-?\d+)\s*(?:,\s*(-?\d+)\s*(?:,\s*(-?\d+)\s*)?)?\)\s*$")
"""``range(stop)``, ``range(start, stop)`` or ``range(start, stop, step)`` with integer arguments."""
MAX_CELLS = 100_000
"""Most cells a sweep may expand to."""


def parse_range(text: str) -> list[int] | None:
    """``"range(2, 8, 2)"`` -> ``[2, 4, 6]`` as Python's ``range``; None when ``text`` is not one.

    Raises
    ------
    ValueError
        On a zero step.
    """
    match = RANGE.match(text)
    if match is None:
        return None
    args = [int(a) for a in match.groups() if a is not None]
    if len(args) == 3 and args[2] == 0:
        raise ValueError("range() step must not be zero")
    values = list(range(*args))
    if len(values) > MAX_CELLS:
        raise ValueError(f"range() of {len(values)} values: more than {MAX_CELLS}")
    return values


class SweepSpec(Options):
    """A validated sweep file."""

    name: str = Field(pattern=NAME_PATTERN, description="the file name without .yaml")
    title: str = Field(description="one line saying what the sweep studies")
    description: str = ""
    problem: str = Field(description="base problem: a name, or a path relative to the sweep file")
    solver: str | None = Field(None, description="solver preset of every cell (an axis 'solver' overrides it)")
    combine: Literal["product", "zip"] = Field("product", description="cells: product of the axes, or zipped")
    axes: dict[str, list[Any]] = Field(min_length=1, description="dotted field -> values (a list or range(...))")
    set: dict[str, Any] = Field(default_factory=dict, description="overrides shared by every cell")
    metrics: list[str] = Field(min_length=1, description="metric keys collected from each cell's result")
    retries: int = Field(2, ge=0, le=10, description="extra tries of a cell whose worker died")

    @field_validator("axes", mode="before")
    @classmethod
    def _ranges(cls, axes: Any) -> Any:
        if not isinstance(axes, dict):
            return axes
        out = {}
        for field, values in axes.items():
            if isinstance(values, str):
                parsed = parse_range(values)
                if parsed is None:
                    raise ValueError(f"{field}: expected a list or range(a[, b[, step]]), got {values!r}")
                values = parsed
            out[field] = values
        return out

    @field_validator("axes")
    @classmethod
    def _fields(cls, axes: dict[str, list[Any]]) -> dict[str, list[Any]]:
        for field, values in axes.items():
            if not field or any(not part for part in field.split(".")):
                raise ValueError(f"{field!r} is not a dotted field")
            if not values:
                raise ValueError(f"{field}: no values")
        return axes


@dataclass(frozen=True)
class Cell:
    """One solve of a sweep: the base problem with ``overrides`` set; picklable, sent to a worker."""

    index: int
    key: str
    problem: str
    solver: str | None
    overrides: tuple[tuple[str, Any], ...]
    axes: tuple[tuple[str, Any], ...]
    metrics: tuple[str, ...]
    marker_dir: str | None = None


def resolve_sweep(name_or_path: str) -> Path:
    """A path as given, or ``sweeps/NAME.yaml`` beside the package (or in the working folder)."""
    if is_path(name_or_path):
        path = Path(name_or_path)
        if not path.is_file():
            raise SpecError(name_or_path, "", "no such file")
        return path
    for folder in (Path.cwd() / "sweeps", shipped_dir("sweeps")):
        if (folder / f"{name_or_path}.yaml").is_file():
            return folder / f"{name_or_path}.yaml"
    raise SpecError(name_or_path, "", "no such sweep (looked in ./sweeps and the shipped sweeps)")


def load_sweep(name_or_path: str) -> tuple[SweepSpec, Path]:
    """Read and validate a sweep file; errors name the file and the dotted field (``axes.data.seed``)."""
    path = resolve_sweep(name_or_path)
    spec = validate_options(SweepSpec, _read_yaml(path), path, "")
    if spec.name != path.stem:
        raise SpecError(path, "name", f"{spec.name!r} differs from the file name {path.stem!r}")
    if spec.combine == "zip" and len({len(v) for v in spec.axes.values()}) > 1:
        lengths = ", ".join(f"{k}: {len(v)}" for k, v in spec.axes.items())
        raise SpecError(path, "axes", f"combine: zip needs axes of equal length ({lengths})")
    return spec, path


def base_problem(spec: SweepSpec, path: Path) -> str:
    """The base problem as :func:`optikin.runner.solve` takes it: a name, or a path made absolute."""
    if not is_path(spec.problem):
        return spec.problem
    problem = Path(spec.problem)
    return str(problem if problem.is_absolute() else (path.parent / problem).resolve())


def _file_digest(name: str, kind: Literal["problems", "solvers"]) -> str:
    try:
        return hashlib.sha256(resolve(name, kind).read_bytes()).hexdigest()
    except OptikinError:
        return f"unresolved:{name}"


def cell_key(problem: str, solver: str | None, overrides: tuple[tuple[str, Any], ...]) -> str:
    """Hash of (problem file content, overrides, solver preset content, optikin version), 16 hex digits.

    The preset is the one the cell names (``solver`` or an override of ``solver``); a problem or preset
    file edited since a cell ran changes its key, so that cell runs again.
    """
    preset = dict(overrides).get("solver", solver)
    payload = {
        "problem": _file_digest(problem, "problems"),
        "overrides": [[k, v] for k, v in overrides],
        "preset": None if preset is None else [preset, _file_digest(str(preset), "solvers")],
        "optikin": __version__,
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:16]


def expand(spec: SweepSpec, path: Path) -> list[Cell]:
    """The cells of a sweep, in order (the last axis varies fastest under ``product``)."""
    fields = list(spec.axes)
    columns = [spec.axes[f] for f in fields]
    combos = list(zip(*columns)) if spec.combine == "zip" else list(itertools.product(*columns))
    if len(combos) > MAX_CELLS:
        raise SpecError(path, "axes", f"{len(combos)} cells: more than {MAX_CELLS}")
    problem = base_problem(spec, path)
    cells = []
    for index, values in enumerate(combos):
        axes = tuple(zip(fields, values))
        overrides = tuple(spec.set.items()) + axes
        cells.append(
            Cell(
                index=index,
                key=cell_key(problem, spec.solver, overrides),
                problem=problem,
                solver=spec.solver,
                overrides=overrides,
                axes=axes,
                metrics=tuple(spec.metrics),
            )
        )
    return cells
