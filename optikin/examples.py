"""``optikin examples [DIR]``: a copy of the shipped examples (problem files and the data they read).

The examples travel with the package (an installed wheel holds them as ``optikin/catalog/examples``,
a checkout as ``examples/``); their problem files name their data relative to their own folder, so
the copy solves from anywhere::

    optikin examples my-examples
    optikin solve my-examples/track-my-demo.yaml

The copy is made into a temporary folder beside ``DIR`` and renamed into place, so an interrupted
or failed copy leaves nothing behind; an existing ``DIR`` is refused, never merged into.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from optikin.errors import SpecError
from optikin.spec import shipped_dir

__all__ = ["DEFAULT_FOLDER", "copy_examples", "example_problems"]

DEFAULT_FOLDER = "optikin-examples"
"""Where ``optikin examples`` copies to when no folder is given (relative to the current folder)."""


def example_problems(folder: Path) -> list[Path]:
    """The problem files of an examples folder (``*.yaml`` at its top level), sorted by name."""
    return sorted(folder.glob("*.yaml"))


def copy_examples(destination: str | Path = DEFAULT_FOLDER) -> Path:
    """Copy the shipped examples into ``destination``, a folder that must not exist yet.

    Parameters
    ----------
    destination:
        The new folder; its parent must exist.

    Returns
    -------
    Path
        The folder written, holding the example problem files, ``README.md`` and ``data/``.

    Raises
    ------
    SpecError
        ``destination`` is empty, exists (as anything, a dangling symlink included), or its parent
        is missing or not writable; nothing is written.
    """
    if not str(destination).strip():
        raise SpecError("DIR", "", "an empty folder name is not accepted (give a folder, e.g. my-examples)")
    target = Path(destination)
    if target.exists() or target.is_symlink():
        raise SpecError(str(target), "", "already exists; give a new folder (nothing is merged into one)")
    parent = target.absolute().parent
    if not parent.is_dir():
        raise SpecError(str(target), "", f"its parent folder {parent} does not exist")
    source = shipped_dir("examples")  # type: ignore[arg-type]
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=parent))
    except OSError as error:
        raise SpecError(str(target), "", f"cannot write into {parent}: {error.strerror or error}") from None
    try:
        copied = staging / "examples"
        shutil.copytree(source, copied, ignore=shutil.ignore_patterns("__pycache__", "*.py[cod]"))
        copied.rename(target)
    except OSError as error:
        raise SpecError(str(target), "", f"cannot copy the examples: {error.strerror or error}") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target
