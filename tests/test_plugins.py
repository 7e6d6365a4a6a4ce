"""Plugins: an arm (kind, backend, source) from another installed package, found through entry points.

The worked example ``examples/plugin`` (a tendon arm with a routing of its own) is made visible to
``importlib.metadata`` as an installed distribution (a ``.dist-info`` folder on ``sys.path``, what pip
writes), then solved from its problem files; its kinematics are checked against optikin's own
constant-curvature arm at the curvature its tendons give (an independent path: numpy trigonometry in
``(theta, phi)``, where the plugin works in the bending vector). One slow test installs it with pip.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from optikin.arms import ConstantCurvatureArm
from optikin.cli import main
from optikin.errors import UnknownNameError
from optikin.registry import ARMS, PROBLEM_KINDS, PluginError, plugin_entry_points

PLUGIN = Path(__file__).resolve().parents[1] / "examples" / "plugin"


def install_entry_points(site: Path, name: str, groups: dict[str, dict[str, str]]) -> None:
    info = site / f"{name}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1.0\n")
    lines = [
        line
        for group, entries in groups.items()
        for line in (f"[{group}]", *(f"{k} = {v}" for k, v in entries.items()))
    ]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")


@pytest.fixture
def plugin_site(tmp_path, monkeypatch):
    """A folder on ``sys.path`` where distributions are 'installed' by writing their ``.dist-info``."""
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(PLUGIN / "src"))
    monkeypatch.syspath_prepend(str(site))
    plugin_entry_points.cache_clear()
    yield site
    plugin_entry_points.cache_clear()
    for registry in (ARMS, PROBLEM_KINDS):
        for name in [n for n in registry._items if n.startswith(("routed_tendon", "broken", "not_an"))]:
            del registry._items[name]
        registry._tried.clear()


@pytest.fixture
def routed_tendon(plugin_site):
    install_entry_points(
        plugin_site,
        "optikin_routed_tendon",
        {"optikin.arms": {"routed_tendon": "optikin_routed_tendon.arm:RoutedTendonArm"}},
    )
    return plugin_site


def test_the_plugin_arm_is_found_by_name(routed_tendon):
    arm_class = ARMS.get("routed_tendon")
    assert arm_class.__module__ == "optikin_routed_tendon.arm"
    assert "routed_tendon" in ARMS.names()


def test_the_plugin_arm_agrees_with_a_constant_curvature_arm_at_its_tendons_curvature(routed_tendon):
    arm = ARMS.get("routed_tendon")(
        section_lengths=(0.15, 0.12), routing_radius=(0.01, 0.008), routing_offset=(0.3, 1.2)
    )
    rng = np.random.default_rng(4)
    for q in rng.uniform(-0.008, 0.008, size=(20, 6)):
        config = []
        for i in range(2):
            d = q[3 * i : 3 * i + 3]
            angles = arm.routing_offset[i] + 2 * np.pi * np.arange(3) / 3
            u = -2.0 / (3.0 * arm.routing_radius[i]) * np.array([d @ np.cos(angles), d @ np.sin(angles)])
            config += [arm.section_lengths[i] + d.mean(), np.hypot(*u), np.arctan2(u[1], u[0])]
        reference = ConstantCurvatureArm(
            section_lengths=tuple(arm.section_lengths), length_range=(0.5, 1.5), theta_max=np.pi
        )
        expected = np.asarray(reference.fk_dq(np.array(config))).ravel()
        got = np.asarray(arm.fk_dq(q)).ravel()
        assert np.allclose(got, expected, atol=1e-12) or np.allclose(got, -expected, atol=1e-12)


def test_the_plugin_arm_is_smooth_through_the_straight_section(routed_tendon):
    arm = ARMS.get("routed_tendon")()
    J = np.asarray(arm.jac_position(np.zeros(6)))
    step = 1e-7
    columns = [
        (np.asarray(arm.fk_position(step * e)).ravel() - np.asarray(arm.fk_position(-step * e)).ravel()) / (2 * step)
        for e in np.eye(6)
    ]
    assert np.all(np.isfinite(J)) and np.allclose(J, np.array(columns).T, atol=1e-6)


@pytest.mark.parametrize("problem", ["routed-tendon-fk.yaml", "routed-tendon-ik.yaml"])
def test_the_plugin_problem_files_solve(routed_tendon, tmp_path, problem, capsys):
    rc = main(["solve", str(PLUGIN / problem), "--set", "data.samples=8", "--no-figures", "--out", str(tmp_path)])
    assert rc == 0, capsys.readouterr().err


def test_without_the_plugin_the_arm_is_unknown(plugin_site):
    with pytest.raises(UnknownNameError, match="routed_tendon"):
        ARMS.get("routed_tendon")


def test_a_plugin_that_cannot_be_imported_is_named(plugin_site, tmp_path, capsys):
    install_entry_points(plugin_site, "broken_lab", {"optikin.arms": {"broken_arm": "no_such_module:Arm"}})
    with pytest.raises(
        PluginError, match=r"plugin 'broken_arm' \(optikin.arms = 'no_such_module:Arm', from broken_lab 0.1.0\)"
    ):
        ARMS.get("broken_arm")


def test_a_plugin_that_loads_the_wrong_thing_is_refused(plugin_site):
    install_entry_points(
        plugin_site,
        "wrong_lab",
        {"optikin.arms": {"not_an_arm": "optikin.errors:OptikinError"}, "optikin.kinds": {"not_a_kind": "math:pi"}},
    )
    with pytest.raises(PluginError, match="not a subclass of ArmModel"):
        ARMS.get("not_an_arm")
    with pytest.raises(PluginError, match="not an optikin.problems.ProblemKind"):
        PROBLEM_KINDS.get("not_a_kind")


def test_a_plugin_never_replaces_a_shipped_name(plugin_site):
    install_entry_points(
        plugin_site, "shadow_lab", {"optikin.arms": {"cbha": "optikin_routed_tendon.arm:RoutedTendonArm"}}
    )
    assert ARMS.get("cbha").__name__ == "CBHAArm"
    assert ARMS.names().count("cbha") == 1


@pytest.mark.slow
def test_the_example_plugin_installs_with_pip_and_solves(tmp_path):
    target, source = tmp_path / "target", tmp_path / "plugin"
    shutil.copytree(PLUGIN, source)  # pip builds inside the source tree
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(target), str(source)]
    build = subprocess.run(pip, capture_output=True, text=True, cwd=tmp_path)
    assert build.returncode == 0, build.stderr[-2000:]
    code = "import sys; from optikin.cli import main; sys.exit(main(sys.argv[1:]))"
    solve = [sys.executable, "-c", code, "solve", str(source / "routed-tendon-ik.yaml"), "--no-figures", "--out", "out"]
    run = subprocess.run(
        solve, capture_output=True, text=True, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(target)}
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "routed-tendon-ik (ik" in run.stdout
