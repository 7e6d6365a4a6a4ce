"""Build hook: the named problem files, solver presets, sweeps and examples go into the wheel as ``optikin/catalog``.

The top-level ``problems/``, ``solvers/``, ``sweeps/`` and ``examples/`` folders are the source; a checkout (or
an editable install) reads them in place, an installed wheel reads its copy through ``importlib.resources``
(:func:`optikin.spec.shipped_dir`); the examples (data files and the problem files that read them) are there
for a user to copy from.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

CATALOG = ("problems", "solvers", "sweeps", "examples")


class BuildWithCatalog(build_py):
    """``build_py`` that also copies the catalog folders into ``optikin/catalog/`` of the build."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        root = Path(__file__).resolve().parent
        for kind in CATALOG:
            target = Path(self.build_lib) / "optikin" / "catalog" / kind
            shutil.rmtree(target, ignore_errors=True)  # no stale file from an earlier build
            shutil.copytree(root / kind, target, ignore=shutil.ignore_patterns("__pycache__"))


setup(cmdclass={"build_py": BuildWithCatalog})
