"""The documentation site builds with ``mkdocs build --strict``: a broken link, a missing page of the
navigation or an unresolved API reference fails, and the generated reference covers every kind."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytest.importorskip("mkdocs", reason="the docs extra is not installed (pip install -e '.[docs]')")
pytest.importorskip("material", reason="mkdocs-material is not installed (the docs extra)")
pytest.importorskip("mkdocstrings_handlers.python", reason="mkdocstrings[python] is not installed (the docs extra)")
pytest.importorskip("mkdocs_jupyter", reason="mkdocs-jupyter is not installed (the docs extra)")


@pytest.mark.slow
def test_site_builds_strict(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "OPTIKIN_DOCS_EXECUTE"}
    env["NO_MKDOCS_2_WARNING"] = "1"
    site = tmp_path / "site"
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-4000:]

    from optikin.problems import load_kinds
    from optikin.registry import PROBLEM_KINDS

    load_kinds()
    for name in PROBLEM_KINDS.names():
        page = (site / "reference" / "kinds" / name / "index.html").read_text(encoding="utf-8")
        kind = PROBLEM_KINDS.get(name)
        for field in kind.options.model_fields:
            assert f"<code>{field}" in page, f"kind {name}: option {field} is missing from its page"
    tracking = (site / "reference" / "kinds" / "tracking" / "index.html").read_text(encoding="utf-8")
    assert "waypoints" in tracking and "qp-osqp" in tracking
    api = (site / "api" / "arms" / "index.html").read_text(encoding="utf-8")
    assert "ConstantCurvatureArm" in api
    for notebook in (ROOT / "notebooks").glob("*.ipynb"):
        assert (site / "notebooks" / notebook.stem / "index.html").exists(), notebook.name
    assert (site / "benchmarks" / "index.html").exists()
