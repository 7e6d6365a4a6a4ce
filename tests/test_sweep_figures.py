"""Sweep figures: one per (metric, swept axis), every method a line at the median over the seeds, the
min-max band over the seeds, log x over a decade, the unit in the y label, the legend outside."""

from __future__ import annotations

import itertools
import statistics

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest

from optikin.sweep.spec import SweepSpec
from optikin.sweep.store import MAX_PANELS, draw_figure, figure_plans, write_figures

NOISE = [1e-4, 1e-3, 1e-2]
OUTSIDE = [0, 2]
SEEDS = [0, 1, 2]
METHODS = {"solver": "solver: error [mm]", "cc-arc": "cc-arc: error [mm]", "ph-ipopt": "ph-ipopt: error [mm]"}


def _spec(axes: dict[str, list]) -> SweepSpec:
    return SweepSpec(name="demo", title="t", problem="cc-ik-position", axes=axes, metrics=["error [mm]", "rate [%]"])


def _rows(axes: dict[str, list], seed: int = 0) -> list[dict]:
    """Table rows with random metrics per method; ``cc-arc`` has no number in one cell (it failed there)."""
    rng = np.random.default_rng(seed)
    rows = []
    for index, values in enumerate(itertools.product(*axes.values())):
        row = {"index": index, "key": f"k{index}"} | dict(zip(axes, values))
        row |= {"status": "done", "tries": 1, "succeeded": True}
        row |= {column: float(rng.uniform(0, 10) + 20 * k) for k, column in enumerate(METHODS.values())}
        row["rate [%]"] = float(rng.uniform(0, 100))
        row["per marker [mm]"] = [1.0, 2.0]
        row |= {"reason": "", "elapsed [s]": 0.1}
        rows.append(row)
    rows[4]["cc-arc: error [mm]"] = None
    return rows


def _lines(ax) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {line.get_label(): (np.asarray(line.get_xdata()), np.asarray(line.get_ydata())) for line in ax.lines}


def _expected(rows, column, axis, fixed: dict) -> tuple[list, list, list]:
    """Median, min and max of ``column`` per value of ``axis`` over the rows matching ``fixed``."""
    med, low, high = [], [], []
    for value in dict.fromkeys(r[axis] for r in rows):
        ys = [
            r[column]
            for r in rows
            if r[axis] == value and r[column] is not None and all(r[a] == v for a, v in fixed.items())
        ]
        med.append(statistics.median(ys))
        low.append(min(ys))
        high.append(max(ys))
    return med, low, high


def test_one_figure_per_metric_and_axis_with_every_method_at_its_median():
    axes = {"data.params.noise": NOISE, "data.params.unreachable": OUTSIDE, "data.seed": SEEDS}
    spec, rows = _spec(axes), _rows(axes)
    plans = figure_plans(spec, rows)
    assert [(p.metric, p.axis) for p in plans] == [
        (m, a) for m in ("error [mm]", "rate [%]") for a in ("data.params.noise", "data.params.unreachable")
    ]
    for plan in plans:
        fig = draw_figure(spec, plan)
        others = [a for a in ("data.params.noise", "data.params.unreachable") if a != plan.axis]
        panels = [ax for ax in fig.axes if ax.lines]
        assert len(panels) == len(axes[others[0]])
        methods = METHODS if plan.metric == "error [mm]" else {"solver": "rate [%]"}
        for ax, other in zip(panels, axes[others[0]]):
            assert ax.get_title() == f"{others[0]}={other}"
            lines = _lines(ax)
            assert sorted(lines) == sorted(methods)
            for method, column in methods.items():
                x, y = lines[method]
                med, low, high = _expected(rows, column, plan.axis, {others[0]: other})
                np.testing.assert_allclose(x, axes[plan.axis])
                np.testing.assert_allclose(y, med, rtol=1e-12)
            bands = [np.asarray(c.get_paths()[0].vertices) for c in ax.collections]
            assert len(bands) == len(methods)
            for band, column in zip(bands, methods.values()):
                _, low, high = _expected(rows, column, plan.axis, {others[0]: other})
                assert band[:, 1].min() == pytest.approx(min(low)) and band[:, 1].max() == pytest.approx(max(high))
        assert panels[0].get_xscale() == ("log" if plan.axis == "data.params.noise" else "linear")
        assert ("[mm]" if plan.metric == "error [mm]" else "[%]") in panels[0].get_ylabel()
        assert len(fig.legends) == 1 and "over data.seed" in fig.legends[0].get_title().get_text()
        plt.close(fig)


def test_solver_and_baselines_are_styled_apart():
    axes = {"data.params.noise": NOISE, "data.seed": SEEDS}
    spec = _spec(axes)
    plan = figure_plans(spec, _rows(axes))[0]
    fig = draw_figure(spec, plan)
    lines = {line.get_label(): line for line in fig.axes[0].lines}
    assert lines["solver"].get_linestyle() == "-"
    assert all(lines[m].get_linestyle() != "-" for m in ("cc-arc", "ph-ipopt"))
    assert len({line.get_color() for line in lines.values()}) == 3
    plt.close(fig)


def test_many_combinations_of_the_other_axes_are_pooled_with_the_seeds():
    axes = {"data.params.noise": NOISE, "arm.params.n": list(range(MAX_PANELS + 1)), "data.seed": [0, 1]}
    spec, rows = _spec(axes), _rows(axes)
    plan = next(p for p in figure_plans(spec, rows) if p.axis == "data.params.noise")
    assert plan.pooled == ("arm.params.n",)
    fig = draw_figure(spec, plan)
    (ax,) = [a for a in fig.axes if a.lines]
    _, y = _lines(ax)["solver"]
    np.testing.assert_allclose(y, _expected(rows, "solver: error [mm]", "data.params.noise", {})[0], rtol=1e-12)
    plt.close(fig)


def test_write_figures_names_one_file_per_metric_and_axis(tmp_path):
    axes = {"data.params.noise": NOISE, "data.params.unreachable": OUTSIDE, "data.seed": SEEDS}
    drawn = write_figures(tmp_path, _spec(axes), _rows(axes))
    assert sorted(p.name for p in drawn) == sorted(
        f"{m}--vs--{a}.png" for m in ("error-mm", "rate") for a in ("data-params-noise", "data-params-unreachable")
    )
    assert all(p.stat().st_size > 0 for p in drawn)
