"""An interactive 3-D view of a written result: one self-contained HTML page (``optikin view RESULT_DIR``).

:func:`write_view` reads a result folder (``result.json`` + ``arrays.npz``, :func:`optikin.results.read_result`)
and writes ``view.html``: the result's 3-D content drawn with plotly (its JavaScript embedded, so the page
needs no network), a slider over the samples (over time ``t`` for a trajectory) with a play button, equal
axis scales in millimetres, and the comparison table, notes and provenance as HTML.

The 3-D content is found from the arrays' names and shapes (:func:`scene_layers`), whatever the kind:

* ``(N, K, 3)`` arrays of positions (names holding ``backbone``, ``point``, ``marker``, ``vertebra``, ...):
  one curve (``K >= 10``, or a backbone) or point set per sample, shown for the slider's sample;
* ``(N, 3)`` arrays (tips, bases, targets, reference positions): the slider's point, and all ``N`` as a
  path (a trajectory) or a faint cloud;
* ``(M, 3)`` arrays with another leading length (obstacles, waypoints): shown throughout;
* the obstacles of the problem spec (``options.obstacles``: spheres, capsules, boxes, half-spaces, static
  or moving along a path; :func:`obstacle_layers`) as translucent surfaces.

Names saying the values are not positions (``distance``, ``error``, ``angle``, ...) are left out. Two
hints fill in what a kind does not store as positions: without any backbone array, configuration arrays
(``solutions``, ``true_configurations``, ``configurations``, ``q``, ``q_METHOD``: ``(N, n_config)``) are turned
into backbones by the arm's forward kinematics (:meth:`optikin.arms.base.ArmModel.backbone`, the arm rebuilt
from the provenance's problem spec); and ``(N, 8)`` unit dual quaternion ``targets`` give their translation.

plotly is a core dependency, imported only here (the page embeds its plotly.js).
"""

from __future__ import annotations

import html
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from optikin.errors import InputDataError, OptikinError
from optikin.results import MethodRow, read_result, result_kind
from optikin.tables import comparison_rows, format_value

MM = 1e3
"""Metres to the page's millimetres."""
MAX_FRAMES = 150
"""Slider positions at most (samples evenly spread over ``N``)."""
MAX_PATH_POINTS = 5000
"""Points of a static path or cloud at most (every k-th sample)."""
POSITION_WORDS = (
    "backbone",
    "point",
    "marker",
    "vertebra",
    "target",
    "tip",
    "base",
    "position",
    "obstacle",
    "waypoint",
    "curve",
    "centre",
    "center",
    "disk",
    "node",
    "truth",
    "measured",
    "fitted",
)
NOT_POSITION_WORDS = (
    "distance",
    "error",
    "angle",
    "residual",
    "orientation",
    "wrench",
    "velocity",
    "rate",
    "force",
    "tension",
    "pressure",
    "length",
    "weight",
    "rpy",
)
CONFIGURATION_NAMES = re.compile(r"(solutions|true_configurations|configurations|q)(_.+)?")
MIN_CURVE_POINTS = 10


class ViewError(OptikinError):
    """The view cannot be written: plotly is missing, or the output file cannot be written."""


@dataclass
class Layer:
    """One labelled piece of the scene, in metres.

    ``points`` is ``(N, K, 3)`` for a per-sample layer (the slider's sample is drawn) or ``(M, 3)`` for a
    static one; ``mode`` is ``"lines"``, ``"markers"``, ``"hull"`` (a convex surface through the points) or
    ``"plane"`` (a quadrilateral); ``visible`` False starts it hidden (legend only).
    """

    name: str
    points: np.ndarray
    mode: str
    per_sample: bool
    visible: bool = True
    size: float = 4.0
    opacity: float = 1.0


def _is_position_name(name: str) -> bool:
    lower = name.lower()
    return any(w in lower for w in POSITION_WORDS) and not any(w in lower for w in NOT_POSITION_WORDS)


def _sample_count(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> int:
    """``N``: the length of ``t`` if stored, else the summary's sample count, else the commonest leading length."""
    if "t" in arrays and np.ndim(arrays["t"]) == 1:
        return len(arrays["t"])
    leading = [a.shape[0] for a in arrays.values() if a.ndim >= 2]
    samples = summary.get("samples")
    if isinstance(samples, int) and samples in leading:
        return samples
    spatial = [a.shape[0] for a in arrays.values() if a.ndim >= 2 and a.shape[-1] == 3] or leading
    return max(set(spatial), key=spatial.count) if spatial else 0


def _label(name: str) -> str:
    return re.sub("_+", " ", name)


def scene_layers(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> tuple[int, list[Layer]]:
    """The sample count ``N`` and the 3-D layers of a result (module docstring).

    Parameters
    ----------
    arrays:
        The result's arrays (``arrays.npz``).
    summary:
        The result's summary (``result.json``).

    Returns
    -------
    tuple[int, list[Layer]]
        ``N`` and the layers: per-sample ones first, then static ones.
    """
    n = _sample_count(arrays, summary)
    trajectory = "t" in arrays and len(arrays["t"]) == n and n > 1
    per_sample: list[Layer] = []
    static: list[Layer] = []
    points: dict[str, np.ndarray] = {}
    for name, value in arrays.items():
        a = np.asarray(value)
        if not np.issubdtype(a.dtype, np.floating) or a.ndim < 2:
            continue
        if a.shape[-1] == 8 and a.ndim == 2 and a.shape[0] == n and name == "targets":
            from optikin.algebra import dq_translation

            points[f"{name} (position)"] = np.asarray(dq_translation(a))
            continue
        if a.ndim == 3 and a.shape[1] == 3 and a.shape[2] != 3 and "backbone" in name.lower():
            a = np.transpose(a, (0, 2, 1))  # (N, 3, K) backbones
        if a.shape[-1] != 3 or not _is_position_name(name):
            continue
        if a.ndim == 3 and a.shape[0] == n:
            curve = a.shape[1] >= MIN_CURVE_POINTS or "backbone" in name.lower()
            per_sample.append(Layer(_label(name), a, "lines" if curve else "markers", True, size=5.0))
        elif a.ndim == 2 and a.shape[0] == n:
            points[name] = a
        elif a.ndim == 2:
            static.append(Layer(_label(name), a, "markers", False, size=6.0))
    if not any(layer.mode == "lines" for layer in per_sample):
        per_sample += _configuration_backbones(arrays, summary, n)
    for name, a in points.items():
        per_sample.append(Layer(_label(name), a[:, None, :], "markers", True, size=7.0))
        stride = max(1, -(-len(a) // MAX_PATH_POINTS))
        path = a[::stride]
        if trajectory:
            static.append(Layer(f"{_label(name)} (path)", path, "lines", False, opacity=0.6))
        else:
            static.append(Layer(f"{_label(name)} (all samples)", path, "markers", False, size=2.0, opacity=0.35))
    for layer in per_sample:
        if layer.mode == "lines" and trajectory:
            tips = layer.points[:, -1, :]
            stride = max(1, -(-len(tips) // MAX_PATH_POINTS))
            static.append(Layer(f"{layer.name} (tip path)", tips[::stride], "lines", False, visible=False))
    return n, per_sample + obstacle_layers(summary, arrays["t"] if trajectory else None, n) + static


def obstacle_layers(summary: Mapping[str, Any], t: np.ndarray | None, n: int) -> list[Layer]:
    """The obstacles of the problem spec's ``options.obstacles`` as surfaces (Mesh3d layers).

    Each entry has a ``type``: ``sphere`` (``center``, ``radius``), ``capsule`` (``a``, ``b``, ``radius``),
    ``box`` (``center``, ``half_extents``, axis-aligned) or ``halfspace`` (``point``, ``normal``), in metres,
    and an optional ``path`` of rows ``(t, dx, dy, dz)`` [s, m], the offset interpolated linearly in time and
    held beyond its ends. Spheres, capsules and boxes are drawn as the convex hull of points on their
    surface; a half-space as a square patch of its plane, ``HALFSPACE_HALF_WIDTH`` from its point. A
    moving obstacle is a per-sample layer when the result is a trajectory ``t`` of ``N`` samples.
    """
    spec = summary.get("provenance", {}).get("problem", {}).get("spec", {})
    entries = (spec.get("options") or {}).get("obstacles") or []
    layers = []
    for index, entry in enumerate(entries if isinstance(entries, list) else []):
        try:
            surface, mode = _obstacle_surface(entry)
        except (KeyError, TypeError, ValueError):
            continue
        name = f"obstacle {index + 1} ({entry['type']})"
        path = entry.get("path")
        if path and t is not None:
            rows = np.asarray(path, dtype=float)
            offsets = np.stack([np.interp(t, rows[:, 0], rows[:, 1 + j]) for j in range(3)], axis=-1)
            layers.append(Layer(name, surface[None, :, :] + offsets[:, None, :], mode, True, opacity=0.35))
        else:
            offset = np.asarray(path, dtype=float)[0, 1:] if path else np.zeros(3)
            layers.append(Layer(name, surface + offset, mode, False, opacity=0.35))
    return layers


HALFSPACE_HALF_WIDTH = 0.3
"""Half side [m] of the square drawn for a half-space's plane."""


def _obstacle_surface(entry: Mapping[str, Any]) -> tuple[np.ndarray, str]:
    """Surface points ``(V, 3)`` [m] of one obstacle at zero offset, and the layer mode (``hull``/``plane``)."""
    polar, azimuth = np.meshgrid(np.linspace(0, np.pi, 13), np.linspace(0, 2 * np.pi, 25), indexing="ij")
    unit = np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], -1)
    unit = unit.reshape(-1, 3)
    kind = entry["type"]
    if kind == "sphere":
        return np.asarray(entry["center"], float) + float(entry["radius"]) * unit, "hull"
    if kind == "capsule":
        ends = [np.asarray(entry[end], float) + float(entry["radius"]) * unit for end in ("a", "b")]
        return np.concatenate(ends), "hull"
    if kind == "box":
        corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
        return np.asarray(entry["center"], float) + corners * np.asarray(entry["half_extents"], float), "hull"
    if kind == "halfspace":
        normal = np.asarray(entry["normal"], float)
        normal = normal / np.linalg.norm(normal)
        helper = np.eye(3)[np.argmin(np.abs(normal))]
        u = np.cross(normal, helper)
        u /= np.linalg.norm(u)
        v = np.cross(normal, u)
        w = HALFSPACE_HALF_WIDTH
        square = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
        return np.array([np.asarray(entry["point"], float) + w * (a * u + b * v) for a, b in square]), "plane"
    raise ValueError(f"unknown obstacle type {kind!r}")


def _configuration_backbones(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any], n: int) -> list[Layer]:
    """Backbones ``(N, K, 3)`` of the configuration arrays by the arm's forward kinematics (none when the arm
    cannot be rebuilt from the provenance or no array fits it)."""
    arm_spec = summary.get("provenance", {}).get("problem", {}).get("spec", {}).get("arm")
    names = [k for k, v in arrays.items() if CONFIGURATION_NAMES.fullmatch(k) and np.ndim(v) == 2 and len(v) == n]
    if not isinstance(arm_spec, dict) or not names:
        return []
    from optikin.arms import build_arm

    try:
        arm = build_arm(arm_spec["type"], arm_spec.get("params", {}))
    except (OptikinError, KeyError, TypeError, ValueError):
        return []
    frames = frame_indices(n)
    layers: list[Layer] = []
    for name in names:
        q = np.asarray(arrays[name], dtype=float)
        if q.shape[1] != arm.n_config:
            continue
        try:
            shown = np.transpose(arm.evaluate("backbone", q[frames], check=False), (0, 2, 1))
        except (OptikinError, ValueError, RuntimeError, NotImplementedError):
            continue
        backbone = np.full((n, *shown.shape[1:]), np.nan)
        backbone[frames] = shown
        layers.append(Layer(f"backbone of {_label(name)}", backbone, "lines", True, visible=len(layers) < 2, size=5.0))
    return layers


def frame_indices(n: int) -> np.ndarray:
    """The samples the slider visits: all of them up to :data:`MAX_FRAMES`, else that many evenly spread."""
    return np.unique(np.linspace(0, max(n - 1, 0), min(n, MAX_FRAMES)).round().astype(int))


def _xyz(points: np.ndarray) -> dict[str, list[float | None]]:
    """Plotly coordinates [mm] of ``(K, 3)`` points, rounded to a micrometre; NaN as a gap."""
    mm = np.round(np.asarray(points, dtype=float) * MM, 3)
    return {axis: [float(v) if np.isfinite(v) else None for v in mm[:, i]] for i, axis in enumerate("xyz")}


def _axis_ranges(layers: list[Layer]) -> list[list[float]]:
    """One equal-length range per axis [mm] holding every finite point (a cube around the content; a
    half-space's plane is cut by it)."""
    drawn = [layer.points.reshape(-1, 3) for layer in layers if layer.mode != "plane"]
    stacked = np.concatenate([np.zeros((0, 3)), *drawn])
    stacked = stacked[np.isfinite(stacked).all(axis=1)] * MM
    if stacked.size == 0:
        stacked = np.zeros((1, 3))
    low, high = stacked.min(axis=0), stacked.max(axis=0)
    centre, half = (low + high) / 2, max(float((high - low).max()) / 2 * 1.05, 1.0)
    return [[float(c - half), float(c + half)] for c in centre]


def build_figure(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> dict[str, Any]:
    """The plotly figure of a result, as plotly's JSON-ready dict: its layers, a slider over the samples and
    equal axes [mm].

    Parameters
    ----------
    arrays:
        The result's arrays.
    summary:
        The result's summary.

    Returns
    -------
    dict
        ``data`` (per-sample traces first, updated by the slider's ``frames``, then static traces),
        ``layout`` and ``frames``, in plotly's figure schema (written without plotly's validation).
    """
    n, layers = scene_layers(arrays, summary)
    frames = frame_indices(n)
    first = int(frames[0]) if len(frames) else 0
    moving = [i for i, layer in enumerate(layers) if layer.per_sample]
    data = [_trace(layer, layer.points[first] if layer.per_sample else layer.points) for layer in layers]
    layout: dict[str, Any] = {}
    figure: dict[str, Any] = {"data": data, "layout": layout, "frames": []}
    t = np.asarray(arrays["t"]) if "t" in arrays and len(arrays["t"]) == n else None
    labels = [f"t = {t[i]:.3g} s" if t is not None else f"sample {i}" for i in frames]
    if moving and len(frames) > 1:
        figure["frames"] = [
            {"name": str(i), "data": [_moved(layers[k], layers[k].points[i]) for k in moving], "traces": moving}
            for i in frames
        ]
        step = {"mode": "immediate", "frame": {"duration": 0, "redraw": True}, "transition": {"duration": 0}}
        layout.update(
            sliders=[
                {
                    "active": 0,
                    "currentvalue": {"prefix": ""},
                    "x": 0.12,
                    "len": 0.88,
                    "y": 0.0,
                    "yanchor": "top",
                    "pad": {"t": 10},
                    "steps": [
                        {"label": label, "method": "animate", "args": [[str(i)], step]}
                        for i, label in zip(frames, labels)
                    ],
                }
            ],
            updatemenus=[
                {
                    "type": "buttons",
                    "showactive": False,
                    "direction": "left",
                    "x": 0.0,
                    "y": 0.0,
                    "xanchor": "left",
                    "yanchor": "top",
                    "pad": {"t": 20},
                    "buttons": [
                        {
                            "label": "play",
                            "method": "animate",
                            "args": [None, {**step, "frame": {"duration": 60, "redraw": True}, "fromcurrent": True}],
                        },
                        {"label": "pause", "method": "animate", "args": [[None], step]},
                    ],
                }
            ],
        )
    ranges = _axis_ranges(layers)
    layout.update(
        height=720,
        margin={"l": 0, "r": 0, "t": 30, "b": 90},
        legend={"itemsizing": "constant"},
        scene={
            "aspectmode": "cube",
            **{f"{axis}axis": {"title": {"text": f"{axis} [mm]"}, "range": r} for axis, r in zip("xyz", ranges)},
        },
    )
    return figure


def _trace(layer: Layer, points: np.ndarray) -> dict[str, Any]:
    """The plotly trace of ``layer`` showing ``points`` ``(K, 3)`` [m]."""
    trace = {**_moved(layer, points), "name": layer.name, "opacity": layer.opacity}
    trace["visible"] = True if layer.visible else "legendonly"
    if layer.mode == "hull":
        return {**trace, "alphahull": 0, "showlegend": True}
    if layer.mode == "plane":
        return {**trace, "i": [0, 0], "j": [1, 2], "k": [2, 3], "showlegend": True}
    style = {"marker": {"size": layer.size}} if layer.mode == "markers" else {"line": {"width": 5}}
    return {**trace, "mode": layer.mode, **style}


def _moved(layer: Layer, points: np.ndarray) -> dict[str, Any]:
    """The frame update of a per-sample ``layer`` to ``points``: the trace type and coordinates [mm]."""
    return {"type": "mesh3d" if layer.mode in ("hull", "plane") else "scatter3d", **_xyz(points)}


def comparison_html(summary: Mapping[str, Any]) -> str:
    """The summary's comparison as an HTML table (method, role, every flattened metric), or empty."""
    rows = [MethodRow(r["method"], r.get("role", ""), r.get("metrics", {})) for r in summary.get("comparison", [])]
    if not rows:
        return ""
    columns, cells = comparison_rows(rows)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in cells)
    return f'<table id="comparison"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


_STYLE = """
body { font-family: sans-serif; margin: 1em 2em; }
table { border-collapse: collapse; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.5em; text-align: right; }
th { background: #eee; }
td:first-child, td:nth-child(2) { text-align: left; }
#view-errors { color: #a00; white-space: pre-wrap; }
"""

_ERRORS = """
window.addEventListener("error", function (event) {
  var box = document.getElementById("view-errors");
  if (box) { box.textContent += "the 3-D view failed: " + event.message + "\\n"; }
});
"""


def page_html(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any]) -> str:
    """The whole self-contained page: the figure (plotly.js embedded), the comparison, notes and provenance.

    Once plotly has drawn the plot, the ``<body>`` gets ``data-plotted="yes"``; a script error is shown in
    ``#view-errors``.
    """
    pio = _plotly_io()
    figure = build_figure(arrays, summary)
    figure["layout"]["template"] = pio.templates["plotly"].to_plotly_json()  # plotly's default look
    plot = pio.to_html(
        figure,
        validate=False,
        full_html=False,
        include_plotlyjs=True,
        div_id="view-plot",
        auto_play=False,
        config={"responsive": True, "displaylogo": False},
        post_script='document.body.setAttribute("data-plotted", "yes");',
    )
    facts = {
        "problem": summary.get("problem"),
        "kind": summary.get("kind"),
        "solver": summary.get("solver"),
        "samples": summary.get("samples"),
        "statuses": summary.get("status_counts"),
        "succeeded": summary.get("succeeded"),
    }
    fact_items = "".join(
        f"<li><b>{html.escape(k)}</b>: {html.escape(json.dumps(v) if isinstance(v, dict) else format_value(v))}</li>"
        for k, v in facts.items()
        if v is not None
    )
    notes = "".join(f"<li>{html.escape(str(note))}</li>" for note in summary.get("notes", []))
    provenance = html.escape(json.dumps(summary.get("provenance", {}), indent=2))
    title = html.escape(str(summary.get("title") or summary.get("problem", "result")))
    table = comparison_html(summary)
    return (
        "<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
        f"<title>{title}</title>\n<style>{_STYLE}</style>\n<script>{_ERRORS}</script>\n</head>\n<body>\n"
        f"<h1>{title}</h1>\n<ul>{fact_items}</ul>\n<div id='view-errors'></div>\n{plot}\n"
        + (f"<h2>Comparison</h2>\n{table}\n" if table else "")
        + (f"<h2>Notes</h2>\n<ul>{notes}</ul>\n" if notes else "")
        + f"<details><summary>Provenance</summary><pre>{provenance}</pre></details>\n</body>\n</html>\n"
    )


def write_view(folder: Path, out: Path | None = None) -> Path:
    """Write the view of the result in ``folder`` to ``out`` (default ``folder/view.html``); returns the file.

    Parameters
    ----------
    folder:
        A result folder (``result.json``, ``arrays.npz``).
    out:
        The HTML file to write.

    Returns
    -------
    Path
        The written page.

    Raises
    ------
    InputDataError
        ``folder`` is not a result folder, names an unknown kind, or holds no arrays or arrays that
        cannot be shown (:func:`optikin.results.read_result`).
    ViewError
        plotly is not installed, or ``out`` cannot be written.
    """
    folder = Path(folder)
    summary, arrays = read_result(folder)
    result_kind(folder, summary)
    if not arrays:
        raise InputDataError("the result holds no arrays: nothing to show", source=str(folder))
    try:
        page = page_html(arrays, summary)
    except (ValueError, IndexError, KeyError, TypeError) as exc:
        raise InputDataError(
            f"the arrays cannot be shown: {type(exc).__name__}: {exc}", source=str(folder / "arrays.npz")
        ) from None
    target = Path(out) if out is not None else folder / "view.html"
    try:
        target.write_text(page, encoding="utf-8")
    except OSError as exc:
        raise ViewError(f"{target}: cannot write the view: {exc.strerror or exc}") from None
    return target


def _plotly_io() -> Any:
    try:
        import plotly.io as pio
    except ImportError:
        raise ViewError("optikin view needs plotly, a dependency of optikin: pip install 'plotly>=5'") from None
    return pio


def open_in_browser(page: Path) -> bool:
    """Open ``page`` in the user's web browser (:mod:`webbrowser`); False when no browser could be started."""
    import webbrowser

    return webbrowser.open(Path(page).resolve().as_uri())
