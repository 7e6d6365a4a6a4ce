"""The C-backed PH fast path (:mod:`optikin.native.ph`) against the Python ``ph_newton`` path it replaces.

Reference: the adapter's own warm-start loop (:meth:`PHAdapter.solve`, Newton in CasADi's virtual machine).
Statuses, Newton steps, notes and messages equal sample by sample; angles, energies and lengths within
1e-12, also where Newton fails, after coarse-grid restarts, through the IPOPT fallback (which the Python
path runs for the C) and with the basin check. Independently of both, no point of a fine angle grid has
a lower energy than a converged sample.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import optikin.native
import optikin.native.ph as native_ph
from optikin.export.ph_shape import ph_setup
from optikin.native.ph import ShapeBatch, native_solve, solve

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler gcc on PATH")

SAMPLES = 40


@pytest.fixture(scope="module")
def setup():
    return ph_setup("cbha-ph-shape")


def adapter_with(setup, max_iterations: int = 50, fallback: bool = True, basin_check: bool = False):
    """A ``ph_newton`` adapter like the problem's, with these limits and options."""
    preset = setup.adapter.preset
    spec = preset.model_copy(update={"limits": preset.limits.model_copy(update={"max_iterations": max_iterations})})
    options = setup.adapter.options.model_copy(update={"fallback": fallback, "basin_check": basin_check})
    return type(setup.adapter)(spec, options)


def assert_same(ours, theirs) -> None:
    assert isinstance(ours, ShapeBatch) and len(ours) == len(theirs)
    assert [s.status for s in ours] == [s.status for s in theirs]
    assert [s.iterations for s in ours] == [s.iterations for s in theirs]
    assert [s.notes for s in ours] == [s.notes for s in theirs]
    assert [s.message for s in ours] == [s.message for s in theirs]
    np.testing.assert_allclose([s.x for s in ours], [s.x for s in theirs], rtol=0, atol=1e-12)
    np.testing.assert_allclose([s.energy for s in ours], [s.energy for s in theirs], rtol=1e-12, atol=0)
    np.testing.assert_allclose([s.arc_length for s in ours], [s.arc_length for s in theirs], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.x, [s.x for s in theirs], rtol=0, atol=1e-12)
    assert ours.status == [s.status for s in theirs]


def test_a_trajectory_matches_the_python_fast_path(setup):
    samples = setup.samples[:SAMPLES]
    ours = native_solve(setup.adapter, setup.model, samples)
    assert ours is not None
    assert_same(ours, setup.adapter.solve(setup.model, samples))
    assert ours.status == ["ok"] * SAMPLES
    # independent of Newton: no point of a 48 x 48 angle grid has a lower energy
    for k in (0, SAMPLES - 1):
        assert ours.energy[k] <= setup.model.solve_grid(samples[k], n=48).energy + 1e-12


def test_failures_without_fallback_match(setup):
    adapter = adapter_with(setup, max_iterations=3, fallback=False)
    ours = native_solve(adapter, setup.model, setup.samples[:SAMPLES])
    assert ours is not None
    assert_same(ours, adapter.solve(setup.model, setup.samples[:SAMPLES]))
    assert 0 < ours.status.count("not_converged") < SAMPLES


@pytest.mark.parametrize("max_iterations", [4, 3])
def test_restarts_and_the_ipopt_fallback_match(setup, max_iterations):
    """Four Newton steps: failed warm starts restart from the grid; three: restarts fail too and the Python
    path's IPOPT answers those samples, after which the C continues from IPOPT's answer."""
    adapter = adapter_with(setup, max_iterations=max_iterations, fallback=True)
    ours = native_solve(adapter, setup.model, setup.samples[:SAMPLES])
    assert ours is not None
    theirs = adapter.solve(setup.model, setup.samples[:SAMPLES])
    assert_same(ours, theirs)
    notes = "; ".join("; ".join(s.notes) for s in theirs)
    assert "coarse grid restart" in notes
    assert ("IPOPT fallback" in notes) == (max_iterations == 3)


def test_the_basin_check_matches(setup):
    adapter = adapter_with(setup, basin_check=True)
    samples = setup.samples[:12]
    ours = native_solve(adapter, setup.model, samples)
    assert ours is not None
    assert_same(ours, adapter.solve(setup.model, samples))


def test_a_sample_the_c_refuses_is_the_python_paths(setup, monkeypatch):
    """A non-finite end point (a ShapeData built without its checks): the Python path decides, the next sample
    starts cold in both; batches split into C calls of 7 samples give the same answers."""
    from dataclasses import replace

    samples = list(setup.samples[:20])
    samples[5] = replace(samples[5], p1=np.array([np.nan, 0.0, 0.1]))
    monkeypatch.setattr(native_ph, "CHUNK", 7)
    ours = native_solve(setup.adapter, setup.model, samples)
    assert ours is not None
    theirs = setup.adapter.solve(setup.model, samples)
    assert [s.status for s in ours] == [s.status for s in theirs]
    assert ours[5] is ours._made[5]
    keep = [k for k in range(20) if k != 5]
    np.testing.assert_allclose(ours.x[keep], [theirs[k].x for k in keep], rtol=0, atol=1e-12)
    assert [ours[k].iterations for k in keep] == [theirs[k].iterations for k in keep]


def test_the_batch_is_a_sequence_of_solutions(setup):
    ours = native_solve(setup.adapter, setup.model, setup.samples[:6])
    assert ours is not None
    assert ours[1] is ours[1] and ours[-1] is ours[5]
    assert [s.x.tolist() for s in ours[2:4]] == ours.x[2:4].tolist()
    assert ours[0].method == "newton" and ours[0].residual == ours[0].energy
    with pytest.raises(IndexError):
        ours[6]


def test_what_the_c_does_not_cover_runs_the_python_path(setup, monkeypatch):
    from optikin.export.context import registered_preset

    samples = setup.samples[:3]
    monkeypatch.setenv(optikin.native.ENVIRONMENT, "no")
    assert native_solve(setup.adapter, setup.model, samples) is None
    assert isinstance(solve(setup.adapter, setup.model, samples), list)
    monkeypatch.delenv(optikin.native.ENVIRONMENT)
    preset = registered_preset("ph-ipopt")
    assert preset is not None
    assert native_solve(preset.build(), setup.model, samples) is None
    free = setup.adapter.model(setup.model.settings, True)
    assert native_solve(setup.adapter, free, samples) is None


def test_without_a_compiler_one_log_line_and_the_python_path(setup, monkeypatch, caplog, tmp_path):
    import logging

    from optikin.curves.min_energy import ShapeEnergyModel

    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(optikin.native, "_reported", set())
    model = ShapeEnergyModel(setup.model.settings, coarse_grid=setup.model.coarse_grid)  # nothing compiled for it
    samples = setup.samples[:3]
    with caplog.at_level(logging.INFO, logger="optikin.native"):
        for _ in range(2):
            assert native_solve(setup.adapter, model, samples) is None
        solutions = solve(setup.adapter, model, samples)
    lines = [r.getMessage() for r in caplog.records if r.name == "optikin.native"]
    assert len(lines) == 1 and "gcc" in lines[0] and "reference path" in lines[0]
    assert [s.status for s in solutions] == ["ok"] * 3
