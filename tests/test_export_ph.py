"""``optikin export --what ph-shape``: the C trajectory call against the Python ``ph_newton`` path.

The C library runs modified Newton on CasADi-generated code: the energy's gradient and Hessian through
the 13 Bernstein coefficients of the bending energy (``bending_derivatives``), the data-only part
of the Hermite family once per sample. The Python path runs CasADi's reverse-mode derivatives of the
model's energy in CasADi's virtual machine (:meth:`ShapeEnergyModel.solve_newton` in the warm-start
loop of the ``ph`` adapters). Statuses and Newton step counts must agree sample by sample, solutions,
energies and lengths to 1e-12, also where Newton fails (a small iteration budget), after coarse-grid
restarts and with the basin check.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from optikin.export import build, export
from optikin.curves.energy import shape_energy
from optikin.curves.newton import modified_newton_function
from optikin.export.ph_shape import newton_functions, ph_setup

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler cc on PATH")

STATUS = {0: "ok", 2: "not_converged", 3: "invalid_input"}
SAMPLES = 40


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The setup of cbha-ph-shape and the example built from its export."""
    folder = tmp_path_factory.mktemp("ph")
    setup = ph_setup("cbha-ph-shape")
    executable = build(export("cbha-ph-shape", "ph-shape", folder))
    return setup, executable, folder


def run(built, P: np.ndarray, *options: int) -> np.ndarray:
    """The example on rows ``P`` with options ``max_iterations restart basin_check``; its rows as an array."""
    _, executable, folder = built
    data = folder / "samples.txt"
    np.savetxt(data, P, fmt="%.17g")
    out = subprocess.run(
        [str(executable), str(data), *map(str, options)], capture_output=True, text=True, timeout=60, check=True
    )
    assert "per_call_us" in out.stderr and "cpu_us" in out.stderr
    return np.array([[float(v) for v in line.split()] for line in out.stdout.splitlines()])


def adapter_with(setup, max_iterations: int, fallback: bool, basin_check: bool = False):
    """A ``ph_newton`` adapter like the problem's, with these limits and options."""
    preset = setup.adapter.preset
    spec = preset.model_copy(update={"limits": preset.limits.model_copy(update={"max_iterations": max_iterations})})
    options = setup.adapter.options.model_copy(update={"fallback": fallback, "basin_check": basin_check})
    return type(setup.adapter)(spec, options)


def compare(out: np.ndarray, solutions) -> None:
    assert [STATUS[int(s)] for s in out[:, 0]] == [s.status for s in solutions]
    assert list(out[:, 1].astype(int)) == [s.iterations for s in solutions]
    np.testing.assert_allclose(out[:, 4:6], [s.x for s in solutions], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out[:, 2], [s.energy for s in solutions], rtol=1e-12, atol=0)
    np.testing.assert_allclose(out[:, 3], [s.arc_length for s in solutions], rtol=0, atol=1e-12)


def test_trajectory_agrees_with_the_python_fast_path(built):
    setup = built[0]
    samples = setup.samples[:SAMPLES]
    out = run(built, setup.parameters[:SAMPLES])
    compare(out, setup.adapter.solve(setup.model, samples))
    assert (out[:, 0] == 0).all()
    # independent of Newton: no point of a 64 x 64 angle grid has a lower energy, and IPOPT's cold
    # three-start solve finds the same minimum
    for k in (0, SAMPLES // 2, SAMPLES - 1):
        grid = setup.model.solve_grid(samples[k], n=64)
        assert out[k, 2] <= grid.energy + 1e-12
        ipopt = setup.model.solve_nlp(samples[k], starts=3)
        assert ipopt.status == "ok" and abs(out[k, 2] - ipopt.energy) <= 1e-9 * ipopt.energy


def test_failures_agree_without_fallback(built):
    """Three Newton steps are not enough for every sample: the failures and their last iterates agree, and a
    failed sample makes the next one start from the coarse grid in both."""
    setup = built[0]
    adapter = adapter_with(setup, max_iterations=3, fallback=False)
    out = run(built, setup.parameters[:SAMPLES], 3, 0, 0)
    solutions = adapter.solve(setup.model, setup.samples[:SAMPLES])
    compare(out, solutions)
    assert 0 < sum(s.status == "not_converged" for s in solutions) < SAMPLES


@pytest.mark.parametrize("max_iterations, outcome", [(4, "coarse grid restart"), (3, "IPOPT fallback")])
def test_a_failed_warm_start_restarts_from_the_grid(built, max_iterations, outcome):
    """With fallback, Python restarts a failed warm start from the coarse grid, then calls IPOPT; C restarts
    alike and reports not_converged where Python needed IPOPT (after which the warm starts differ: IPOPT's
    answer is Python's). Four steps: a restart succeeds at sample 32; three: restarts fail too, from 31."""
    setup = built[0]
    adapter = adapter_with(setup, max_iterations=max_iterations, fallback=True)
    out = run(built, setup.parameters[:SAMPLES], max_iterations, 1, 0)
    solutions = adapter.solve(setup.model, setup.samples[:SAMPLES])
    notes = ["; ".join(s.notes) for s in solutions]
    ipopt = ["IPOPT fallback" in n for n in notes]
    first = ipopt.index(True) if any(ipopt) else SAMPLES
    assert any(outcome in n for n in notes[: first + 1])
    compare(out[:first], solutions[:first])
    assert first == SAMPLES or out[first, 0] == 2


def test_basin_check_agrees(built):
    setup = built[0]
    adapter = adapter_with(setup, max_iterations=50, fallback=True, basin_check=True)
    n = 12
    out = run(built, setup.parameters[:n], 50, 1, 1)
    compare(out, adapter.solve(setup.model, setup.samples[:n]))


def test_invalid_input_is_a_status_and_the_next_sample_starts_cold(built):
    setup = built[0]
    P = setup.parameters[:3].copy()
    P[1, 4] = np.nan
    out = run(built, P)
    assert [STATUS[int(s)] for s in out[:, 0]] == ["ok", "invalid_input", "ok"]
    assert np.isnan(out[1, 2:]).all()
    cold = setup.model.solve_newton(setup.samples[2], None, fallback=False)
    np.testing.assert_allclose(out[2, 4:6], cold.x, rtol=0, atol=1e-12)
    assert int(out[2, 1]) == cold.iterations


def test_free_end_speeds_are_refused():
    from optikin.errors import SolverError

    with pytest.raises(SolverError, match="given end speeds only"):
        ph_setup("cbha-ph-shape", [("options.free_speeds", True)])


def test_the_cut_after_the_family_keeps_the_models_energy(built):
    """The grid energy of (x, family(P)) is the model's energy of (x, P), rounding included."""
    setup = built[0]
    (family, _, _), grid = newton_functions(setup.model, "cut")
    rng = np.random.default_rng(3)
    for k in (0, 50, 99):
        P = setup.parameters[k]
        F = family(P)
        for x in rng.uniform(-np.pi, np.pi, (25, 2)):
            assert float(grid(x, F)) == float(setup.model.energy_function(x, P)[0])


def test_the_structured_derivatives_agree_with_reverse_mode(built):
    """The Newton outputs from the coefficient chain rule against CasADi's gradient and Hessian of the
    model's energy, near the solutions (where Newton runs) and at random angles."""
    setup = built[0]
    model = setup.model
    (family, newton, _), _ = newton_functions(model, "chain")
    x, P, curve = model.symbols()
    energy = shape_energy(curve, model.settings.twist_weight, model.settings.nodes, model.settings.curvature_floor)
    reference = modified_newton_function(energy, curve.arc_length(), x, P)
    solutions = setup.adapter.solve(model, setup.samples[:20])
    rng = np.random.default_rng(4)
    for k, sol in enumerate(solutions):
        P_k = setup.parameters[k]
        for point in (sol.x + rng.normal(0, 0.05, 2), rng.uniform(-np.pi, np.pi, 2)):
            got = np.array(newton(point, family(P_k))).ravel()
            want = np.array(reference(point, P_k)).ravel()
            assert got[1] == want[1]  # S: the same operations
            np.testing.assert_allclose(got[0], want[0], rtol=1e-14)  # E: the mirrored node pairs
            scale = 1.0 + abs(want[0])
            np.testing.assert_allclose(got[2:4], want[2:4], rtol=1e-10, atol=1e-12 * scale)  # max|g|, lambda_min
            np.testing.assert_allclose(got[4:6], want[4:6], rtol=1e-9, atol=1e-12)  # the step


def test_every_converged_sample_is_a_minimum(built):
    """Where a full step predicted to converge ends Newton without the Hessian there (C and Python alike),
    the returned point still passes the whole test: CasADi's gradient within the tolerance and its Hessian
    positive definite, on every sample of the trajectory and of the basin-checked run."""
    setup = built[0]
    model = setup.model
    x, P, curve = model.symbols()
    energy = shape_energy(curve, model.settings.twist_weight, model.settings.nodes, model.settings.curvature_floor)
    reference = modified_newton_function(energy, curve.arc_length(), x, P)
    tolerance = setup.adapter.preset.limits.tolerance
    for out in (run(built, setup.parameters), run(built, setup.parameters, 50, 1, 1)):
        assert (out[:, 0] == 0).all()
        for row, P_k in zip(out, setup.parameters):
            E, S, gmax, lmin = np.array(reference(row[4:6], P_k)).ravel()[:4]
            assert gmax <= tolerance * (1.0 + abs(E)) and lmin > 0
            assert abs(E - row[2]) <= 1e-12 * abs(E)


def test_with_twist_the_export_agrees(tmp_path):
    """With a twist term the derivatives are CasADi's of the energy (no coefficient chain rule); the export
    still agrees with the Python fast path, basin check included. Built with -O0: the code of CasADi's
    Hessian with twist takes -O2 most of a minute."""
    overrides = [("options.twist_weight", 0.5)]
    setup = ph_setup("cbha-ph-shape", overrides)
    executable = build(
        export("cbha-ph-shape", "ph-shape", tmp_path, overrides=overrides), flags=("-O0",)
    )  # a quick build
    n = 8
    out = run((setup, executable, tmp_path), setup.parameters[:n], 50, 1, 1)
    compare(
        out,
        adapter_with(setup, max_iterations=50, fallback=True, basin_check=True).solve(setup.model, setup.samples[:n]),
    )
    assert (out[:, 0] == 0).all()


def test_an_odd_coarse_grid_agrees(tmp_path):
    """A 7 x 7 coarse grid (a loop the vectoriser leaves scalar): the cold starts, restarts and basin checks
    pick the same grid points as Python's."""
    from optikin.export.ph_shape import PHExportSetup, export_ph_shape

    setup = ph_setup("cbha-ph-shape")
    adapter = adapter_with(setup, max_iterations=50, fallback=True, basin_check=True)
    adapter.options = adapter.options.model_copy(update={"coarse_grid": 7})
    model = adapter.model(setup.model.settings, False)
    assert model.coarse_grid == 7
    n = 12
    odd = PHExportSetup(model, adapter, setup.samples[:n], setup.parameters[:n])
    executable = build(export_ph_shape("cbha-ph-shape", odd, tmp_path, n), flags=("-O0",))
    out = run((odd, executable, tmp_path), setup.parameters[:n], 50, 1, 1)
    compare(out, adapter.solve(model, setup.samples[:n]))
