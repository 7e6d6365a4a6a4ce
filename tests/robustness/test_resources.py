"""Memory limits: a run too large for the machine is refused before it allocates, naming data.samples."""

from __future__ import annotations

import os
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from optikin import resources
from optikin.cli import EXIT_BAD_INPUT, main
from optikin.errors import SpecError
from optikin.problems import ProblemContext
from optikin.runner import prepare, solve

PROBLEM = """\
name: big
title: a problem with many samples
kind: fk
arm:
  type: constant_curvature
  params: {{section_lengths: [0.18, 0.18]}}
data:
  source: random
  seed: 3
  samples: {samples}
baselines: [numpy]
"""


def problem(tmp_path: Path, samples: int) -> Path:
    path = tmp_path / "big.yaml"
    path.write_text(PROBLEM.format(samples=samples))
    return path


def test_ten_million_samples_are_refused_before_anything_is_allocated(tmp_path, monkeypatch):
    monkeypatch.delenv(resources.ENVIRONMENT, raising=False)
    monkeypatch.setattr(resources, "available_memory", lambda: 8 << 30)
    path = problem(tmp_path, 10_000_000)
    with pytest.raises(SpecError) as info:
        prepare(str(path))
    assert info.value.field == "data.samples"
    message = str(info.value)
    assert message.startswith(f"{path}: data.samples: 10000000 samples would need about ")
    assert "GiB of memory" in message and "more than the limit of 4.0 GiB (half the available memory" in message


def test_the_environment_sets_the_limit_and_the_cli_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(resources.ENVIRONMENT, "1M")
    path = problem(tmp_path, 100_000)
    assert main(["solve", str(path), "--out", str(tmp_path / "out"), "--no-figures"]) == EXIT_BAD_INPUT
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1
    assert "data.samples: 100000 samples would need about" in error[0]
    assert f"the limit of 1.0 MiB ({resources.ENVIRONMENT})" in error[0]
    assert not (tmp_path / "out").exists()


def test_a_bad_limit_in_the_environment_is_named(tmp_path, monkeypatch):
    monkeypatch.setenv(resources.ENVIRONMENT, "lots")
    with pytest.raises(SpecError, match=f"^{resources.ENVIRONMENT}: 'lots' is not a size"):
        prepare(str(problem(tmp_path, 10)))


@pytest.mark.parametrize(
    "text, size",
    [("1000", 1000), ("8G", 8 * 1024**3), ("512M", 512 * 1024**2), ("512 MiB", 512 * 1024**2), ("1.5k", 1536)],
)
def test_sizes(text, size):
    assert resources.parse_size(text) == size


@pytest.mark.parametrize("text", ["", "0", "-1G", "8X", "G"])
def test_not_sizes(text):
    with pytest.raises(ValueError):
        resources.parse_size(text)


def test_available_memory_lies_within_the_physical_memory():
    total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    available = resources.available_memory()
    assert available is not None and 0 < available <= total


def test_unknown_available_memory_means_no_limit(tmp_path, monkeypatch):
    monkeypatch.delenv(resources.ENVIRONMENT, raising=False)
    monkeypatch.setattr(resources, "available_memory", lambda: None)
    kind, ctx = prepare(str(problem(tmp_path, 10_000_000)))
    assert ctx.spec.data.samples == 10_000_000


@pytest.mark.parametrize(
    "name", ["cc-two-section-fk", "cbha-fk", "cc-ik-position", "cbha-ph-shape", "dmp-kinect-position"]
)
def test_one_copy_per_sample_holds_the_result_arrays(name):
    """The per-sample estimate covers what a run returns per sample (measured on 4 and 8 samples)."""
    nbytes = []
    for samples in (4, 8):
        kind, ctx = prepare(name)
        ctx.spec = ctx.spec.model_copy(update={"data": ctx.spec.data.model_copy(update={"samples": samples})})
        result = kind.run(ctx)
        nbytes.append(sum(np.asarray(a).nbytes for a in result.arrays.values()))
    per_sample = (nbytes[1] - nbytes[0]) / 4
    estimate = resources.bytes_per_sample(kind.name, ctx.arm, 1 + len(ctx.spec.baselines))
    assert 0 < per_sample <= estimate / resources.WORKING_COPIES


@pytest.mark.parametrize("name", ["cc-two-section-fk", "cbha-fk"])
def test_the_estimate_bounds_the_peak_memory_of_an_fk_run(name):
    """Peak Python-side memory (tracemalloc) grows by less than the estimate per added sample."""
    peaks = []
    for samples in (2000, 4000):
        kind, ctx = prepare(name)
        ctx.spec = ctx.spec.model_copy(update={"data": ctx.spec.data.model_copy(update={"samples": samples})})
        tracemalloc.start()
        kind.run(ctx)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    per_sample = (peaks[1] - peaks[0]) / 2000
    assert per_sample <= resources.bytes_per_sample(kind.name, ctx.arm, 1 + len(ctx.spec.baselines))


def test_running_out_of_memory_exits_2_naming_data_samples(tmp_path, monkeypatch, capsys):
    def exhausted(self):
        raise MemoryError

    monkeypatch.setattr(ProblemContext, "load_data", exhausted)
    path = problem(tmp_path, 10)
    with pytest.raises(SpecError) as info:
        solve(str(path))
    assert info.value.field == "data.samples"
    assert main(["solve", str(path), "--out", str(tmp_path / "out"), "--no-figures"]) == EXIT_BAD_INPUT
    error = capsys.readouterr().err.strip().splitlines()
    assert error == [
        f"optikin: error: {path}: data.samples: the run ran out of memory with 10 samples; use fewer samples"
    ]
