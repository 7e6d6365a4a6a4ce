"""Problem kinds ``nn_fkm`` and ``nn_ikm``: the hybrid networks of seed 004 against exact solvers.

Seed 004 replaces the numerical solution of the kinematic equations by networks
because "least square, Newton-Raphson methods [...] are usually computationally
intensive" (section IV-A). The baselines are those methods: any solver preset of
the ``nonlinear`` family (``newton``, ``gauss-newton``, ``lm``, ``trf``, ``ipopt``,
``sqpmethod``, or a user's own), on the inverse problems of
:mod:`optikin.ik.platform` and :mod:`optikin.ik.formulation`, on the
first ``exact_samples`` held-out samples.

``nn_fkm`` (seed 004 section IV, Fig. 9, Table II): a forward network per
section predicts the platform variables from the leg lengths; the tip follows
by the exact chain of eq. (5). A baseline solves eqs. (7)-(9) of every platform
from their linearisation (:func:`~optikin.ik.platform.linearised_start`).

``nn_ikm`` (section V, Fig. 10, Table III, eq. 11): NN1-NN4 predict the platform
variables from the tip position, eqs. (7)-(9) turn them into leg lengths. A
baseline solves the tip-position IK for the admissible configuration nearest the
straight mid-range pose (redundancy ``rest``, every leg within Table I), from that
pose. Every method's lengths are clipped to Table I and realised through the exact
forward kinematics (:func:`~optikin.ik.platform.realise`, Newton on every
platform) before its tip error is measured.

Every MSE is on the test split of the database; every tip error is the
distance between the exact forward kinematics of a method's configuration and
the held-out arm's tip. Per-sample status: ``ok`` when the first variant's tip
is finite, ``failed`` otherwise; the residual is its tip error [m]. A solver's
row gives its share of ``ok`` samples; a sample without a finite tip is counted,
never dropped.

``data`` (source ``fig7``, :mod:`optikin.baselines.nn_database`)::

    data:
      source: fig7
      seed: 2016                # every draw and the split
      samples: 1500000          # candidate draws per platform
      params:
        z_range_mm: [0, 25]     # the wide box of Fig. 7
        angle_range_deg: [-45, 45]
        require_upright: true
        coupling: platform      # or section
        split: [0.7, 0.15, 0.15]

``options`` (all optional)::

    variants: [seed, adam]      # training settings (optikin.baselines.nn_models.SETTINGS)
    setting: full               # or small: two widths, 15 epochs (tests, notebooks)
    penalty: 1.0e-3             # lambda of eq. (11), nn_ikm only
    store: null                 # folder of trained models (relative to the working directory):
                                # loaded when it matches the problem, otherwise trained and written
    exact_samples: 200          # test samples given to the exact solvers (the first ones)
    latency_repeats: 50         # one-sample calls timed for the latency
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Literal

import matplotlib.pyplot as plt
import numpy as np
from pydantic import Field

from optikin.arms.cbha import CBHAArm
from optikin.baselines.nn_database import DatabaseSpec, Fig7Params, LearningDatabase
from optikin.baselines.nn_models import (
    SETTINGS, Task, TrainedModel, TrainingSetting, forward_tasks, hybrid_forward_configurations,
    hybrid_inverse_configurations, inverse_tasks, split_mse, split_rmse_by_variable, train_model)
from optikin.baselines.nn_store import load_models, save_models
from optikin.options import Options, validate_options
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.ik.platform import linearised_start, platform_problems, realise, solve_platforms
from optikin.results import MethodRow, Result
from optikin.solvers import build_preset
from optikin.solvers.base import SolutionBatch

MM = 1e3
BATCH_REPEATS = 5
"""Calls of a batched method whose median time is reported."""
PLATFORM_TOLERANCE = 1e-12
"""Largest leg-length residual [m] of a solved platform (eqs. 7-9)."""
TIP_TOLERANCE = 1e-10
"""Largest tip error [m] of a solved tip-position IK."""
REALISER = "newton"
"""The solver preset that finds the pose commanded leg lengths produce (:func:`realise`)."""
SettingName = Literal["seed", "adam", "adam-wide"]
"""A training setting of :data:`optikin.baselines.nn_models.SETTINGS`."""


class NNOptions(Options):
    """``options`` of the ``nn_fkm`` and ``nn_ikm`` kinds."""

    variants: tuple[SettingName, ...] = Field(
        ("seed", "adam"), min_length=1, description="training settings, one trained variant each "
                                                    "(optikin.baselines.nn_models.SETTINGS)")
    setting: Literal["full", "small"] = Field(
        "full", description="full: the settings as named; small: two widths, at most 15 epochs (tests, notebooks)")
    penalty: float = Field(1e-3, ge=0, description="lambda of eq. (11) (nn_ikm only)")
    store: str | None = Field(None, description="folder of trained models (relative to the working directory): "
                                                "loaded when it matches the problem, otherwise trained and written")
    exact_samples: int = Field(200, ge=1, description="test samples given to the exact solvers (the first ones)")
    latency_repeats: int = Field(50, ge=1, description="one-sample calls timed for the latency")


# ---------------------------------------------------------------------------------------- reading the file
def database_spec(ctx: ProblemContext) -> DatabaseSpec:
    """The :class:`DatabaseSpec` of the problem's ``data`` section (its ``data.params`` validated
    against :class:`Fig7Params` when ``ctx`` was built by hand)."""
    params = ctx.data_params
    if not isinstance(params, Fig7Params):
        params = validate_options(Fig7Params, ctx.spec.data.params, ctx.path, "data.params")
    return params.database_spec(ctx.spec.data)


def options(ctx: ProblemContext) -> NNOptions:
    """The validated options of ``ctx`` (validated here when ``ctx`` was built by hand)."""
    if isinstance(ctx.options, NNOptions):
        return ctx.options
    return validate_options(NNOptions, ctx.spec.options, ctx.path, "options")


def settings_of(o: NNOptions) -> list[TrainingSetting]:
    return [SETTINGS[n].small() if o.setting == "small" else SETTINGS[n] for n in o.variants]


def cbha_arm(ctx: ProblemContext) -> CBHAArm:
    if not isinstance(ctx.arm, CBHAArm):
        raise ctx.error("arm.type", f"the nn kinds model the CBHA of seed 004, not {ctx.arm.name!r}")
    return ctx.arm


# ---------------------------------------------------------------------------------------- models
def obtain_models(ctx: ProblemContext, db: LearningDatabase, tasks: list[Task], setting: TrainingSetting,
                  penalty: float, store: str | None, label: str) -> tuple[list[TrainedModel], bool]:
    """Models of ``tasks``: loaded from ``store/label`` when it exists, else trained (and saved there)."""
    penalties = {t.key: (penalty if t.penalised else 0.0) for t in tasks}
    folder = Path(store) / label if store else None
    if folder is not None and folder.exists():
        required = {t.key: (setting, penalties[t.key]) for t in tasks}
        return load_models(folder, db.geometry, db.spec, required), False
    models = []
    with ctx.progress.task(f"training {label}: {len(tasks)} models x {len(setting.neurons)} widths",
                           total=len(tasks) * len(setting.neurons)) as advance:
        for task in tasks:
            models.append(train_model(task, db, setting, penalties[task.key], on_width=lambda n, v: advance()))
    if folder is not None:
        save_models(folder, models, db)
    return models, True


def timed(fn: Callable[[], Any], repeats: int = 1) -> tuple[Any, float]:
    """The value of ``fn()`` and the median wall time of ``repeats`` calls [s]."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - start)
    return value, float(np.median(times))


def latency(fn: Callable[[np.ndarray], Any], inputs: np.ndarray, repeats: int) -> float:
    """Median seconds of ``fn`` on one sample, over ``repeats`` samples (after one warm-up call)."""
    fn(inputs[:1])
    times = []
    for i in range(repeats):
        row = inputs[i % len(inputs): i % len(inputs) + 1]
        start = time.perf_counter()
        fn(row)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def error_stats(errors: np.ndarray) -> dict[str, float]:
    """Mean, median, 95th percentile and max of the finite tip errors given in metres, in millimetres,
    and how many samples have none (a failed solve)."""
    e = np.asarray(errors) * MM
    finite = e[np.isfinite(e)]
    stats = {"samples without a tip": int(e.size - finite.size)}
    if finite.size:
        stats |= {"tip error mean [mm]": float(finite.mean()), "tip error median [mm]": float(np.median(finite)),
                  "tip error p95 [mm]": float(np.percentile(finite, 95)), "tip error max [mm]": float(finite.max())}
    return stats


def model_metrics(label: str, models: list[TrainedModel], db: LearningDatabase) -> dict[str, Any]:
    """One entry per model (``"<label> <task>"``) and one for its width search, test split only."""
    out: dict[str, Any] = {}
    for m in models:
        seed = m.task.seed_reference
        _, Y = m.task.arrays(db, db.test)
        out[f"{label} {m.task.key}"] = {
            "neurons": m.neurons,
            "test MSE": split_mse(m, db, "test"),
            "test output variance": float(Y.var(axis=0).mean()),
            "seed 004 (neurons, test MSE)": list(seed) if seed else None,
            "test RMSE": split_rmse_by_variable(m, db, "test"),
            "training time [s]": m.training_time,
        }
        out[f"{label} {m.task.key} validation criterion per width"] = {str(n): v for n, v in m.search.items()}
    return out


# ---------------------------------------------------------------------------------------- figures
def draw_search(path: Path, searches: dict[str, dict[int, float]], title: str) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for label, search in searches.items():
        widths = sorted(search)
        ax.semilogy(widths, [search[n] for n in widths], "o-", label=label)
    ax.set_xlabel("neurons per hidden layer")
    ax.set_ylabel("validation criterion (MSE, + eq. 11 penalty), SI units")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def draw_tip_errors(path: Path, errors: dict[str, np.ndarray], title: str) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    labels = list(errors)
    data = [np.maximum(errors[k][np.isfinite(errors[k])] * MM, 1e-12) for k in labels]  # failures: in the table
    ax.boxplot(data, showfliers=True)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=20, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("tip error through exact FK [mm]")
    ax.set_title(title)
    ax.grid(True, which="both", axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------------------------------- nn_fkm
def prepare(ctx: ProblemContext) -> tuple[CBHAArm, NNOptions, LearningDatabase, float]:
    """Either kind's checked inputs: the arm, the options, the learning database of the ``data``
    section and the seconds it took to build. The networks are the method under test, so a
    ``solver`` is refused: exact solvers are named as baselines."""
    arm = cbha_arm(ctx)
    if ctx.solver is not None:
        raise ctx.error("solver", f"{ctx.solver.name!r}: the nn kinds train networks; list the exact solver "
                                  "presets to compare with under baselines")
    o = options(ctx)
    db, seconds = timed(ctx.load_data)
    return arm, o, db, seconds


def network_row(label: str, models: list[TrainedModel], db: LearningDatabase, trained: bool,
                hybrid: Callable[[np.ndarray], Any], inputs: np.ndarray, errors: np.ndarray,
                o: NNOptions, metrics: dict[str, Any], extra: dict[str, Any] | None = None) -> MethodRow:
    """The comparison row of one trained variant (its model metrics are added to ``metrics``)."""
    hybrid(inputs[:1])
    _, seconds = timed(lambda: hybrid(inputs), BATCH_REPEATS)
    mm = model_metrics(label, models, db)
    metrics |= {f"{label} setting": models[0].setting.description, f"{label} loaded from store": not trained, **mm}
    row = {f"test MSE {m.task.key}": mm[f"{label} {m.task.key}"]["test MSE"] for m in models}
    row |= {f"neurons {m.task.key}": m.neurons for m in models}
    row |= error_stats(errors) | (extra or {})
    row |= {"time per sample, batch [us]": seconds / len(inputs) * 1e6,
            "latency, one sample [us]": latency(hybrid, inputs, o.latency_repeats) * 1e6,
            "training time [s]": sum(m.training_time for m in models)}
    return MethodRow(label, "solver", row)


def solver_row(name: str, report: SolutionBatch, errors: np.ndarray, seconds: float,
               extra: dict[str, Any]) -> MethodRow:
    """The comparison row of an exact solver preset on ``len(report)`` samples."""
    return MethodRow(name, "baseline", {
        "samples": len(report), "ok [%]": float(100 * np.mean(np.array(report.status) == "ok")),
        **error_stats(errors), **extra, "batched": report.batched,
        "time per sample [us]": seconds / len(report) * 1e6})


def comparison_result(ctx: ProblemContext, arm: CBHAArm, comparison: list[MethodRow], errors: dict[str, np.ndarray],
                      searches: dict[str, dict[int, float]], metrics: dict[str, Any], arrays: dict[str, np.ndarray],
                      t_db: float, what: str, note: str) -> Result:
    """The result of either kind: the first network variant is the method, every row a comparison."""
    spec, main = ctx.spec, comparison[0].method
    title = f"{spec.name}: hybrid {what} vs exact"
    return Result(
        problem=spec.name, kind=spec.kind, solver=main, title=spec.title, arm=arm.describe(),
        status=["ok" if np.isfinite(e) else "failed" for e in errors[main]], residuals=errors[main],
        timings={"database [s]": t_db}, metrics=metrics, comparison=comparison, arrays=arrays,
        figures={"search": lambda p: draw_search(p, searches, f"{spec.name}: width search"),
                 "tip_errors": lambda p: draw_tip_errors(p, errors, title)},
        notes=[note],
    )


def run_fkm(ctx: ProblemContext) -> Result:
    spec, (arm, o, db, t_db) = ctx.spec, prepare(ctx)
    test = db.test
    legs, truth_tip = db.leg_lengths[test], db.tip[test]
    n = len(test)

    comparison, searches, errors, arrays = [], {}, {}, {}
    metrics: dict[str, Any] = {"database": db.summary(), "database time [s]": t_db, "test samples": n}
    for setting in settings_of(o):
        models, trained = obtain_models(ctx, db, forward_tasks(db), setting, 0.0, o.store, f"fkm-{setting.name}")

        def hybrid(L, models=models):
            return arm.evaluate("fk_position", hybrid_forward_configurations(models, L))

        Q = hybrid_forward_configurations(models, legs)
        tip = arm.evaluate("fk_position", Q)
        label = f"mlp-{setting.name}"
        errors[label] = np.linalg.norm(tip - truth_tip, axis=1)
        comparison.append(network_row(label, models, db, trained, hybrid, legs, errors[label], o, metrics))
        searches |= {f"{label} {m.task.key}": m.search for m in models}
        arrays |= {f"tip_{setting.name}": tip, f"configurations_{setting.name}": Q}

    k = min(n, o.exact_samples)
    problems = platform_problems(arm, PLATFORM_TOLERANCE)
    for name in spec.baselines:
        adapter = build_preset(name)

        def solve(L, adapter=adapter):
            return solve_platforms(adapter, problems, L, linearised_start(arm, L))

        solve(legs[:1])  # build (and compile) before the clock starts
        report, seconds = timed(lambda: solve(legs[:k]))
        tip = arm.evaluate("fk_position", report.x)
        errors[name] = np.linalg.norm(tip - truth_tip[:k], axis=1)
        arrays[f"tip_{name}"] = tip
        comparison.append(solver_row(name, report, errors[name], seconds, {
            "max |platform variables - truth|": float(np.max(np.abs(report.x - db.configurations[test[:k]]))),
            "max leg residual [m]": float(np.max(report.residual)),
            "latency, one sample [us]": latency(solve, legs, o.latency_repeats) * 1e6}))

    arrays |= {"test_rows": test, "leg_lengths": legs, "configurations": db.configurations[test], "tip": truth_tip}
    return comparison_result(ctx, arm, comparison, errors, searches, metrics, arrays, t_db, "FKM",
                             "Every MSE is on the test split; tip errors through the exact chain of eq. (5); "
                             f"exact solvers on the first {k} test arms, every platform from eqs. (7)-(9) "
                             "linearised.")


def run_ikm(ctx: ProblemContext) -> Result:
    spec, (arm, o, db, t_db) = ctx.spec, prepare(ctx)
    test = db.test
    targets = db.tip[test]
    n = len(test)
    platforms, realiser = platform_problems(arm, PLATFORM_TOLERANCE), build_preset(REALISER)

    comparison, searches, errors, arrays = [], {}, {}, {}
    metrics: dict[str, Any] = {"database": db.summary(), "database time [s]": t_db, "test samples": n,
                               "penalty (eq. 11)": o.penalty}
    for setting in settings_of(o):
        models, trained = obtain_models(ctx, db, inverse_tasks(db), setting, o.penalty, o.store,
                                        f"ikm-{setting.name}")

        def hybrid(P, models=models):
            return arm.evaluate("leg_lengths", hybrid_inverse_configurations(models, P))

        Q = hybrid_inverse_configurations(models, targets)
        realised = realise(arm, Q, realiser, platforms)
        label = f"mlp-{setting.name}"
        errors[label] = np.linalg.norm(realised.tip - targets, axis=1)
        unclipped = np.linalg.norm(arm.evaluate("fk_position", Q) - targets, axis=1)
        comparison.append(network_row(label, models, db, trained, hybrid, targets, errors[label], o, metrics, {
            "tip error of the predicted pose, unclipped, median [mm]": float(np.median(unclipped) * MM),
            "lengths clipped to Table I [%]": float(100 * realised.clipped.mean())}))
        searches |= {f"{label} {m.task.key}": m.search for m in models}
        arrays |= {f"tip_{setting.name}": realised.tip, f"leg_lengths_{setting.name}": realised.commanded,
                   f"predicted_{setting.name}": Q, f"configurations_{setting.name}": realised.configurations}

    k = min(n, o.exact_samples)
    formulation = Formulation(target="position", redundancy="rest", rest=rest_configuration(arm),
                              weights=1.0 / (arm.upper - arm.lower), tolerance=TIP_TOLERANCE)
    problem = build_problem(arm, formulation)
    for name in spec.baselines:
        adapter = build_preset(name)
        adapter.solve(problem, formulation.rest, targets[0])  # build before the clock starts
        report, seconds = timed(lambda: adapter.solve_many(problem, formulation.rest, targets[:k]))
        realised = realise(arm, report.x, realiser, platforms)
        errors[name] = np.linalg.norm(realised.tip - targets[:k], axis=1)
        arrays |= {f"tip_{name}": realised.tip, f"configurations_{name}": realised.configurations}
        comparison.append(solver_row(name, report, errors[name], seconds, {
            "lengths clipped to Table I [%]": float(100 * realised.clipped.mean()),
            "median iterations": float(np.median(report.iterations)) if np.all(report.iterations >= 0) else None}))

    arrays |= {"test_rows": test, "targets": targets, "configurations": db.configurations[test]}
    return comparison_result(ctx, arm, comparison, errors, searches, metrics, arrays, t_db, "IKM",
                             "Every MSE is on the test split; each method's leg lengths are clipped to Table I and "
                             "realised through the exact platform and chain kinematics before its tip error is "
                             f"measured; exact solvers on the first {k} test tips, from the straight mid-range "
                             f"pose, for the admissible configuration nearest it ({formulation.label()}).")


register_kind(ProblemKind(
    options=NNOptions,
    data_family="nn_database",
    name="nn_fkm",
    summary="seed 004 hybrid forward kinematics (MLP per section) against exact platform solvers",
    run=run_fkm,
    backend_families=("nonlinear",),
    default_solver=None,
))

register_kind(ProblemKind(
    options=NNOptions,
    data_family="nn_database",
    name="nn_ikm",
    summary="seed 004 hybrid inverse kinematics (MLPs NN1-NN4, eq. 11) against exact tip IK solvers",
    run=run_ikm,
    backend_families=("nonlinear",),
    default_solver=None,
))
