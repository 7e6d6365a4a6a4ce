"""``optikin view``: the 3-D page of a result, its content, and the page in a real headless browser."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import plotly.graph_objects as go
import pytest

from optikin.results import MethodRow, Result, write_result
from optikin.spec import project_root
from optikin.view import MAX_FRAMES, ViewError, build_figure, page_html, write_view

N, K = 12, 30
CC_ARM = {"type": "constant_curvature", "params": {"section_lengths": [0.1, 0.1], "theta_max": 3.0}}


def _helix(n: int = N, k: int = K) -> np.ndarray:
    """``(n, k, 3)`` curves: sample ``i`` is a helix of radius 10 mm + i mm, 0.2 m high [m]."""
    s = np.linspace(0.0, 1.0, k)
    radius = (10.0 + np.arange(n))[:, None] * 1e-3
    return np.stack([radius * np.cos(4 * s), radius * np.sin(4 * s), np.broadcast_to(0.2 * s, (n, k))], axis=-1)


def _write(tmp_path: Path, arrays: dict[str, np.ndarray], kind: str = "fk", provenance: dict | None = None) -> Path:
    result = Result(
        problem="viewed",
        kind=kind,
        solver="s",
        title="A viewed result",
        arm={},
        status=["ok"] * N,
        comparison=[
            MethodRow("fast", "solver", {"median time [us]": 12.3456, "ok": "12/12", "nested": {"a": 1.0}}),
            MethodRow("slow <b>", "baseline", {"median time [us]": 4567.0, "max error [mm]": 0.001}),
        ],
        arrays=arrays,
        provenance=provenance or {},
    )
    return write_result(result, tmp_path, figures=False)


def _trajectory_arrays() -> dict[str, np.ndarray]:
    backbone = _helix()
    return {
        "t": np.linspace(0.0, 1.1, N),
        "backbone": backbone,
        "markers": backbone[:, ::10, :] + 1e-3,
        "tip_position": backbone[:, -1, :],
        "marker_distance": np.ones((N, 3)),  # ends in 3 but is no position
        "obstacle_centres": np.array([[0.05, 0.0, 0.1], [-0.05, 0.0, 0.1]]),
    }


def _mm(trace, axis: str) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in trace[axis]], dtype=float)


def test_layers_and_frames_of_a_trajectory(tmp_path):
    folder = _write(tmp_path, _trajectory_arrays())
    from optikin.results import read_result

    summary, arrays = read_result(folder)
    figure = build_figure(arrays, summary)
    names = [trace["name"] for trace in figure["data"]]
    assert names[:3] == ["backbone", "markers", "tip position"]
    assert {"tip position (path)", "backbone (tip path)", "obstacle centres"} <= set(names)
    assert not any("distance" in name for name in names)
    assert figure["data"][0]["mode"] == "lines" and figure["data"][1]["mode"] == "markers"
    go.Figure(figure)  # plotly's own schema check of every trace, frame and layout field
    # one slider position per sample, labelled by t; frame i holds sample i of the helix in mm
    assert len(figure["frames"]) == N
    steps = figure["layout"]["sliders"][0]["steps"]
    assert steps[-1]["label"] == "t = 1.1 s"
    backbone = _helix() * 1e3
    for i in (0, 7):
        frame = figure["frames"][i]
        assert frame["traces"] == [0, 1, 2]
        got = np.stack([_mm(frame["data"][0], a) for a in "xyz"], axis=1)
        np.testing.assert_allclose(got, backbone[i], atol=1e-3)
        np.testing.assert_allclose([_mm(frame["data"][2], a)[0] for a in "xyz"], backbone[i, -1], atol=1e-3)
    path = next(t for t in figure["data"] if t["name"] == "tip position (path)")
    assert len(path["x"]) == N and path["mode"] == "lines"
    obstacles = next(t for t in figure["data"] if t["name"] == "obstacle centres")
    np.testing.assert_allclose(_mm(obstacles, "x"), [50.0, -50.0])
    # equal axis scales: a cube holding every point of every sample
    scene = figure["layout"]["scene"]
    ranges = np.array([scene[f"{a}axis"]["range"] for a in "xyz"])
    assert scene["aspectmode"] == "cube" and scene["zaxis"]["title"] == {"text": "z [mm]"}
    spans = ranges[:, 1] - ranges[:, 0]
    np.testing.assert_allclose(spans, spans[0])
    every = backbone.reshape(-1, 3)
    assert (ranges[:, 0] <= every.min(axis=0)).all() and (ranges[:, 1] >= every.max(axis=0)).all()
    assert spans[2] < 1.2 * 200.0  # no more than 5 % margin around the 0.2 m height


def test_samples_without_time_get_a_cloud_and_sample_labels(tmp_path):
    n = MAX_FRAMES + 50
    targets = np.random.default_rng(0).normal(size=(n, 3)) * 0.1
    from optikin.view import scene_layers

    count, layers = scene_layers({"target_positions": targets}, {"samples": n})
    assert count == n
    names = [layer.name for layer in layers]
    assert names == ["target positions", "target positions (all samples)"]
    assert layers[1].mode == "markers" and layers[1].points.shape == (n, 3)
    figure = build_figure({"target_positions": targets}, {"samples": n})
    assert len(figure["frames"]) == MAX_FRAMES
    assert figure["layout"]["sliders"][0]["steps"][-1]["label"] == f"sample {n - 1}"


def test_configurations_become_backbones_by_forward_kinematics(tmp_path):
    """Without a backbone array the arm of the provenance draws the configurations: a straight two-section
    arm is the z axis up to 0.2 m, one bent by theta in its first section has the chord 2 L sin(theta/2)/theta."""
    theta = 1.2
    solutions = np.zeros((N, 6))
    solutions[:, 0] = solutions[:, 3] = 0.1
    solutions[1:, 1] = theta
    provenance = {"problem": {"spec": {"arm": CC_ARM}}}
    dq_targets = np.zeros((N, 8))
    dq_targets[:, 0] = 1.0
    dq_targets[:, 5:8] = 0.5 * np.array([0.01, 0.02, 0.15])  # identity rotation: dual part p/2
    folder = _write(tmp_path, {"solutions": solutions, "targets": dq_targets}, kind="ik", provenance=provenance)
    from optikin.results import read_result

    summary, arrays = read_result(folder)
    figure = build_figure(arrays, summary)
    names = [trace["name"] for trace in figure["data"]]
    assert names[:2] == ["backbone of solutions", "targets (position)"]
    straight = np.stack([_mm(figure["data"][0], a) for a in "xyz"], axis=1)
    np.testing.assert_allclose(straight[:, :2], 0.0, atol=1e-9)
    np.testing.assert_allclose(straight[-1], [0.0, 0.0, 200.0], atol=1e-3)
    bent = np.stack([_mm(figure["frames"][1]["data"][0], a) for a in "xyz"], axis=1)
    first_section_end = bent[20]  # 20 backbone points per section after the base point
    np.testing.assert_allclose(
        np.linalg.norm(first_section_end), 2 * 100 * np.sin(theta / 2) / theta, atol=2e-3
    )  # mm, rounded to 1 um
    np.testing.assert_allclose([figure["data"][1][a][0] for a in "xyz"], [10.0, 20.0, 150.0], atol=1e-3)


def test_obstacles_of_the_spec_are_drawn_as_surfaces(tmp_path):
    """A sphere's surface points lie at its radius, a moving sphere is offset by the linear interpolation of
    its path at each sample's time, a half-space's patch lies on its plane, a box's hull has its 8 corners."""
    t = np.linspace(0.0, 1.1, N)
    obstacles = [
        {"type": "sphere", "center": [0.1, 0.0, 0.2], "radius": 0.02},
        {"type": "sphere", "center": [0.0, 0.0, 0.1], "radius": 0.01, "path": [[0.0, 0, 0, 0], [1.0, 0.05, 0, 0]]},
        {"type": "halfspace", "point": [0.0, 0.0, -0.01], "normal": [0.0, 1.0, 1.0]},
        {"type": "box", "center": [0.0, 0.1, 0.1], "half_extents": [0.01, 0.02, 0.03]},
    ]
    provenance = {"problem": {"spec": {"options": {"obstacles": obstacles}}}}
    folder = _write(tmp_path, {"t": t, "backbone": _helix()}, kind="tracking", provenance=provenance)
    from optikin.results import read_result

    summary, arrays = read_result(folder)
    figure = build_figure(arrays, summary)
    go.Figure(figure)
    meshes = {trace["name"]: (i, trace) for i, trace in enumerate(figure["data"]) if trace["type"] == "mesh3d"}
    assert list(meshes) == ["obstacle 1 (sphere)", "obstacle 2 (sphere)", "obstacle 3 (halfspace)", "obstacle 4 (box)"]

    def points(trace):
        return np.stack([_mm(trace, a) for a in "xyz"], axis=1)

    sphere = points(meshes["obstacle 1 (sphere)"][1])
    np.testing.assert_allclose(np.linalg.norm(sphere - [100.0, 0.0, 200.0], axis=1), 20.0, atol=2e-3)
    index = meshes["obstacle 2 (sphere)"][0]
    for i in (3, N - 1):  # t = 0.3 s: 15 mm along x; past the path's end: held at 50 mm
        frame = figure["frames"][i]
        moved = points(frame["data"][frame["traces"].index(index)])
        centre = [50.0 * min(t[i], 1.0), 0.0, 100.0]
        np.testing.assert_allclose(np.linalg.norm(moved - centre, axis=1), 10.0, atol=2e-3)
    plane = points(meshes["obstacle 3 (halfspace)"][1])
    np.testing.assert_allclose((plane - [0.0, 0.0, -10.0]) @ np.array([0.0, 1.0, 1.0]), 0.0, atol=2e-3)
    box = points(meshes["obstacle 4 (box)"][1])
    np.testing.assert_allclose(box.min(axis=0), [-10.0, 80.0, 70.0], atol=1e-9)
    np.testing.assert_allclose(box.max(axis=0), [10.0, 120.0, 130.0], atol=1e-9)
    assert len(box) == 8


def test_backbones_stored_as_n_3_k_are_turned(tmp_path):
    from optikin.view import scene_layers

    backbone = _helix()
    _, layers = scene_layers({"backbone": np.transpose(backbone, (0, 2, 1))}, {"samples": N})
    np.testing.assert_array_equal(layers[0].points, backbone)
    assert layers[0].mode == "lines"


class _Tables(HTMLParser):
    """The cells of every ``<table>`` row of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[str]] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append("".join(self._cell))
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def test_page_is_self_contained_with_the_comparison_table(tmp_path):
    folder = _write(tmp_path, _trajectory_arrays())
    page = write_view(folder)
    assert page == folder / "view.html"
    text = page.read_text()
    assert not re.search(r"<script[^>]+src=", text), "the page loads a script from elsewhere"
    assert len(text) > 3_000_000 and "Plotly.newPlot" in text  # plotly.js itself is inside
    tables = _Tables()
    tables.feed(text)
    assert tables.rows[0] == ["method", "role", "median time [us]", "ok", "nested.a", "max error [mm]"]
    assert tables.rows[1] == ["fast", "solver", "12.35", "12/12", "1", ""]
    assert tables.rows[2] == ["slow <b>", "baseline", "4567", "", "", "0.001"]  # escaped, not markup
    assert "<b>slow" not in text and "slow &lt;b&gt;" in text
    other = write_view(folder, tmp_path / "elsewhere.html")
    assert other.read_text() == text


def test_plotly_is_a_core_dependency():
    """A plain ``pip install optikin`` has plotly (optikin view needs no extra); the extra ``view`` stays, empty,
    so that ``pip install 'optikin[view]'`` still works."""
    tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from Python 3.11")
    project = tomllib.loads((project_root() / "pyproject.toml").read_text())["project"]
    assert any(re.match(r"plotly\b", requirement) for requirement in project["dependencies"])
    assert project["optional-dependencies"]["view"] == []


def test_a_broken_install_without_plotly_names_the_fix(monkeypatch):
    monkeypatch.setitem(sys.modules, "plotly.io", None)
    with pytest.raises(ViewError, match=r"pip install 'plotly>=5'"):
        page_html({"tip_position": np.zeros((2, 3))}, {"samples": 2})


def test_cli_writes_the_page_and_names_a_bad_folder(tmp_path, capsys):
    from optikin.cli import EXIT_BAD_INPUT, EXIT_OK, main

    folder = _write(tmp_path, _trajectory_arrays())
    assert main(["view", str(folder), "--out", str(tmp_path / "page.html")]) == EXIT_OK
    assert (tmp_path / "page.html").stat().st_size > 1_000_000  # plotly.js is inside
    assert str(tmp_path / "page.html") in capsys.readouterr().out
    assert main(["view", str(tmp_path / "nothing")]) == EXIT_BAD_INPUT
    assert "nothing" in capsys.readouterr().err


def test_open_hands_the_file_url_to_the_browser(tmp_path, monkeypatch, capsys):
    import webbrowser

    from optikin.cli import EXIT_OK, main

    opened: list[str] = []
    monkeypatch.setattr(webbrowser, "open", lambda url: opened.append(url) or False)
    folder = _write(tmp_path, _trajectory_arrays())
    assert main(["view", str(folder), "--open"]) == EXIT_OK
    assert opened == [(folder / "view.html").resolve().as_uri()]
    assert "no web browser could be started" in capsys.readouterr().err


# ---------------------------------------------------------------------- the page in a real browser


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return "/usr/bin/chromium" if os.access("/usr/bin/chromium", os.X_OK) else None


def _browse(page: Path, shot: Path, budget_ms: int = 10000) -> list[str]:
    """Load ``page`` from its file URL in headless chromium, screenshot it; returns the console messages."""
    browser = _chromium()
    assert browser is not None
    run = subprocess.run(
        [
            browser,
            "--headless",
            "--disable-gpu",
            "--no-sandbox",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            f"--screenshot={shot}",
            "--window-size=1200,900",
            f"--virtual-time-budget={budget_ms}",
            "--enable-logging=stderr",
            "--v=0",
            f"--user-data-dir={shot.parent / 'chromium-profile'}",
            page.resolve().as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert shot.is_file(), f"chromium wrote no screenshot (exit {run.returncode}): {run.stderr[-2000:]}"
    return re.findall(r":CONSOLE[^\]]*\] (.*)", run.stderr)


def _script_errors(messages: list[str]) -> list[str]:
    return [m for m in messages if re.search(r"Uncaught|\b\w*Error\b|failed", m)]


needs_chromium = pytest.mark.skipif(
    _chromium() is None, reason="no chromium on PATH or at /usr/bin/chromium (apt-get install chromium)"
)


@needs_chromium
def test_browser_console_errors_are_caught(tmp_path):
    """The console parsing of :func:`_browse` sees a script error (so its silence on the view means something)."""
    page = tmp_path / "broken.html"
    page.write_text("<html><body><p>text</p><script>notDefinedAnywhere();</script></body></html>")
    errors = _script_errors(_browse(page, tmp_path / "broken.png", budget_ms=500))
    assert any("notDefinedAnywhere" in e for e in errors), errors


@needs_chromium
@pytest.mark.slow
def test_page_draws_in_a_headless_browser(tmp_path):
    from matplotlib.image import imread

    folder = _write(tmp_path, _trajectory_arrays())
    page = write_view(folder)
    shot = tmp_path / "view.png"
    messages = _browse(page, shot)
    assert _script_errors(messages) == [], messages
    image = imread(shot)[..., :3]
    assert image.shape[:2] == (900, 1200)
    assert image.std() > 0.05, "the screenshot is blank"
    # the scene (left of the legend, below the heading): the first trace's colour (plotly's #636efa, the
    # backbone) must be drawn by WebGL there; the legend's swatch of it lies further right
    scene = image[250:880, 40:780] * 255
    backbone_colour = np.array([99, 110, 250])
    drawn = np.linalg.norm(scene - backbone_colour, axis=-1) < 40
    assert drawn.sum() > 50, f"the backbone is not drawn ({drawn.sum()} pixels of its colour in the scene)"
    assert scene.std() > 5.0, "the scene area is blank"
