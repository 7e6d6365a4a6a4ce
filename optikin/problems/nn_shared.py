"""What the ``nn_fkm`` and ``nn_ikm`` kinds share: options, database, trained variants, rows, figures.

Seed 004 (Lakhal et al. 2016) replaces the numerical solution of the kinematic
equations of the CBHA by networks because "least square, Newton-Raphson methods
[...] are usually computationally intensive" (section IV-A). Both kinds draw the
learning database of Fig. 7 (data source ``fig7``,
:mod:`optikin.baselines.nn_database`), train one variant of their networks per
training setting in ``options.variants`` (or load it from ``options.store``), and
compare it on the test split with exact solver presets of the ``nonlinear``
family named under ``baselines``.

Every MSE is on the test split of the database; every tip error is the distance
between the exact forward kinematics of a method's configuration and the
held-out arm's tip. With the data source ``cosserat`` (:mod:`optikin.data.cosserat_nn`)
the networks still train on a vertebra-model database, but the test postures are
equilibria of a Cosserat-rod CBHA, read through its six tube lengths and its tip, and
seed 004 Table IV's other methods join the rows: constant-curvature sections
(:func:`constant_curvature_tips`, :func:`constant_curvature_lengths`) and MLPs trained on the
Cosserat postures themselves (:func:`direct_model`). Per-sample status: ``ok`` when the first variant's tip is
finite, ``failed`` otherwise; the residual is its tip error [m]. A solver's row
gives its share of ``ok`` samples; a sample without a finite tip is counted,
never dropped.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Literal, Mapping, Sequence

import numpy as np
from pydantic import Field
from scipy.sparse import block_diag
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from optikin.algebra import quat_multiply, quat_rotate
from optikin.arms.cbha import LEG_DIRECTIONS, CBHAArm
from optikin.arms.constant_curvature import section_position, section_quaternion
from optikin.baselines.nn_database import DatabaseSpec, Fig7Params, LearningDatabase
from optikin.baselines.nn_models import (
    DIRECT_SETTING,
    SETTINGS,
    Task,
    TrainedModel,
    TrainingSetting,
    direct_tasks,
    split_mse,
    split_rmse_by_variable,
    train_model,
)
from optikin.baselines.nn_store import load_models, save_models
from optikin.data.cosserat_nn import CosseratDatabase
from optikin.options import Options, validate_options
from optikin.problems import ProblemContext
from optikin.problems.fairness import ArmSize, Given, Manifest, cbha_name, cbha_size, coverage, recorded_arm
from optikin.progress import Progress
from optikin.results import Drawer, MethodRow, Result
from optikin.solvers.base import SolutionBatch
from optikin.spec import ProblemSpec
from optikin.status import Status

MM = 1e3
BATCH_REPEATS = 5
"""Calls of a batched method whose median time is reported."""
PLATFORM_TOLERANCE = 1e-12
"""Largest leg-length residual [m] of a solved platform (eqs. 7-9)."""
TIP_TOLERANCE = 1e-10
"""Largest tip error [m] of a solved tip-position IK."""
REALISER = "newton"
"""The solver preset that finds the pose commanded leg lengths produce
(:func:`optikin.ik.platform.realise`)."""

SettingName = Literal["seed", "seed-raw", "adam", "adam-wide"]
"""A training setting of :data:`optikin.baselines.nn_models.SETTINGS`."""


class NNOptions(Options):
    """``options`` of the ``nn_fkm`` and ``nn_ikm`` kinds."""

    variants: tuple[SettingName, ...] = Field(
        ("seed", "adam"),
        min_length=1,
        description="training settings, one trained variant each (optikin.baselines.nn_models.SETTINGS)",
    )
    setting: Literal["full", "small"] = Field(
        "full", description="full: the settings as named; small: two widths, at most 15 epochs (tests, notebooks)"
    )
    penalty: float = Field(1e-3, ge=0, description="lambda of eq. (11) (nn_ikm only)")
    store: str | None = Field(
        None,
        description="folder of trained models (relative to the working directory): "
        "loaded when it matches the problem, otherwise trained and written",
    )
    exact_samples: int = Field(200, ge=1, description="test samples given to the exact solvers (the first ones)")
    tube_sensors: bool = Field(
        True,
        description="nn_fkm: also give every method the legs its test arms' six tube lengths give by the "
        "percentage split of Fig. 6 (the pipeline of Fig. 9), rows <method>-fig9; the only input on the "
        "cosserat source",
    )
    goal_babbling: int = Field(
        1500,
        ge=0,
        description="cosserat source, nn_ikm: pressures the Cosserat arm executes while learning an inverse model "
        "by goal babbling (Rolf et al.; seed 004 Table IV's BHA row, a quarter with setting small); 0: no such row",
    )
    direct: bool = Field(
        True,
        description="cosserat source: also train seed 004 Table IV's qualitative models (Melingui et al.) on "
        "the Cosserat training postures, tube lengths -> tip (nn_fkm) and tip -> tube lengths (nn_ikm)",
    )
    latency_repeats: int = Field(50, ge=1, description="one-sample calls timed for the latency")

    def settings(self) -> list[TrainingSetting]:
        """The training setting of every variant (their quick versions with ``setting: small``)."""
        return [SETTINGS[n].small() if self.setting == "small" else SETTINGS[n] for n in self.variants]


# ---------------------------------------------------------------------------------------- reading the file
def database_spec(ctx: ProblemContext) -> DatabaseSpec:
    """The :class:`DatabaseSpec` of the problem's ``data`` section.

    ``data.params`` is validated against :class:`Fig7Params` here when ``ctx`` was built by
    hand rather than by the runner.
    """
    params = ctx.data_params
    if not isinstance(params, Fig7Params):
        params = validate_options(Fig7Params, ctx.spec.data.params, ctx.path, "data.params")
    return params.database_spec(ctx.spec.data)


def options(ctx: ProblemContext) -> NNOptions:
    """The validated options of ``ctx`` (validated here when ``ctx`` was built by hand)."""
    if isinstance(ctx.options, NNOptions):
        return ctx.options
    return validate_options(NNOptions, ctx.spec.options, ctx.path, "options")


@dataclass
class Prepared:
    """Either kind's checked inputs.

    Attributes
    ----------
    spec, arm, options:
        The problem file, its CBHA and its validated options.
    db, seconds:
        The learning database of the hybrid networks and the seconds ``data`` took to build.
    truth:
        With the ``cosserat`` source, its postures (``db`` is then its vertebra-model database);
        otherwise ``None`` and the test split of ``db`` is the truth.
    """

    spec: ProblemSpec
    arm: CBHAArm
    options: NNOptions
    db: LearningDatabase
    seconds: float
    truth: CosseratDatabase | None = None


def prepare(ctx: ProblemContext) -> Prepared:
    """Either kind's checked inputs (:class:`Prepared`).

    The networks are the method under test, so a ``solver`` is refused: exact solvers are
    named as baselines.
    """
    if not isinstance(ctx.arm, CBHAArm):
        raise ctx.error("arm.type", f"the nn kinds model the CBHA of seed 004, not {ctx.arm.name!r}")
    if ctx.solver is not None:
        raise ctx.error(
            "solver",
            f"{ctx.solver.name!r}: the nn kinds train networks; list the exact solver "
            "presets to compare with under baselines",
        )
    o = options(ctx)
    data, seconds = timed(ctx.load_data)
    if isinstance(data, CosseratDatabase):
        return Prepared(ctx.spec, ctx.arm, o, data.model, seconds, data)
    return Prepared(ctx.spec, ctx.arm, o, data, seconds)


def nearest_distances(reference: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """``(n,)`` distance of each of ``queries`` ``(n, 3)`` to the nearest of ``reference`` ``(m, 3)`` [m]."""
    return cKDTree(reference).query(queries)[0]


def coverage_metrics(prep: Prepared, test_tips: np.ndarray) -> dict[str, Any]:
    """How far the test tips ``(n, 3)`` [m] lie from the training tips of the hybrid networks' database:
    the median and 95th percentile of the distance to the nearest one [mm]."""
    db = prep.db
    distances = nearest_distances(db.tip[db.train], test_tips) * MM
    return {
        "test tips: median distance to the nearest training tip [mm]": float(np.median(distances)),
        "test tips: 95th percentile distance to the nearest training tip [mm]": float(np.percentile(distances, 95)),
    }


def direct_model(prep: Prepared, key: str) -> TrainedModel:
    """The direct model ``key`` (:func:`~optikin.baselines.nn_models.direct_tasks`) trained on the Cosserat
    postures with :data:`~optikin.baselines.nn_models.DIRECT_SETTING`: its quick version with ``setting:
    small``, except for the ``controller``, which belongs to the arm rather than to a method under test."""
    assert prep.truth is not None
    task = {t.key: t for t in direct_tasks()}[key]
    quick = prep.options.setting == "small" and key != "controller"
    setting = DIRECT_SETTING.small() if quick else DIRECT_SETTING
    return train_model(task, prep.truth, setting)


# ---------------------------------------------------------------------------------------- geometric rows
def section_tube_radii(arm: CBHAArm) -> np.ndarray:
    """``(sections,)`` mean tube offset [m] over each section's vertebrae (eq. 2): the constant-curvature
    model's radius."""
    g = arm.geometry
    bounds = np.cumsum((0,) + g.platforms_per_section)
    return np.array([g.radii[a : b + 1].mean() for a, b in zip(bounds[:-1], bounds[1:])])


def constant_curvature_tips(tube_lengths: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Seed 004 Table IV's quantitative FKM (Escande et al.): every section a constant-curvature arc.

    A section of backbone length ``L`` bent with curvature ``kappa`` towards the direction ``d`` of its
    base plane puts a tube at ``r u_m`` (:data:`~optikin.arms.cbha.LEG_DIRECTIONS`) at length
    ``l_m = L (1 - kappa r u_m . d)``. The three ``u_m`` add up to zero and ``sum_m u_m u_m^T = 3/2``
    in the plane, so ``L = mean(l_m)`` and ``kappa d = 2 / (3 r L) sum_m (L - l_m) u_m``; the arc's
    tip and rotation (bending angle ``kappa L`` about ``(-d_y, d_x, 0)``) follow
    (:func:`optikin.arms.constant_curvature.section_position`, ``section_quaternion``), and the
    sections chain.

    Parameters
    ----------
    tube_lengths:
        ``(n, sections, 3)`` [m].
    radii:
        ``(sections,)`` tube offset of each section [m].

    Returns
    -------
    numpy.ndarray
        ``(n, 3)`` tip positions [m] in the base frame.
    """
    lengths = np.asarray(tube_lengths, dtype=float)
    n = len(lengths)
    tip = np.zeros((n, 3))
    frame = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    for s in range(lengths.shape[1]):
        L = lengths[:, s].mean(axis=1)
        k = 2.0 / (3.0 * radii[s] * L)[:, None] * ((L[:, None] - lengths[:, s]) @ LEG_DIRECTIONS[:, :2])
        theta, phi = np.linalg.norm(k, axis=1) * L, np.arctan2(k[:, 1], k[:, 0])
        tip = tip + quat_rotate(frame, section_position(L, theta, phi), check=False)
        frame = quat_multiply(frame, section_quaternion(theta, phi))
    return tip


def constant_curvature_lengths(
    targets: np.ndarray, radii: np.ndarray, lower: np.ndarray, upper: np.ndarray, weight: float = 1e-3
) -> np.ndarray:
    """Seed 004 Table IV's quantitative IKM, the geometric class of Mahl et al. (one arc per section: their
    variable curvature is not modelled): the tube lengths whose constant-curvature tip
    (:func:`constant_curvature_tips`) is each target, nearest the mid lengths.

    All targets in one ``least_squares`` on ``(tip(l_i) - target_i, weight (l_i - l_mid))`` [m] within the
    bounds; the targets are independent, so the Jacobian is block diagonal and its finite differences
    perturb every target at once.

    Parameters
    ----------
    targets:
        ``(n, 3)`` tips [m].
    radii:
        ``(sections,)`` tube offsets [m].
    lower, upper:
        ``(sections,)`` bounds of a tube's length over each section [m] (Table I totals).
    weight:
        Of the pull towards the mid lengths (the redundancy: 6 lengths for 3 coordinates).

    Returns
    -------
    numpy.ndarray
        ``(n, sections, 3)`` [m].
    """
    targets = np.asarray(targets, dtype=float)
    n, S = len(targets), len(radii)
    lo, hi = np.tile(np.repeat(lower, 3), n), np.tile(np.repeat(upper, 3), n)
    mid = 0.5 * (lo + hi)

    def residual(x: np.ndarray) -> np.ndarray:
        tips = constant_curvature_tips(x.reshape(n, S, 3), radii) - targets
        return np.concatenate([tips, weight * (x - mid).reshape(n, -1)], axis=1).ravel()

    block = np.ones((3 + 3 * S, 3 * S))
    sparsity = block_diag([block] * n, format="csr")
    x = least_squares(residual, mid, bounds=(lo, hi), jac_sparsity=sparsity, xtol=1e-12, ftol=1e-12).x
    return x.reshape(n, S, 3)


# ---------------------------------------------------------------------------------------- running
def obtain_models(
    progress: Progress,
    db: LearningDatabase,
    tasks: list[Task],
    setting: TrainingSetting,
    penalty: float,
    store: str | None,
    label: str,
) -> tuple[list[TrainedModel], bool]:
    """Models of ``tasks`` and whether they were trained: loaded from ``store/label`` when it
    exists, else trained (and saved there when ``store`` is given)."""
    penalties = {t.key: (penalty if t.penalised else 0.0) for t in tasks}
    folder = Path(store) / label if store else None
    if folder is not None and folder.exists():
        required = {t.key: (setting, penalties[t.key]) for t in tasks}
        return load_models(folder, db.geometry, db.spec, required), False
    models = []
    with progress.task(
        f"training {label}: {len(tasks)} models x {len(setting.neurons)} widths",
        total=len(tasks) * len(setting.neurons),
    ) as advance:
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
        row = inputs[i % len(inputs) : i % len(inputs) + 1]
        start = time.perf_counter()
        fn(row)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


@dataclass
class NetworkRun:
    """One trained variant on the test split.

    Attributes
    ----------
    setting, models, trained:
        Its training setting, its models (one per task), and whether they were trained
        (rather than loaded from the store).
    errors:
        ``(n,)`` tip errors through the exact kinematics [m].
    batch_seconds, latency:
        Median seconds of one call on the whole test split, and of a one-sample call.
    arrays:
        The variant's arrays of the result.
    suffix:
        Of its label: ``""``, or ``-fig9`` when given the legs split from the six tube lengths.
    """

    setting: TrainingSetting
    models: list[TrainedModel]
    trained: bool
    errors: np.ndarray
    batch_seconds: float
    latency: float
    arrays: dict[str, np.ndarray]
    suffix: str

    @property
    def label(self) -> str:
        """The variant's method name, ``mlp-<setting><suffix>`` (``-fig9``: from the six tube lengths)."""
        return f"{NETWORK_PREFIX}{self.setting.name}{self.suffix}"


def time_network(hybrid: Callable[[np.ndarray], Any], inputs: np.ndarray, repeats: int) -> tuple[float, float]:
    """Median seconds of ``hybrid`` on all of ``inputs`` (of :data:`BATCH_REPEATS` calls) and on one
    sample (of ``repeats`` calls), after a warm-up call."""
    hybrid(inputs[:1])
    _, seconds = timed(lambda: hybrid(inputs), BATCH_REPEATS)
    return seconds, latency(hybrid, inputs, repeats)


@dataclass
class SolverRun:
    """One exact solver preset on the first test samples: its batch, tip errors [m], wall time [s]
    and arrays."""

    name: str
    report: SolutionBatch
    errors: np.ndarray
    seconds: float
    arrays: dict[str, np.ndarray]


# ---------------------------------------------------------------------------------------- reporting
def error_stats(errors: np.ndarray) -> dict[str, float]:
    """Mean, median, 95th percentile and max of the finite tip errors given in metres, in millimetres,
    and how many samples have none (a failed solve)."""
    e = np.asarray(errors) * MM
    finite = e[np.isfinite(e)]
    stats: dict[str, float] = {"samples without a tip": int(e.size - finite.size)}
    if finite.size:
        stats |= {
            "tip error mean [mm]": float(finite.mean()),
            "tip error median [mm]": float(np.median(finite)),
            "tip error p95 [mm]": float(np.percentile(finite, 95)),
            "tip error max [mm]": float(finite.max()),
        }
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


def network_row(
    run: NetworkRun, db: LearningDatabase, metrics: dict[str, Any], extra: dict[str, Any] | None = None
) -> MethodRow:
    """The comparison row of one trained variant (its model metrics are added to ``metrics``)."""
    label, models = run.label, run.models
    mm = model_metrics(label, models, db)
    metrics |= {f"{label} setting": run.setting.description, f"{label} loaded from store": not run.trained, **mm}
    row = {f"test MSE {m.task.key}": mm[f"{label} {m.task.key}"]["test MSE"] for m in models}
    row |= {f"neurons {m.task.key}": m.neurons for m in models}
    row |= error_stats(run.errors) | (extra or {})
    row |= {
        "time per sample, batch [us]": run.batch_seconds / len(run.errors) * 1e6,
        "latency, one sample [us]": run.latency * 1e6,
        "training time [s]": sum(m.training_time for m in models),
    }
    return MethodRow(label, "solver", row)


def solver_row(run: SolverRun, extra: dict[str, Any]) -> MethodRow:
    """The comparison row of an exact solver preset on ``len(run.report)`` samples."""
    report = run.report
    return MethodRow(
        run.name,
        "baseline",
        {
            "samples": len(report),
            "ok [%]": float(100 * np.mean(np.array(report.status) == Status.OK)),
            **error_stats(run.errors),
            **extra,
            "batched": report.batched,
            "time per sample [us]": run.seconds / len(report) * 1e6,
        },
    )


def search_arrays(run: NetworkRun) -> dict[str, np.ndarray]:
    """``search_<setting>_<task>``: ``(widths, 2)`` rows of (width, validation criterion), widths sorted."""
    return {
        f"search_{run.setting.name}_{m.task.key}": np.array([[n, m.search[n]] for n in sorted(m.search)])
        for m in run.models
    }


def comparison_result(
    prep: Prepared,
    networks: Sequence[NetworkRun],
    comparison: list[MethodRow],
    errors: dict[str, np.ndarray],
    metrics: dict[str, Any],
    arrays: dict[str, np.ndarray],
    note: str,
    fairness: Sequence[str] = (),
) -> Result:
    """The result of either kind: the first network variant is the method, every row a comparison.

    Parameters
    ----------
    errors:
        Tip errors [m] of every row's method, added to the arrays as ``tip_errors_<method>``
        beside the width searches (:func:`search_arrays`), for the figures.
    """
    spec, main = prep.spec, comparison[0].method
    for run in networks:
        arrays |= search_arrays(run)
    arrays |= {f"tip_errors_{name}": e for name, e in errors.items()}
    return Result(
        problem=spec.name,
        kind=spec.kind,
        solver=main,
        title=spec.title,
        arm=prep.arm.describe(),
        status=[Status.OK if np.isfinite(e) else Status.FAILED for e in errors[main]],
        residuals=errors[main],
        timings={"database [s]": prep.seconds},
        metrics=metrics,
        comparison=comparison,
        arrays=arrays,
        notes=[note, *fairness],
    )


# ---------------------------------------------------------------------------------------- fairness
FIG9_SUFFIX = "-fig9"
"""Suffix of a row whose legs are split from the six tube lengths (Fig. 9)."""
NETWORK_PREFIX = "mlp-"
"""Prefix of a network variant's row (:attr:`NetworkRun.label`)."""
TABLE_IV_ROWS = ("constant-curvature", "direct-mlp", "goal-babbling", "true-lengths")


def method_names(kind: str, spec: ProblemSpec, o: NNOptions) -> list[str]:
    """The rows a run of ``spec`` reports, in order, known before the run (for the fairness manifest's test)."""
    cosserat = spec.data.source == "cosserat"
    if kind == "nn_fkm":
        suffixes = [FIG9_SUFFIX] if cosserat else [""] + ([FIG9_SUFFIX] if o.tube_sensors else [])
    else:
        suffixes = [""]
    names = [f"{NETWORK_PREFIX}{s.name}{x}" for s in o.settings() for x in suffixes]
    names += [f"{b}{x}" for b in spec.baselines for x in suffixes]
    if kind == "nn_fkm" and (cosserat or o.tube_sensors):
        names.append("constant-curvature")
    if cosserat and o.direct:
        names.append("direct-mlp")
    if kind == "nn_ikm" and cosserat:
        names += ["constant-curvature"] + (["goal-babbling"] if o.goal_babbling else []) + ["true-lengths"]
    return names


def nn_manifest(
    spec: ProblemSpec, arm: CBHAArm, o: NNOptions, data_params: Any, methods: Sequence[str], database: str = ""
) -> Manifest:
    """What every row of an ``nn_fkm`` / ``nn_ikm`` comparison is given (:mod:`optikin.problems.fairness`).

    The networks and the exact solvers model the problem's CBHA (the generator's own on a
    vertebra-model database, the measured radii and a Table I sized to the recorded arm on a
    Cosserat one); constant-curvature gets the tube offsets; direct-mlp, goal-babbling and
    true-lengths no model of the arm. ``database`` describes the networks' training set.
    """
    truth, shared = recorded_arm(spec.data.source, data_params, arm)
    model = cbha_size(arm.geometry, cbha_name(arm.geometry))
    source = "generator's own" if shared else "measured"
    variants = {s.name: s for s in o.settings()}
    trained_on = database or "the vertebra-model database of data"
    entries = []
    for name in methods:
        base = name.removesuffix(FIG9_SUFFIX)
        variant = base.removeprefix(NETWORK_PREFIX)
        split = "the six tube lengths split over the legs (Fig. 6)" if name.endswith(FIG9_SUFFIX) else ""
        if base.startswith(NETWORK_PREFIX) and variant in variants:
            entries.append(
                Given(
                    name,
                    source,
                    model,
                    training=f"{trained_on}, setting {variants[variant].description}",
                    budget="one forward pass per sample",
                    limits="Table I (lengths clipped)" if spec.kind == "nn_ikm" else "none",
                    information=split,
                )
            )
        elif base in spec.baselines:
            entries.append(
                Given(
                    name,
                    source,
                    model,
                    budget=f"preset {base} on the first {o.exact_samples} test samples",
                    limits="Table I",
                    information=split,
                )
            )
        elif name == "constant-curvature":
            radii = (float(arm.geometry.r_max), float(arm.geometry.r_min))
            entries.append(
                Given(
                    name,
                    "measured",
                    ArmSize("the tube offsets of the problem's arm", radii),
                    information="the true tube offsets; each section an arc (the model nearest a Cosserat arm's)",
                )
            )
        elif name == "direct-mlp":
            entries.append(Given(name, "none", training="the Cosserat training postures"))
        elif name == "goal-babbling":
            entries.append(Given(name, "none", training=f"{o.goal_babbling} babbling commands on the arm"))
        elif name == "true-lengths":
            entries.append(
                Given(name, "none", information="the postures' own tube lengths: the controller's floor, not a method")
            )
        else:
            entries.append(Given(name, "none"))
    return Manifest(truth, shared, tuple(entries))


def network_inputs(prep: Prepared, kind: str) -> tuple[np.ndarray, np.ndarray, str]:
    """The networks' training inputs and the test inputs they are given, and what those are: the tips
    (``nn_ikm``) or the six tube lengths (``nn_fkm``) [m]."""
    db, truth = prep.db, prep.truth
    if kind == "nn_ikm":
        test = truth.tip[truth.test] if truth is not None else db.tip[db.test]
        return db.tip[db.train], test, "tips"
    test = truth.tube_lengths[truth.test] if truth is not None else db.tube_lengths[db.test]
    return db.tube_lengths[db.train], test, "tube lengths"


def direct_inputs(prep: Prepared, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """The direct MLP's training and test inputs (Cosserat postures): tips (``nn_ikm``) or tube lengths."""
    truth = prep.truth
    assert truth is not None, "direct-mlp is trained on Cosserat postures"
    X = truth.tip if kind == "nn_ikm" else truth.tube_lengths
    return X[truth.train], X[truth.test]


def annotate_fairness(prep: Prepared, comparison: list[MethodRow], metrics: dict[str, Any]) -> list[str]:
    """Add the fairness manifest to the rows (``given.*``) and ``metrics`` (``fairness``); its printed notes."""
    kind, db = prep.spec.kind, prep.db
    database = f"the vertebra-model database ({db.spec.coupling}, {len(db.train)} training rows)"
    data_params = prep.truth.params if prep.truth is not None else None
    manifest = nn_manifest(prep.spec, prep.arm, prep.options, data_params, [r.method for r in comparison], database)
    train, test, what = network_inputs(prep, kind)
    found = coverage(train, test)
    label = f"tested outside its training range: its test {what} lie beyond the database's (coverage columns)"
    for g in manifest.given:
        if g.method.removesuffix(FIG9_SUFFIX) in {f"{NETWORK_PREFIX}{s.name}" for s in prep.options.settings()}:
            manifest = manifest.with_coverage(g.method, found, label)
        elif g.method == "direct-mlp":
            manifest = manifest.with_coverage(g.method, coverage(*direct_inputs(prep, kind)), label)
    comparison[:] = manifest.annotate(comparison)
    metrics |= manifest.metrics()
    return manifest.notes()


# ---------------------------------------------------------------------------------------- figures
def figures(arrays: Mapping[str, np.ndarray], summary: Mapping[str, Any], what: str) -> dict[str, Drawer]:
    """The width searches (``search``) and the tip errors of every method (``tip_errors``).

    Parameters
    ----------
    arrays, summary:
        A result's arrays (``search_<setting>_<task>``, ``tip_errors_<method>``) and summary
        (its comparison rows give the methods, in order).
    what:
        ``FKM`` or ``IKM``, for the title.
    """
    name = summary["problem"]
    rows = summary.get("comparison", [])
    searches = searches_of(arrays, [row["method"] for row in rows if row["role"] == "solver"])
    out: dict[str, Drawer] = {}
    if searches:
        out["search"] = lambda path: draw_search(path, searches, f"{name}: width search")
    methods = [row["method"] for row in rows]
    if methods and all(f"tip_errors_{m}" in arrays for m in methods):
        errors = {m: np.asarray(arrays[f"tip_errors_{m}"]) for m in methods}
        out["tip_errors"] = lambda path: draw_tip_errors(path, errors, f"{name}: hybrid {what} vs exact")
    return out


def searches_of(arrays: Mapping[str, np.ndarray], networks: list[str]) -> dict[str, np.ndarray]:
    """``"<network> <task>"`` -> ``(widths, 2)`` width search, for every network ``mlp-<setting>``."""
    out: dict[str, np.ndarray] = {}
    for network in networks:
        prefix = f"search_{network.removeprefix('mlp-')}_"
        out |= {f"{network} {key.removeprefix(prefix)}": arrays[key] for key in arrays if key.startswith(prefix)}
    return out


def draw_search(path: Path, searches: Mapping[str, np.ndarray], title: str) -> None:
    """Validation criterion against width, one line per model (``(widths, 2)`` arrays), legend beside the axes."""
    from matplotlib.ticker import MaxNLocator

    from optikin import plots

    fig, axes = plots.subplots(1, 1, figsize=(8.8, 4.2))
    ax = axes[0, 0]
    styles = plots.method_styles(list(searches), {})
    for label, search in searches.items():
        style = plots.unmarked(styles[label]) | {"marker": styles[label]["marker"], "ms": 5}
        ax.semilogy(search[:, 0], search[:, 1], label=label, **style)
    ax.set_xlabel("neurons per hidden layer")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("validation MSE (+ eq. 11 penalty)\n[SI units squared]")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    plots.legend_outside(fig)
    plots.save(fig, path)


def draw_tip_errors(path: Path, errors: Mapping[str, np.ndarray], title: str) -> None:
    """Box plot of every method's finite tip errors [mm] (failures are counted in the table)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    labels = list(errors)
    data = [np.maximum(errors[k][np.isfinite(errors[k])] * MM, 1e-12) for k in labels]
    ax.boxplot(data, showfliers=True)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=20, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("tip error through exact FK [mm]")
    ax.set_title(title)
    ax.grid(True, which="both", axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
