"""The one key that names a data file in a problem file: ``data.params.file``.

Every source that reads a file (configurations, targets, markers, demonstrations, tracking
references and lab recordings) takes it as ``data.params.file``, a path relative to the
folder of the problem file (an absolute path is kept as it is)::

    data:
      source: csv
      params: {file: data/my-demo.csv}

Demonstrations and lab recordings used to call it ``path``. That name is still read, with a
:class:`FutureWarning` naming ``data.params.path`` and saying to write ``file``: a file written
for an earlier release keeps running, and says what to change. Giving both is an error.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

from pydantic import Field, model_validator

from optikin.options import Options

DEPRECATED_KEY = "path"
"""The former name of ``file`` in the params of demonstration and recording sources."""


class FileParams(Options):
    """``data.params`` of a source that reads one file: ``file``, relative to the problem file's folder."""

    file: str = Field(min_length=1, description="the data file, relative to the problem file's folder")

    @model_validator(mode="before")
    @classmethod
    def _former_key(cls, data: Any) -> Any:
        """``path`` (the former name of ``file``) is read as ``file``, with a :class:`FutureWarning`."""
        if not isinstance(data, dict) or DEPRECATED_KEY not in data:
            return data
        if "file" in data:
            raise ValueError("give the file once, as file (path is its former name)")
        warnings.warn(
            "data.params.path is deprecated: name the data file with data.params.file (same value)",
            FutureWarning,
            stacklevel=2,
        )
        renamed = {k: v for k, v in data.items() if k != DEPRECATED_KEY}
        renamed["file"] = data[DEPRECATED_KEY]
        return renamed

    def resolve(self, problem: str | Path) -> Path:
        """The file, relative to the folder of the problem file ``problem`` (an absolute ``file`` as it is)."""
        return (Path(problem).parent / self.file).resolve()
