"""Problem kind ``dmp``: learn a demonstrated motion with DMPs and generalise it (issue 5; seed 000 secs. III-IV).

The methods under study are the weight regression posed in cvxpy (all weights
at once, optional ridge and bounds) and the gain tuning by a gradient-based
NLP (IPOPT through CasADi, :mod:`optikin.dmp.tuning`); the baselines, run on
the same demonstration, are the closed-form fit (``lstsq``), locally weighted
regression (``lwr``) and the seed's genetic algorithm (``genetic``). Each
DMP representation listed in ``variants`` learns the demonstration and is
rolled out: reproduction, and optionally a goal switch and a perturbation.

Demonstrations (``data.source``, :mod:`optikin.data.demonstrations`)::

    data:
      source: imu        # imu | kinect | smooth | gimbal | csv
      seed: 7
      samples: 1000      # imu / kinect / smooth / gimbal
      params: {...}      # the keyword arguments of the source's function (imu: the sections
                         # default to the arm's); csv: {path: demo.csv (relative to the
                         # problem file), samples: N (resample)}

Options (all optional)::

    variants: [cartesian]   # seed | dual-quaternion | cartesian | quaternion | rpy | position
    n_basis: 50
    smoothing: null         # cutoff [Hz] of the low-pass applied to the demonstration before learning
                            # (optikin.dmp.smoothing; sensor data), null: learn the samples as given
    gains: {beta: 25, gamma: 6.25, zeta: 4.6, beta_g0: .inf, alpha_s: 0, alpha: 0}
    regression: {method: cvxpy, ridge: 0.0, bound: null}   # bound: |w| <= bound (cvxpy only)
    goal_switches: [{time: 4.0, rotate: [rx, ry, rz], translate: [x, y, z]}]  # new goals relative to the last
    disturbance: {start: 5.0, stop: 7.0, amplitude: 1.0, component: 0}       # step force in eq. (17)
    couplings: {coupled: {alpha_s: 5.0}}   # label -> {alpha_s, alpha, phase_stopping} of each DMP coupled
                                           # to the demonstration (eq. 27) and run against the plain one under
                                           # the disturbance; alpha > 0 needs phase_stopping: seed (eq. 28);
                                           # each reports its peak and final deviation from its own
                                           # undisturbed roll-out and its phase at the end
    tuning: {gains: [beta, gamma, zeta], variant: quaternion, scenario: reproduction,
             max_iterations: 60, screen: 16, starts: 2,    # IPOPT: iterations per start; Latin-hypercube
             population: 20, generations: 15}               # screening points; starts from the best of them
    settle: 5.0     # goal-switch roll-outs last settle x tau; the final errors measure convergence
    tolerance: {position_mm: 0.01, orientation_mrad: 0.01}

Per-roll-out status (one per variant and scenario): ``ok``; ``failed`` for a
non-finite roll-out or a unit quaternion / dual quaternion off by more than
1e-9; ``not_converged`` when a goal-switch roll-out ends farther than the
tolerance from its goal.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optikin import plots
from optikin.algebra import (
    dq_from_rotation_translation,
    dq_norm_residual,
    dq_rotation,
    dq_translation,
    quat_angle,
    quat_conjugate,
    quat_exp,
    quat_from_rpy,
    quat_multiply,
    rpy_from_quat,
)
from optikin.data import demonstrations as sources
from optikin.dmp import DMP, Euclidean, Gains, UnitQuaternion
from optikin.dmp.pose import POSE_VARIANTS, pose_dmp
from optikin.dmp.tuning import tune_genetic, tune_gradient, tuning_problem
from optikin.errors import InputDataError, OptikinError, SpecError
from optikin.problems import ProblemContext, ProblemKind, register_kind
from optikin.problems.dmp.options import Coupling, DmpOptions, GoalSwitch, Tuning
from optikin.results import MethodRow, Result

MM, MRAD = 1e3, 1e3


# ----------------------------------------------------------------------------- reading the problem file


def load_demonstration(ctx: ProblemContext) -> tuple[sources.PoseDemonstration, Any]:
    """The demonstration of ``data`` and the recording it came from."""
    recording = ctx.load_data()
    return sources.pose_demonstration(recording), recording


# ----------------------------------------------------------------------------- variants


def make_dmp(variant: str, n_basis: int, gains: Gains, **options) -> DMP:
    """The DMP of a variant label; ``options``: the other keyword arguments of :class:`DMP` (smoothing, ...)."""
    if variant in POSE_VARIANTS:
        return pose_dmp(variant, n_basis=n_basis, gains=gains, **options)
    space = UnitQuaternion() if variant == "quaternion" else Euclidean(3)
    return DMP(space, n_basis=n_basis, gains=gains, **options)


def variant_data(variant: str, position: np.ndarray, quaternion: np.ndarray,
                 rpy_reference: np.ndarray | None = None) -> np.ndarray:
    """Poses ``(..., size)`` in the state layout of a variant; ``rpy`` angles are unwrapped (near ``rpy_reference``)."""
    if variant in ("seed", "dual-quaternion"):
        return dq_from_rotation_translation(quaternion, position)
    if variant == "cartesian":
        return np.concatenate([position, quaternion], axis=-1)
    if variant == "quaternion":
        return quaternion
    if variant == "position":
        return position
    rpy = rpy_from_quat(quaternion)
    if rpy.ndim == 2:
        return np.unwrap(rpy, axis=0)
    return rpy + 2 * np.pi * np.round((rpy_reference - rpy) / (2 * np.pi))


def variant_pose(variant: str, y: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(positions, quaternions)`` of states of a variant (``None`` where it has none)."""
    if variant in ("seed", "dual-quaternion"):
        return dq_translation(y), dq_rotation(y)
    if variant == "cartesian":
        return y[..., :3], y[..., 3:]
    if variant == "quaternion":
        return None, y
    if variant == "position":
        return y, None
    return None, quat_from_rpy(y[..., 0], y[..., 1], y[..., 2])


def pose_errors(variant: str, y: np.ndarray, position: np.ndarray, quaternion: np.ndarray) -> dict[str, np.ndarray]:
    """Per-sample position error [m] and orientation error [rad] of roll-out states against poses."""
    p, q = variant_pose(variant, y)
    errors = {}
    if p is not None:
        errors["position"] = np.linalg.norm(p - position, axis=-1)
    if q is not None:
        errors["orientation"] = quat_angle(quat_multiply(q, quat_conjugate(quaternion)))
    return errors


def unit_error(variant: str, y: np.ndarray) -> float:
    """Largest departure from unit norm of the quaternion parts the variant should keep unit."""
    if variant == "dual-quaternion":
        n, d = dq_norm_residual(y)
        return float(max(np.abs(n).max(), np.abs(d).max()))
    if variant in ("seed", "quaternion"):
        return float(np.abs(np.linalg.norm(y[..., :4], axis=-1) - 1).max())
    if variant == "cartesian":
        return float(np.abs(np.linalg.norm(y[..., 3:], axis=-1) - 1).max())
    return 0.0


def _summary(errors: dict[str, np.ndarray], prefix: str) -> dict[str, float]:
    out = {}
    if "position" in errors:
        out[f"{prefix} position max [mm]"] = float(errors["position"].max() * MM)
    if "orientation" in errors:
        out[f"{prefix} orientation max [mrad]"] = float(errors["orientation"].max() * MRAD)
    return out


# ----------------------------------------------------------------------------- the run


def run(ctx: ProblemContext) -> Result:
    spec = ctx.spec
    o: DmpOptions = ctx.options
    variants = list(o.variants)
    n_basis = o.n_basis
    smoothing = o.smoothing
    gains = o.gains.gains()
    regression = o.regression
    bound = regression.bound
    settle = o.settle
    tolerance = o.tolerance

    demo, recording = load_demonstration(ctx)
    tau = float(demo.t[-1] - demo.t[0])
    truth = _true_motion(ctx, recording)
    final_rpy = np.unwrap(rpy_from_quat(demo.quaternion), axis=0)[-1]

    def fit(dmp: DMP, variant: str, method: str, source: str):
        kwargs: dict[str, Any] = {"ridge": regression.ridge}
        if method == "cvxpy" and bound is not None:
            kwargs.update(lower=-float(bound), upper=float(bound))
        if method == "lwr":
            kwargs = {}
        try:
            return dmp.imitate(demo.t, variant_data(variant, demo.position, demo.quaternion), method=method,
                               source=source, **kwargs)
        except InputDataError:
            raise
        except OptikinError as exc:
            raise SpecError(ctx.path, "options.regression", str(exc)) from None

    source = f"{ctx.path.name}: data ({spec.data.source})"
    models: dict[str, DMP] = {}
    fits: dict[str, Any] = {}
    rollouts: dict[tuple[str, str], np.ndarray] = {}
    status: list[str] = []
    labels: list[str] = []
    metrics: dict[str, Any] = {"demonstration samples": int(demo.t.size), "demonstration duration [s]": tau}
    comparison: list[MethodRow] = []
    notes: list[str] = []

    with ctx.progress.task(f"dmp: {len(variants)} variants", total=len(variants)) as advance:
        for variant in variants:
            dmp = make_dmp(variant, n_basis, gains, smoothing=smoothing)
            fits[variant] = fit(dmp, variant, regression.method, source)
            models[variant] = dmp
            out = dmp.rollout()
            rollouts[(variant, "reproduction")] = out.y
            errors = pose_errors(variant, out.y, demo.position, demo.quaternion)
            row = {"fit residual": fits[variant].residual, "fit time [ms]": fits[variant].seconds * 1e3,
                   "roll-out time [ms]": out.seconds * 1e3, **_summary(errors, "reproduction")}
            if truth is not None:  # the recording's noise-free motion
                row |= _summary(pose_errors(variant, out.y, *truth), "vs true motion")
            row["unit-norm error"] = unit_error(variant, out.y)
            labels.append(f"{variant}: reproduction")
            status.append(_status(out.y, row["unit-norm error"]))
            comparison.append(MethodRow(f"dmp {variant} ({regression.method})", "solver", row))
            advance()

    # The regression methods compared on the first variant.
    first = variants[0]
    for method in spec.baselines:
        if method not in ("lstsq", "lwr") or method == regression.method:
            continue
        dmp = make_dmp(first, n_basis, gains, smoothing=smoothing)
        baseline_fit = fit(dmp, first, method, source)
        out = dmp.rollout()
        errors = pose_errors(first, out.y, demo.position, demo.quaternion)
        comparison.append(MethodRow(f"dmp {first} ({method})", "baseline", {
            "fit residual": baseline_fit.residual, "fit time [ms]": baseline_fit.seconds * 1e3,
            "roll-out time [ms]": out.seconds * 1e3, **_summary(errors, "reproduction")}))

    goals = _goal_switches(ctx, o.goal_switches, demo, tau)
    if goals:
        for variant, dmp in models.items():
            switches = [(when, variant_data(variant, p, q, final_rpy)) for when, p, q in goals]
            out = dmp.rollout(duration=settle * tau, goal_switches=switches)
            rollouts[(variant, "goal switch")] = out.y
            _, p_goal, q_goal = goals[-1]
            final = pose_errors(variant, out.y[-1:], p_goal, q_goal)
            metrics |= {f"{variant}: goal switch final {k} [{'mm' if k == 'position' else 'mrad'}]":
                        float(v[0] * (MM if k == "position" else MRAD)) for k, v in final.items()}
            labels.append(f"{variant}: goal switch")
            converged = (final.get("position", np.zeros(1))[0] * MM <= tolerance.position_mm
                         and final.get("orientation", np.zeros(1))[0] * MRAD <= tolerance.orientation_mrad)
            state = _status(out.y, unit_error(variant, out.y))
            status.append(state if state != "ok" or converged else "not_converged")

    if o.disturbance is not None:
        d = o.disturbance
        couplings = o.couplings
        for variant in variants:
            dim = models[variant].space.dim
            component = d.component
            if not 0 <= component < dim:
                raise ctx.error("options.disturbance.component", f"must be in 0 .. {dim - 1} for {variant}")

            def step(t, component=component, dim=dim):
                force = np.zeros((t.size, dim))
                force[(t >= d.start) & (t < d.stop), component] = d.amplitude
                return force

            runs: list[tuple[str, Coupling | None]] = [("plain", None), *couplings.items()]
            for label, extra in runs:
                coupled_gains = gains if extra is None else gains.with_values(alpha_s=extra.alpha_s,
                                                                              alpha=extra.alpha)
                dmp = make_dmp(variant, n_basis, coupled_gains, smoothing=smoothing,
                               phase_stopping="tracking" if extra is None else extra.phase_stopping)
                fit(dmp, variant, regression.method, source)
                coupled_to = None if extra is None else dmp.demo.Y  # the demonstration as learned (smoothed if asked)
                calm = dmp.rollout(reference=coupled_to)
                out = dmp.rollout(disturbance=step, reference=coupled_to)
                rollouts[(variant, f"perturbation {label}")] = out.y
                # the disturbance's effect: the deviation from the same DMP's undisturbed roll-out
                p_calm, q_calm = variant_pose(variant, calm.y)
                deviation = pose_errors(variant, out.y, p_calm, q_calm)
                for k, v in deviation.items():
                    unit, scale = ("mm", MM) if k == "position" else ("mrad", MRAD)
                    metrics[f"{variant}: perturbation {label} peak {k} deviation [{unit}]"] = float(v.max() * scale)
                    metrics[f"{variant}: perturbation {label} final {k} deviation [{unit}]"] = float(v[-1] * scale)
                metrics[f"{variant}: perturbation {label} phase at the end"] = float(out.phase[-1])
                metrics[f"{variant}: perturbation {label} undisturbed phase at the end"] = float(calm.phase[-1])
                labels.append(f"{variant}: perturbation {label}")
                status.append(_status(out.y, unit_error(variant, out.y)))

    if o.tuning is not None:
        comparison += _tuning(ctx, o.tuning, demo, variants, n_basis, gains, smoothing, goals, final_rpy)

    arrays: dict[str, np.ndarray] = {"t": demo.t, "demo_position": demo.position, "demo_quaternion": demo.quaternion}
    for (variant, scenario), y in rollouts.items():
        arrays[f"{variant}__{scenario.replace(' ', '_')}"] = y
    if recording is not None and hasattr(recording, "imu"):
        arrays |= {"imu": recording.imu, "relative": recording.relative, "section_angles": recording.angles}
    if recording is not None and hasattr(recording, "filtered_rpy"):
        arrays |= {"kinect_position": recording.position, "kinect_rpy": recording.rpy,
                   "kinect_filtered_rpy": recording.filtered_rpy}
    if "seed" in variants:
        qd = rollouts[("seed", "reproduction")][:, 4:]
        notes.append("seed variant: |Q_d| stays at its initial value "
                     f"({np.linalg.norm(qd[0]):.4f}; demonstration ends at "
                     f"{np.linalg.norm(demo.dual_quaternion[-1, 4:]):.4f}), so the tip cannot change its "
                     "distance from the origin (optikin.dmp.pose)")
    notes.append(f"labels of the per-roll-out status: {labels}")
    return Result(problem=spec.name, kind=spec.kind, solver=f"{regression.method} regression",
                  title=spec.title, arm={"demonstration": spec.data.source}, status=status,
                  timings={"fit [ms]": fits[first].seconds * 1e3}, metrics=metrics, comparison=comparison,
                  arrays=arrays, figures=_figures(spec.name, demo, variants, rollouts), notes=notes)


def _true_motion(ctx: ProblemContext, recording: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """The noise-free tip motion of an IMU recording (forward kinematics of its true configurations)."""
    if not isinstance(recording, sources.InterfaceRecording):
        return None
    quaternion, position = ctx.arm.section_frames(recording.configuration)[-1]
    sign = np.where(np.sum(quaternion * recording.demonstration.quaternion, axis=1) < 0, -1.0, 1.0)
    return position, quaternion * sign[:, None]


def _status(y: np.ndarray, unit: float) -> str:
    return "ok" if np.isfinite(y).all() and unit < 1e-9 else "failed"


def _goal_switches(ctx: ProblemContext, given: tuple[GoalSwitch, ...], demo,
                   tau: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``(time, position, quaternion)`` of each new goal, each relative to the goal before it."""
    goals, position, quaternion = [], demo.position[-1], demo.quaternion[-1]
    for i, switch in enumerate(given):
        if not switch.time <= 3 * tau:
            raise ctx.error(f"options.goal_switches.{i}.time", f"must be within 0 .. {3 * tau:.3g} s")
        position = position + np.asarray(switch.translate)
        quaternion = quat_multiply(quat_exp(0.5 * np.asarray(switch.rotate)), quaternion)
        goals.append((switch.time, position, quaternion))
    return goals


def _tuning(ctx: ProblemContext, s: Tuning, demo, variants: list[str], n_basis: int, gains: Gains,
            smoothing: float | None, goals, final_rpy) -> list[MethodRow]:
    names = tuple(s.gains)
    variant = s.variant or variants[0]
    extra = {}
    if s.scenario == "goal":
        if not goals:
            raise ctx.error("options.tuning.scenario", "the goal scenario needs options.goal_switches")
        when, p, q = goals[0]
        extra = {"new_goal": variant_data(variant, p, q, final_rpy), "switch_time": when}
    dmp = make_dmp(variant, n_basis, gains, smoothing=smoothing)
    problem = tuning_problem(dmp, demo.t, variant_data(variant, demo.position, demo.quaternion), names,
                             scenario=s.scenario, **extra)
    rows = []
    with ctx.progress.task(f"dmp: tuning {', '.join(names)}", total=2) as advance:
        results = [tune_gradient(problem, max_iterations=s.max_iterations, screen=s.screen,
                                 starts=s.starts, seed=ctx.spec.data.seed)]
        advance()
        if "genetic" in ctx.spec.baselines:
            results.append(tune_genetic(problem, population=s.population, generations=s.generations,
                                        seed=ctx.spec.data.seed))
        advance()
    for result in results:
        metrics = {"eq. 29 error": result.error, "eq. 29 error at start": result.initial_error,
                   "time [s]": result.seconds, "objective evaluations": result.evaluations,
                   "status": result.status, **{n: getattr(result.gains, n) for n in names}}
        rows.append(MethodRow(f"tuning {variant} ({result.method})",
                              "solver" if result.method == "ipopt" else "baseline", metrics))
    return rows


def _figures(name: str, demo, variants: list[str], rollouts: dict[tuple[str, str], np.ndarray]) -> dict:
    figures = {}

    def errors_figure(scenario: str):
        def draw(path):
            series = {}
            for variant in variants:
                y = rollouts.get((variant, scenario))
                if y is None:
                    continue
                n = min(len(y), len(demo.t))
                for k, v in pose_errors(variant, y[:n], demo.position[:n], demo.quaternion[:n]).items():
                    unit = MM if k == "position" else MRAD
                    series[f"{variant} {k}"] = v[:, None] * unit
            plots.time_series(path, demo.t[:n], series, "[mm | mrad]", f"{name}: {scenario} error",
                              labels=("error",))
        return draw

    def quaternion_figure(variant: str, scenario: str):
        def draw(path):
            y = rollouts[(variant, scenario)]
            _, q = variant_pose(variant, y)
            t = np.arange(len(y)) * (demo.t[1] - demo.t[0])
            series = {f"{variant} Q_r": q}
            if variant in ("seed", "dual-quaternion"):
                series[f"{variant} Q_d"] = y[:, 4:]
            if len(y) == len(demo.t):  # the demonstration above its reproduction
                series = {"demonstration Q_r": demo.quaternion, **series}
                if variant in ("seed", "dual-quaternion"):
                    series = {"demonstration Q_d": demo.dual_quaternion[:, 4:], **series}
            plots.time_series(path, t, series, "", f"{name}: {variant}, {scenario}", labels=("w", "x", "y", "z"))
        return draw

    figures["reproduction_error"] = errors_figure("reproduction")
    for variant in variants:
        if variant in ("position", "rpy"):
            continue
        for scenario in ("reproduction", "goal switch", "perturbation coupled"):
            if (variant, scenario) in rollouts:
                figures[f"{variant}_{scenario.replace(' ', '_')}"] = quaternion_figure(variant, scenario)
    return figures


register_kind(ProblemKind(
    name="dmp",
    summary="learn a demonstrated motion with DMPs (cvxpy regression, NLP gain tuning) and generalise it",
    run=run,
    backend_families=(),
    default_solver=None,
    baselines=("lstsq", "lwr", "genetic"),
    options=DmpOptions,
    data_family="demonstrations",
))
