"""Problem kind ``fk``: an arm's forward kinematics over a configuration sweep or trajectory.

Evaluates the tip pose (dual quaternion), the end pose of every section and
the backbone for every sample with the chosen evaluation backend, checks the
result (finite, unit dual quaternions), and compares it in the same run with
the ``numpy`` baseline: the same formulas evaluated on vectorised numpy arrays
instead of CasADi. Figures: the backbones in 3-D and the tip over time.

Options (``options:`` in the problem file): none yet.
"""

from __future__ import annotations

import time

import numpy as np

from optikin import plots
from optikin.algebra import dq_from_rotation_translation, dq_norm_residual, dq_translation
import optikin.data.configurations  # noqa: F401 - registers the configuration sources
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.results import MethodRow, Result

MM = 1e3


def _timed(fn, repeats: int = 1):
    """Run ``fn`` ``repeats`` times; return the last value and the median wall time in seconds."""
    times, value = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - start)
    return value, float(np.median(times))


def numpy_tip_dq(arm, Q: np.ndarray) -> np.ndarray:
    """Tip dual quaternions of a batch by the arm's formulas on numpy arrays (the ``numpy`` baseline)."""
    quat, pos = arm.section_frames(Q)[-1]
    return dq_from_rotation_translation(quat, pos)


def run(ctx: ProblemContext) -> Result:
    spec, arm = ctx.spec, ctx.arm
    Q, t = ctx.load_data()
    Q = arm.validate(Q, source=f"{ctx.path.name}: data ({spec.data.source})")
    n = Q.shape[0]
    evaluator = ctx.adapter

    # Build the Functions (and compile them, for compiled backends) before timing.
    t_build = _timed(lambda: [evaluator.evaluate(arm, name, Q[:1]) for name in ("fk_dq", "section_dq", "backbone")])[1]
    with ctx.progress.task(f"fk: {n} samples", total=3) as advance:
        tip, t_tip = _timed(lambda: evaluator.evaluate(arm, "fk_dq", Q)[:, :, 0])
        advance()
        sections, _ = _timed(lambda: evaluator.evaluate(arm, "section_dq", Q).transpose(0, 2, 1))
        advance()
        backbone, _ = _timed(lambda: evaluator.evaluate(arm, "backbone", Q).transpose(0, 2, 1))
        advance()

    finite = np.isfinite(tip).all(axis=1) & np.isfinite(backbone).all(axis=(1, 2))
    norm_err, dot_err = dq_norm_residual(tip)
    unit_error = np.maximum(np.abs(norm_err), np.abs(dot_err))
    status = ["ok" if ok and e < 1e-9 else "failed" for ok, e in zip(finite, unit_error)]
    position = dq_translation(tip)

    comparison = [MethodRow(ctx.solver.name, "solver", {
        "time per sample [us]": t_tip / n * 1e6,
        "max |tip - numpy| [mm]": 0.0,
    })]
    for baseline in spec.baselines:
        if baseline == "numpy":
            reference, t_np = _timed(lambda: numpy_tip_dq(arm, Q))
            comparison.append(MethodRow("numpy", "baseline", {
                "time per sample [us]": t_np / n * 1e6,
                "max |tip - numpy| [mm]": float(np.abs(dq_translation(reference) - position).max() * MM),
            }))
            comparison[0].metrics["max |tip - numpy| [mm]"] = comparison[-1].metrics["max |tip - numpy| [mm]"]

    reach = np.linalg.norm(position, axis=1)
    metrics = {
        "tip x range [mm]": [float(position[:, 0].min() * MM), float(position[:, 0].max() * MM)],
        "tip y range [mm]": [float(position[:, 1].min() * MM), float(position[:, 1].max() * MM)],
        "tip z range [mm]": [float(position[:, 2].min() * MM), float(position[:, 2].max() * MM)],
        "max distance base-tip [mm]": float(reach.max() * MM),
        "max unit-norm error of tip dual quaternion": float(unit_error.max()),
    }
    arrays = {"configurations": Q, "tip_dq": tip, "tip_position": position, "section_dq": sections,
              "backbone": backbone}
    if t is not None:
        arrays["t"] = t
    section_ends = dq_translation(sections)

    def draw_backbones(path):
        plots.backbones_3d(path, backbone, f"{spec.name}: backbones ({arm.name})", section_ends)

    def draw_tip(path):
        if t is not None:
            plots.time_series(path, t, {"tip position": position * MM}, "[mm]", f"{spec.name}: tip position")
        else:
            plots.scatter_3d(path, position, f"{spec.name}: tip positions", colour=reach * MM,
                             colour_label="distance from base [mm]")

    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=arm.describe(),
        status=status,
        residuals=unit_error,
        timings={"build [s]": t_build, "fk_dq total [s]": t_tip, "per sample [us]": t_tip / n * 1e6},
        metrics=metrics, comparison=comparison, arrays=arrays,
        figures={"backbones": draw_backbones, "tip": draw_tip},
    )


register_kind(ProblemKind(
    options=None,
    name="fk",
    summary="forward kinematics over a configuration sweep or trajectory",
    run=run,
    backend_families=("evaluation",),
    default_solver="casadi-map",
    baselines=("numpy",),
    data_family="configurations",
))
