"""Figures people can read: checked on the matplotlib Figure objects the kinds' drawers build.

Legends cover no data (the tracking tip figure, in display coordinates), every limit line has a legend
entry, curves that lie on one another stay distinguishable and say so, every y label holds one unit, 3-D
axes have one scale on every axis (box aspect = data extent) and a colour bar explaining their colours,
and a controller name the style has never seen gets a style of its own. The data are synthetic, made to
fill the axes, so a legend placed inside would cover some of them.
"""

from __future__ import annotations

import re
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from mpl_toolkits.mplot3d import Axes3D  # noqa: E402

from optikin import plots  # noqa: E402
from optikin.problems.calibrate import figures as calibrate_figures  # noqa: E402
from optikin.problems.dmp import figures as dmp_figures  # noqa: E402
from optikin.problems.fk import figures as fk_figures  # noqa: E402
from optikin.problems.ik import figures as ik_figures  # noqa: E402
from optikin.problems.ph_chain import figures as ph_chain_figures  # noqa: E402
from optikin.problems.ph_ik import figures as ph_ik_figures  # noqa: E402
from optikin.problems.ph_shape import figures as ph_shape_figures  # noqa: E402
from optikin.problems.statics import figures as statics_figures  # noqa: E402
from optikin.problems.tracking import figures as tracking_figures  # noqa: E402

N = 150
T = np.linspace(0.0, 3.0, N)
NAMES = ["S1", "theta1", "phi1", "S2", "theta2", "phi2"]
LOWER = [0.162, -2.09, -np.pi, 0.162, -2.09, -np.pi]
UPPER = [0.198, 2.09, np.pi, 0.198, 2.09, np.pi]


@pytest.fixture
def drawn(monkeypatch, tmp_path):
    """``draw(drawer) -> Figure``: runs a drawer with ``plt.close`` held back and returns the figure it drew.

    Saving only lays the figure out and draws it on its canvas (no PNG is encoded), which keeps these tests fast.
    """
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda *args, **kwargs: None)
    monkeypatch.setattr(Figure, "savefig", lambda self, *args, **kwargs: self.canvas.draw())

    def draw(drawer) -> Figure:
        before = set(plt.get_fignums())
        drawer(tmp_path / "figure.png")
        (new,) = set(plt.get_fignums()) - before
        return plt.figure(new)

    yield draw
    close("all")


def wave(phase: float, amplitude: float = 1.0) -> np.ndarray:
    """A curve that sweeps its axes' whole range several times."""
    return amplitude * np.sin(2 * np.pi * 2.3 * T / T[-1] + phase)


def tracking_result(extra: tuple[str, ...] = ()) -> tuple[dict[str, np.ndarray], dict]:
    """Arrays and summary of a pose-tracking run of ``qp`` and three baselines whose configurations coincide."""
    reference = np.stack([0.2 + 0.1 * wave(0.0), 0.05 * wave(1.0), 0.25 + 0.08 * wave(2.0)], axis=1)
    arrays: dict[str, np.ndarray] = {"t": T, "reference_position": reference}
    q_common = np.stack(
        [0.18 + 0.03 * wave(0.3), 1.9 * wave(0.1), wave(0.2), 0.18 + 0.03 * wave(0.5)] + [wave(0.7)] * 2, 1
    )
    controllers = {"qp": 0.0, "mrac": 1e-9, "pseudo_inverse": 0.0, "damped_least_squares": 2e-9} | dict.fromkeys(
        extra, 0.02
    )
    for name, offset in controllers.items():
        q = q_common + (0.01 if name == "qp" else offset)
        arrays[f"q_{name}"] = q
        arrays[f"x_{name}"] = reference + (0.002 if name == "qp" else offset)
        arrays[f"V_{name}"] = 1e-6 * (1.5 + wave(0.4)) + offset
        arrays[f"step_time_{name}"] = 2e-5 * (1.5 + wave(0.1))
    rows = [{"method": "qp (osqp)", "role": "solver"}]
    rows += [{"method": m, "role": "baseline"} for m in ("mrac", "pseudo-inverse", "damped least squares", *extra)]
    summary = {
        "problem": "synthetic",
        "arm": {"config_names": NAMES, "lower": LOWER, "upper": UPPER},
        "comparison": rows,
    }
    return arrays, summary


def legends(fig: Figure) -> list:
    return list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]


def legend_texts(fig: Figure) -> set[str]:
    return {text.get_text() for legend in legends(fig) for text in legend.get_texts()}


def data_axes(fig: Figure) -> list:
    """The axes that hold data (colour bars left out)."""
    return [ax for ax in fig.axes if getattr(ax, "_colorbar", None) is None]


def test_the_tracking_tip_figure_has_its_legend_clear_of_every_curve(drawn):
    arrays, summary = tracking_result()
    fig = drawn(tracking_figures.figures(arrays, summary)["tracking"])
    renderer = fig.canvas.get_renderer()
    boxes = [legend.get_window_extent(renderer) for legend in legends(fig)]
    assert boxes, "the tip figure has no legend"
    for ax in data_axes(fig):
        for line in ax.get_lines():
            xy = line.get_transform().transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
            for box in boxes:
                inside = (xy[:, 0] > box.x0) & (xy[:, 0] < box.x1) & (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1)
                assert not inside.any(), f"the legend covers {inside.sum()} points of {line.get_label()!r}"


def test_every_limit_line_of_the_limits_figure_is_in_the_legend(drawn):
    arrays, summary = tracking_result()
    fig = drawn(tracking_figures.figures(arrays, summary)["limits"])
    texts = legend_texts(fig)
    found = 0
    for ax in data_axes(fig):
        bounds = []
        for line in ax.get_lines():
            x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
            if len(y) == 2 and y[0] == y[1] and list(x) == [0.0, 1.0]:  # an axhline
                bounds.append(y[0])
                assert line.get_label() in texts, f"limit line at {y[0]:g} has no legend entry"
        found += len(bounds)
        scale = 1e3 if ax.get_ylabel().startswith("S") else 180.0 / np.pi
        name = ax.get_ylabel().split(" ")[0]
        i = NAMES.index(name)
        assert sorted(bounds) == pytest.approx(sorted([LOWER[i] * scale, UPPER[i] * scale]))
    assert found == 8  # S1, theta1, S2, theta2, two bounds each


def test_coinciding_baselines_stay_distinguishable_and_say_so(drawn):
    arrays, summary = tracking_result()
    fig = drawn(tracking_figures.figures(arrays, summary)["limits"])
    ax = data_axes(fig)[0]
    lines = {line.get_label(): line for line in ax.get_lines() if not line.get_label().startswith("_")}
    baselines = [label for label in lines if label.startswith(("mrac", "pseudo-inverse", "damped least squares"))]
    assert len(baselines) == 3
    looks = {(str(lines[b].get_linestyle()), lines[b].get_marker(), lines[b].get_color()) for b in baselines}
    assert len(looks) == 3, "the three baselines look alike"
    for b in baselines:
        marks = lines[b].get_markevery()
        assert lines[b].get_marker() not in (None, "None", "") and marks is not None
    assert len({lines[b].get_markevery() for b in baselines}) == 3, "their markers sit on one another"
    assert {b for b in baselines if "on mrac's curve" in b} == {b for b in baselines if not b.startswith("mrac")}


def test_a_controller_name_never_seen_gets_a_style_of_its_own(drawn):
    arrays, summary = tracking_result(extra=("mpc",))
    fig = drawn(tracking_figures.figures(arrays, summary)["errors"])
    ax = data_axes(fig)[0]
    looks = [(str(line.get_linestyle()), line.get_marker(), line.get_color()) for line in ax.get_lines()]
    assert len(looks) == 5 and len(set(looks)) == 5
    many = [f"model {k}" for k in range(20)]
    styles = plots.method_styles(many, {many[0]: "solver"})
    assert len({(s.get("marker"), s["color"]) for s in styles.values()}) == 20, "colour and marker repeat together"


def dmp_result() -> tuple[dict[str, np.ndarray], dict]:
    """A demonstration and the reproductions of a dual-quaternion and a quaternion variant."""
    from optikin.algebra import dq_from_rotation_translation

    half = 0.3 * wave(0.0)
    quaternion = np.stack([np.cos(half), np.sin(half), 0 * half, 0 * half], axis=1)
    position = np.stack([0.1 * wave(0.0), 0.1 * wave(1.0), 0.3 + 0 * T], axis=1)
    noisy = quaternion + 1e-3 * np.stack([0 * T, 0 * T, wave(2.0), 0 * T], axis=1)
    noisy /= np.linalg.norm(noisy, axis=1, keepdims=True)
    arrays = {
        "t": T,
        "demo_position": position,
        "demo_quaternion": quaternion,
        "dual-quaternion__reproduction": dq_from_rotation_translation(noisy, position + 1e-3, check=False),
        "quaternion__reproduction": noisy,
    }
    return arrays, {"problem": "synthetic"}


def test_every_panel_of_the_dmp_errors_has_its_own_unit(drawn):
    arrays, summary = dmp_result()
    fig = drawn(dmp_figures.figures(arrays, summary)["reproduction_error"])
    labels = [ax.get_ylabel() for ax in data_axes(fig)]
    assert len(labels) == 3
    for label in labels:
        assert "|" not in label
        assert label.endswith("[mm]") == ("position" in label) and label.endswith("[mrad]") == ("orientation" in label)


def ph_arrays() -> dict[str, np.ndarray]:
    """PH shapes of 8 postures: a flat fan (x, y ~ 200 mm, z ~ 20 mm), its markers and ground truth."""
    s = np.linspace(0.0, 1.0, 30)
    angle = np.linspace(-1.0, 1.0, 8)
    curves = np.stack([np.stack([0.2 * s * np.cos(a), 0.2 * s * np.sin(a), 0.02 * s**2], axis=1) for a in angle])
    return (
        {
            "ph_points": curves,
            "markers": curves[:, [10, 20]],
            "base_position": curves[:, 0],
            "tip_position": curves[:, -1],
            "vertebrae": curves[:, ::3] + 1e-3,
            "marker_distance": np.abs(curves[:, [10, 20], 2]),
            "seconds_ph-newton": np.full(8, 1e-4),
            "seconds_ph-ipopt": np.full(8, 1e-3),
            "tube_lengths": np.full((8, 3), 0.2),
            "reference_tube_lengths": np.full((8, 3), 0.201),
            "ik_seconds_ph-newton": np.full(8, 1e-4),
        }
        | {
            f"{k}_{part}": v
            for k in ("arm1", "rope", "arm2")
            for part, v in (("ph_points", curves), ("markers", curves[:, [10, 20]]))
        }
        | {
            "arm1_vertebrae": curves,
            "rope_truth": curves,
            "arm2_vertebrae": curves,
        }
        | {f"{k}_marker_distance": np.abs(curves[:, [10, 20], 2]) for k in ("arm1", "rope", "arm2")}
    )


def three_d_figures() -> dict[str, Any]:
    """Every 3-D figure a kind draws, from synthetic arrays that are far flatter along z than along x and y."""
    ph = ph_arrays()
    summary = {"problem": "synthetic", "solver": "ph-newton", "comparison": [{"method": "m", "role": "solver"}]}
    backbone = ph["ph_points"]
    rng = np.random.default_rng(0)
    measured = backbone[:, [10, 20, 29]] + 1e-3 * rng.standard_normal((8, 3, 3))
    arrays, tracking_summary = tracking_result()
    k = 3
    arrays |= {
        "snapshot_t": np.array([0.0, 1.0, 2.0]),
        "snapshot_obstacles": np.stack([backbone[0] + [0.0, 0.05, 0.0]] * k),
        "snapshot_backbone_qp": np.stack([backbone[j].T for j in range(k)]),
        "snapshot_backbone_mrac": np.stack([backbone[j + 3].T for j in range(k)]),
        "clearance_qp": 0.02 + 0.01 * wave(0.0),
        "clearance_mrac": 0.01 * wave(1.0),
        "barrier_margin": np.array([0.01]),
    }
    return {
        "fk backbones": fk_figures.figures({"backbone": backbone, "t": np.arange(8.0)}, {"problem": "p"})["backbones"],
        "fk tip positions": fk_figures.figures({"tip_position": backbone[:, -1]}, {"problem": "p"})["tip"],
        "statics backbones": statics_figures.figures({"backbone": backbone}, {"problem": "p"})["backbones"],
        "ph_shape shapes": ph_shape_figures.figures(ph, summary)["shapes"],
        "ph_chain shapes": ph_chain_figures.figures(ph, summary)["shapes"],
        "calibrate markers": calibrate_figures.figures(
            {"measured": measured, "backbone": backbone.transpose(0, 2, 1), "outlier": np.arange(8) == 3}, summary
        )["markers"],
        "ik targets": lambda path: ik_figures.draw_targets(path, backbone[:, -1], np.full(8, 1e-9), "targets"),
        "tracking obstacles": tracking_figures.figures(arrays, tracking_summary)["obstacles"],
    }


@pytest.mark.parametrize("name", list(three_d_figures()))
def test_3d_axes_have_one_scale_and_explain_their_colours(drawn, name):
    fig = drawn(three_d_figures()[name])
    spaces = [ax for ax in fig.axes if isinstance(ax, Axes3D)]
    assert spaces
    for ax in spaces:
        span = np.array([np.ptp(ax.get_xlim3d()), np.ptp(ax.get_ylim3d()), np.ptp(ax.get_zlim3d())])
        box = np.asarray(ax.get_box_aspect(), dtype=float)
        assert span / span.max() == pytest.approx(box / box.max(), rel=1e-6), f"{name}: unequal axis scales"
        assert span[2] < 0.5 * span[:2].max(), f"{name}: the limits are not the data's extent"
        for axis in (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()):
            assert axis.endswith("[mm]"), f"{name}: axis label {axis!r}"
        colours = {
            tuple(np.round(line.get_color(), 6)) if not isinstance(line.get_color(), str) else line.get_color()
            for line in ax.get_lines()
        }
        colours |= {tuple(np.round(c, 6)) for art in ax.collections for c in np.atleast_2d(art.get_facecolor())}
        if len(colours) > 2:
            assert any(getattr(a, "_colorbar", None) is not None for a in fig.axes), f"{name}: colours unexplained"


def two_d_figures() -> dict[str, Any]:
    """Every 2-D figure of the synthetic results."""
    arrays, summary = tracking_result()
    dmp_arrays, dmp_summary = dmp_result()
    ph = ph_arrays()
    ph_summary = {"problem": "synthetic", "solver": "ph-newton"}
    out = {f"tracking {k}": v for k, v in tracking_figures.figures(arrays, summary).items() if k != "obstacles"}
    out |= {f"dmp {k}": v for k, v in dmp_figures.figures(dmp_arrays, dmp_summary).items()}
    out |= {f"ph_shape {k}": v for k, v in ph_shape_figures.figures(ph, ph_summary).items() if k != "shapes"}
    out |= {f"ph_chain {k}": v for k, v in ph_chain_figures.figures(ph, ph_summary).items() if k != "shapes"}
    out |= {f"ph_ik {k}": v for k, v in ph_ik_figures.figures(ph, ph_summary).items()}
    out["fk tip"] = fk_figures.figures({"tip_position": ph["tip_position"], "t": np.arange(8.0)}, {"problem": "p"})[
        "tip"
    ]
    errors = np.abs(np.random.default_rng(1).standard_normal((40, 3))) * 1e-3
    out["calibrate residuals"] = calibrate_figures.figures(
        {"errors": errors, "held_out_errors": errors * 1.1, "outlier": np.arange(40) == 5},
        {"problem": "synthetic", "metrics": {"markers": "disk1, disk2, disk3"}},
    )["residuals"]
    return out


@pytest.mark.parametrize("name", list(two_d_figures()))
def test_2d_panels_have_unit_labels_and_legends_outside_the_data(drawn, name):
    fig = drawn(two_d_figures()[name])
    renderer = fig.canvas.get_renderer()
    axes = data_axes(fig)
    assert axes[-1].get_xlabel(), f"{name}: no x label"
    for ax in axes:
        label = ax.get_ylabel()
        assert "|" not in label and re.search(r"\[[^\[\]|]+\]$", label), f"{name}: y label {label!r}"
        frame = ax.get_window_extent(renderer)
        for legend in legends(fig):
            box = legend.get_window_extent(renderer)
            assert not frame.overlaps(box), f"{name}: a legend lies over a panel"
