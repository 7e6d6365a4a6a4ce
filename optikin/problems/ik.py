"""Problem kind ``ik``: inverse kinematics as root finding / bounded nonlinear least squares.

For each target the configuration ``q`` solves ``min 1/2 ||r(q, target)||^2``
within the arm's bounds (:mod:`optikin.solvers.nonlinear`), with

* ``target: position``: ``r = p(q) - p*`` (metres), the tip position of the arm's
  :meth:`~optikin.arms.base.ArmModel.section_frames`;
* ``target: pose``: ``r = (p(q) - p*, 2 L vec(q*^-1 q(q)))``, the position error
  and the unit-quaternion orientation error (Siciliano et al., Robotics, 2009,
  sec. 3.7.3), scaled
  by the length ``L`` (``orientation_length``, default: the arm's reach bound) so
  ``||r||`` is in metres. ``2 vec(q*^-1 q) = 2 sin(a/2) n`` is the rotation vector
  ``a n`` of the error to first order, vanishes exactly when the orientations
  agree (either quaternion sign), and is smooth everywhere: unlike the rotation
  log it has no branch at ``a = pi``, which left Gauss-Newton in spurious minima
  on more random targets (5.3 % against 3.0 % of 2,000, before restarts). The
  target is a unit dual quaternion (DESIGN.md conventions). For a two-section CC
  arm the 6 x 6 pose Jacobian has rank 5 at every configuration (torsion-free
  sections: the reachable poses form a 5-D set), so pose IK is a rank-deficient
  least-squares problem with a curve of solutions per reachable pose.
* ``target: legs`` (CBHA only): the 48 leg lengths of the 16 platforms ->
  ``(Z_k, theta_k, psi_k)``, seed 004 eqs. (7)-(9) inverted platform by platform
  (:mod:`optikin.ik.platform`); ``||r||`` in metres of leg length.

For a CBHA every leg length must also lie within Table I of seed 004: the NLP
backends impose these limits as constraints, and any backend's configuration
that breaks one is reported ``failed`` naming the leg.

With fewer target coordinates than configuration variables (tip position of a
two-section CC arm: 3 for 6) the solutions form a set, and ``redundancy``
chooses among them, in the weighted norm ``||W (q - q_ref)||`` (``weights``,
default the inverse ranges of the variables):

``rest``          closest to the rest configuration ``rest`` (default: straight
                  at nominal lengths for the CC arm, mid-range otherwise);
``previous``      closest to the previous solution along a trajectory (to the start
                  point for independent targets);
``minimum_norm``  the solution reached by weighted minimum-norm corrections from
                  the start point (the pseudo-inverse Newton-Raphson iteration);
``penalty``       seed 004 eq. (11): no exact constraint, the tip error plus
                  ``penalty`` (lambda) times a squared norm is minimised
                  (``penalty_on: configuration``, the weighted distance to ``rest``;
                  or ``position``, the tip's distance to the base, as printed);
                  see :mod:`optikin.ik.formulation`. A sample is ``ok``
                  at a stationary point of that cost; its tip error is reported
                  beside (in general larger than ``tolerance``).

On a CBHA, ``elongation: distributed`` adds the elongation distribution of seed
004 section IV (every inter-vertebra a fixed fraction of its section's tube
length, from Table I; :mod:`optikin.ik.cbha`) to any of these;
``elongation: affine`` its other reading (the elongation above Table I's minimum
shared in proportion to each inter-vertebra's range).

Backends that minimise a distance (``newton`` through the optimality system,
``ipopt``, ``sqpmethod``) do so exactly, with ``q_ref`` the rest configuration or
the start point; ``gauss_newton``, ``lm`` and ``trf`` take minimum-norm steps
from the start point, which is the rest configuration for independent targets
under ``rest``.

Targets come from :mod:`optikin.data.targets` (``random``: forward kinematics of
random admissible configurations, optionally with targets outside the workspace;
``trajectory``: a smooth motion, solved in order, each solve warm-started from
the previous solution; ``csv``). Independent targets are solved as one batch
when the backend has a batched path (``gauss_newton``); those not solved are
retried ``restarts`` times, keeping the best point: first from the solution of
the nearest solved target, then from random admissible configurations
(seeded); a sample's time and iterations include its retries.
Targets outside the workspace end as ``unreachable`` at the closest
configuration the backend found, with its residual: never ``ok``.

Every backend listed in ``baselines`` (solver presets of the ``nonlinear``
family) solves the same targets in the same run, and so does the problem's
solver on each of the ``variants`` (other formulations of the same targets,
e.g. the penalty of eq. (11) beside the exact tip with the closest-to-rest
choice). Each row of the comparison reports the success rate on reachable
targets, how unreachable targets were flagged, residuals, the tip error
recomputed independently with ``fk_dq`` (and how many samples reach the target
within ``tolerance``), the weighted distance from ``rest``, on a CBHA the margin
of the legs to Table I and their deviation from the elongation distribution,
iterations and time per solve (arrays per row: solutions, statuses, residuals,
times, iterations, these checks and, on a CBHA, the six tube lengths, the output
of seed 004's inverse model); the figure ``comparison`` draws the tip errors,
times and (CBHA) leg margins of every row.

Options: ``target``, ``redundancy``, ``rest``, ``weights``, ``start`` (``rest`` or
a configuration), ``restarts`` (default 2), ``tolerance`` (``||r||`` in metres
counted as solved, default 1e-10), ``orientation_length``, ``penalty`` (lambda,
default 1e-6: m^2 on the configuration, a pure number on the position),
``penalty_on`` (``configuration`` or ``position``), ``elongation`` (``free``,
``distributed`` or ``affine``), ``variants`` (``{label: {option: value}}`` over the options
``redundancy``, ``penalty``, ``penalty_on``, ``elongation``, ``rest``, ``weights``,
``tolerance``, ``orientation_length``).
"""

from __future__ import annotations

import re
import time
from collections.abc import Mapping
from typing import Any, Callable

import numpy as np

from optikin import plots
from optikin.algebra import dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm
from optikin.data.targets import FAMILY as TARGETS, TARGET_KINDS, Targets, reach_bound
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.ik.cbha import distribution_deviation, leg_checks, leg_margins
from optikin.problems.ik_figures import draw_comparison
from optikin.ik.formulation import (
    ELONGATIONS,
    PENALTY_READINGS,
    REDUNDANCY_CHOICES,
    Formulation,
    build_problem,
    rest_configuration,
)
from optikin.ik.platform import solve_platforms
from optikin.results import MethodRow, Result
from optikin.solvers.nonlinear import FAMILY, LeastSquaresProblem, NonlinearAdapter
from optikin.solvers.base import SolutionBatch
from optikin.solvers import build_preset

DEFAULTS: dict[str, Any] = {"target": "position", "redundancy": "rest", "rest": None, "weights": None,
                            "start": "rest", "restarts": 2, "tolerance": 1e-10, "orientation_length": None,
                            "penalty": 1e-6, "penalty_on": "configuration", "elongation": "free", "variants": {}}
FORMULATION_KEYS = ("redundancy", "penalty", "penalty_on", "elongation", "rest", "weights", "tolerance",
                    "orientation_length")
"""Options a variant may change (the targets, start and restarts are shared by every row)."""


# --------------------------------------------------------------------------------------- checks of answers
def tip_errors(arm: ArmModel, targets: Targets, X: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Position error [m] and, for poses, rotation error [rad] of solutions ``X``, recomputed with ``fk_dq``."""
    finite = np.all(np.isfinite(X), axis=1)
    reached = arm.evaluate("fk_dq", np.where(finite[:, None], X, rest_configuration(arm)))
    position_error = np.linalg.norm(dq_translation(reached) - targets.positions, axis=1)
    position_error[~finite] = np.nan
    if targets.kind == "position":
        return position_error, None
    relative = quat_multiply(quat_conjugate(targets.values[:, :4]), reached[:, :4])
    angle = quat_angle(relative)
    angle[~finite] = np.nan
    return position_error, angle


def rest_distances(arm: ArmModel, formulation: Formulation, X: np.ndarray) -> np.ndarray:
    """``||W dist(q, q_rest)||`` per solution (chord distance ``2 sin(d/2)`` for angles that wrap)."""
    d = X - formulation.rest
    with np.errstate(invalid="ignore"):  # a failed sample's NaN stays NaN
        d = np.where(arm.periodic, 2.0 * np.sin(d / 2.0), d)
    return np.linalg.norm(formulation.weights * d, axis=1)


# --------------------------------------------------------------------------------------- options
class Settings:
    """The validated ``options`` of an ``ik`` problem file: the formulation, its variants, starts and restarts."""

    def __init__(self, ctx: ProblemContext):
        arm = ctx.arm
        for key in ctx.spec.options:
            if key not in DEFAULTS:
                raise ctx.error(f"options.{key}", f"unknown option of kind ik; known: {', '.join(DEFAULTS)}")
        o = {**DEFAULTS, **ctx.spec.options}
        if o["target"] not in TARGET_KINDS:
            raise ctx.error("options.target", f"{o['target']!r} is not one of {', '.join(TARGET_KINDS)}")
        if o["target"] == "legs" and not isinstance(arm, CBHAArm):
            raise ctx.error("options.target", f"leg-length targets need a cbha arm, not {ctx.spec.arm.type!r}")
        self.target: str = o["target"]
        self.formulation = self._formulation(ctx, o, {})
        self.start = self.rest if o["start"] == "rest" else self._configuration(ctx, "options.start", o["start"])
        self.restarts = o["restarts"]
        if isinstance(self.restarts, bool) or not isinstance(self.restarts, int) or self.restarts < 0:
            raise ctx.error("options.restarts", f"expected a count >= 0, got {self.restarts!r}")
        if not isinstance(o["variants"], Mapping):
            raise ctx.error("options.variants", f"expected a mapping of label to options, got {o['variants']!r}")
        self.variants: dict[str, Formulation] = {}
        for label, overrides in o["variants"].items():
            where = f"options.variants.{label}"
            if not isinstance(overrides, Mapping):
                raise ctx.error(where, f"expected a mapping of options, got {overrides!r}")
            for key in overrides:
                if key not in FORMULATION_KEYS:
                    raise ctx.error(f"{where}.{key}", f"a variant may set only {', '.join(FORMULATION_KEYS)}")
            self.variants[str(label)] = self._formulation(ctx, {**o, **overrides}, overrides, where)

    @property
    def rest(self) -> np.ndarray:
        return self.formulation.rest

    @property
    def redundancy(self) -> str:
        return self.formulation.redundancy

    @property
    def tolerance(self) -> float:
        return self.formulation.tolerance

    def _formulation(self, ctx: ProblemContext, o: dict, overrides: Mapping, where: str = "") -> Formulation:
        """A :class:`Formulation` from options ``o``; errors name ``where.key`` for keys in ``overrides``."""
        arm = ctx.arm

        def field(key: str) -> str:
            return f"{where}.{key}" if key in overrides else f"options.{key}"

        if o["redundancy"] not in REDUNDANCY_CHOICES:
            raise ctx.error(field("redundancy"), f"{o['redundancy']!r} is not one of {', '.join(REDUNDANCY_CHOICES)}")
        if o["penalty_on"] not in PENALTY_READINGS:
            raise ctx.error(field("penalty_on"), f"{o['penalty_on']!r} is not one of {', '.join(PENALTY_READINGS)}")
        if o["elongation"] not in ELONGATIONS:
            raise ctx.error(field("elongation"), f"{o['elongation']!r} is not one of {', '.join(ELONGATIONS)}")
        if o["elongation"] != "free" and not isinstance(arm, CBHAArm):
            raise ctx.error(field("elongation"), f"the elongation distribution needs a cbha arm, "
                                                 f"not {ctx.spec.arm.type!r}")
        if self.target == "legs" and (o["elongation"] != "free" or o["redundancy"] == "penalty"):
            key = "elongation" if o["elongation"] != "free" else "redundancy"
            raise ctx.error(field(key), "leg-length targets have a unique solution: no penalty, no distribution")
        rest = self._configuration(ctx, field("rest"), o["rest"]) if o["rest"] is not None else rest_configuration(arm)
        weights = 1.0 / (arm.upper - arm.lower) if o["weights"] is None else o["weights"]
        weights = self._vector(ctx, field("weights"), weights)
        if np.any(weights <= 0):
            raise ctx.error(field("weights"), "every weight must be positive")
        orientation_length = 1.0
        if self.target == "pose":
            length = reach_bound(arm) if o["orientation_length"] is None else o["orientation_length"]
            orientation_length = self._positive(ctx, field("orientation_length"), length)
        return Formulation(target=self.target, redundancy=o["redundancy"], rest=rest, weights=weights,
                           tolerance=self._positive(ctx, field("tolerance"), o["tolerance"]),
                           orientation_length=orientation_length,
                           penalty=self._positive(ctx, field("penalty"), o["penalty"]),
                           penalty_on=o["penalty_on"], elongation=o["elongation"])

    @staticmethod
    def _positive(ctx: ProblemContext, field: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise ctx.error(field, f"expected a positive number, got {value!r}")
        return float(value)

    @staticmethod
    def _vector(ctx: ProblemContext, field: str, value: Any) -> np.ndarray:
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ctx.error(field, f"expected {ctx.arm.n_config} numbers, got {value!r}") from None
        if v.shape != (ctx.arm.n_config,) or not np.all(np.isfinite(v)):
            raise ctx.error(field, f"expected {ctx.arm.n_config} numbers ({', '.join(ctx.arm.config_names)}), "
                                   f"got {value!r}")
        return v

    def _configuration(self, ctx: ProblemContext, field: str, value: Any) -> np.ndarray:
        q = self._vector(ctx, field, value)
        span = ctx.arm.upper - ctx.arm.lower
        outside = (q < ctx.arm.lower - 1e-12 * span) | (q > ctx.arm.upper + 1e-12 * span)
        if outside.any():
            j = int(np.argmax(outside))
            raise ctx.error(field, f"{ctx.arm.config_names[j]} = {q[j]:.6g} outside its bounds "
                                   f"[{ctx.arm.lower[j]:.6g}, {ctx.arm.upper[j]:.6g}]")
        return q


# --------------------------------------------------------------------------------------- solving
class Method:
    """One row of the comparison: a backend on a formulation of the targets."""

    def __init__(self, name: str, role: str, adapter: NonlinearAdapter, formulation: Formulation,
                 problem: LeastSquaresProblem | list[LeastSquaresProblem]):
        self.name, self.role, self.adapter, self.formulation, self.problem = name, role, adapter, formulation, problem


def methods_of(ctx: ProblemContext, settings: Settings) -> list[Method]:
    """The problem's solver, each baseline preset not already listed, then the solver on each variant."""
    problem = build_problem(ctx.arm, settings.formulation)
    methods = [Method(ctx.solver.name, "solver", ctx.adapter, settings.formulation, problem)]
    for name in ctx.spec.baselines:
        if name in [m.name for m in methods]:
            continue
        # the runner checked that it is a preset of this kind's family
        methods.append(Method(name, "baseline", build_preset(name), settings.formulation, problem))
    for label, formulation in settings.variants.items():
        methods.append(Method(f"{ctx.solver.name} [{label}]", "variant", ctx.adapter, formulation,
                              build_problem(ctx.arm, formulation)))
    return methods


Solve = Callable[[np.ndarray, np.ndarray, bool, "np.ndarray | None"], SolutionBatch]
"""``(starts, targets, warm_start, x_ref) -> SolutionBatch``: one backend on one kind of target."""


def solver_of(adapter: NonlinearAdapter, problem: LeastSquaresProblem | list[LeastSquaresProblem]) -> Solve:
    if isinstance(problem, list):  # CBHA platforms, one problem each
        return lambda X0, P, warm, x_ref: solve_platforms(adapter, problem, P, X0, warm)
    return lambda X0, P, warm, x_ref: adapter.solve_many(problem, X0, P, warm_start=warm, x_ref=x_ref)


def solve_targets(solve: Solve, targets: Targets, settings: Settings, formulation: Formulation,
                  ctx: ProblemContext, arm: ArmModel) -> SolutionBatch:
    """Solve every target (module docstring): warm-started along a trajectory, batched and retried otherwise."""
    x_ref = formulation.rest if formulation.redundancy == "rest" else None
    if targets.trajectory:
        return solve(settings.start, targets.values, True, x_ref)
    report = solve(settings.start, targets.values, False, x_ref)
    for attempt in range(settings.restarts):
        status = np.array(report.status)
        retry = np.flatnonzero(status != "ok")
        if retry.size == 0:
            break
        if attempt == 0 and (status == "ok").any():
            starts = nearest_solutions(targets.values, report.x, status == "ok", retry)
        else:
            starts = arm.sample_configurations(retry.size, ctx.rng(100 + attempt))
        again = solve(starts, targets.values[retry], False, x_ref)
        for j, i in enumerate(retry):
            better = again.status[j] == "ok" or (np.isfinite(again.residual[j]) and
                                                 not again.residual[j] >= report.residual[i])
            report.iterations[i] += again.iterations[j]
            report.seconds[i] += again.seconds[j]
            if better:
                report.x[i], report.status[i] = again.x[j], again.status[j]
                report.residual[i], report.messages[i] = again.residual[j], again.messages[j]
    return report


def nearest_solutions(values: np.ndarray, X: np.ndarray, solved: np.ndarray, retry: np.ndarray) -> np.ndarray:
    """For each sample in ``retry``, the solution of the solved target nearest to its own target.

    Dual quaternions ``Q`` and ``-Q`` are the same pose: the distance takes the nearer sign.
    """
    candidates = np.flatnonzero(solved)
    a, b = values[retry][:, None, :], values[candidates][None, :, :]
    distance = np.linalg.norm(a - b, axis=2)
    if values.shape[1] == 8:
        distance = np.minimum(distance, np.linalg.norm(a + b, axis=2))
    return X[candidates[np.argmin(distance, axis=1)]]


# --------------------------------------------------------------------------------------- reporting
def array_key(method: str) -> str:
    """A method's name as part of an array name: ``gauss-newton [penalty 1e-6]`` -> ``gauss-newton_penalty_1e-6``."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", method).strip("_")


def _stat(f: Callable[[np.ndarray], float], values: np.ndarray) -> float:
    """``f`` over the finite values, NaN when there are none."""
    values = values[np.isfinite(values)]
    return float(f(values)) if values.size else float("nan")


def answer_checks(arm: ArmModel, targets: Targets, formulation: Formulation, X: np.ndarray) -> dict[str, np.ndarray]:
    """Per-sample checks of the solutions, independent of the solver's own residual (module docstring)."""
    if targets.kind == "legs":
        leg_error, within = leg_checks(arm, targets.values, X)
        return {"leg_error": leg_error, "within_table_i": within}
    position_error, angle_error = tip_errors(arm, targets, X)
    checks = {"tip_error": position_error, "rest_distance": rest_distances(arm, formulation, X)}
    if angle_error is not None:
        checks["angle_error"] = angle_error
    if isinstance(arm, CBHAArm):
        checks["leg_margin"] = leg_margins(arm, X)
        rule = "distributed" if formulation.elongation == "free" else formulation.elongation
        checks["distribution_deviation"] = distribution_deviation(arm, X, rule)
        # seed 004's inverse model ends with the tube lengths (section, tube), "summing the elongations"
        finite = np.all(np.isfinite(X), axis=1)
        tubes = arm.evaluate("tube_lengths", np.where(finite[:, None], X, rest_configuration(arm)))
        checks["tube_lengths"] = np.where(finite[:, None], tubes.reshape(len(X), -1), np.nan)
    return checks


def method_metrics(report: SolutionBatch, targets: Targets, formulation: Formulation, checks: dict[str, np.ndarray],
                   wall: float) -> dict[str, Any]:
    status = np.array(report.status)
    ok = status == "ok"
    reachable = targets.reachable
    metrics: dict[str, Any] = {
        "formulation": formulation.label(),
        "success [%]": 100.0 * ok[reachable].mean() if reachable.any() else float("nan"),
        "median residual": _stat(np.median, report.residual[ok]),
        "max residual": _stat(np.max, report.residual[ok]),
    }
    if targets.kind == "legs":
        metrics["max leg error ok, eqs. (7)-(9) [m]"] = _stat(np.max, checks["leg_error"][ok])
        metrics["ok within Table I"] = f"{int(checks['within_table_i'][ok].sum())}/{int(ok.sum())}"
    else:
        tip_error = checks["tip_error"]
        metrics["max tip error ok [m]"] = _stat(np.max, tip_error[ok])
        metrics["median tip error [m]"] = _stat(np.median, tip_error)
        within = reachable & (tip_error <= formulation.tolerance)
        metrics["tip within tolerance [%]"] = 100.0 * within.sum() / max(int(reachable.sum()), 1)
        if "angle_error" in checks:
            metrics["max angle error ok [rad]"] = _stat(np.max, checks["angle_error"][ok])
        metrics["median distance from rest"] = _stat(np.median, checks["rest_distance"])
        if "leg_margin" in checks:
            metrics["min leg margin [mm]"] = _stat(np.min, checks["leg_margin"]) * 1e3
            metrics["median leg margin [mm]"] = _stat(np.median, checks["leg_margin"]) * 1e3
            metrics["median deviation from distribution [mm]"] = _stat(np.median,
                                                                       checks["distribution_deviation"]) * 1e3
    if (~reachable).any():
        metrics["unreachable flagged"] = f"{int((status[~reachable] == 'unreachable').sum())}/{int((~reachable).sum())}"
        metrics["unreachable reported ok"] = int(ok[~reachable].sum())
    metrics.update({
        "median iterations": float(np.median(report.iterations)) if np.all(report.iterations >= 0) else None,
        "median time per solve [us]": float(np.median(report.seconds) * 1e6),
        "mean time per solve [us]": float(wall / len(report) * 1e6),
        "batched": report.batched,
        "statuses": ", ".join(f"{s}: {int((status == s).sum())}" for s in dict.fromkeys(report.status)),
    })
    return metrics


def run(ctx: ProblemContext) -> Result:
    spec, arm = ctx.spec, ctx.arm
    settings = Settings(ctx)
    targets = ctx.data_source.load(arm, spec.data, ctx.data_params, ctx.path, kind=settings.target)
    methods = methods_of(ctx, settings)

    reports: dict[str, SolutionBatch] = {}
    checks: dict[str, dict[str, np.ndarray]] = {}
    comparison = []
    with ctx.progress.task(f"ik: {len(targets)} targets x {len(methods)} methods", total=len(methods)) as advance:
        for method in methods:
            solve = solver_of(method.adapter, method.problem)
            solve(settings.start, targets.values[:1], False, None)  # build (and compile) before timing
            started = time.perf_counter()
            report = solve_targets(solve, targets, settings, method.formulation, ctx, arm)
            wall = time.perf_counter() - started
            reports[method.name] = report
            checks[method.name] = answer_checks(arm, targets, method.formulation, report.x)
            metrics = method_metrics(report, targets, method.formulation, checks[method.name], wall)
            comparison.append(MethodRow(method.name, method.role, metrics))
            advance()

    main = reports[ctx.solver.name]
    error = checks[ctx.solver.name]["leg_error" if targets.kind == "legs" else "tip_error"]
    arrays = {"targets": targets.values, "reachable": targets.reachable, "true_configurations": targets.configurations,
              "solutions": main.x, "error": error}
    for name, r in reports.items():
        key = array_key(name)
        arrays |= {f"residual_{key}": r.residual, f"status_{key}": np.array(r.status), f"solutions_{key}": r.x,
                   f"time_{key}": r.seconds, f"iterations_{key}": r.iterations}
        arrays |= {f"{check}_{key}": values for check, values in checks[name].items()}
    if targets.t is not None:
        arrays["t"] = targets.t
    metrics = {
        "targets": len(targets),
        "reachable targets": int(targets.reachable.sum()),
        "target": settings.target,
        "redundancy": settings.redundancy,
        "trajectory (warm-started)": targets.trajectory,
        "tolerance [m]": settings.tolerance,
    }

    def draw_targets(path):
        colour = np.log10(np.maximum(main.residual, 1e-18))
        if targets.kind == "legs":
            tips = arm.evaluate("fk_position", np.where(np.isfinite(main.x), main.x, settings.start))
            title = f"{spec.name}: tips of the solved configurations ({ctx.solver.name})"
        else:
            tips, title = targets.positions, f"{spec.name}: targets ({ctx.solver.name})"
        plots.scatter_3d(path, tips, title, colour=colour, colour_label="log10 residual")

    def draw_trajectory(path):
        series = {"residual": main.residual[:, None], "error [mm]": error[:, None] * 1e3}
        plots.time_series(path, targets.t, series, "", f"{spec.name}: along the trajectory", labels=("",))

    figures = {"targets": draw_targets}
    if targets.t is not None:
        figures["trajectory"] = draw_trajectory
    if targets.kind != "legs":
        figures["comparison"] = lambda path: draw_comparison(path, spec.name, reports, checks)
    notes = []
    for name, r in reports.items():
        for status in ("failed", "timeout"):
            where = [i for i, s in enumerate(r.status) if s == status]
            if where:
                notes.append(f"{name}: {len(where)} samples {status}, e.g. sample {where[0]}: {r.messages[where[0]]}")
    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=arm.describe(),
        status=list(main.status), iterations=main.iterations, residuals=main.residual,
        timings={"median per solve [us]": float(np.median(main.seconds) * 1e6)},
        metrics=metrics, comparison=comparison, arrays=arrays, figures=figures, notes=notes,
    )


register_kind(ProblemKind(
    options=None,
    name="ik",
    summary="inverse kinematics by Newton / nonlinear least squares, backends compared on the same targets",
    run=run,
    backend_families=(FAMILY,),
    default_solver="gauss-newton",
    baselines=(),
    data_family=TARGETS,
))
