"""The one key that names a data file in a problem file: ``data.params.file``.

Every source that reads a file (configurations, targets, markers, demonstrations, tracking
references and lab recordings) takes it as ``data.params.file``, a path relative to the
folder of the problem file (an absolute path is kept as it is)::

    data:
      source: csv
      params: {file: data/my-demo.csv}

Demonstrations and lab recordings used to call it ``path``. That name is still read: when the
file is resolved, a :class:`FutureWarning` names the problem file and the line of ``path`` and
says to write ``file``, so a problem file written for an earlier release keeps running and says
what to change. Giving both is an error.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

from pydantic import Field, PrivateAttr, model_validator
from pydantic_core.core_schema import ValidatorFunctionWrapHandler

from optikin.errors import SpecError
from optikin.options import Options

DEPRECATED_KEY = "path"
"""The former name of ``file`` in the params of demonstration and recording sources."""
_KEY_RE = re.compile(rf"(^|[\s{{,]){DEPRECATED_KEY}\s*:")


class FileParams(Options):
    """``data.params`` of a source that reads one file: ``file``, relative to the problem file's folder."""

    file: str = Field(min_length=1, description="the data file, relative to the problem file's folder")
    _former_key: bool = PrivateAttr(False)

    @model_validator(mode="wrap")
    @classmethod
    def _read_former_key(cls, data: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        """``path`` (the former name of ``file``) is read as ``file``, and remembered for the warning."""
        if not isinstance(data, dict) or DEPRECATED_KEY not in data:
            return handler(data)
        if "file" in data:
            raise ValueError(f"give the file once, as file ({DEPRECATED_KEY} is its former name)")
        params = handler({("file" if k == DEPRECATED_KEY else k): v for k, v in data.items()})
        params._former_key = True
        return params

    def resolve(self, problem: str | Path) -> Path:
        """The file, relative to the folder of the problem file ``problem`` (an absolute ``file`` as it is).

        Warns (:class:`FutureWarning`, naming ``problem`` and the line of the key) when the problem
        file named it with the former key ``path``.
        """
        if self._former_key:
            warnings.warn_explicit(
                f"data.params.{DEPRECATED_KEY} is deprecated: name the data file data.params.file (same value)",
                FutureWarning,
                str(problem),
                former_key_line(Path(problem)),
            )
        return data_file(problem, self.file)


def data_file(problem: str | Path, file: str, field: str = "data.params.file") -> Path:
    """The data file ``file`` of the problem file ``problem``: relative to its folder (an absolute path as it is),
    symbolic links resolved.

    Raises
    ------
    SpecError
        Naming ``problem`` and ``field`` when the path cannot be resolved (a loop of symbolic links).
    """
    try:
        return (Path(problem).parent / file).resolve()
    except RuntimeError:  # Python < 3.13: a loop of symbolic links
        raise SpecError(problem, field, f"{file[:80]!r} is a loop of symbolic links") from None
    except OSError as exc:
        raise SpecError(problem, field, f"cannot resolve {file[:80]!r}: {exc.strerror or exc}") from None


def former_key_line(problem: Path) -> int:
    """The 1-based line of ``path:`` in the ``data:`` section of the problem file (1 if it cannot be read)."""
    try:
        lines = problem.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return 1
    inside = False
    for number, line in enumerate(lines, 1):
        if line[:1].strip() and not line.startswith("#"):  # a top-level key
            inside = line.startswith("data:")
        if inside and _KEY_RE.search(line.split("#", 1)[0]):
            return number
    return 1
