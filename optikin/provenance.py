"""What a result was solved from and on: the validated files, the versions, the machine, the wall time.

:func:`provenance_of` is recorded as ``provenance`` in every ``result.json``, so a result can be
traced to the exact problem and preset (as validated, defaults filled in), the optikin version and,
when run from a git checkout, its commit, the versions of the numerical libraries, and the machine
and its load when it ran.
"""

from __future__ import annotations

import os
import platform
import subprocess
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

from optikin import __version__

if TYPE_CHECKING:
    from optikin.problems import ProblemContext

LIBRARIES = ("casadi", "numpy", "scipy", "cvxpy", "osqp", "qpsolvers", "pydantic")
"""Distributions whose versions a result records."""


def git_commit(folder: Path) -> str | None:
    """``git describe --always --dirty`` of the checkout holding ``folder``; None outside one."""
    if not (folder / ".git").exists():
        return None
    try:
        out = subprocess.run(
            ["git", "-C", str(folder), "describe", "--always", "--dirty", "--abbrev=12"],
            capture_output=True,
            text=True,
            timeout=5,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def versions() -> dict[str, str | None]:
    """optikin's version, its git commit when run from a checkout, Python's and :data:`LIBRARIES`'."""
    found: dict[str, str | None] = {"optikin": __version__}
    found["git commit"] = git_commit(Path(__file__).resolve().parent.parent)
    found["python"] = platform.python_version()
    for name in LIBRARIES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    return found


def machine() -> dict[str, Any]:
    """The machine: system, processor, logical and usable cores, the 1/5/15-minute load averages."""
    info: dict[str, Any] = {
        "system": f"{platform.system()} {platform.release()}",
        "machine": platform.machine(),
        "processor": processor_name(),
        "cores": os.cpu_count(),
        "usable cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
    }
    if hasattr(os, "getloadavg"):
        info["load average"] = [round(v, 2) for v in os.getloadavg()]
    return info


def processor_name() -> str:
    """The CPU model from ``/proc/cpuinfo`` where there is one, else :func:`platform.processor`."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def provenance_of(ctx: ProblemContext, started: datetime, wall_seconds: float) -> dict[str, Any]:
    """The ``provenance`` of a run of ``ctx`` that began at ``started`` and took ``wall_seconds``."""
    preset = None
    if ctx.preset is not None:
        preset = {
            "file": str(ctx.preset.path),
            "spec": ctx.preset.spec.model_dump(mode="json"),
            "options": ctx.preset.options.model_dump(mode="json"),
        }
    return {
        "problem": {
            "file": str(ctx.path),
            "spec": ctx.spec.model_dump(mode="json"),
            "options": ctx.options.model_dump(mode="json") if ctx.options is not None else None,
            "data params": ctx.data_params.model_dump(mode="json") if ctx.data_params is not None else None,
        },
        "preset": preset,
        "versions": versions(),
        "machine": machine(),
        "started": started.astimezone(timezone.utc).isoformat(timespec="seconds"),
        "wall seconds": wall_seconds,
    }


def now() -> datetime:
    """The current time, UTC."""
    return datetime.now(timezone.utc)
