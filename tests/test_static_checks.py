"""The package lints, is formatted and type-checks clean (ruff and mypy, configured in pyproject.toml)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def run(*command: str) -> subprocess.CompletedProcess:
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True)


def test_ruff_lint_and_format():
    pytest.importorskip("ruff")
    lint = run(sys.executable, "-m", "ruff", "check", "optikin", "tests")
    assert lint.returncode == 0, lint.stdout[-3000:]
    fmt = run(sys.executable, "-m", "ruff", "format", "--check", "optikin", "tests")
    assert fmt.returncode == 0, fmt.stdout[-3000:]


def test_mypy():
    pytest.importorskip("mypy")
    result = run(sys.executable, "-m", "mypy")
    assert result.returncode == 0, result.stdout[-3000:]
