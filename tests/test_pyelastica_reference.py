"""The shipped PyElastica reference equilibria (tests/data/pyelastica) are well-formed and physically right.

The files are made by tools/pyelastica_reference.py. Besides shapes and metadata, two cases are checked against
closed forms: a follower tip couple bends the rod into a circular arc of curvature M/(EI), and a small tip force
deflects it by the Timoshenko cantilever formula. PyElastica's clamp fixes the first element's directors, an
O(1/n) error, so those checks use the Richardson extrapolation 2 x(n=200) - x(n=100) of the shipped nodes.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data" / "pyelastica"
CASES = [
    "tip_force_small",
    "tip_force_large",
    "tip_couple_x",
    "tip_force_couple_y",
    "gravity_horizontal",
    "gravity_45deg_tip_force",
]
ELEMENTS = [50, 100, 200]
LENGTH, RADIUS, E = 0.3, 0.01, 1.0e6
AREA = np.pi * RADIUS**2
EI = E * np.pi * RADIUS**4 / 4.0


def load(case: str, n: int) -> dict:
    with np.load(DATA / f"{case}_n{n}.npz") as f:
        return {k: f[k] for k in f.files}


def extrapolated(case: str) -> np.ndarray:
    """Richardson extrapolation of the nodes shared by the 100- and 200-element runs, shape (101, 3) [m]."""
    return 2.0 * load(case, 200)["positions"][::2] - load(case, 100)["positions"]


@pytest.mark.parametrize("n", ELEMENTS)
@pytest.mark.parametrize("case", CASES)
def test_file_is_well_formed(case, n):
    d = load(case, n)
    x, q = d["positions"], d["directors"]
    assert int(d["n_elements"]) == n and x.shape == (n + 1, 3) and q.shape == (n, 3, 3)
    assert d["continuum_positions"].shape == d["continuum_positions_pyelastica_law"].shape == (n + 1, 3)
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(q))
    np.testing.assert_allclose(x[0], 0.0, atol=1e-12)  # base at the origin
    # metres: 0.3 m of rod, stretched by well under 1 %
    seg = np.linalg.norm(np.diff(x, axis=0), axis=1)
    np.testing.assert_allclose(seg.sum(), LENGTH, rtol=1e-2)
    assert float(d["length"]) == LENGTH and float(d["radius"]) == RADIUS
    # directors: rows d1, d2, d3 of each element, orthonormal and right-handed
    np.testing.assert_allclose(q @ np.transpose(q, (0, 2, 1)), np.broadcast_to(np.eye(3), q.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(q), 1.0, atol=1e-9)
    # the clamped first element keeps its rest frame
    np.testing.assert_allclose(q[0, 2], d["base_direction"], atol=1e-12)
    np.testing.assert_allclose(q[0, 0], d["base_normal"], atol=1e-12)
    # d3 follows the centreline up to the (small) shear angle
    cos_shear = np.einsum("ki,ki->k", q[:, 2], np.diff(x, axis=0) / seg[:, None])
    assert np.all(cos_shear > np.cos(1e-2))
    # relaxed: nodes at rest and the tip no longer moving
    assert float(d["max_node_speed"]) < 1e-6 and float(d["tip_drift_last_10pct"]) < 1e-7
    assert int(d["steps"]) > 0 and float(d["dt"]) > 0 and float(d["wall_time"]) > 0
    assert str(d["pyelastica_version"]).startswith("1.")


def test_follower_couple_gives_a_circular_arc():
    """Pure bending by M about d1 = +x: the centreline is the arc y = -(1 - cos ks)/k, z = sin(ks)/k, k = M/EI."""
    k = float(load("tip_couple_x", 100)["tip_couple_material"][0]) / EI
    s = np.linspace(0.0, LENGTH, 101)
    arc = np.stack([np.zeros_like(s), -(1.0 - np.cos(k * s)) / k, np.sin(k * s) / k], axis=1)
    np.testing.assert_allclose(extrapolated("tip_couple_x"), arc, atol=1e-6)


def test_small_tip_force_matches_timoshenko_cantilever():
    """FL^2/EI = 0.11: the tip deflection is within 0.5 % of F L^3 / (3 E I) + F L / (alpha_c G A)."""
    d = load("tip_force_small", 200)
    force, g, alpha_c = float(d["tip_force"][0]), float(d["shear_modulus"]), 27.0 / 28.0
    linear = force * LENGTH**3 / (3.0 * EI) + force * LENGTH / (alpha_c * g * AREA)
    np.testing.assert_allclose(extrapolated("tip_force_small")[-1, 0], linear, rtol=5e-3)


@pytest.mark.slow
def test_script_reproduces_a_shipped_case():
    """Re-relaxing the 50-element small-force case for the shipped number of steps gives the shipped nodes."""
    pytest.importorskip("elastica")
    spec = importlib.util.spec_from_file_location("pyelastica_reference", ROOT / "tools" / "pyelastica_reference.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    shipped = load("tip_force_small", 50)
    result = module.relax(module.CASES["tip_force_small"], 50, float(shipped["dt"]), n_steps=int(shipped["steps"]))
    np.testing.assert_allclose(result["positions"], shipped["positions"], atol=1e-6)
    np.testing.assert_allclose(result["directors"], shipped["directors"], atol=1e-6)
