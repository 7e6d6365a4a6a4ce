"""Schemas of problem files (``problems/*.yaml``) and solver presets (``solvers/*.yaml``).

Both are validated with pydantic; any error is re-raised as
:class:`optikin.errors.SpecError` naming the file and the dotted field path
(``arm.params.theta_max``). Unknown fields are errors, not silently ignored.

A problem file::

    name: cc-two-section-fk          # must match the file name
    title: One line for `optikin list`
    kind: fk                         # a registered problem kind
    arm:
      type: constant_curvature       # a registered arm
      params: {section_lengths: [0.18, 0.18]}
    data:                            # where the samples come from
      source: trajectory             # random | grid | trajectory | csv
      seed: 7
      samples: 200
      params: {}
    solver: casadi-map               # a solver preset name or path (optional)
    baselines: [numpy]               # compared in the same run
    outputs: {figures: true, arrays: [tip_dq]}
    options: {}                      # kind-specific settings

A solver preset::

    name: ipopt
    backend: ipopt                   # a registered backend
    title: Interior point through CasADi nlpsol
    options: {tol: 1.0e-10}          # handed to the backend
    limits: {max_iterations: 100, time_limit: 5.0}
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from optikin.errors import SpecError, UnknownNameError

NAME_PATTERN = r"^[a-z0-9][a-z0-9_\-]*$"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ArmSpec(_Strict):
    type: str = Field(description="registered arm name, e.g. constant_curvature or cbha")
    params: dict[str, Any] = Field(default_factory=dict, description="constructor arguments of the arm")


class DataSpec(_Strict):
    source: str = Field(description="registered data source of the problem kind")
    seed: int = Field(0, description="seed of every random draw in this problem")
    samples: int = Field(100, ge=1, le=10_000_000)
    params: dict[str, Any] = Field(default_factory=dict)


class OutputSpec(_Strict):
    figures: bool = True
    arrays: list[str] | None = Field(None, description="arrays to keep in the NPZ file; all when omitted")


class ProblemSpec(_Strict):
    name: str = Field(pattern=NAME_PATTERN)
    title: str
    kind: str
    arm: ArmSpec
    data: DataSpec
    solver: str | None = None
    baselines: list[str] = Field(default_factory=list)
    outputs: OutputSpec = Field(default_factory=OutputSpec)
    options: dict[str, Any] = Field(default_factory=dict)
    description: str = ""


class LimitsSpec(_Strict):
    max_iterations: int = Field(100, ge=1)
    time_limit: float = Field(10.0, gt=0, description="seconds per solve")
    tolerance: float = Field(1e-10, gt=0)


class SolverSpec(_Strict):
    name: str = Field(pattern=NAME_PATTERN)
    backend: str
    title: str = ""
    options: dict[str, Any] = Field(default_factory=dict)
    limits: LimitsSpec = Field(default_factory=LimitsSpec)

# --------------------------------------------------------------------------- locating files


def project_root() -> Path:
    """The checkout that holds ``problems/`` and ``solvers/`` beside the package."""
    return Path(__file__).resolve().parent.parent


def search_dirs(kind: Literal["problems", "solvers"]) -> list[Path]:
    """Folders searched for named files: ``$OPTIKIN_PATH`` entries, ``./kind``, the checkout's ``kind``."""
    dirs = [Path(p) / kind for p in os.environ.get("OPTIKIN_PATH", "").split(os.pathsep) if p]
    dirs += [Path.cwd() / kind, project_root() / kind]
    unique: list[Path] = []
    for d in dirs:
        if d.is_dir() and d.resolve() not in [u.resolve() for u in unique]:
            unique.append(d)
    return unique


def available(kind: Literal["problems", "solvers"]) -> dict[str, Path]:
    """Named files of ``kind`` found on the search path (first one wins)."""
    found: dict[str, Path] = {}
    for d in search_dirs(kind):
        for path in sorted(d.glob("*.yaml")):
            found.setdefault(path.stem, path)
    return found


def resolve(name_or_path: str, kind: Literal["problems", "solvers"]) -> Path:
    """A path as given, or the named file on the search path."""
    candidate = Path(name_or_path)
    if candidate.suffix in (".yaml", ".yml") or os.sep in name_or_path:
        if not candidate.is_file():
            raise SpecError(name_or_path, "", "no such file")
        return candidate
    named = available(kind)
    if name_or_path not in named:
        raise UnknownNameError(kind[:-1], name_or_path, list(named))
    return named[name_or_path]


# --------------------------------------------------------------------------- loading


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text()
    except OSError as exc:
        raise SpecError(path, "", f"cannot read: {exc.strerror or exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise SpecError(path, "", f"malformed YAML: {where}{problem}") from None
    if not isinstance(data, dict):
        raise SpecError(path, "", f"expected a mapping at the top level, got {type(data).__name__}")
    return data


def _field_path(loc: tuple) -> str:
    return ".".join(str(p) for p in loc if not str(p).startswith("function-"))


def _validate(model: type[BaseModel], data: dict[str, Any], path: Path) -> Any:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        message = first["msg"]
        if first["type"] == "extra_forbidden":
            message = "unknown field"
        elif first["type"] == "missing":
            message = "required field is missing"
        raise SpecError(path, _field_path(first["loc"]), message) from None


def load_problem(name_or_path: str) -> tuple[ProblemSpec, Path]:
    """Read and validate a problem file; returns the spec and the file it came from."""
    path = resolve(name_or_path, "problems")
    spec = _validate(ProblemSpec, _read_yaml(path), path)
    if spec.name != path.stem:
        raise SpecError(path, "name", f"{spec.name!r} differs from the file name {path.stem!r}")
    return spec, path


def load_solver(name_or_path: str) -> tuple[SolverSpec, Path]:
    """Read and validate a solver preset; returns the spec and the file it came from."""
    path = resolve(name_or_path, "solvers")
    spec = _validate(SolverSpec, _read_yaml(path), path)
    if spec.name != path.stem:
        raise SpecError(path, "name", f"{spec.name!r} differs from the file name {path.stem!r}")
    return spec, path
