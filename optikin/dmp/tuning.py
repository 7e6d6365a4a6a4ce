"""DMP gains chosen by optimisation: the reproduction error of Seleem et al. (2020) eq. (29) as a CasADi Function.

Seleem et al. (2020) pick ``beta, gamma, zeta`` by a genetic algorithm minimising
``FT = sum_i E_i^2`` (eq. 29), the squared error between demonstrated and
reproduced ``Q_r`` (or ``Q_d``) over the components and samples, and
``beta_g0, alpha_s`` by the same algorithm minimising the error between the
roll-out and a new goal (Figs. 5-6). Here the whole chain

    gains -> design matrix (phase, centres, widths) and target forces  (eqs. 13-16, 21-22, 25)
          -> weights by least squares (normal equations, unit-norm columns, a 1e-10 ridge)
          -> roll-out (:mod:`optikin.dmp.rollout`)                       (eqs. 11-12, 17-28)
          -> mean over samples of sum_i E_i^2                            (eq. 29)

is one CasADi graph of the gains' logarithms (positive gains, scale-free
steps), so a gradient-based NLP solver gets exact derivatives
(:func:`tune_gradient`: IPOPT with a limited-memory Hessian, started from the
best points of a Latin-hypercube screening of the box, since eq. (29) is not
convex in the gains), and the GA baseline (:mod:`optikin.baselines.genetic`)
evaluates the very same Function on a whole population at once
(:func:`tune_genetic`).

Scenarios: ``reproduction`` (the roll-out against the demonstration) and
``goal`` (a switch to ``new_goal`` at ``switch_time``; the roll-out against
the new goal from the switch on).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Literal, get_args

import casadi as ca
import numpy as np
from scipy.optimize import minimize
from scipy.stats import qmc

from optikin.algebra import backend as B
from optikin.baselines import genetic
from optikin.dmp.gains import GAIN_NAMES, Gains, stable_bounds
from optikin.dmp.imitation import design_matrix, target_forces
from optikin.dmp.model import DMP
from optikin.dmp.rollout import rollout_function
from optikin.errors import InputDataError, SolverError

Scenario = Literal["reproduction", "goal"]
"""What eq. (29) measures: the reproduction of the demonstration, or the approach to a new goal."""
SCENARIOS: tuple[Scenario, ...] = get_args(Scenario)
RIDGE = 1e-10
"""Ridge weight of the regression inside the graph: keeps ``X'X`` invertible, far below the data's scale."""


@dataclass(frozen=True)
class TuningProblem:
    """``objective(log gains) -> eq. (29)`` for the gains ``names``, with bounds and the starting point.

    Attributes
    ----------
    names:
        The tuned gains (:data:`~optikin.dmp.gains.GAIN_NAMES`).
    objective:
        CasADi Function ``log_gains (n,) -> error``: eq. (29), the squared error
        summed over components and averaged over samples (gap-layout units squared).
    lower, upper:
        ``(n,)`` bounds on the gains (not their logarithms).
    initial:
        ``(n,)`` starting gains (the DMP's, clipped into the bounds).
    fixed:
        The gains not tuned.
    dim:
        Gap components of the DMP (the length of a diagonal ``beta_g0``).
    """

    names: tuple[str, ...]
    objective: ca.Function
    lower: np.ndarray  # bounds on the gains (not their logarithms)
    upper: np.ndarray
    initial: np.ndarray
    fixed: Gains
    dim: int

    def gains(self, values: np.ndarray) -> Gains:
        """The fixed gains with the tuned ones set to ``values (n,)`` (``beta_g0[i]``: the diagonal of beta_g0)."""
        plain = {n: float(v) for n, v in zip(self.names, values) if not n.startswith("beta_g0[")}
        diagonal = {int(n[len("beta_g0[") : -1]): float(v) for n, v in zip(self.names, values) if n not in plain}
        if diagonal:
            rates = list(self.fixed.goal_rates(self.dim))
            for i, v in diagonal.items():
                rates[i] = v
            plain["beta_g0"] = tuple(rates)  # type: ignore[assignment]
        return self.fixed.with_values(**plain)

    def error(self, values: np.ndarray) -> float:
        """Eq. (29) at gains ``values (n,)`` (not logarithms)."""
        return float(self.objective(np.log(np.asarray(values, dtype=float))))


@dataclass(frozen=True)
class TuningResult:
    """The gains a tuner found.

    Attributes
    ----------
    method:
        ``ipopt`` or ``genetic``.
    gains:
        The gains found (the fixed ones unchanged).
    error, initial_error:
        Eq. (29) at the gains found and at the starting gains.
    seconds:
        Wall time [s].
    evaluations:
        Objective (and gradient) evaluations.
    history:
        Best error after each iteration / generation.
    status:
        The solver's status.
    """

    method: str
    gains: Gains
    error: float
    initial_error: float
    seconds: float
    evaluations: int
    history: np.ndarray
    status: str


ELITE = 2
"""Individuals the GA keeps unchanged (unevaluated) each generation."""
STABLE_MARGIN = 0.9
"""Fraction of the stability limit of ``beta dt / tau`` the tuning box allows (:func:`default_bounds`)."""
GOAL_RATE_STEPS = 3.0
"""``beta_g0 <= GOAL_RATE_STEPS tau/dt``: the goal filter closes ``1 - exp(-3) = 95%`` of a switch in one step."""


def default_bounds(dmp: DMP, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the tuned gains.

    Upper: :func:`~optikin.dmp.gains.stable_bounds` with a margin of
    :data:`STABLE_MARGIN` (``beta, alpha_s <= 0.9 tau/dt``, ``gamma <= 2 tau/dt``:
    ``k1 = beta dt/tau <= 0.9`` and ``k2 = beta gamma (dt/tau)^2 <= 1.8 < 4 - 2 k1``, inside the
    Jury region at every corner of the box; a margin of 1 would put the corner
    ``k1 = 1, k2 = 2`` on its edge), ``zeta <= 15`` (phase 3e-7 at ``tau``) and
    ``beta_g0 <= 3 tau/dt`` (the goal filter is integrated exactly, so it is
    stable at any rate; past 3 tau/dt a switch is 95% done in one step and
    eq. (29) no longer changes). On Seleem et al.'s 100 Hz, 10 s recordings
    (``tau/dt = 1000``) the box holds the gains they report (``beta, gamma =
    348, 977`` for ``Q_r`` and ``723, 768`` for ``Q_d``, Figs. 15-16; ``beta_g0``
    up to 1972, Figs. 18-19); at a lower rate those gains are outside the
    stable region of the fixed-step roll-out altogether.
    Lower: the DMP must keep an attractor, or eq. (29) alone drives the spring
    to zero and lets the forcing term do everything (a reproduction without
    generalisation): ``beta >= 5`` (the damping settles in ``2 tau/beta <= 0.4 tau``),
    ``gamma >= 1``, ``zeta >= 1`` (the forcing term fades to ``1/e`` by ``tau``).
    """
    stable = stable_bounds(dmp.dt, dmp.tau, margin=STABLE_MARGIN)
    table = {
        "beta": (5.0, stable["beta"][1]),
        "gamma": (1.0, stable["gamma"][1]),
        "zeta": (1.0, 15.0),
        "beta_g0": (0.1, GOAL_RATE_STEPS * dmp.tau / dmp.dt),
        "alpha_s": (1e-3, stable["alpha_s"][1]),
        "alpha": (1e-3, 100.0),
    }
    key = [n if not n.startswith("beta_g0[") else "beta_g0" for n in names]
    return np.array([table[n][0] for n in key]), np.array([table[n][1] for n in key])


def tuning_problem(
    dmp: DMP,
    t: np.ndarray,
    Y: np.ndarray,
    names: tuple[str, ...] = ("beta", "gamma", "zeta"),
    scenario: str = "reproduction",
    new_goal: np.ndarray | None = None,
    switch_time: float = 0.0,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
) -> TuningProblem:
    """Build the objective of eq. (29) in the gains ``names``; the other gains stay at ``dmp.gains``.

    Parameters
    ----------
    dmp:
        Supplies the space, basis size, overlap, amplitude scaling, phase
        stopping and the fixed gains; it learns the demonstration here (with its
        current gains).
    t:
        ``(N,)`` equally spaced times [s].
    Y:
        ``(N, size)`` demonstration in the DMP's layout.
    names:
        The gains tuned: of :data:`~optikin.dmp.gains.GAIN_NAMES`, or ``beta_g0[i]`` for the rates of a
        diagonal ``beta_g0`` (eq. 24), ``i < dim``.
    scenario:
        ``reproduction`` (the roll-out against the demonstration) or ``goal``
        (the roll-out against ``new_goal`` from ``switch_time`` on).
    new_goal:
        ``(size,)`` the new goal of the ``goal`` scenario.
    switch_time:
        When the goal switches [s].
    bounds:
        ``(lower (n,), upper (n,))`` on the gains; default :func:`default_bounds`.

    Returns
    -------
    TuningProblem

    Raises
    ------
    ValueError
        Unknown gains or scenario, or the goal scenario without a new goal.
    """
    diagonal = tuple(f"beta_g0[{i}]" for i in range(dmp.space.dim))
    unknown = [n for n in names if n not in GAIN_NAMES + diagonal]
    if unknown or not names or ("beta_g0" in names and set(diagonal) & set(names)):
        raise ValueError(f"tunable gains are {GAIN_NAMES} and the diagonal {diagonal} of beta_g0, got {names}")
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown tuning scenario {scenario!r}; choose from {SCENARIOS}")
    if scenario == "goal" and new_goal is None:
        raise ValueError("the goal scenario needs new_goal")
    dmp.imitate(t, Y)
    demo = dmp.learned
    space = dmp.space

    log_gains = ca.MX.sym("log_gains", len(names))
    value: dict[str, Any] = {n: getattr(dmp.gains, n) for n in GAIN_NAMES if n != "beta_g0"}
    # exp(-beta_g0 dt / tau) = 0 without an inf in the graph
    rates: list[Any] = list(np.minimum(dmp.gains.goal_rates(space.dim), 1e12))
    for i, n in enumerate(names):
        if n == "beta_g0":
            rates = [ca.exp(log_gains[i])] * space.dim
        elif n.startswith("beta_g0["):
            rates[int(n[len("beta_g0[") : -1])] = ca.exp(log_gains[i])
        else:
            value[n] = ca.exp(log_gains[i])

    X, _, c, h, s_end = design_matrix(demo, dmp.n_basis, value["zeta"], value["alpha"], dmp.overlap, dmp.phase_stopping)
    scale = dmp.plan().amplitude  # the learned demonstration's start-goal scaling (ones when not scaling)
    F = target_forces(demo, value["beta"], value["gamma"], value["alpha_s"]) / ca.repmat(
        ca.DM(scale).T, demo.Y.shape[0] - 1, 1
    )
    # Normal equations on unit-norm columns (late basis functions have columns ~ s = 0.01 in size).
    column = ca.sqrt(ca.sum1(X * X)).T
    Xs = X / ca.repmat(column.T, X.shape[0], 1)
    W = (
        ca.solve(ca.mtimes(Xs.T, Xs) + RIDGE * ca.DM.eye(dmp.n_basis), ca.mtimes(Xs.T, F))
        / ca.repmat(column, 1, space.dim)
    ).T

    if scenario == "reproduction":
        plan = dmp.plan()
        reference = demo.Y
        rows = slice(0, None)
    else:
        assert new_goal is not None
        plan = dmp.plan(goal_switches=[(switch_time, new_goal)])
        reference = np.broadcast_to(plan.final_goal, demo.Y.shape)
        rows = slice(int(np.searchsorted(plan.t, switch_time)), None)
    x0 = (
        plan.initial_state(value["alpha_s"])
        if B.is_casadi(value["alpha_s"])
        else ca.DM(plan.initial_state(value["alpha_s"]))
    )
    gains_vector = ca.vertcat(*[value.get(n, 0.0) for n in GAIN_NAMES])  # beta_g0: goal_rates below
    rollout = rollout_function(space, dmp.n_basis, plan.steps)
    states = rollout(
        x0,
        plan.inputs.T,
        W,
        c,
        h,
        plan.amplitude,
        gains_vector,
        plan.tau,
        plan.dt,
        s_end,
        dmp.goal_stopping,
        ca.vertcat(*rates),
    )
    E = states[: space.size, rows] - ca.DM(reference[rows].T)
    samples = reference[rows].shape[0]
    objective = ca.Function("dmp_eq29", [log_gains], [ca.sumsqr(E) / samples], ["log_gains"], ["error"])

    lower, upper = bounds if bounds is not None else default_bounds(dmp, names)
    empty = [n for n, lo, hi in zip(names, lower, upper) if not lo <= hi]
    if empty:
        raise InputDataError(
            f"no admissible range for gain(s) {', '.join(empty)} with the demonstration's time step "
            f"dt = {dmp.dt:.3g} s "
            f"and duration tau = {dmp.tau:.3g} s (the stable upper bound falls below the lower bound): use a longer "
            f"demonstration or fewer tuned gains",
            field="tuning.gains",
        )
    start = dmp.gains.goal_rates(space.dim)
    initial = np.clip(
        [
            start[int(n[len("beta_g0[") : -1])] if n.startswith("beta_g0[") else np.max(getattr(dmp.gains, n))
            for n in names
        ],
        lower,
        upper,
    )
    return TuningProblem(
        tuple(names), objective, np.asarray(lower, float), np.asarray(upper, float), initial, dmp.gains, space.dim
    )


def _batch(problem: TuningProblem) -> Callable[[np.ndarray], np.ndarray]:
    """``P (k, n) log-gains -> (k,)`` errors: the objective mapped over a batch in one call (cached per size)."""
    mapped: dict[int, ca.Function] = {}

    def evaluate(P: np.ndarray) -> np.ndarray:
        f = mapped.get(len(P))
        if f is None:
            f = mapped[len(P)] = problem.objective.map(len(P), "serial")
        return np.asarray(f(np.asarray(P, dtype=float).T)).ravel()

    return evaluate


def screening_points(problem: TuningProblem, points: int, seed: int = 0) -> np.ndarray:
    """The starting gains and a ``points``-point Latin hypercube of the log-box: ``(points + 1, n)`` log-gains."""
    n = len(problem.names)
    lower, upper = np.log(problem.lower), np.log(problem.upper)
    unit = qmc.LatinHypercube(d=n, rng=seed).random(points) if points else np.empty((0, n))
    return np.vstack([np.log(problem.initial)[None, :], lower + unit * (upper - lower)])


def tune_gradient(
    problem: TuningProblem,
    max_iterations: int = 60,
    tolerance: float = 1e-6,
    time_limit: float = 60.0,
    screen: int = 16,
    starts: int = 2,
    seed: int = 0,
    budget: int | None = None,
) -> TuningResult:
    """Minimise eq. (29) over the log-gains: multi-start IPOPT (exact gradient, limited-memory Hessian, box bounds).

    Parameters
    ----------
    problem:
        From :func:`tuning_problem`.
    max_iterations:
        IPOPT iterations per start.
    tolerance:
        IPOPT's tolerance on the objective scaled by its starting value.
    time_limit:
        Wall time for all starts [s].
    screen:
        Latin-hypercube points screened (>= 0).
    starts:
        IPOPT runs, from the best screened points (>= 1).
    seed:
        Seed of the Latin hypercube.
    budget:
        Objective evaluations (values and gradients, the screening included) to spend: runs start from
        the screened points in order, up to ``starts`` of them or more, until the budget is spent, each
        limited to the iterations left (an IPOPT iteration takes at least one value and one gradient,
        so a run may end a line search past the budget: the count reported is the true one).
        ``None``: ``starts`` runs of ``max_iterations``.

    Returns
    -------
    TuningResult
        ``method="ipopt"``; ``status`` IPOPT's return status of the best run (``screening`` if none improved).

    Notes
    -----

    Eq. (29) is not convex in the gains (on the IMU demonstrations a single
    IPOPT run from the default gains stops at a local point or at its
    iteration limit, above what the GA's random population finds), so the
    starts are chosen globally first: the starting gains and ``screen``
    points of a Latin hypercube of the log-box are evaluated in one mapped call,
    and IPOPT runs from the ``starts`` best of them (``max_iterations`` each,
    ``time_limit`` seconds for all). ``screen=0, starts=1`` is a single local
    run from the starting gains. The history is the best error after the
    screening and after each IPOPT iteration, run after run; the evaluation
    count adds the screening to IPOPT's objective and gradient calls.
    ``tolerance`` applies to the objective scaled by its starting value: the
    regression inside it (normal equations) leaves a rounding floor near 1e-8
    of that, where a tighter tolerance only buys failing line searches (30-odd
    backtracks per iteration, 300+ evaluations for nothing).
    """
    if starts < 1 or screen < 0:
        raise ValueError(f"need starts >= 1 and screen >= 0, got {starts}, {screen}")
    begin = time.perf_counter()
    initial_error = problem.error(problem.initial)
    candidates = screening_points(problem, screen, seed)
    values = _batch(problem)(candidates)
    values = np.where(np.isfinite(values), values, np.inf)
    order = np.argsort(values, kind="stable")[: starts if budget is None else len(candidates)]

    p = ca.MX.sym("p", len(problem.names))
    scale = 1.0 / max(initial_error, 1e-300)
    best_x, best_error, best_status = candidates[order[0]], float(values[order[0]]), "screening"
    history, evaluations = [best_error], len(candidates)
    for k in order:
        remaining = time_limit - (time.perf_counter() - begin)
        iterations = max_iterations if budget is None else min(max_iterations, (budget - evaluations) // 2)
        if remaining <= 0 or iterations < 1:
            break
        options: dict[str, Any] = {
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.hessian_approximation": "limited-memory",
            "ipopt.max_iter": int(iterations),
            "ipopt.tol": float(tolerance),
            "ipopt.max_wall_time": float(remaining),
        }
        nlp: dict[str, Any] = {"x": p, "f": scale * problem.objective(p)}
        solver = ca.nlpsol("dmp_gain_tuning", "ipopt", nlp, options)
        solution = solver(x0=candidates[k], lbx=np.log(problem.lower), ubx=np.log(problem.upper))
        stats = solver.stats()
        evaluations += int(stats.get("n_call_nlp_f", 0)) + int(stats.get("n_call_nlp_grad_f", 0))
        # IPOPT may end a relative 1e-8 outside the box (its bound_relax_factor): back into it
        x = np.clip(np.asarray(solution["x"]).ravel(), np.log(problem.lower), np.log(problem.upper))
        error = problem.error(np.exp(x))
        history += list(np.asarray(stats.get("iterations", {}).get("obj", []), dtype=float) / scale)
        if math.isfinite(error) and error < best_error:
            best_x, best_error, best_status = x, error, str(stats.get("return_status"))
    if not math.isfinite(best_error):
        raise SolverError("gain tuning found no finite value of eq. (29) at any start")
    seconds = time.perf_counter() - begin
    return TuningResult(
        "ipopt",
        problem.gains(np.exp(best_x)),
        best_error,
        initial_error,
        seconds,
        evaluations,
        np.minimum.accumulate(np.asarray(history)),
        best_status,
    )


def tune_genetic(
    problem: TuningProblem, population: int = 20, generations: int = 15, seed: int = 0, budget: int | None = None
) -> TuningResult:
    """Minimise eq. (29) with the GA baseline over the log-gains, evaluating each generation in one mapped call.

    Parameters
    ----------
    problem:
        From :func:`tuning_problem`.
    population, generations, seed:
        Of :func:`optikin.baselines.genetic.minimise` (the starting gains are in the first population).
    budget:
        Objective evaluations: the first population, then ``population - 2`` new individuals a
        generation (the 2 best survive unevaluated), so ``generations = (budget - population) //
        (population - 2)`` (at least 0); ``None``: ``generations`` as given.

    Returns
    -------
    TuningResult
        ``method="genetic"``.
    """
    if budget is not None:
        generations = max((budget - population) // (population - ELITE), 0)
    initial_error = problem.error(problem.initial)
    found = genetic.minimise(
        _batch(problem),
        np.log(problem.lower),
        np.log(problem.upper),
        population=population,
        generations=generations,
        seed=seed,
        elite=ELITE,
        initial=np.log(problem.initial),
    )
    values = np.exp(found.x)
    return TuningResult(
        "genetic",
        problem.gains(values),
        found.value,
        initial_error,
        found.seconds,
        found.evaluations,
        found.history,
        "finished",
    )


def tune_multistart(
    problem: TuningProblem,
    budget: int = 400,
    screen: int = 16,
    seed: int = 0,
    tolerance: float = 1e-10,
) -> TuningResult:
    """Minimise eq. (29) by L-BFGS-B (scipy, exact CasADi gradient) from the screened points in turn, on a budget.

    Parameters
    ----------
    problem:
        From :func:`tuning_problem`.
    budget:
        Objective evaluations, the screening included; a value with its gradient counts as two, as for
        IPOPT in :func:`tune_gradient`.
    screen:
        Latin-hypercube points screened (:func:`screening_points`); the local runs start from them, best first.
    seed:
        Seed of the Latin hypercube.
    tolerance:
        ``ftol`` of L-BFGS-B on the objective scaled by its starting value.

    Returns
    -------
    TuningResult
        ``method="multistart"``; ``status`` the message of the best run (``screening`` if none improved).

    Notes
    -----
    A plain box-constrained quasi-Newton method, restarted while budget is
    left: the gradient-based counterpart of the GA's spending of evaluations
    on the whole box, where :func:`tune_gradient` spends most of them on two
    deep local runs.
    """
    begin = time.perf_counter()
    initial_error = problem.error(problem.initial)
    candidates = screening_points(problem, screen, seed)
    values = _batch(problem)(candidates)
    values = np.where(np.isfinite(values), values, np.inf)
    order = np.argsort(values, kind="stable")
    p = ca.MX.sym("p", len(problem.names))
    f = problem.objective(p)
    both = ca.Function("dmp_eq29_and_gradient", [p], [f, ca.gradient(f, p)])
    scale = 1.0 / max(initial_error, 1e-300)
    best_x, best_error, best_status = candidates[order[0]], float(values[order[0]]), "screening"
    history, evaluations = [best_error], len(candidates)
    bounds = list(zip(np.log(problem.lower), np.log(problem.upper)))

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad = both(x)
        value, grad = float(value) * scale, np.asarray(grad, dtype=float).ravel() * scale
        if not math.isfinite(value) or not np.isfinite(grad).all():
            return math.inf, np.zeros_like(x)
        return value, grad

    for k in order:
        left = (budget - evaluations) // 2
        if left < 2:
            break
        found = minimize(
            fun, candidates[k], jac=True, method="L-BFGS-B", bounds=bounds, options={"maxfun": left, "ftol": tolerance}
        )
        evaluations += 2 * int(found.nfev)
        error = float(found.fun) / scale
        history.append(min(history[-1], error))
        if math.isfinite(error) and error < best_error:
            best_x, best_error, best_status = np.asarray(found.x), error, str(found.message)
    if not math.isfinite(best_error):
        raise SolverError("gain tuning found no finite value of eq. (29) at any start")
    return TuningResult(
        "multistart",
        problem.gains(np.exp(best_x)),
        best_error,
        initial_error,
        time.perf_counter() - begin,
        evaluations,
        np.asarray(history),
        best_status,
    )
