"""How much memory a run will need, estimated before anything is allocated, and the limit it must stay under.

A run holds its samples and, for every sample, the arrays its kind computes (the
result's arrays) while it works on them. :func:`estimate_bytes` counts those, per
sample, from the arm's sizes and the number of compared methods:

``bytes = data.samples x 8 x WORKING_COPIES x values_per_sample``

``values_per_sample`` is the number of float64 values a kind keeps per sample
(:data:`VALUES_PER_SAMPLE`, one formula per kind, written from the arrays of its
``report.py``), with

``n``
    the configuration size of the arm (``arm.n_config``),
``m``
    its number of sections,
``K``
    its backbone points, ``m x backbone_points_per_section + 1``,
``M``
    the methods compared: the solver and every baseline.

A kind without a formula is given :func:`generic_values`: per method a
configuration, the section poses, the backbone and a few scalars. ``tracking``
takes its length from the path and rate, not ``data.samples``, and counts zero.

:func:`check_memory` refuses a run whose estimate passes :func:`memory_limit`: by
default half the memory the machine has available (``MemAvailable`` of
``/proc/meminfo``, else ``os.sysconf``), or the environment variable
``OPTIKIN_MEMORY_LIMIT``: bytes, or a number with a binary suffix ``K``, ``M``,
``G`` or ``T`` (``8G``, ``512M``; ``B`` and ``iB`` are accepted after it). The
refusal is a :class:`~optikin.errors.SpecError` on ``data.samples`` giving the
estimate and the limit.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from optikin.arms.base import ArmModel
from optikin.errors import SpecError

ENVIRONMENT = "OPTIKIN_MEMORY_LIMIT"
"""The environment variable that replaces the default memory limit."""

WORKING_COPIES = 2
"""A run holds its result's arrays and, while computing them, about one more copy of each."""

CURVE_POINTS = 101
"""Points along each Pythagorean-hodograph curve in the results of the PH kinds."""

ROPE_TRUTH_POINTS = 200
"""Points of the simulated rope of a ``ph_chain`` recording (:func:`optikin.data.markers.synthetic_rope_chain`)."""

SUFFIXES = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


@dataclass(frozen=True)
class Sizes:
    """What the per-sample formulas read: ``n`` configuration variables, ``m`` sections, ``K`` backbone points
    and ``M`` compared methods."""

    n: int
    m: int
    K: int
    M: int


def generic_values(s: Sizes) -> int:
    """Per method a configuration, the section end poses (8 each), the backbone (3 per point) and 16 scalars."""
    return s.M * (s.n + 8 * s.m + 3 * s.K + 16) + 16


VALUES_PER_SAMPLE: dict[str, Callable[[Sizes], int]] = {
    # configuration, section poses, backbone, one tip pose per method, time, norm error and tip position
    "fk": lambda s: s.n + 8 * s.m + 3 * s.K + 8 * s.M + 16,
    # target pose, time and tip; per method a solution and its residual, status, time, iterations, errors
    "ik": lambda s: s.M * (s.n + 16) + 16,
    # a pose per time step, one rollout per method
    "dmp": lambda s: 8 * s.M + 16,
    # a candidate draw (three platform variables) and the leg lengths of the kept ones, one platform at a time
    "nn_fkm": lambda s: 32,
    "nn_ikm": lambda s: 32,
    # the curve's points, the vertebrae and their distances, energy and time per method, markers and coefficients
    "ph_shape": lambda s: 3 * CURVE_POINTS + 4 * s.K + 2 * s.M + 64,
    # the curve's points; tube lengths, status and time per method
    "ph_ik": lambda s: 3 * CURVE_POINTS + 8 * s.M + 64,
    # three curves (two arms and the rope), the rope's simulated points, both arms' vertebrae, time per link and method
    "ph_chain": lambda s: 9 * CURVE_POINTS + 3 * ROPE_TRUTH_POINTS + 6 * s.K + 6 * s.M + 64,
    # the run length follows from the path and the rate, not from data.samples
    "tracking": lambda s: 0,
}
"""Kind -> float64 values it keeps per sample of ``data.samples``."""


NO_ARM = Sizes(n=6, m=3, K=61, M=1)
"""The sizes assumed for a problem without an arm (the data carry the shapes): three sections of 20
backbone points, as the shape kinds reconstruct."""


def sizes(arm: ArmModel | None, methods: int) -> Sizes:
    """The :class:`Sizes` of ``arm`` compared across ``methods`` methods (:data:`NO_ARM` without one)."""
    if arm is None:
        return Sizes(n=NO_ARM.n, m=NO_ARM.m, K=NO_ARM.K, M=methods)
    m = arm.n_sections
    return Sizes(n=arm.n_config, m=m, K=m * arm.backbone_points_per_section + 1, M=methods)


def bytes_per_sample(kind: str, arm: ArmModel | None, methods: int) -> int:
    """Estimated bytes a run of ``kind`` on ``arm`` comparing ``methods`` methods needs per sample."""
    values = VALUES_PER_SAMPLE.get(kind, generic_values)(sizes(arm, methods))
    return 8 * WORKING_COPIES * values


def estimate_bytes(kind: str, arm: ArmModel | None, methods: int, samples: int) -> int:
    """Estimated bytes of a run of ``samples`` samples (the module docstring gives the formula)."""
    return samples * bytes_per_sample(kind, arm, methods)


def parse_size(text: str) -> int:
    """Bytes of ``"8G"``, ``"512 MiB"``, ``"1000000"``: a number with an optional binary suffix.

    Raises
    ------
    ValueError
        ``text`` is not a positive size.
    """
    match = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([KMGT]?)(?:I?B)?\s*", text.upper())
    if match is None or float(match.group(1)) <= 0:
        raise ValueError(f"{text!r} is not a size (bytes, or a number with K, M, G or T, e.g. 8G)")
    return int(float(match.group(1)) * SUFFIXES[match.group(2)])


def available_memory() -> int | None:
    """Bytes of memory available to new processes: ``MemAvailable`` of ``/proc/meminfo``, else the free
    physical pages of ``os.sysconf``; None when neither is known."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


def memory_limit() -> tuple[int | None, str]:
    """The memory limit in bytes (None: unknown, no limit) and where it comes from, for messages.

    Raises
    ------
    SpecError
        ``OPTIKIN_MEMORY_LIMIT`` is set but is not a size.
    """
    text = os.environ.get(ENVIRONMENT)
    if text is not None:
        try:
            return parse_size(text), ENVIRONMENT
        except ValueError as exc:
            raise SpecError(ENVIRONMENT, "", str(exc)) from None
    available = available_memory()
    if available is None:
        return None, "no limit: the available memory is unknown"
    return available // 2, f"half the available memory; set {ENVIRONMENT}, e.g. to 8G, to change it"


def format_bytes(n: float) -> str:
    """``n`` bytes in the largest binary unit that keeps it at least 1, e.g. ``"25.6 GiB"``."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"


def check_memory(kind: str, arm: ArmModel | None, methods: int, samples: int, path: str | Path) -> None:
    """Refuse a run whose estimated memory passes :func:`memory_limit`.

    Parameters
    ----------
    kind:
        The problem kind.
    arm:
        The arm model of the problem (None when it has none).
    methods:
        The methods compared: the solver and every baseline.
    samples:
        ``data.samples``.
    path:
        The problem file, named in the error.

    Raises
    ------
    SpecError
        On ``data.samples``, with the estimate and the limit.
    """
    limit, origin = memory_limit()
    estimate = estimate_bytes(kind, arm, methods, samples)
    if limit is not None and estimate > limit:
        raise SpecError(
            path,
            "data.samples",
            f"{samples} samples would need about {format_bytes(estimate)} of memory "
            f"({format_bytes(bytes_per_sample(kind, arm, methods))} per sample), more than the limit of "
            f"{format_bytes(limit)} ({origin}); use fewer samples",
        )
