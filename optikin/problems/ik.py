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
  (:mod:`optikin.problems.ik_platform`); ``||r||`` in metres of leg length.

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
                  the start point (the pseudo-inverse Newton-Raphson iteration).

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
family) solves the same targets in the same run; each row of the comparison
reports the success rate on reachable targets, how unreachable targets were
flagged, residuals, the tip error recomputed independently with ``fk_dq``,
iterations and time per solve.

Options: ``target``, ``redundancy``, ``rest``, ``weights``, ``start`` (``rest`` or
a configuration), ``restarts`` (default 2), ``tolerance`` (``||r||`` in metres
counted as solved, default 1e-10), ``orientation_length``.
"""

from __future__ import annotations

import time
from typing import Any, Callable

import casadi as ca
import numpy as np

from optikin import plots
from optikin.algebra import dq_rotation, dq_translation, quat_angle, quat_conjugate, quat_multiply
from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm, printed_leg_lengths
from optikin.data.targets import TARGET_KINDS, TARGET_SOURCES, Targets, reach_bound
from optikin.errors import SpecError
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.problems.ik_platform import platform_problems, solve_platforms
from optikin.registry import BACKENDS
from optikin.results import MethodRow, Result
from optikin.solvers.nonlinear import FAMILY, BatchReport, LeastSquaresProblem, NonlinearAdapter
from optikin.spec import load_solver

REDUNDANCY_CHOICES = ("rest", "previous", "minimum_norm")
DEFAULTS: dict[str, Any] = {"target": "position", "redundancy": "rest", "rest": None, "weights": None,
                            "start": "rest", "restarts": 2, "tolerance": 1e-10, "orientation_length": None}


# --------------------------------------------------------------------------------------- the problem
def tip_residual(arm: ArmModel, target: str, orientation_length: float) -> ca.Function:
    """``r(q, target)``: the tip position error; for poses also ``2 L vec(q_target^-1 q_tip)``."""
    q = ca.SX.sym("q", arm.n_config)
    quat, position = arm.section_frames(q)[-1]
    if target == "position":
        p = ca.SX.sym("p", 3)
        return ca.Function(f"{arm.name}_ik_position", [q, p], [position - p], ["q", "p"], ["r"])
    p = ca.SX.sym("dq", 8)
    error = quat_multiply(quat_conjugate(dq_rotation(p)), quat)
    r = ca.vertcat(position - dq_translation(p), orientation_length * 2.0 * error[1:])
    return ca.Function(f"{arm.name}_ik_pose", [q, p], [r], ["q", "dq"], ["r"])


def rest_configuration(arm: ArmModel) -> np.ndarray:
    """Straight at nominal lengths when the arm defines it, else the middle of the bounds."""
    straight = getattr(arm, "straight_configuration", None)
    return straight() if callable(straight) else 0.5 * (arm.lower + arm.upper)


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


def leg_checks(arm: ArmModel, targets: Targets, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest leg-length error per sample by the printed eqs. (7)-(9) of seed 004 (an independent
    transcription), and whether every leg lies within Table I."""
    Z, theta, psi = np.moveaxis(X.reshape(len(X), -1, 3), 2, 0)
    radii = arm.geometry.radii
    legs = np.stack(printed_leg_lengths(Z, theta, psi, radii[:-1], radii[1:]), axis=2).reshape(len(X), -1)
    lo, hi = arm.leg_limits()
    return np.abs(legs - targets.values).max(axis=1), np.all((legs >= lo - 1e-12) & (legs <= hi + 1e-12), axis=1)


# --------------------------------------------------------------------------------------- options
class Settings:
    """The validated ``options`` of an ``ik`` problem file."""

    def __init__(self, ctx: ProblemContext):
        arm = ctx.arm
        for key in ctx.spec.options:
            if key not in DEFAULTS:
                raise ctx.error(f"options.{key}", f"unknown option of kind ik; known: {', '.join(DEFAULTS)}")
        o = {**DEFAULTS, **ctx.spec.options}
        if o["target"] not in TARGET_KINDS:
            raise ctx.error("options.target", f"{o['target']!r} is not one of {', '.join(TARGET_KINDS)}")
        if o["redundancy"] not in REDUNDANCY_CHOICES:
            raise ctx.error("options.redundancy",
                            f"{o['redundancy']!r} is not one of {', '.join(REDUNDANCY_CHOICES)}")
        if o["target"] == "legs" and not isinstance(arm, CBHAArm):
            raise ctx.error("options.target", f"leg-length targets need a cbha arm, not {ctx.spec.arm.type!r}")
        self.target: str = o["target"]
        self.redundancy: str = o["redundancy"]
        self.rest = self._configuration(ctx, "rest", o["rest"], rest_configuration(arm))
        self.start = self.rest if o["start"] == "rest" else self._configuration(ctx, "start", o["start"], None)
        weights = 1.0 / (arm.upper - arm.lower) if o["weights"] is None else o["weights"]
        self.weights = self._vector(ctx, "weights", weights)
        if np.any(self.weights <= 0):
            raise ctx.error("options.weights", "every weight must be positive")
        self.restarts = o["restarts"]
        if isinstance(self.restarts, bool) or not isinstance(self.restarts, int) or self.restarts < 0:
            raise ctx.error("options.restarts", f"expected a count >= 0, got {self.restarts!r}")
        self.tolerance = self._positive(ctx, "tolerance", o["tolerance"])
        self.orientation_length = 1.0
        if self.target == "pose":
            length = reach_bound(arm) if o["orientation_length"] is None else o["orientation_length"]
            self.orientation_length = self._positive(ctx, "orientation_length", length)

    @staticmethod
    def _positive(ctx: ProblemContext, key: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise ctx.error(f"options.{key}", f"expected a positive number, got {value!r}")
        return float(value)

    @staticmethod
    def _vector(ctx: ProblemContext, key: str, value: Any) -> np.ndarray:
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ctx.error(f"options.{key}", f"expected {ctx.arm.n_config} numbers, got {value!r}") from None
        if v.shape != (ctx.arm.n_config,) or not np.all(np.isfinite(v)):
            raise ctx.error(f"options.{key}",
                            f"expected {ctx.arm.n_config} numbers ({', '.join(ctx.arm.config_names)}), got {value!r}")
        return v

    def _configuration(self, ctx: ProblemContext, key: str, value: Any, default: np.ndarray | None) -> np.ndarray:
        if value is None:
            return default
        q = self._vector(ctx, key, value)
        span = ctx.arm.upper - ctx.arm.lower
        outside = (q < ctx.arm.lower - 1e-12 * span) | (q > ctx.arm.upper + 1e-12 * span)
        if outside.any():
            j = int(np.argmax(outside))
            raise ctx.error(f"options.{key}", f"{ctx.arm.config_names[j]} = {q[j]:.6g} outside its bounds "
                                              f"[{ctx.arm.lower[j]:.6g}, {ctx.arm.upper[j]:.6g}]")
        return q


def build_problem(arm: ArmModel, settings: Settings) -> LeastSquaresProblem | list[LeastSquaresProblem]:
    """The least-squares problem of the target kind; for CBHA leg lengths, one per platform.

    A CBHA's leg lengths must stay within Table I (seed 004): they are the problem's constraints.
    """
    if settings.target == "legs":
        return platform_problems(arm, settings.tolerance)
    residual = tip_residual(arm, settings.target, settings.orientation_length)
    limits = {}
    if isinstance(arm, CBHAArm):
        lower, upper = arm.leg_limits()
        limits = {"constraints": arm.leg_lengths, "constraint_lower": lower, "constraint_upper": upper,
                  "constraint_names": arm.leg_names}
    return LeastSquaresProblem(residual, arm.lower, arm.upper, arm.periodic, tolerance=settings.tolerance,
                               weights=settings.weights, name=f"{arm.name}_ik_{settings.target}",
                               variable_names=arm.config_names, **limits)


# --------------------------------------------------------------------------------------- solving
def adapters(ctx: ProblemContext) -> list[tuple[str, str, NonlinearAdapter]]:
    """``(preset name, role, adapter)``: the problem's solver, then each baseline preset not already listed."""
    methods = [(ctx.solver.name, "solver", ctx.adapter)]
    for name in ctx.spec.baselines:
        if name in [m[0] for m in methods]:
            continue
        preset, _ = load_solver(name)  # the runner checked that it is a preset of this kind's family
        methods.append((name, "baseline", BACKENDS.get(preset.backend).build(preset)))
    return methods


Solve = Callable[[np.ndarray, np.ndarray, bool, "np.ndarray | None"], BatchReport]
"""``(starts, targets, warm_start, x_ref) -> BatchReport``: one backend on one kind of target."""


def solver_of(adapter: NonlinearAdapter, problem: LeastSquaresProblem | list[LeastSquaresProblem]) -> Solve:
    if isinstance(problem, list):  # CBHA platforms, one problem each
        return lambda X0, P, warm, x_ref: solve_platforms(adapter, problem, P, X0, warm)
    return lambda X0, P, warm, x_ref: adapter.solve_many(problem, X0, P, warm_start=warm, x_ref=x_ref)


def solve_targets(solve: Solve, targets: Targets, settings: Settings, ctx: ProblemContext,
                  arm: ArmModel) -> BatchReport:
    """Solve every target (module docstring): warm-started along a trajectory, batched and retried otherwise."""
    x_ref = settings.rest if settings.redundancy == "rest" else None
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
            report.time[i] += again.time[j]
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


def method_metrics(report: BatchReport, targets: Targets, arm: ArmModel, wall: float) -> dict[str, Any]:
    status = np.array(report.status)
    ok = status == "ok"
    reachable = targets.reachable
    metrics: dict[str, Any] = {
        "success [%]": 100.0 * ok[reachable].mean() if reachable.any() else float("nan"),
        "median residual": float(np.median(report.residual[ok])) if ok.any() else float("nan"),
        "max residual": float(np.max(report.residual[ok])) if ok.any() else float("nan"),
    }
    if targets.kind == "legs":
        leg_error, within = leg_checks(arm, targets, report.x)
        metrics["max leg error ok, eqs. (7)-(9) [m]"] = float(np.max(leg_error[ok])) if ok.any() else float("nan")
        metrics["ok within Table I"] = f"{int(within[ok].sum())}/{int(ok.sum())}"
    else:
        position_error, angle_error = tip_errors(arm, targets, report.x)
        metrics["max tip error ok [m]"] = float(np.max(position_error[ok])) if ok.any() else float("nan")
        if angle_error is not None:
            metrics["max angle error ok [rad]"] = float(np.max(angle_error[ok])) if ok.any() else float("nan")
    if (~reachable).any():
        metrics["unreachable flagged"] = f"{int((status[~reachable] == 'unreachable').sum())}/{int((~reachable).sum())}"
        metrics["unreachable reported ok"] = int(ok[~reachable].sum())
    metrics.update({
        "median iterations": float(np.median(report.iterations)),
        "median time per solve [us]": float(np.median(report.time) * 1e6),
        "mean time per solve [us]": float(wall / len(report) * 1e6),
        "batched": report.batched,
        "statuses": ", ".join(f"{s}: {int((status == s).sum())}" for s in dict.fromkeys(report.status)),
    })
    return metrics


def run(ctx: ProblemContext) -> Result:
    spec, arm = ctx.spec, ctx.arm
    settings = Settings(ctx)
    try:
        source = TARGET_SOURCES.get(spec.data.source)
    except Exception as exc:
        raise SpecError(ctx.path, "data.source", str(exc)) from None
    targets = source(arm, spec.data, ctx.path, settings.target)
    problem = build_problem(arm, settings)
    methods = adapters(ctx)

    reports: dict[str, BatchReport] = {}
    comparison = []
    with ctx.progress.task(f"ik: {len(targets)} targets x {len(methods)} methods", total=len(methods)) as advance:
        for name, role, adapter in methods:
            solve = solver_of(adapter, problem)
            solve(settings.start, targets.values[:1], False, None)  # build (and compile) before timing
            started = time.perf_counter()
            report = solve_targets(solve, targets, settings, ctx, arm)
            wall = time.perf_counter() - started
            reports[name] = report
            comparison.append(MethodRow(name, role, method_metrics(report, targets, arm, wall)))
            advance()

    main = reports[ctx.solver.name]
    if targets.kind == "legs":
        error = leg_checks(arm, targets, main.x)[0]
    else:
        error = tip_errors(arm, targets, main.x)[0]
    arrays = {"targets": targets.values, "reachable": targets.reachable, "true_configurations": targets.configurations,
              "solutions": main.x, "error": error}
    arrays |= {f"residual_{name}": r.residual for name, r in reports.items()}
    arrays |= {f"status_{name}": np.array(r.status) for name, r in reports.items()}
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
    notes = []
    for name, r in reports.items():
        for status in ("failed", "timeout"):
            where = [i for i, s in enumerate(r.status) if s == status]
            if where:
                notes.append(f"{name}: {len(where)} samples {status}, e.g. sample {where[0]}: {r.messages[where[0]]}")
    return Result(
        problem=spec.name, kind=spec.kind, solver=ctx.solver.name, title=spec.title, arm=arm.describe(),
        status=list(main.status), iterations=main.iterations, residuals=main.residual,
        timings={"median per solve [us]": float(np.median(main.time) * 1e6)},
        metrics=metrics, comparison=comparison, arrays=arrays, figures=figures, notes=notes,
    )


register_kind(ProblemKind(
    name="ik",
    summary="inverse kinematics by Newton / nonlinear least squares, backends compared on the same targets",
    run=run,
    backend_families=(FAMILY,),
    default_solver="gauss-newton",
    baselines=(),
))
