"""Schemas of problem files (``problems/*.yaml``) and solver presets (``solvers/*.yaml``).

Both are validated with pydantic; any error is re-raised as
:class:`optikin.errors.SpecError` naming the file and the dotted field path
(``arm.params.theta_max``). Unknown fields are errors, not silently ignored.

Every file (and every ``--set`` value) is read as YAML 1.2 with the core schema only
(:func:`load_yaml`): ``1e6`` is a float, ``yes`` and ``1:30`` are strings, and tags other
than the core schema's (``!!binary``, ``!!python/...``, ``!custom``), aliases, duplicate
keys and nesting deeper than :data:`MAX_DEPTH` are refused naming the line. Numbers and
booleans are strict (a quoted number is not a number, ``true`` is not an integer).

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
    expect: {exit: 1, because: ...}  # optional: the exit status the run is expected to end with, and why

``expect`` states a verdict the problem reaches by design (a reference that leaves the workspace,
targets outside it): ``exit`` is 0 or 1 and ``because`` (required when ``exit`` is 1) says why. The exit
status of ``optikin solve`` stays truthful (1 still means a sample failed or a criterion was missed);
the output adds one line saying whether the verdict was the expected one
(:func:`optikin.report.print_result`), and ``result.json`` records ``expect``.

A solver preset::

    name: ipopt
    backend: ipopt                   # a registered backend
    title: Interior point through CasADi nlpsol
    options: {tol: 1.0e-10}          # handed to the backend
    limits: {max_iterations: 100, time_limit: 5.0}
"""

from __future__ import annotations

import copy
import math
import os
import re
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar, Literal, Sequence, cast

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from optikin.errors import SpecError, UnknownNameError
from optikin.options import StrictNumbers, spec_error

NAME_PATTERN = r"^[a-z0-9][a-z0-9_\-]*$"


class _Strict(StrictNumbers):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ArmSpec(_Strict):
    type: str = Field(description="registered arm name, e.g. constant_curvature or cbha")
    params: dict[str, Any] = Field(default_factory=dict, description="constructor arguments of the arm")


class DataSpec(_Strict):
    """Where the samples come from."""

    source: str = Field(description="registered data source of the problem kind")
    seed: int = Field(0, ge=0, description="seed of every random draw in this problem")
    samples: int = Field(100, ge=1, le=10_000_000, description="number of samples (targets, postures, steps)")
    params: dict[str, Any] = Field(default_factory=dict, description="the data source's parameters (its own model)")


class OutputSpec(_Strict):
    """What is written into the result folder."""

    figures: bool = Field(True, description="draw the kind's figures")
    arrays: list[str] | None = Field(None, description="arrays to keep in the NPZ file; all when omitted")


class ExpectSpec(_Strict):
    """The verdict a problem file expects its run to reach (``expect:``): ``optikin solve`` keeps its truthful exit
    status (1 for a failed sample or a missed criterion, expected or not) and prints one line saying whether the
    status is the expected one."""

    exit: Literal[0, 1] = Field(description="the exit status the run should end with: 0 solved, 1 by design not")
    because: str = Field("", description="why the run ends with that status; required when exit is 1")

    @model_validator(mode="after")
    def _because_given(self) -> ExpectSpec:
        if self.exit == 1 and not self.because.strip():
            raise ValueError("because is required when exit is 1: say why the run is expected to fail")
        return self


class ProblemSpec(_Strict):
    """A problem file (``problems/*.yaml``)."""

    name: str = Field(pattern=NAME_PATTERN, description="the file's name without .yaml")
    title: str = Field(description="one line shown in listings and reports")
    kind: str = Field(description="registered problem kind (optikin list --kinds)")
    arm: ArmSpec | None = Field(
        None, description="the arm (or a path to a file holding an arm: section); kinds that need none omit it"
    )
    data: DataSpec = Field(description="where the samples come from")
    solver: str | None = Field(None, description="solver preset (name or path); default the kind's")
    baselines: list[str] = Field(
        default_factory=list, description="methods compared in the same run: the kind's own or solver presets"
    )
    outputs: OutputSpec = Field(default_factory=OutputSpec, description="what is written into the result folder")
    options: dict[str, Any] = Field(default_factory=dict, description="the kind's options (its own model)")
    description: str = Field("", description="what the problem shows and why, in prose")
    expect: ExpectSpec | None = Field(
        None, description="the exit status the run is expected to end with (0 or 1) and, for 1, why"
    )


class LimitsSpec(_Strict):
    """Budgets of every solve of a preset."""

    max_iterations: int = Field(100, ge=1, description="iterations (or evaluations) per solve: the budget")
    time_limit: float = Field(10.0, gt=0, description="seconds per solve: a safety net above the budget")
    tolerance: float = Field(1e-10, gt=0, description="the solver's own stopping tolerance")


class SolverSpec(_Strict):
    """A solver preset (``solvers/*.yaml``)."""

    name: str = Field(pattern=NAME_PATTERN, description="the file's name without .yaml")
    backend: str = Field(description="registered backend (optikin list --solvers --where)")
    title: str = Field("", description="one line shown in listings")
    options: dict[str, Any] = Field(default_factory=dict, description="the backend's options (its own model)")
    limits: LimitsSpec = Field(default_factory=LimitsSpec, description="budgets of every solve")


# --------------------------------------------------------------------------- locating files

MAX_FILE_BYTES = 1_000_000
"""Largest problem or preset file read, in bytes (these files are short; a larger one is refused)."""


def project_root() -> Path:
    """The checkout that holds ``problems/`` and ``solvers/`` beside the package."""
    return Path(__file__).resolve().parent.parent


def shipped_dir(kind: Literal["problems", "solvers", "sweeps"]) -> Path:
    """The folder of the named files that come with optikin.

    An installed wheel carries them as ``optikin/catalog/<kind>`` (copied there by the build, found
    through :mod:`importlib.resources`); a checkout or an editable install reads the top-level
    ``problems/``, ``solvers/`` and ``sweeps/`` beside the package.
    """
    catalog = resources.files("optikin") / "catalog" / kind
    if catalog.is_dir():
        return Path(str(catalog))
    return project_root() / kind


def search_dirs(kind: Literal["problems", "solvers"]) -> list[Path]:
    """Folders searched for named files: ``$OPTIKIN_PATH`` entries, ``./kind``, the shipped ``kind``."""
    dirs = [Path(p) / kind for p in os.environ.get("OPTIKIN_PATH", "").split(os.pathsep) if p]
    dirs += [Path.cwd() / kind, shipped_dir(kind)]
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


def is_path(name_or_path: str) -> bool:
    """True when ``name_or_path`` is a path to a file rather than a name to look up."""
    return Path(name_or_path).suffix in (".yaml", ".yml") or os.sep in name_or_path


def resolve(name_or_path: str, kind: Literal["problems", "solvers"]) -> Path:
    """A path as given, or the named file on the search path."""
    candidate = Path(name_or_path)
    if is_path(name_or_path):
        if not candidate.is_file():
            raise SpecError(name_or_path, "", "no such file")
        return candidate
    named = available(kind)
    if name_or_path not in named:
        raise UnknownNameError(kind[:-1], name_or_path, list(named))
    return named[name_or_path]


def provenance(name_or_path: str, path: Path, kind: Literal["problems", "solvers"]) -> str | None:
    """One line saying which file a *name* resolved to, when it is not one of optikin's own.

    None for optikin's own files and for files given by path. A file named like a shipped one
    says that it shadows it, so a preset copied into the current folder or ``$OPTIKIN_PATH``
    cannot silently replace the shipped one.
    """
    if is_path(name_or_path):
        return None
    path = Path(path).resolve()
    shipped = shipped_dir(kind).resolve()
    if path.parent == shipped:
        return None
    line = f"using {kind[:-1]} file {path}"
    if (shipped / path.name).is_file():
        line += f" (shadows the shipped {kind[:-1]} {path.stem!r})"
    return line


# --------------------------------------------------------------------------- loading


MAX_DEPTH = 50
"""Deepest nesting of mappings and lists read from a problem, preset or sweep file (or a ``--set`` value)."""

_CORE = "tag:yaml.org,2002:"
_INT_RE = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT_RE = re.compile(
    r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
)
_BOOL_RE = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")
_NULL_RE = re.compile(r"^(?:~|null|Null|NULL|)$")


class _StrictLoader(yaml.SafeLoader):
    """The YAML reader of optikin's files: the YAML 1.2 core schema and nothing else.

    Plain scalars resolve as in YAML 1.2 (``1e6`` and ``1.0e6`` are floats, ``yes``, ``on``,
    ``0b1``, ``1_000``, ``1:30`` and ``2024-01-01`` are strings); the only tags are the core
    schema's (``!!null``, ``!!bool``, ``!!int``, ``!!float``, ``!!str``, ``!!seq``, ``!!map``), so
    ``!!binary``, ``!!python/...``, ``!!timestamp``, ``!!set``, the merge key ``<<`` and any custom
    ``!tag`` are refused, as are aliases (``*name``, the "billion laughs"), duplicate keys and
    nesting deeper than :data:`MAX_DEPTH`. Every refusal names the line.
    """

    yaml_implicit_resolvers: dict[Any, Any] = {}
    yaml_constructors: ClassVar[dict[Any, Any]] = {}

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.constructor.ConstructorError(
                None, None, f"aliases (*{event.anchor}) are not accepted in optikin files", event.start_mark
            )
        if self.check_event(yaml.CollectionStartEvent) and self._depth >= MAX_DEPTH:
            raise yaml.constructor.ConstructorError(
                None, None, f"nested too deeply (more than {MAX_DEPTH} levels)", self.peek_event().start_mark
            )
        self._depth += 1
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if node is not None and (not node.tag.startswith(_CORE) or node.tag[len(_CORE) :] not in _CORE_TAGS):
            shown = "!!" + node.tag[len(_CORE) :] if node.tag.startswith(_CORE) else node.tag
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"tag {shown[:40]!r} is not accepted (only the YAML core schema: "
                "!!null, !!bool, !!int, !!float, !!str, !!seq, !!map)",
                node.start_mark,
            )
        return node

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        seen: dict[object, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, (str, int, float, bool)) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first on line {seen[key] + 1})", key_node.start_mark
                )
            if isinstance(key, (str, int, float, bool)):
                seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)

    def _scalar(self, node: Any, pattern: re.Pattern[str], what: str) -> str:
        value = str(self.construct_scalar(node))
        if not pattern.match(value):
            raise yaml.constructor.ConstructorError(None, None, f"{value[:40]!r} is not {what}", node.start_mark)
        return value

    def construct_core_null(self, node: Any) -> None:
        self._scalar(node, _NULL_RE, "null")

    def construct_core_bool(self, node: Any) -> bool:
        return self._scalar(node, _BOOL_RE, "true or false").lower() == "true"

    def construct_core_int(self, node: Any) -> int:
        value = self._scalar(node, _INT_RE, "an integer (YAML 1.2: decimal, 0o octal or 0x hexadecimal)")
        try:
            if value[:2] in ("0o", "0x"):
                return int(value[2:], 8 if value[1] == "o" else 16)
            return int(value, 10)
        except ValueError:
            raise yaml.constructor.ConstructorError(
                None, None, f"an integer of {len(value)} digits is too long", node.start_mark
            ) from None

    def construct_core_float(self, node: Any) -> float:
        value = self._scalar(node, _FLOAT_RE, "a number")
        if value.lower().endswith(".inf"):
            return -math.inf if value.startswith("-") else math.inf
        return math.nan if value.lower() == ".nan" else float(value)


_CORE_TAGS = ("null", "bool", "int", "float", "str", "seq", "map")
_StrictLoader.add_constructor(_CORE + "null", _StrictLoader.construct_core_null)
_StrictLoader.add_constructor(_CORE + "bool", _StrictLoader.construct_core_bool)
_StrictLoader.add_constructor(_CORE + "int", _StrictLoader.construct_core_int)
_StrictLoader.add_constructor(_CORE + "float", _StrictLoader.construct_core_float)
_StrictLoader.add_constructor(_CORE + "str", cast(Any, yaml.SafeLoader.construct_yaml_str))
_StrictLoader.add_constructor(_CORE + "seq", cast(Any, yaml.SafeLoader.construct_yaml_seq))
_StrictLoader.add_constructor(_CORE + "map", cast(Any, yaml.SafeLoader.construct_yaml_map))
_StrictLoader.add_implicit_resolver(_CORE + "null", _NULL_RE, ["~", "n", "N", ""])
_StrictLoader.add_implicit_resolver(_CORE + "bool", _BOOL_RE, list("tTfF"))
_StrictLoader.add_implicit_resolver(_CORE + "int", _INT_RE, list("-+0123456789"))
_StrictLoader.add_implicit_resolver(_CORE + "float", _FLOAT_RE, list("-+0123456789."))


def load_yaml(text: str, source: str | Path) -> Any:
    """The value of the YAML document ``text`` read by :class:`_StrictLoader` (YAML 1.2 core schema only).

    Raises
    ------
    SpecError
        Naming ``source`` and the line and column of a malformed document, a refused tag or alias,
        a duplicate key or nesting deeper than :data:`MAX_DEPTH`.
    """
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass, core tags only
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise SpecError(source, "", f"malformed YAML: {where}{problem}") from None
    except RecursionError:
        raise SpecError(source, "", "malformed YAML: nested too deeply") from None


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise SpecError(path, "", f"{size} bytes: larger than the {MAX_FILE_BYTES} bytes accepted")
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise SpecError(path, "", f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise SpecError(path, "", f"not UTF-8 text (byte {exc.start}): is this a YAML file?") from None
    data = load_yaml(text, path)
    if not isinstance(data, dict):
        raise SpecError(path, "", f"expected a mapping at the top level, got {type(data).__name__}")
    return data


def _validate(model: type[BaseModel], data: dict[str, Any], path: Path) -> Any:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise spec_error(path, exc) from None


def parse_override(text: str) -> tuple[str, Any]:
    """``"data.seed=3"`` -> ``("data.seed", 3)``: a dotted field and a YAML value (read safely).

    Raises
    ------
    SpecError
        Without ``=``, with an empty field, or with a value that is not YAML.
    """
    field, sep, value = text.partition("=")
    field = field.strip()
    if not sep or not field or any(not part for part in field.split(".")):
        raise SpecError("--set", field, f"expected FIELD=VALUE with a dotted field, got {text!r}")
    if not value.strip():
        return field, None
    try:
        return field, load_yaml(value, "--set")
    except SpecError as exc:
        problem = str(exc).removeprefix("--set: malformed YAML: ")
        raise SpecError("--set", field, f"value {value[:40]!r} is not YAML: {problem}") from None


def apply_overrides(data: dict[str, Any], overrides: Sequence[tuple[str, Any]], path: Path) -> dict[str, Any]:
    """A copy of the file's mapping ``data`` with each ``(dotted field, value)`` set, creating mappings on
    the way; the result is validated like the file itself, so a misspelt field is reported by name."""
    out = copy.deepcopy(data)
    for field, value in overrides:
        parts = field.split(".")
        node = out
        for depth, part in enumerate(parts[:-1]):
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                raise SpecError(path, ".".join(parts[: depth + 1]), f"--set {field}: not a mapping in the file")
            node = child
        node[parts[-1]] = value
    return out


def include_arm(data: dict[str, Any], path: Path) -> dict[str, Any]:
    """``arm: other.yaml`` (a path relative to the problem file) replaced by that file's ``arm:`` mapping,
    e.g. the calibrated arm a ``calibrate`` run writes; a mapping is left as it is.

    Raises
    ------
    SpecError
        On ``arm`` when the file cannot be read or holds no ``arm:`` mapping (an included file cannot
        include another).
    """
    arm = data.get("arm")
    if not isinstance(arm, str):
        return data
    included = (path.parent / arm).resolve()
    if not included.is_file():
        raise SpecError(path, "arm", f"no such file {str(included)!r} (a path is relative to the problem file)")
    try:
        content = _read_yaml(included)
    except SpecError as exc:
        raise SpecError(path, "arm", f"{included}: {exc}") from None
    section = content.get("arm")
    if not isinstance(section, dict):
        raise SpecError(path, "arm", f"{included} has no arm: mapping (type and params) to include")
    return data | {"arm": section}


MAX_ARM_PARAMETER = 1e12
"""Largest magnitude of a number in ``arm.params`` (SI units): every physical parameter of a continuum arm is
below it (Young's moduli are below 1e12 Pa, lengths below 1e3 m); a larger one is a unit or typing error."""
_QUOTED_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


def check_arm_params(params: Any, path: Path, field: str = "arm.params") -> None:
    """Refuse, in the arm's parameters (handed to its constructor as they are), a quoted number (``"2.0"``)
    and a number above :data:`MAX_ARM_PARAMETER` in magnitude.

    Raises
    ------
    SpecError
        Naming the file and the dotted field (``arm.params.section_lengths.0``).
    """
    items = params.items() if isinstance(params, dict) else enumerate(params) if isinstance(params, list) else ()
    for key, value in items:
        where = f"{field}.{key}"
        if isinstance(value, str) and _QUOTED_NUMBER.match(value):
            raise SpecError(path, where, f"expected a number, got the string {value[:40]!r} (write it without quotes)")
        if isinstance(value, (int, float)) and not isinstance(value, bool) and abs(value) > MAX_ARM_PARAMETER:
            raise SpecError(
                path, where, f"{value:g} is above the largest magnitude of an arm parameter, {MAX_ARM_PARAMETER:g}"
            )
        check_arm_params(value, path, where)


def load_problem(name_or_path: str, overrides: Sequence[tuple[str, Any]] = ()) -> tuple[ProblemSpec, Path]:
    """Read and validate a problem file, its ``arm:`` included from a file if it names one
    (:func:`include_arm`) and ``overrides`` (:func:`apply_overrides`) set; returns the spec and the
    file it came from."""
    path = resolve(name_or_path, "problems")
    spec = _validate(ProblemSpec, apply_overrides(include_arm(_read_yaml(path), path), overrides, path), path)
    if spec.arm is not None:
        check_arm_params(spec.arm.params, path)
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
