"""A discrete DMP on any space of :mod:`optikin.dmp.spaces`: learn from a demonstration, roll out.

>>> dmp = DMP(UnitQuaternion(), n_basis=50)
>>> fit = dmp.imitate(t, Q)                                   # Seleem et al.'s eqs. 21-22, least squares
>>> out = dmp.rollout(goal=q_new, tau=2 * dmp.tau)            # new goal, twice as slow
>>> out = dmp.rollout(goal_switches=[(1.5, q_new)])           # goal filter, eq. 24

Per-angle DMPs (Seleem et al.'s eqs. 11-16) are ``DMP(Euclidean(3))`` on roll-pitch-yaw,
the quaternion DMP (eqs. 17-23) is ``DMP(UnitQuaternion())``, the pose DMPs
are in :mod:`optikin.dmp.pose`. ``tau`` is the temporal scaling: the same
weights replay the motion in ``tau`` seconds instead of the demonstration's.
Past the demonstration's final phase the forcing term is off
(:mod:`optikin.dmp.basis`), so every roll-out ends as the critically damped
spring of eqs. (11) / (17) on the goal; noisy (sensor) demonstrations should
be learned with ``smoothing`` (:mod:`optikin.dmp.smoothing`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Callable, Sequence

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.dmp import basis, regression
from optikin.dmp.canonical import goal_stopping_weight
from optikin.dmp.compiled import ENGINES, CompiledRollout, compiled_rollout
from optikin.dmp.gains import GAIN_NAMES, Gains
from optikin.dmp.imitation import Demonstration, amplitude, design_matrix, prepare, target_forces
from optikin.dmp.rollout import input_size, rollout_function
from optikin.dmp.spaces import Space
from optikin.errors import InputDataError

PerStep = np.ndarray | Callable[[np.ndarray], np.ndarray] | None
IMITATION_ENGINES = ("auto", "compiled", "numpy")
"""Where :meth:`DMP.imitate` computes the demonstration's gaps."""


@dataclass(frozen=True)
class Rollout:
    """A roll-out of :meth:`DMP.rollout`.

    Attributes
    ----------
    t:
        ``(K+1,)`` times [s] from 0.
    y:
        ``(K+1, size)`` poses in the space's layout.
    eta:
        ``(K+1, dim)`` scaled velocities ``tau dy/dt`` in gap units (eqs. 12, 18).
    phase:
        ``(K+1,)`` phase ``s`` (eq. 15, slowed by eqs. 25, 28).
    goal:
        ``(K+1, size)`` filtered goal (eq. 24).
    seconds:
        Wall time of the integration [s].
    """

    t: np.ndarray
    y: np.ndarray
    eta: np.ndarray
    phase: np.ndarray
    goal: np.ndarray
    seconds: float


@dataclass(frozen=True)
class RolloutPlan:
    """Checked roll-out inputs: times, steps, time constants, start, goal, per-step inputs ``(K, nu)``.

    ``start_gap`` is the goal gap ``e_0`` on the branch the roll-out starts
    from (:meth:`~optikin.dmp.spaces.Space.lift`: nearest the one learned at the
    demonstration's start); ``start_coupling`` is ``e_0 + r_0`` (the gaps the
    coupling of eqs. 26-27 sees at the start); ``eta_0 = -alpha_s
    start_coupling`` starts at rest.
    """

    t: np.ndarray
    steps: int
    tau: float
    dt: float
    start: np.ndarray
    goal: np.ndarray
    final_goal: np.ndarray
    inputs: np.ndarray
    start_coupling: np.ndarray
    amplitude: np.ndarray
    start_gap: np.ndarray

    def initial_state(self, alpha_s: Any) -> Any:
        """``x0 = (y_0, eta_0, s_0 = 1, g_0, e_0)`` of :mod:`optikin.dmp.rollout`, at rest for the coupling
        ``alpha_s`` (a number: ``(nx,)``; a CasADi symbol: an ``nx x 1`` column)."""
        if B.is_casadi(alpha_s):
            return ca.vertcat(self.start, -alpha_s * ca.DM(self.start_coupling), 1.0, self.goal, self.start_gap)
        return np.concatenate([self.start, -alpha_s * self.start_coupling, [1.0], self.goal, self.start_gap])


@dataclass(frozen=True)
class RegressionProblem:
    """The weight regression of one demonstration: ``X W^T ~ F`` with the phase along it, the basis, and
    the phase below which the forcing term is off; the activations on first use."""

    demo: Demonstration
    X: np.ndarray
    F: np.ndarray
    phase: np.ndarray
    centres: np.ndarray
    widths: np.ndarray
    forcing_end: float

    @cached_property
    def activations(self) -> np.ndarray:
        """``(N-1, n_basis)`` unnormalised activations along the rows (:func:`optikin.dmp.basis.activations`)."""
        return basis.activations(self.phase, self.centres, self.widths)


class DMP:
    """Discrete DMP (Seleem et al. 2020, eqs. 11-28) on ``space`` with ``n_basis`` Gaussians per gap component.

    Parameters
    ----------
    space:
        The space it moves in (:mod:`optikin.dmp.spaces`): ``size`` stored and
        ``dim`` gap components.
    n_basis:
        Gaussian basis functions per gap component (eq. 13), at least 2.
    gains:
        ``beta, gamma, zeta, beta_g0, alpha_s, alpha`` (:class:`~optikin.dmp.Gains`).
    overlap:
        Value at which neighbouring Gaussians cross, in ``(0, 1)`` (:func:`optikin.dmp.basis.widths`).
    scale_by_amplitude:
        Scale the forcing term by the start-goal gap (eq. 11; Ude et al.'s ``D_0``).
    smoothing:
        Cutoff [Hz] of the low-pass applied to demonstrations before learning
        (:mod:`optikin.dmp.smoothing`); ``None`` learns the samples as given.
    phase_stopping:
        The error that slows the phase when ``gains.alpha > 0``
        (:mod:`optikin.dmp.canonical`): ``tracking`` (Ijspeert et al. 2013,
        Ude et al. 2014) or ``seed`` (eqs. 25, 28 as printed).

    Attributes
    ----------
    weights:
        ``(dim, n_basis)`` forcing-term weights once learned (``None`` before :meth:`imitate`).
    centres, widths, forcing_end:
        The basis learned with them: centres ``(n_basis,)`` and widths
        ``(n_basis,)`` in phase, and the phase below which the forcing term is off.
    demo, fit:
        The demonstration as learned and the fit of the weights.
    """

    def __init__(
        self,
        space: Space,
        n_basis: int = 50,
        gains: Gains = Gains(),
        overlap: float = basis.DEFAULT_OVERLAP,
        scale_by_amplitude: bool = False,
        smoothing: float | None = None,
        phase_stopping: str = "tracking",
    ):
        if n_basis < 2:
            raise ValueError(f"a DMP needs at least 2 basis functions, got {n_basis}")
        if smoothing is not None and not smoothing > 0:
            raise ValueError(f"the smoothing cutoff must be a positive frequency in Hz (or None), got {smoothing}")
        self.space = space
        self.n_basis = int(n_basis)
        self.gains = gains
        self.overlap = float(overlap)
        self.scale_by_amplitude = bool(scale_by_amplitude)
        self.smoothing = None if smoothing is None else float(smoothing)
        self.goal_stopping = goal_stopping_weight(phase_stopping)
        self.phase_stopping = phase_stopping
        self.weights: np.ndarray | None = None
        self.centres: np.ndarray | None = None
        self.widths: np.ndarray | None = None
        self.forcing_end: float | None = None
        self.demo: Demonstration | None = None
        self.fit: regression.Fit | None = None

    # ------------------------------------------------------------------ learning
    def regression_problem(
        self, t: np.ndarray, Y: np.ndarray, source: str = "demonstration", engine: str = "numpy"
    ) -> RegressionProblem:
        """Design matrix and target forces of a demonstration under this DMP's gains (eqs. 13, 16, 21-22).

        Parameters
        ----------
        t:
            ``(N,)`` equally spaced times [s].
        Y:
            ``(N, size)`` samples in the space's layout.
        source:
            Names the data in errors.
        engine:
            Where the demonstration's gaps are computed: ``numpy`` (the reference), ``compiled`` (one C call,
            :meth:`optikin.dmp.compiled.CompiledRollout.prepare`, built now if needed) or ``auto`` (C once built).

        Returns
        -------
        RegressionProblem
            ``X (N-1, n_basis)``, ``F (N-1, dim)`` (scaled by the amplitude), the
            phase ``(N-1,)`` and activations ``(N-1, n_basis)`` along the rows, the
            basis and its end phase.
        """
        if engine not in IMITATION_ENGINES:
            raise ValueError(f"unknown imitation engine {engine!r}; choose from {IMITATION_ENGINES}")
        kernels = self._kernels(engine)
        demo = prepare(self.space, t, Y, source, self.smoothing, None if kernels is None else kernels.prepare)
        g = self.gains
        X, s, c, h, s_end = design_matrix(demo, self.n_basis, g.zeta, g.alpha, self.overlap, self.phase_stopping)
        amp = amplitude(self.space, demo.start, demo.goal, self.scale_by_amplitude, source, gap=demo.goal_gap[0])
        F = target_forces(demo, g.beta, g.gamma, g.alpha_s) / amp
        return RegressionProblem(demo, X, F, s, c, h, s_end)

    def imitate(
        self,
        t: np.ndarray,
        Y: np.ndarray,
        method: str = "lstsq",
        ridge: float = 0.0,
        lower: float | np.ndarray | None = None,
        upper: float | np.ndarray | None = None,
        source: str = "demonstration",
        factorisation: str = "cholesky",
        engine: str = "auto",
    ) -> regression.Fit:
        """Learn the weights from a demonstration (eqs. 16, 21-22) and keep them, with the demonstration and basis.

        Parameters
        ----------
        t:
            ``(N,)`` equally spaced times [s]; ``tau`` becomes ``t[-1] - t[0]``.
        Y:
            ``(N, size)`` samples in the space's layout (quaternion blocks of either sign).
        method:
            ``lstsq`` (closed form), ``cvxpy`` (all weights at once, optional bounds) or ``lwr``
            (:mod:`optikin.dmp.regression`).
        ridge:
            Weight of ``|W|^2`` (``lstsq``, ``cvxpy``).
        lower, upper:
            Bounds on the weights, scalars or ``(n_basis, dim)`` (``cvxpy`` only).
        source:
            Names the data in errors.
        factorisation:
            How ``lstsq`` solves: ``cholesky`` (one factorisation for every gap component) or ``svd``
            (the reference; :func:`optikin.dmp.regression.fit_lstsq`).
        engine:
            Where the demonstration's gaps are computed (:meth:`regression_problem`): ``auto`` (the compiled
            library of the roll-out once built), ``compiled`` or ``numpy`` (the reference).

        Returns
        -------
        Fit
            The weights ``(dim, n_basis)``, ``rms(X W^T - F)`` and the wall time [s].

        Raises
        ------
        InputDataError
            A demonstration that is not finite, not on a fixed step or too short.
        """
        problem = self.regression_problem(t, Y, source, engine)
        if method == "lstsq":
            if lower is not None or upper is not None:
                raise ValueError("bounds on the weights need method='cvxpy'")
            fit = regression.fit_lstsq(problem.X, problem.F, ridge, factorisation)
        elif method == "cvxpy":
            fit = regression.fit_cvxpy(problem.X, problem.F, ridge, lower, upper)
        elif method == "lwr":
            fit = regression.fit_lwr(problem.phase, problem.activations, problem.X, problem.F)
        else:
            raise ValueError(f"unknown regression method {method!r}; choose from {regression.METHODS}")
        self.weights, self.demo, self.fit = fit.weights, problem.demo, fit
        self.centres, self.widths, self.forcing_end = problem.centres, problem.widths, problem.forcing_end
        return fit

    @property
    def tau(self) -> float:
        """The learned demonstration's duration [s] (the time constant of eqs. 11-12, 15)."""
        return self._learned().tau

    @property
    def dt(self) -> float:
        """The learned demonstration's sample step [s] (the roll-out's default step)."""
        return self._learned().dt

    @property
    def learned(self) -> Demonstration:
        """The demonstration as learned (sign-continuous, smoothed if asked); :meth:`imitate` first."""
        return self._learned()

    def _basis(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Learned weights' basis: centres ``(n,)``, widths ``(n,)`` and the phase below which it is off."""
        if self.centres is None or self.widths is None or self.forcing_end is None:
            raise RuntimeError("the DMP has not learned a demonstration yet: call imitate() first")
        return self.centres, self.widths, self.forcing_end

    def _kernels(self, engine: str) -> CompiledRollout | None:
        """The compiled library for ``engine`` (``compiled``: built now if needed; ``auto``: if built), or ``None``."""
        if engine in ("numpy", "casadi"):
            return None
        return compiled_rollout(self.space, self.n_basis, build=engine == "compiled")

    def _learned(self) -> Demonstration:
        if self.demo is None or self.weights is None:
            raise RuntimeError("the DMP has not learned a demonstration yet: call imitate() first")
        return self.demo

    # ------------------------------------------------------------------ roll-out
    def rollout(
        self,
        duration: float | None = None,
        *,
        tau: float | None = None,
        dt: float | None = None,
        start: np.ndarray | None = None,
        goal: np.ndarray | None = None,
        goal_switches: Sequence[tuple[float, np.ndarray]] = (),
        disturbance: PerStep = None,
        reference: PerStep = None,
        offset: PerStep = None,
        gains: Gains | None = None,
        weights: np.ndarray | None = None,
        engine: str = "auto",
    ) -> Rollout:
        """Integrate the DMP from ``start`` at rest towards ``goal`` (eqs. 11-12, 15, 17-18, 23-28).

        Parameters
        ----------
        duration:
            Length of the roll-out [s]; default ``tau``. Past the demonstration's
            phase the forcing term is off and the DMP is the spring on the goal.
        tau:
            Time scaling [s] (default the demonstration's duration): the same
            weights replay the motion in ``tau`` seconds.
        dt:
            Step [s] (default the demonstration's).
        start, goal:
            ``(size,)`` poses (default the demonstration's first and last sample).
        goal_switches:
            ``(time [s], new goal (size,))`` pairs; the goal moves to each new goal
            through the filter of eq. (24) (rate ``gains.beta_g0``, one per gap component if a tuple).
        disturbance:
            Per-step force ``(K, dim)`` added to eq. (17), or a function of the step times ``(K,)``.
        reference:
            Per-step poses ``(K, size)`` the DMP is coupled to by eqs. (27)-(28),
            or a function of the step times.
        offset:
            An output disturbance: the pose at ``t_1 .. t_K`` is displaced by ``offset (K, dim)``
            (gap units: rad, m), or a function of those times; the DMP integrates on from the displaced
            pose (it sees the displacement), and the pose jumps back as the offset goes (the start is
            not displaced).
        gains, weights:
            Override the learned gains and weights ``(dim, n_basis)`` (tuning).
        engine:
            ``compiled``: the step as generated C in one C loop (:mod:`optikin.dmp.compiled`; the
            forcing term of every step in advance where ``alpha = 0``), built now if needed (where no C
            compiler is found, the CasADi Function); ``casadi``: the CasADi Function of
            :func:`optikin.dmp.rollout.rollout_function` and the start's gaps in numpy (the reference);
            ``auto``: the C loop once built (by an earlier ``compiled`` call, in the per-user cache, or
            after :data:`optikin.dmp.compiled.AUTO_BUILD_AFTER` roll-outs in this process), else CasADi.

        Returns
        -------
        Rollout
            Times ``(K+1,)`` [s], poses ``(K+1, size)``, velocities ``(K+1, dim)``,
            phase ``(K+1,)``, filtered goal ``(K+1, size)`` and the wall time [s].
        """
        gains = gains or self.gains
        plan = self.plan(
            duration,
            tau=tau,
            dt=dt,
            start=start,
            goal=goal,
            goal_switches=goal_switches,
            disturbance=disturbance,
            reference=reference,
            offset=offset,
            engine=engine,
        )  # checks that the DMP has learned and the engine
        W = np.asarray(self.weights if weights is None else weights, dtype=float)
        space, size, dim = self.space, self.space.size, self.space.dim
        x0 = plan.initial_state(gains.alpha_s)
        compiled = self._kernels(engine)
        f = rollout_function(space, self.n_basis, plan.steps) if compiled is None else None
        begin = time.perf_counter()
        c, h, s_end = self._basis()
        rates = np.minimum(gains.goal_rates(dim), 1e300)
        vector = gains.vector()
        params = (W, c, h, plan.amplitude, vector, plan.tau, plan.dt, s_end, self.goal_stopping, rates)
        if compiled is not None:
            # without phase stopping (alpha = 0) the phase of every step is known: its forcing term in advance
            zeta, alpha = vector[GAIN_NAMES.index("zeta")], vector[GAIN_NAMES.index("alpha")]
            forcing = None
            if alpha == 0:
                table = basis.rollout_features(plan.steps, plan.dt, plan.tau, zeta, c, h, s_end)
                forcing = (table @ W.T) * plan.amplitude
            X = compiled(x0, plan.inputs, *params, forcing=forcing)
        else:
            assert f is not None
            X = np.asarray(f(x0, plan.inputs.T, *params)).T
        seconds = time.perf_counter() - begin
        return Rollout(
            t=plan.t,
            y=X[:, :size],
            eta=X[:, size : size + dim],
            phase=X[:, size + dim],
            goal=X[:, size + dim + 1 : 2 * size + dim + 1],
            seconds=seconds,
        )

    def plan(
        self,
        duration: float | None = None,
        *,
        tau: float | None = None,
        dt: float | None = None,
        start: np.ndarray | None = None,
        goal: np.ndarray | None = None,
        goal_switches: Sequence[tuple[float, np.ndarray]] = (),
        disturbance: PerStep = None,
        reference: PerStep = None,
        offset: PerStep = None,
        engine: str = "auto",
    ) -> "RolloutPlan":
        """The checked inputs of a roll-out (parameters as :meth:`rollout`), before the gains and weights are chosen.

        ``engine`` (as :meth:`rollout`) also says where the few gaps of the start are computed: in the compiled
        library (``compiled``, ``auto`` once built) or in numpy (``casadi``, the reference).

        Returns
        -------
        RolloutPlan
            Times ``(K+1,)``, step count ``K``, ``tau`` and ``dt`` [s], start and
            goal ``(size,)``, the last goal, per-step inputs ``(K, nu)``, the
            start coupling ``(dim,)`` and the amplitude ``(dim,)``.
        """
        demo = self._learned()
        if engine not in ENGINES:
            raise ValueError(f"unknown roll-out engine {engine!r}; choose from {ENGINES}")
        kernels = self._kernels(engine)
        space = self.space
        tau = demo.tau if tau is None else float(tau)
        dt = demo.dt if dt is None else float(dt)
        duration = tau if duration is None else float(duration)
        if tau <= 0 or dt <= 0 or duration <= 0:
            raise ValueError(f"tau, dt and duration must be positive (got {tau}, {dt}, {duration})")
        steps = max(1, int(round(duration / dt)))
        t = np.arange(steps + 1) * dt
        # The goal as learned (sign-continuous with the start along the demonstration); whatever the sign of a
        # goal, its gap is taken on the branch nearest the one learned (start_gap below, Space.lift).
        y0 = demo.start if start is None else self._element(start, "start")
        goal = demo.goal if goal is None else space.align(self._element(goal, "goal"), y0)

        dim, size = space.dim, space.size
        U = np.zeros((steps, input_size(space)))  # per step: (d, y_ref, m, g_new, o)
        new_goal = slice(dim + size + 1, dim + 2 * size + 1)
        U[:, dim : dim + size] = y0  # a valid pose where no reference is given (m = 0)
        U[:, new_goal] = goal
        current = goal
        for when, target in sorted(goal_switches, key=lambda pair: pair[0]):
            current = space.align(self._element(target, "goal switch"), current)
            U[t[:-1] >= when, new_goal] = current
        if offset is not None:
            displaced = self._per_step(offset, t[1:], dim, "offset")
            U[:, dim + 2 * size + 1 :] = np.diff(displaced, axis=0, prepend=0.0)
        if disturbance is not None:
            U[:, :dim] = self._per_step(disturbance, t[:-1], dim, "disturbance")
        if reference is not None:
            U[:, dim : dim + size] = self._per_step(reference, t[:-1], size, "reference")
            U[:, dim + size] = 1.0
        # At rest: the velocity eta + alpha_s (e + r) of eqs. (26)-(27) vanishes at the start.
        if kernels is None:
            start_gap = np.asarray(space.lift(space.gap(goal, y0), demo.goal_gap[0]), dtype=float)
            coupling = start_gap + U[0, dim + size] * np.asarray(space.gap(U[0, dim : dim + size], y0))
            final_gap = np.asarray(space.lift(space.gap(current, y0), start_gap), dtype=float)
        else:
            start_gap = kernels.gap(goal, y0, demo.goal_gap[0])
            coupling = start_gap + U[0, dim + size] * kernels.gap(U[0, dim : dim + size], y0)
            final_gap = kernels.gap(current, y0, start_gap)
        return RolloutPlan(
            t=t,
            steps=steps,
            tau=tau,
            dt=dt,
            start=y0,
            goal=goal,
            final_goal=current,
            inputs=U,
            start_coupling=coupling,
            amplitude=amplitude(
                space,
                y0,
                current,
                self.scale_by_amplitude,
                "rollout",
                gap=final_gap,
            ),
            start_gap=start_gap,
        )

    def _element(self, x: np.ndarray, what: str) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape != (self.space.size,) or not np.isfinite(x).all():
            raise InputDataError(
                f"expected {self.space.size} finite components for the space {self.space}, "
                f"got {x.shape} {x if x.size <= 8 else ''}",
                field=what,
            )
        return x

    @staticmethod
    def _per_step(value: np.ndarray | Callable, t: np.ndarray, width: int, what: str) -> np.ndarray:
        values = np.asarray(value(t) if callable(value) else value, dtype=float)
        if values.ndim == 1 and width == 1:
            values = values[:, None]
        if values.ndim != 2 or values.shape[1] != width or values.shape[0] < t.size:
            raise InputDataError(f"expected at least {t.size} rows of {width} values, got {values.shape}", field=what)
        values = values[: t.size]
        bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
        if bad.size:
            raise InputDataError("value is not finite", sample=int(bad[0]), field=what)
        return values
