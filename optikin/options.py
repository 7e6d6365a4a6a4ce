"""Typed options: every problem kind, solver backend and data source declares what it accepts.

An options model is a pydantic model derived from :class:`Options`: unknown
fields are errors, NaN and infinite numbers are refused, numbers and booleans
are taken only as written (:class:`StrictNumbers`: a quoted number, ``true``
for an integer or ``1`` for a boolean are field errors), defaults are stated
once on the field, units go in the field's ``description`` (``[m]``, ``[s]``,
``[rad]``: a number field so described is bounded by :data:`UNIT_BOUNDS`) and
other bounds are constraints (``Field(gt=0)``). :func:`validate_options` checks one section of
a file (``options``, ``data.params``, a preset's ``options``) and turns the
first pydantic error into a :class:`~optikin.errors.SpecError` naming the file
and the dotted field, exactly as the rest of the file is checked.

Example
-------
>>> from pydantic import Field
>>> class Settings(Options):
...     gain: float = Field(10.0, gt=0, description="task gain K [1/s]")
>>> validate_options(Settings, {"gain": 5}, "track.yaml", "options").gain
5.0
"""

from __future__ import annotations

import re
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Literal, Mapping, TypeVar, Union, cast, get_args, get_origin

from pydantic import BaseModel, ConfigDict, GetCoreSchemaHandler, ValidationError
from pydantic_core import CoreSchema

from optikin.errors import SpecError

M = TypeVar("M", bound=BaseModel)


UNIT_BOUNDS: dict[str, float] = {
    "m": 100.0,
    "mm": 1e5,
    "s": 1e6,
    "rad": 1e3,
    "mrad": 1e6,
    "deg": 1e5,
    "Hz": 1e6,
    "rad/s": 1e4,
    "deg/s": 1e6,
    "m/s^2": 1e4,
    "kg": 1e4,
    "N": 1e7,
    "N m": 1e6,
    "Pa": 1e12,
}
"""Largest magnitude of a number field by the unit its description states (``[m]``, ``[s]``, ...): no
length in a continuum arm's problem is above 100 m, no time above 1e6 s (11.6 days), no angle above
1e3 rad; a larger value is a unit or typing error. The bound applies to every entry of a vector field."""

_UNIT_RE = re.compile(r"\[(" + "|".join(re.escape(u) for u in sorted(UNIT_BOUNDS, key=len, reverse=True)) + r")\]")


def _strict_scalars(schema: Any) -> Any:
    """``schema`` (a pydantic core schema) with every int, float and bool leaf made strict, in place."""
    if isinstance(schema, dict):
        if schema.get("type") in ("int", "float", "bool"):
            schema["strict"] = True
        for value in schema.values():
            _strict_scalars(value)
    elif isinstance(schema, list):
        for value in schema:
            _strict_scalars(value)
    return schema


def _bound_numbers(schema: Any, bound: float) -> None:
    """Every int and float leaf of a field's ``schema`` (nested models excepted) bounded to ``|x| <= bound``."""
    if isinstance(schema, dict):
        if schema.get("type") in ("model", "definition-ref"):
            return
        if schema.get("type") in ("int", "float"):
            schema["le"] = min(schema.get("le", bound), bound)
            schema["ge"] = max(schema.get("ge", -bound), -bound)
        for value in schema.values():
            _bound_numbers(value, bound)
    elif isinstance(schema, list):
        for value in schema:
            _bound_numbers(value, bound)


def _model_node(schema: Any, cls: type) -> dict[str, Any] | None:
    """The ``model`` node of ``cls`` in a core schema (validator wrappers and definitions searched)."""
    if isinstance(schema, dict):
        if schema.get("type") == "model":
            return schema if schema.get("cls") is cls else None
        for value in schema.values():
            found = _model_node(value, cls)
            if found is not None:
                return found
    elif isinstance(schema, list):
        for value in schema:
            found = _model_node(value, cls)
            if found is not None:
                return found
    return None


def _unit_bounds(schema: Any, cls: type[BaseModel]) -> Any:
    """``schema`` with the number fields of ``cls`` whose description states a unit bounded by :data:`UNIT_BOUNDS`."""
    node = _model_node(schema, cls)
    fields = node.get("schema", {}) if node is not None else {}
    while isinstance(fields, dict) and fields.get("type") != "model-fields" and "schema" in fields:
        fields = fields["schema"]
    for name, field in (fields.get("fields", {}) if isinstance(fields, dict) else {}).items():
        info = cls.model_fields.get(name)
        unit = _UNIT_RE.search(info.description or "") if info is not None else None
        if unit is not None:
            _bound_numbers(field, UNIT_BOUNDS[unit.group(1)])
    return schema


class StrictNumbers(BaseModel):
    """A model whose numbers and booleans are taken only as written, and bounded by their unit.

    ``"2.0"`` (a quoted number) is not a float, ``true`` is not an integer, ``1`` is not a boolean and
    ``3.0`` is not an integer; an integer is a float. Lists, tuples and strings keep pydantic's
    ordinary (lax) rules, so a YAML list fills a tuple field. A number field whose description states
    its unit (``[m]``, ``[s]``, ``[rad]``, ...) is bounded by :data:`UNIT_BOUNDS`.
    """

    @classmethod
    def __get_pydantic_core_schema__(cls, source: type[BaseModel], handler: GetCoreSchemaHandler) -> CoreSchema:
        return cast(CoreSchema, _unit_bounds(_strict_scalars(handler(source)), source))


class Options(StrictNumbers):
    """Base of every options model: strict about unknown fields and about number and boolean types
    (:class:`StrictNumbers`), finite numbers only, immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, arbitrary_types_allowed=True)


class NoOptions(Options):
    """Takes no options."""


_STEP = re.compile(r"^(function-.*|\[key\]|(constrained-)?(float|int|str|bool|none)|[a-z-]+\[.*\])$")
"""Parts of a pydantic error location that are validation steps, not fields: validator functions, the
branch of a union (``constrained-float``, ``list[float]``) and a mapping's key."""


def field_path(loc: tuple[Any, ...]) -> str:
    """A pydantic error location as a dotted path (``arm.params.theta_max``), validation steps dropped."""
    return ".".join(str(p) for p in loc if not (isinstance(p, str) and _STEP.match(p)))


def error_message(error: Mapping[str, Any]) -> str:
    """The one-line message of a pydantic error, in the words the rest of optikin uses."""
    kind = error["type"]
    if kind == "extra_forbidden":
        return "unknown field"
    if kind == "missing":
        return "required field is missing"
    message = str(error["msg"])
    if kind in _EXPECTED:
        return f"expected {_EXPECTED[kind]}, got {describe_value(error.get('input'))}"
    if kind == "finite_number":
        return "expected a finite number (NaN and infinity are refused)"
    if kind in ("less_than_equal", "greater_than_equal") and isinstance(error.get("input"), (int, float)):
        bound = error.get("ctx", {}).get("le" if kind == "less_than_equal" else "ge")
        side = "less" if kind == "less_than_equal" else "greater"
        return f"expected a number {side} than or equal to {bound:g}, got {error['input']:g}"
    if kind == "value_error":
        return message.removeprefix("Value error, ")
    if kind.startswith("literal_") or kind == "enum":
        return message.replace("Input should be", "expected")
    return message


_EXPECTED = {"int_type": "an integer", "float_type": "a number", "bool_type": "a boolean (true or false)"}
_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


def describe_value(value: Any) -> str:
    """A short description of a value read from a file, for a message: ``the string '2.0' (a quoted number:
    write it without quotes)``, ``true``, ``a list of 2 values``, ``a mapping``, ``null``, ``3.5``."""
    if isinstance(value, str):
        hint = " (a quoted number: write it without quotes)" if _NUMBER.match(value) else ""
        return f"the string {value[:40]!r}{'...' if len(value) > 40 else ''}{hint}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)} value{'s' if len(value) != 1 else ''}"
    if isinstance(value, dict):
        return "a mapping"
    return repr(value)[:40]


def spec_error(path: str | Path, exc: ValidationError, prefix: str = "") -> SpecError:
    """The first error of ``exc`` as a :class:`SpecError` naming ``path`` and ``prefix.field``.

    An unknown field is reported before anything else: a misspelt required field then reads
    ``params.fiel: unknown field`` rather than ``params.file: required field is missing``.
    """
    errors = exc.errors()
    first: Mapping[str, Any] = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    where = ".".join(p for p in (prefix, field_path(first["loc"])) if p)
    return SpecError(path, where, error_message(first))


def validate_options(model: type[M], data: Any, path: str | Path, prefix: str) -> M:
    """Validate one section of a file against ``model``.

    Parameters
    ----------
    model:
        The options model (a subclass of :class:`Options`).
    data:
        The section as read from YAML (a mapping, or None for an absent section).
    path:
        The file, for the error message.
    prefix:
        The section's dotted field (``options``, ``data.params``), prepended to the field at fault.

    Raises
    ------
    SpecError
        Naming the file and the dotted field of the first error.
    """
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise SpecError(path, prefix, f"expected a mapping, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise spec_error(path, exc, prefix) from None


def describe_options(model: type[BaseModel], prefix: str = "") -> list[tuple[str, str, str, str]]:
    """Rows ``(field, type, default, description)`` of a model, nested models flattened with dots."""
    rows: list[tuple[str, str, str, str]] = []
    for name, info in model.model_fields.items():
        dotted = f"{prefix}{name}"
        annotation = info.annotation
        nested = annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None
        if nested is not None:
            summary = ((nested.__doc__ or "").strip().splitlines() or [""])[0]
            rows.append((dotted, nested.__name__, "", info.description or summary))
            rows += describe_options(nested, f"{dotted}.")
            continue
        type_name = type_name_of(annotation)
        default = "required" if info.is_required() else repr(info.get_default(call_default_factory=True))
        rows.append((dotted, type_name, default, info.description or ""))
    return rows


def type_name_of(annotation: Any) -> str:
    """A short readable name of a field's type: ``float``, ``list[float]``, ``'hold' | 'damped_least_squares'``."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Literal:
        return " | ".join(repr(a) for a in args)
    if origin in (Union, UnionType):
        return " | ".join(type_name_of(a) for a in args)
    if origin is Annotated:
        return type_name_of(args[0])
    if origin is not None:
        inner = ", ".join("..." if a is Ellipsis else type_name_of(a) for a in args)
        return f"{getattr(origin, '__name__', str(origin))}[{inner}]"
    if annotation is type(None):
        return "None"
    return getattr(annotation, "__name__", None) or str(annotation).replace("typing.", "")


def options_schema(model: type[BaseModel]) -> dict[str, Any]:
    """The JSON schema of an options model (for ``optikin list --kinds --json`` and editors)."""
    return model.model_json_schema()
