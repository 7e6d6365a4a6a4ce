"""``optikin solve --jobs N`` / ``--dask``: a problem's samples split across worker processes give the
single-process run's answers, sample for sample, to the bit."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from optikin.cli import main
from optikin.errors import SpecError
from optikin.runner import solve
from optikin.sweep.chunks import MIN_PIECE, Chunks, chunks_of

TIMING = ("time_",)
"""Per-sample arrays of wall times: the only ones allowed to differ."""

IK = ("cc-ik-unreachable", [("data.samples", 200), ("baselines", ["newton"])])
"""250 targets, 50 outside the workspace: the retries (from the nearest solved target's solution, then
from seeded random configurations) run on the unsolved samples of every piece."""
FK = ("cc-two-section-fk", [("data.samples", 300)])


def _assert_same_samples(single, split) -> None:
    assert sorted(single.arrays) == sorted(split.arrays)
    for name, expected in single.arrays.items():
        if name.startswith(TIMING):
            continue
        got = split.arrays[name]
        assert got.shape == expected.shape, name
        if expected.dtype.kind == "f":
            assert got.tobytes() == expected.tobytes(), f"{name}: not bit-identical"
        else:
            assert np.array_equal(got, expected), name
    single_rows = {row.method: row.metrics for row in single.comparison}
    for row in split.comparison:
        for metric, value in row.metrics.items():
            if "time" not in metric:
                expected = single_rows[row.method][metric]
                both_nan = isinstance(value, float) and value != value and expected != expected
                assert both_nan or value == expected, (row.method, metric, value, expected)


def _check_engine(chunks: Chunks) -> None:
    for problem, overrides in (IK, FK):
        single, _ = solve(problem, overrides=overrides)
        split, _ = solve(problem, overrides=overrides, chunks=chunks)
        _assert_same_samples(single, split)
        assert "solved in pieces" in split.notes[-1] and not any("pieces" in note for note in single.notes)
        assert len(single.arrays["configurations" if problem == FK[0] else "targets"]) >= 2 * MIN_PIECE


def test_split_covers_the_samples_in_order():
    chunks = Chunks(jobs=2)
    slices = chunks.split(250)
    assert [(s.start, s.stop) for s in slices] == [(0, 84), (84, 168), (168, 250)]
    assert chunks.split(MIN_PIECE + 10) == [slice(0, MIN_PIECE + 10)]  # solved here: one piece
    assert Chunks(jobs=1).split(1000) == [slice(0, 1000)]
    assert chunks_of(1, None) is None
    with pytest.raises(SpecError, match="--jobs"):
        chunks_of(0, None)


@pytest.mark.slow
def test_joblib_two_workers_give_the_single_process_samples():
    status = np.array(solve(*IK[:1], overrides=IK[1])[0].arrays["status_gauss-newton"])
    assert (status != "ok").sum() >= 50  # the unreachable targets, retried
    _check_engine(Chunks(jobs=2))


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="needs dask[distributed]")
def test_dask_local_cluster_gives_the_single_process_samples():
    _check_engine(Chunks(dask="local:2"))


def test_kind_without_pieces_and_trajectory_say_they_run_as_one_piece(tmp_path, capsys):
    assert main(["solve", "trunk-ph-shape", "--jobs", "2", "--out", str(tmp_path)]) == 2
    assert "--jobs: kind 'ph_shape' runs as one piece" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())
    with pytest.raises(SpecError, match="run as one piece"):
        solve("cc-ik-trajectory", overrides=[("data.samples", 20), ("baselines", [])], chunks=Chunks(jobs=2))
