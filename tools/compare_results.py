"""Check that a change to optikin changes no result: solve shipped problems at small settings and compare them.

``python tools/compare_results.py --write REFERENCE`` solves every problem of :data:`PROBLEMS` with its
overrides (few samples, no figures) and writes ``REFERENCE/<problem>/result.json`` and ``arrays.npz``;
``python tools/compare_results.py REFERENCE`` solves them again and compares, exiting 0 when every result is
the same to the bit and 1 with one line per differing key otherwise (``--problems`` picks some,
``--against FOLDER`` compares a folder written earlier instead of solving).

Compared are ``result.json`` without the fields that hold wall times or where and when the run was
(:data:`UNTIMED`, and every key naming a time: :func:`is_timing`), the checkout's folder taken out of the
texts (:data:`CHECKOUT`), and every array of ``arrays.npz`` but the wall times (their bytes, shape and
dtype). Left out of :data:`PROBLEMS`, and why: the neural-network kinds
(``cbha-nn-*``: a training set of a few samples is refused, and the model fits take minutes), the dynamics
kinds (``cosserat-tendon-step``, ``cosserat-cantilever-vibration``, ``cbha-pneumatic-dynamics``: seconds of
simulated time each), ``cosserat-tendon-fk`` (40 s for five samples), ``cbha-ik`` and ``cbha-ph-ik-cosserat``
(the CBHA's numerical solvers, tens of seconds), the problems with the genetic DMP tuner (``dmp-goal-switch``:
minutes) and the recorded-data ones (``trunk-ik``, ``trunk-*-motive``, ``trunk-lab-*``: files outside the
checkout).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

TRACKING = [("data.params.rate", 100), ("data.params.segment_time", 0.6), ("data.params.hold", 0.6)]
"""Tracking runs at 100 Hz with 0.6 s segments (every baseline kept)."""

PROBLEMS: dict[str, list[tuple[str, Any]]] = {
    "cc-two-section-fk": [("data.samples", 20)],
    "cbha-fk": [("data.samples", 20)],
    "cc-ik-pose": [("data.samples", 8)],
    "cc-ik-unreachable": [("data.samples", 8), ("baselines", ["newton", "lm"])],
    "trunk-calibrate": [("data.samples", 40)],
    "cbha-calibrate-cosserat": [("data.samples", 5)],
    "cbha-c1-chain": [("data.samples", 5)],
    "cbha-ph-shape": [("data.samples", 5)],
    "cbha-rope-chain": [("data.samples", 5)],
    "cbha-ph-ik": [("data.samples", 5)],
    "cbha-ph-shape-cosserat": [("data.samples", 3)],
    "cbha-rope-chain-cosserat": [("data.samples", 3)],
    "cbha-platform-fk": [("data.samples", 5)],
    "cc-ik-points": [("data.samples", 8)],
    "cc-ik-trajectory": [("data.samples", 20)],
    "cosserat-tendon-ik": [("data.samples", 5)],
    "cosserat-cbha-fk": [("data.samples", 5)],
    "trunk-calibrate-tendons": [("data.samples", 40)],
    "trunk-ph-shape": [("data.samples", 5)],
    "dmp-imu-dualquat": [("data.samples", 200), ("baselines", ["lstsq", "lwr"])],
    "dmp-kinect-position": [("data.samples", 100)],
    "track-nominal": TRACKING,
    "track-into-limits": TRACKING,
    "track-obstacle-sphere": TRACKING,
    "mpc-obstacle": TRACKING,
    "track-two-arms-shared-space": TRACKING,
    "rope-skipping": [("data.params.rate", 100), ("data.params.cycles", 1)],
}
"""The problems solved and their overrides, chosen so the whole run takes a couple of minutes."""

UNTIMED = ("created", "timings", "provenance", "optikin")
"""Top-level ``result.json`` fields left out: wall times, the run's date, machine and version."""

TIMING = re.compile(r"time|seconds|speed|\[(s|ms|us)\]|_(s|ms|us)$", re.IGNORECASE)
"""What a key or an array's name holding a wall time (or a rate measured from one) contains."""


CHECKOUT = re.compile(r"/[^\s'\"]*/(?=problems/)")
"""The folder of the checkout a shipped file's path names (a note may give it): left out, so two checkouts compare."""


def is_timing(key: str) -> bool:
    """Whether a ``result.json`` key or an array's name holds a wall time (``time_lm``, ``solve [ms]``, ...)."""
    return TIMING.search(key) is not None


def write(out: Path, problems: Sequence[str]) -> None:
    """Solve ``problems`` (names of :data:`PROBLEMS`) into ``out``, one folder each."""
    from optikin.runner import solve

    for name in problems:
        solve(name, out=out, figures=False, overrides=PROBLEMS[name])


def _flatten(data: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """``(dotted path, leaf)`` of JSON data, keys naming a time left out."""
    if isinstance(data, dict):
        for key, value in data.items():
            if not is_timing(str(key)):
                yield from _flatten(value, f"{path}.{key}" if path else str(key))
    elif isinstance(data, list) and data and all(isinstance(v, dict) for v in data):
        for i, value in enumerate(data):
            label = value.get("method", i) if isinstance(value, dict) else i
            yield from _flatten(value, f"{path}[{label}]")
    else:
        yield path, data


def _without_checkout(data: Any) -> Any:
    """``data`` with the checkout's folder taken out of every text (``/home/x/optikin/problems/a.yaml`` ->
    ``problems/a.yaml``)."""
    if isinstance(data, str):
        return CHECKOUT.sub("", data)
    if isinstance(data, list):
        return [_without_checkout(v) for v in data]
    return data


def _same_leaf(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def compare_json(reference: Path, other: Path) -> list[str]:
    """The keys of ``result.json`` that differ between two result folders, with both values."""
    want = json.loads((reference / "result.json").read_text())
    got = json.loads((other / "result.json").read_text())
    for key in UNTIMED:
        want.pop(key, None)
        got.pop(key, None)
    left = {key: _without_checkout(value) for key, value in _flatten(want)}
    right = {key: _without_checkout(value) for key, value in _flatten(got)}
    lines = []
    for key in sorted(set(left) | set(right)):
        if key not in right:
            lines.append(f"result.json {key}: missing (was {left[key]!r})")
        elif key not in left:
            lines.append(f"result.json {key}: new ({right[key]!r})")
        elif not _same_leaf(left[key], right[key]):
            lines.append(f"result.json {key}: {left[key]!r} -> {right[key]!r}")
    return lines


def _arrays(folder: Path) -> dict[str, np.ndarray]:
    path = folder / "arrays.npz"
    if not path.exists():
        return {}
    with np.load(path, allow_pickle=False) as data:
        return {key: data[key] for key in data.files if not is_timing(key)}


def compare_arrays(reference: Path, other: Path) -> list[str]:
    """The arrays of ``arrays.npz`` that differ (bytes, shape or dtype) between two result folders."""
    want, got = _arrays(reference), _arrays(other)
    lines = []
    for key in sorted(set(want) | set(got)):
        if key not in got:
            lines.append(f"arrays.npz {key}: missing")
        elif key not in want:
            lines.append(f"arrays.npz {key}: new")
        elif want[key].dtype != got[key].dtype or want[key].shape != got[key].shape:
            lines.append(f"arrays.npz {key}: {want[key].dtype}{want[key].shape} -> {got[key].dtype}{got[key].shape}")
        elif want[key].tobytes() != got[key].tobytes():
            differ = want[key] != got[key]
            if want[key].dtype.kind in "fc":
                differ &= ~(np.isnan(want[key]) & np.isnan(got[key]))
            count = int(np.count_nonzero(differ))
            lines.append(f"arrays.npz {key}: {count} of {want[key].size} entries differ")
    return lines


def compare(reference: Path, other: Path, problems: Sequence[str]) -> dict[str, list[str]]:
    """Per problem, the differences between the results in ``reference`` and in ``other`` (empty: identical)."""
    found = {}
    for name in problems:
        want, got = reference / name, other / name
        if not (want / "result.json").exists():
            found[name] = [f"{want}: no reference result"]
        elif not (got / "result.json").exists():
            found[name] = [f"{got}: no result"]
        else:
            found[name] = compare_json(want, got) + compare_arrays(want, got)
    return found


def main(argv: Sequence[str] | None = None) -> int:
    """Run the tool (``--help`` says how); returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reference", type=Path, help="the folder of reference results")
    parser.add_argument("--write", action="store_true", help="write the reference instead of comparing")
    parser.add_argument("--against", type=Path, help="compare the results in this folder (nothing is solved)")
    parser.add_argument("--problems", nargs="+", choices=sorted(PROBLEMS), default=list(PROBLEMS))
    args = parser.parse_args(argv)
    if args.write:
        write(args.reference, args.problems)
        return 0
    with tempfile.TemporaryDirectory() as scratch:
        other = args.against
        if other is None:
            other = Path(scratch)
            write(other, args.problems)
        found = compare(args.reference, other, args.problems)
    for name, lines in found.items():
        print(f"{name}: {'identical' if not lines else f'{len(lines)} difference(s)'}")
        for line in lines:
            print(f"  {line}")
    return 1 if any(found.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
