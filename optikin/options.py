"""Typed options: every problem kind, solver backend and data source declares what it accepts.

An options model is a pydantic model derived from :class:`Options`: unknown
fields are errors, NaN and infinite numbers are refused, defaults are stated
once on the field, units go in the field's ``description`` and bounds are
constraints (``Field(gt=0)``). :func:`validate_options` checks one section of
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

from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Literal, Mapping, TypeVar, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, ValidationError

from optikin.errors import SpecError

M = TypeVar("M", bound=BaseModel)


class Options(BaseModel):
    """Base of every options model: strict about unknown fields, finite numbers only, immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, arbitrary_types_allowed=True)


class NoOptions(Options):
    """Takes no options."""


def field_path(loc: tuple[Any, ...]) -> str:
    """A pydantic error location as a dotted path (``arm.params.theta_max``), validator steps dropped."""
    return ".".join(str(p) for p in loc if not str(p).startswith("function-"))


def error_message(error: Mapping[str, Any]) -> str:
    """The one-line message of a pydantic error, in the words the rest of optikin uses."""
    kind = error["type"]
    if kind == "extra_forbidden":
        return "unknown field"
    if kind == "missing":
        return "required field is missing"
    message = str(error["msg"])
    if kind == "finite_number":
        return "expected a finite number (NaN and infinity are refused)"
    if kind.startswith("literal_") or kind == "enum":
        return message.replace("Input should be", "expected")
    return message


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
