"""Exceptions that name the file, field or sample at fault.

Every error a user can cause derives from :class:`OptikinError`; the command
line prints its message and exits non-zero.
"""

from __future__ import annotations

import difflib

from os import PathLike


class OptikinError(Exception):
    """Base of every error optikin raises on bad input or failed solves."""


class SpecError(OptikinError):
    """A problem or solver file is malformed: names the file and the field."""

    def __init__(self, path: str | PathLike[str], field: str, message: str) -> None:
        self.path, self.field = str(path), field
        where = f"{self.path}: {field}" if field else self.path
        super().__init__(f"{where}: {message}")


class UnknownNameError(OptikinError):
    """A name (problem, solver, kind, arm, backend) that no registry holds."""

    def __init__(self, what: str, name: str, known: list[str] | tuple[str, ...]) -> None:
        self.what, self.name, self.known = what, name, sorted(known)
        choices = ", ".join(self.known) if self.known else "none registered"
        close = difflib.get_close_matches(name, self.known, n=1)
        self.suggestion = close[0] if close else None
        hint = f"did you mean {self.suggestion!r}? " if self.suggestion else ""
        super().__init__(f"unknown {what} {name!r}; {hint}known: {choices}")


class InputDataError(OptikinError):
    """Numeric input is unusable (wrong shape, NaN, out of bounds, non-unit quaternion).

    ``source`` says where the data came from, ``sample`` which row, ``field`` which column.
    """

    def __init__(self, message: str, *, source: str = "", sample: int | None = None, field: str = "") -> None:
        self.source, self.sample, self.field = source, sample, field
        where = [w for w in (source, f"sample {sample}" if sample is not None else "", field) if w]
        super().__init__(f"{': '.join(where)}: {message}" if where else message)


class SolverError(OptikinError):
    """A solver backend failed as a whole (not a single sample, which is reported in the result)."""
