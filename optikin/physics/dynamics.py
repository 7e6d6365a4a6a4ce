"""Implicit Cosserat-rod dynamics: each BDF-alpha time step a BVP solved by multiple shooting, warm-started.

The equations and the time discretisation are in :mod:`optikin.physics.dynamics_equations`
(Till, Aloi and Rucker, IJRR 38(6), 2019). :class:`RodDynamics` builds one time step as
CasADi Functions of the shooting unknowns ``z`` (the base wrench ``(N(0), M(0))``, then the
state at the start of every further shooting interval), the loads ``P`` (the statics' load
vector, :attr:`optikin.physics.RodArm.load_names`) and the history ``H`` of every RK4
stage: the shape (every node's state, the residual, the new stage values and the energy).
Newton on the residual finds the unknowns; in numpy on the shape compiled to C
(``compiled``, the default, :mod:`optikin.codegen`), its Jacobian by forward differences
(all columns in one batched C call: compiling the exact forward sensitivities takes about
a minute) kept across steps while Newton contracts, or by CasADi's ``rootfinder`` (exact
derivatives) in the VM. Each step starts from the unknowns extrapolated quadratically from
the three steps before.

The discrete state after step ``i`` is :class:`DynamicState`: the history of step ``i + 1``
(``H = c1 y_i + c2 y_{i-1} + d1 (y_t)_i``) and the stage values ``y_i``; a rod at rest in an
equilibrium (:meth:`RodDynamics.rest`) has ``H = -c0 y``. :meth:`RodDynamics.derivatives`
differentiates a step (the implicit function theorem through the rootfinder) with respect
to the state and the loads.

Stability and resolution (checked when the stepper is built, errors naming ``dt``):
BDF-alpha with ``-1/2 <= alpha <= 0`` is A-stable for a stable semi-discrete system, so
the step length has no stability limit of its own; a step longer than a quarter of the
first bending period (Euler-Bernoulli, the whole arm as one uniform cantilever of its most
flexible segment) no longer resolves the motion and is refused. A step so short that the
spatial exponents of the step's BVP, ``L sqrt(c0) (rho A / E I)^(1/4)`` (bending) and
``c0 L sqrt(rho / G)`` (shear waves), exceed :data:`MAX_SHOOTING_EXPONENT` makes shooting
ill-conditioned (its Jacobian grows like ``exp`` of the exponent) and is refused too. The
less dissipative alphas, and coarse grids at short steps, can leave modes of the
time-discretised BVP growing (Till et al.'s Euler-in-``s`` scheme more so);
``docs/guide/dynamics.md`` tabulates the spectral radii of the linearised step: BDF2 (the
default) is the robust choice.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import casadi as ca
import numpy as np
from pydantic import Field, StrictFloat, StrictInt, field_validator

from optikin.algebra import matrix_from_quat
from optikin.codegen import CompiledFunction, CompilerFlag
from optikin.errors import InputDataError, SolverError
from optikin.options import Options
from optikin.physics.dynamics_equations import (
    ENERGY_NAMES,
    RATE_SIZE,
    STAGES,
    STATE_SIZE,
    Coefficients,
    DynamicEquations,
    SegmentDamping,
)
from optikin.physics.model import Loads, RodArm, load_vector
from optikin.physics.rod import Rod

Vector3 = tuple[StrictFloat, StrictFloat, StrictFloat]
HISTORY_ROWS = RATE_SIZE * STAGES
"""Rows of the stage arrays ``H`` and ``Y``: ``(v, u, q, w)`` at the four RK4 stages of a grid step."""
MAX_SHOOTING_EXPONENT = 36.0
"""Largest spatial exponent of a step's BVP accepted (``exp(36) ~ 4e15``, the reciprocal of the double epsilon)."""
INTERVAL_EXPONENT = 6.0
"""Largest spatial exponent of one shooting interval (its Jacobian grows like ``exp(6) ~ 400``)."""
MIN_STEPS_PER_PERIOD = 4.0
FD_STEP = 1e-7
"""Relative step of the forward differences of the shooting Jacobian."""
"""Fewest time steps per first bending period accepted."""
EULER_BERNOULLI_BETA1 = 1.8751040687
"""``beta_1 L`` of the first bending mode of a clamped-free Euler-Bernoulli beam."""


class Damping(Options):
    """Kelvin-Voigt damping on the strain rates and quadratic air drag of one segment (diagonals, material frame).

    ``n = R (K_se (v - v*) + B_se v_t)``, ``m = R (K_bt (u - u*) + B_bt u_t)``; drag force per unit
    length ``-R (C q |q|)``.
    """

    B_se: Vector3 = Field((0.0, 0.0, 0.0), description="shear/extension damping diag(B_se) [N s]")
    B_bt: Vector3 = Field((0.0, 0.0, 0.0), description="bending/torsion damping diag(B_bt) [N m^2 s]")
    drag: Vector3 = Field((0.0, 0.0, 0.0), description="air-drag coefficients C [N s^2 / m^3]")

    @field_validator("B_se", "B_bt", "drag")
    @classmethod
    def _non_negative(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        for i, x in enumerate(value):
            if x < 0:
                raise ValueError(f"entry {i} is {x}: a negative damping adds energy (non-physical)")
        return value

    @classmethod
    def kelvin_voigt(cls, rod: Rod, viscosity: float, drag: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Damping:
        """Damping proportional to the stiffness, ``B = (eta / E) K``: a Kelvin-Voigt solid of viscosity ``eta``.

        Parameters
        ----------
        rod : Rod
            The segment's rod.
        viscosity : float
            ``eta`` [Pa s], ``>= 0``; every mode then decays at ``eta omega^2 / (2 E)``.
        drag : tuple of float
            Air-drag coefficients.

        Raises
        ------
        ValueError
            For a negative viscosity.
        """
        if viscosity < 0:
            raise ValueError(f"viscosity: {viscosity} Pa s is negative (non-physical)")
        ratio = viscosity / rod.youngs_modulus
        return cls(
            B_se=tuple(float(x) for x in ratio * rod.K_se),
            B_bt=tuple(float(x) for x in ratio * rod.K_bt),
            drag=drag,
        )

    def segment(self) -> SegmentDamping:
        """The values the equations use."""
        return SegmentDamping(self.B_se, self.B_bt, self.drag)


class DynamicsOptions(Options):
    """Settings of :class:`RodDynamics`."""

    dt: StrictFloat = Field(gt=0, description="time step [s]")
    alpha: StrictFloat = Field(
        0.0, ge=-0.5, le=0.0, description="BDF-alpha parameter: 0 = BDF2, -0.5 = trapezoidal (no numerical damping)"
    )
    steps_per_segment: StrictInt = Field(39, ge=1, description="RK4 steps per segment (points - 1)")
    tolerance: StrictFloat = Field(1e-9, gt=0, description="largest accepted tip residual per step [N, N m]")
    max_iterations: StrictInt = Field(25, ge=1, description="Newton iterations per time step")
    tip_mass: StrictFloat = Field(0.0, ge=0, description="payload at the tip, a point mass [kg]")
    actuator_iterations: StrictInt = Field(4, ge=0, description="fixed-point iterations on the tendon tangents")
    compiled: bool = Field(True, description="Newton on the C-compiled shape (else CasADi's rootfinder in the VM)")
    flags: tuple[CompilerFlag, ...] = Field(("-O3",), description="compiler flags when compiled")


class StepError(SolverError):
    """A time step whose BVP did not converge: names the step, its time and the residual."""

    def __init__(self, step: int, t: float, residual: float, tolerance: float) -> None:
        self.step, self.t, self.residual = step, t, residual
        super().__init__(
            f"time step {step} (t = {t:.6g} s): Newton did not converge, tip residual {residual:.3g} "
            f"above the tolerance {tolerance:.3g}"
        )


@dataclass(frozen=True)
class DynamicState:
    """The rod after a time step (or at rest).

    Attributes
    ----------
    t : float
        Time [s].
    step : int
        Steps taken since the start.
    history : numpy.ndarray
        ``(48, S + 1)`` the next step's history ``H`` at every stage of the ``S`` grid steps, then (rows
        0-11 of the last column) at the tip.
    rates : numpy.ndarray
        ``(48, S + 1)`` the stage (and tip) values ``y = (v, u, q, w)`` of this step.
    unknowns, previous_unknowns, older_unknowns : numpy.ndarray
        The shooting unknowns of this step and of the two before (the warm start): the base wrench
        ``(N(0), M(0))`` then the full state (19) at the start of every further shooting interval.
    states : numpy.ndarray
        ``(19, K)`` the nodes' ``(p, quaternion, N, M, q, w)``.
    energy : numpy.ndarray
        ``(3,)`` kinetic, elastic and gravitational energy [J] (:data:`ENERGY_NAMES`).
    residual : float
        Norm of the tip residual [N, N m].
    iterations : int
        Newton iterations of the step.
    """

    t: float
    step: int
    history: np.ndarray
    rates: np.ndarray
    unknowns: np.ndarray
    previous_unknowns: np.ndarray
    older_unknowns: np.ndarray
    states: np.ndarray
    energy: np.ndarray
    residual: float
    iterations: int = 0

    @property
    def wrench(self) -> np.ndarray:
        """``(6,)`` the base wrench ``(N(0), M(0))`` [N, N m]."""
        return self.unknowns[:6].copy()

    @property
    def positions(self) -> np.ndarray:
        """``(K, 3)`` centre line [m]."""
        return self.states[0:3].T

    @property
    def tip_position(self) -> np.ndarray:
        """``(3,)`` [m]."""
        return self.states[0:3, -1].copy()

    @property
    def tip_orientation(self) -> np.ndarray:
        """``(4,)`` unit quaternion."""
        return self.states[3:7, -1].copy()

    @property
    def total_energy(self) -> float:
        """Kinetic + elastic + gravitational [J]."""
        return float(self.energy.sum())

    @property
    def vector(self) -> np.ndarray:
        """``(96 (S + 1),)`` the discrete state ``(vec H, vec y)``, what :meth:`RodDynamics.derivatives` takes."""
        return np.concatenate([self.history.ravel(order="F"), self.rates.ravel(order="F")])


@dataclass(frozen=True)
class StepDerivatives:
    """Derivatives of one time step at a state and loads (implicit function theorem through the BVP).

    Attributes
    ----------
    wrt_state : numpy.ndarray or None
        ``(n_x, n_x)`` d next :attr:`DynamicState.vector` / d state vector (None unless asked for).
    wrt_loads : numpy.ndarray
        ``(n_x, n_P)`` d next state vector / d ``P``.
    tip_wrt_state : numpy.ndarray
        ``(3, n_x)`` d next tip position / d state vector.
    tip_wrt_loads : numpy.ndarray
        ``(3, n_P)`` d next tip position / d ``P``.
    """

    wrt_state: np.ndarray | None
    wrt_loads: np.ndarray
    tip_wrt_state: np.ndarray
    tip_wrt_loads: np.ndarray


@dataclass(frozen=True)
class Trajectory:
    """A simulated run: one row per time (the start first).

    Attributes
    ----------
    t : numpy.ndarray
        ``(T,)`` [s].
    tip : numpy.ndarray
        ``(T, 3)`` tip positions [m].
    positions : numpy.ndarray
        ``(T, K, 3)`` centre lines [m]; ``(2, K, 3)``, the start's and the last's, without ``keep_shapes``.
    energy : numpy.ndarray
        ``(T, 3)`` kinetic, elastic, gravitational [J].
    residual : numpy.ndarray
        ``(T,)`` tip residual of each step.
    iterations : numpy.ndarray
        ``(T,)`` Newton iterations of each step.
    final : DynamicState
        The last converged state.
    failure : StepError or None
        The step that did not converge (the trajectory stops before it), or None.
    """

    t: np.ndarray
    tip: np.ndarray
    positions: np.ndarray
    energy: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray
    final: DynamicState
    failure: StepError | None = None

    @property
    def complete(self) -> bool:
        """Every step converged."""
        return self.failure is None


def first_bending_period(arm: RodArm) -> float:
    """Euler-Bernoulli first period of the arm as one uniform cantilever of its most flexible segment [s]."""
    ratio = min(seg.rod.EI / (seg.rod.density * seg.rod.A) for seg in arm.segments)
    omega = EULER_BERNOULLI_BETA1**2 * np.sqrt(ratio / arm.length**4)
    return float(2 * np.pi / omega)


def shooting_exponent(arm: RodArm, coefficients: Coefficients) -> float:
    """The largest spatial exponent of a step's BVP over the arm [-].

    Bending ``L sqrt(c0) (rho A / E I)^(1/4)``, shear waves ``c0 L sqrt(rho / G)``, summed over the segments.
    """
    c0 = coefficients.c0
    bending = sum(s.rod.length * np.sqrt(c0) * (s.rod.density * s.rod.A / s.rod.EI) ** 0.25 for s in arm.segments)
    shear = sum(c0 * s.rod.length * np.sqrt(s.rod.density / s.rod.G) for s in arm.segments)
    return float(max(bending, shear))


def check_arm(arm: RodArm, damping: tuple[Damping, ...], options: DynamicsOptions) -> None:
    """Refuse what the dynamics cannot step.

    Raises
    ------
    InputDataError
        Naming the field: a Kirchhoff or massless segment, damping not one per segment, ``dt`` too long
        to resolve the first bending mode or too short for a well-conditioned shooting.
    """
    if len(damping) != len(arm.segments):
        raise InputDataError(f"give one per segment ({len(arm.segments)}), got {len(damping)}", field="damping")
    for k, seg in enumerate(arm.segments):
        if seg.rod.model != "cosserat":
            raise InputDataError(
                "the dynamics integrate the shear-extensible rod only (model: cosserat)",
                field=f"segments.{k}.rod.model",
            )
        if seg.rod.density <= 0:
            raise InputDataError(
                "a massless rod has no dynamics: give a density > 0", field=f"segments.{k}.rod.density"
            )
    period = first_bending_period(arm)
    if options.dt > period / MIN_STEPS_PER_PERIOD:
        raise InputDataError(
            f"{options.dt:.3g} s is longer than a quarter of the first bending period ({period:.3g} s, "
            "Euler-Bernoulli): the step would not resolve the motion",
            field="dt",
        )
    exponent = shooting_exponent(arm, Coefficients(options.dt, options.alpha))
    if exponent > MAX_SHOOTING_EXPONENT:
        raise InputDataError(
            f"{options.dt:.3g} s is too short for shooting: the step's BVP grows like exp({exponent:.1f}) "
            f"along the rod (at most exp({MAX_SHOOTING_EXPONENT:.0f})); lengthen dt",
            field="dt",
        )


class RodDynamics:
    """Time steps of a :class:`~optikin.physics.RodArm` with inertia and damping.

    Each step's BVP is solved by multiple shooting when one interval would be
    ill-conditioned: the grid is cut into :attr:`intervals` intervals of about equal
    spatial exponent (at most :data:`INTERVAL_EXPONENT` each), whose start states are
    unknowns besides the base wrench, with continuity residuals at the cuts.

    Parameters
    ----------
    arm : RodArm
        The arm (shear-extensible rods with a density).
    options : DynamicsOptions
        ``dt``, ``alpha``, grid, tolerance, compiled or VM.
    damping : tuple of Damping, optional
        One per segment; default none.

    Attributes
    ----------
    s : numpy.ndarray
        ``(K,)`` arc length of the nodes [m].
    intervals : int
        Shooting intervals.
    shape : casadi.Function
        ``(z, P, H) -> (states 19 x K, residual, Y 48 x S, energy 3)``, ``z`` the shooting unknowns.
    residual : casadi.Function
        ``(z, P, H) -> residual``.

    Raises
    ------
    optikin.errors.InputDataError
        From :func:`check_arm`.
    optikin.errors.SolverError
        With ``compiled=True``, when compiling fails.
    """

    def __init__(self, arm: RodArm, options: DynamicsOptions, damping: tuple[Damping, ...] | None = None) -> None:
        damping = damping if damping is not None else tuple(Damping() for _ in arm.segments)
        check_arm(arm, damping, options)
        self.arm, self.options, self.damping = arm, options, damping
        self.coefficients = Coefficients(options.dt, options.alpha)
        segments = tuple(d.segment() for d in damping)
        self.equations = DynamicEquations(arm, segments, self.coefficients, options.actuator_iterations)
        self.n_loads = self.equations.n_loads
        n = options.steps_per_segment
        self.n_steps = n * len(arm.segments)
        self.columns = self.n_steps + 1  # of H and Y: every grid step's stages, then the tip
        bounds = arm.boundaries
        self.s = np.concatenate(
            [[0.0]]
            + [bounds[k] + (bounds[k + 1] - bounds[k]) / n * np.arange(1, n + 1) for k in range(len(arm.segments))]
        )
        exponent = shooting_exponent(arm, self.coefficients)
        self.intervals = int(min(self.n_steps, max(1, np.ceil(exponent / INTERVAL_EXPONENT))))
        self.cuts = np.round(np.linspace(0, self.n_steps, self.intervals + 1)).astype(int)
        self.n_unknowns = 6 + STATE_SIZE * (self.intervals - 1)
        self.shape = self._shape(self.equations, "rod_dynamics")
        statics = DynamicEquations(arm, segments, Coefficients(np.inf, options.alpha), options.actuator_iterations)
        self.static_shape = self._shape(statics, "rod_dynamics_rest")
        z, P, H = self._symbols()
        self.residual = ca.Function(
            "rod_dynamics_residual", [z, P, H], [self.shape(z, P, H)[1]], ["z", "P", "H"], ["residual"]
        )
        zero = ca.DM.zeros(HISTORY_ROWS, self.columns)
        self._static_residual = ca.Function("rod_rest_residual", [z, P], [self.static_shape(z, P, zero)[1]])
        self._compiled: CompiledFunction | None = None
        if options.compiled:
            self._compiled = CompiledFunction(self._packed_shape(), options.flags)
        self._jacobian_inverse: np.ndarray | None = None

    # ----------------------------------------------------------------- the Functions

    def _symbols(self) -> tuple[ca.MX, ca.MX, ca.MX]:
        return (
            ca.MX.sym("z", self.n_unknowns),
            ca.MX.sym("P", self.n_loads),
            ca.MX.sym("H", HISTORY_ROWS, self.columns),
        )

    def _shape(self, equations: DynamicEquations, name: str) -> ca.Function:
        n, bounds = self.options.steps_per_segment, self.arm.boundaries
        z, P, H = self._symbols()
        starts = [equations.base_state(z[:6])] + [
            z[6 + STATE_SIZE * j : 6 + STATE_SIZE * (j + 1)] for j in range(self.intervals - 1)
        ]
        columns, rates, energy, residual = [starts[0]], [], ca.MX.zeros(len(ENERGY_NAMES)), []
        steps: dict[tuple[int, int], ca.Function] = {}
        for j in range(self.intervals):
            x = starts[j]
            a, b = int(self.cuts[j]), int(self.cuts[j + 1])
            while a < b:
                k = a // n
                end = min(b, (k + 1) * n)
                h = (bounds[k + 1] - bounds[k]) / n
                if (k, end - a) not in steps:
                    steps[(k, end - a)] = equations.rk4_step(k, h).mapaccum(end - a)
                s_row = ca.DM(bounds[k] + h * np.arange(a - k * n, end - k * n)).T
                X, Y, E = steps[(k, end - a)](x, s_row, H[:, a:end], ca.repmat(P, 1, end - a))
                x = X[:, -1]
                columns.append(X)
                rates.append(Y)
                energy += ca.sum2(E)
                a = end
            if j < self.intervals - 1:
                residual.append(x - starts[j + 1])
        r_tip, y_tip, e_tip = equations.tip_function(self.options.tip_mass)(x, H[0:RATE_SIZE, self.n_steps], P)
        residual.append(r_tip)
        rates.append(ca.vertcat(y_tip, ca.MX.zeros(HISTORY_ROWS - RATE_SIZE)))
        energy += e_tip
        return ca.Function(
            name,
            [z, P, H],
            [ca.horzcat(*columns), ca.vertcat(*residual), ca.horzcat(*rates), energy],
            ["z", "P", "H"],
            ["states", "residual", "Y", "energy"],
        )

    def _split(self, packed: ca.MX) -> tuple[ca.MX, ca.MX, ca.MX]:
        m = self.n_unknowns
        z, P = packed[:m], packed[m : m + self.n_loads]
        H = ca.reshape(packed[m + self.n_loads :], HISTORY_ROWS, self.columns)
        return z, P, H

    @property
    def _packed_size(self) -> int:
        return self.n_unknowns + self.n_loads + HISTORY_ROWS * self.columns

    def _packed_shape(self) -> ca.Function:
        """``(z, P, vec H) -> (residual, energy, vec Y, vec states)``, one vector."""
        packed = ca.MX.sym("packed", self._packed_size)
        states, r, Y, E = self.shape(*self._split(packed))
        return ca.Function("rod_dynamics_packed", [packed], [ca.vertcat(r, E, ca.vec(Y), ca.vec(states))])

    # ----------------------------------------------------------------- Newton

    def _evaluate(self, z: np.ndarray, P: np.ndarray, H: np.ndarray, rest: bool = False):
        """``(residual, energy, Y, states)`` at the unknowns ``z``."""
        if self._compiled is None or rest:
            f = self.static_shape if rest else self.shape
            states, r, Y, E = f(z, P, H)
            return (np.asarray(r).ravel(), np.asarray(E).ravel(), np.asarray(Y), np.asarray(states))
        return self._evaluate_packed(self._pack(P, H), z)

    def _pack(self, P: np.ndarray, H: np.ndarray) -> np.ndarray:
        """``(1, n)`` the compiled shape's input with the loads and the history in place (the unknowns to fill)."""
        nz = self.n_unknowns
        packed = np.empty((1, self._packed_size))
        packed[0, nz : nz + self.n_loads] = P
        packed[0, nz + self.n_loads :] = H.ravel(order="F")
        return packed

    def _evaluate_packed(self, packed: np.ndarray, z: np.ndarray):
        """``(residual, energy, Y, states)`` at ``z``, written into ``packed`` (from :meth:`_pack`)."""
        assert self._compiled is not None
        nz = self.n_unknowns
        packed[0, :nz] = z
        out = self._compiled.raw(packed)[0]
        m = HISTORY_ROWS * self.columns
        return (
            out[:nz],
            out[nz : nz + 3],
            out[nz + 3 : nz + 3 + m].reshape(HISTORY_ROWS, self.columns, order="F"),
            out[nz + 3 + m :].reshape(STATE_SIZE, self.s.size, order="F"),
        )

    def _fresh_jacobian_inverse(self, packed: np.ndarray, z: np.ndarray) -> np.ndarray | None:
        """The inverse of the residual's Jacobian at ``z`` by forward differences, all columns in one C call.

        ``packed`` is the step's input (:meth:`_pack`). The steps ``1e-7 (1 + |z_j|)`` leave a relative
        error near ``1e-6``, which only slows Newton by that factor per iteration.
        """
        assert self._compiled is not None
        nz = self.n_unknowns
        steps = FD_STEP * (1.0 + np.abs(z))
        batch = np.repeat(packed, nz + 1, axis=0)
        batch[:, :nz] = z
        batch[np.arange(1, nz + 1), np.arange(nz)] += steps
        r = self._compiled.raw(batch)[:, :nz]
        J = ((r[1:] - r[0]) / steps[:, None]).T
        try:
            inverse = np.linalg.inv(J)
        except np.linalg.LinAlgError:
            return None
        return inverse if np.all(np.isfinite(inverse)) else None

    def _newton(self, z0: np.ndarray, P: np.ndarray, H: np.ndarray):
        """``(z, (residual, energy, Y, states), iterations, converged)`` from ``z0`` (compiled path).

        Newton with the Jacobian kept while the residual falls at least twofold per iteration,
        refreshed when it does not, and a backtracking line search (halving the step) when a
        step with a fresh Jacobian does not lower the residual.
        """
        tol = self.options.tolerance
        z = np.array(z0, dtype=float)
        packed = self._pack(P, H)
        out = self._evaluate_packed(packed, z)
        norm = float(np.linalg.norm(out[0]))
        if norm <= tol:
            return z, out, 0, True
        if not np.isfinite(norm):
            return z, out, 0, False
        fresh = False
        for it in range(1, self.options.max_iterations + 1):
            if self._jacobian_inverse is None:
                self._jacobian_inverse, fresh = self._fresh_jacobian_inverse(packed, z), True
                if self._jacobian_inverse is None:
                    return z, out, it, False
            dz, lam = self._jacobian_inverse @ out[0], 1.0
            while True:
                trial = z - lam * dz
                trial_out = self._evaluate_packed(packed, trial)
                trial_norm = float(np.linalg.norm(trial_out[0]))
                if trial_norm < norm:
                    break
                if not fresh:
                    self._jacobian_inverse, fresh = self._fresh_jacobian_inverse(packed, z), True
                    if self._jacobian_inverse is None:
                        return z, out, it, False
                    dz, lam = self._jacobian_inverse @ out[0], 1.0
                    continue
                lam *= 0.5
                if lam < 1e-6:
                    return z, out, it, False
            contraction = trial_norm / norm
            z, out, norm = trial, trial_out, trial_norm
            if norm <= tol:
                return z, out, it, True
            if contraction > 0.5:
                self._jacobian_inverse = None
            fresh = False
        return z, out, self.options.max_iterations, False

    def _rootfinder_of(self, residual: ca.Function, name: str) -> ca.Function:
        return ca.rootfinder(
            name,
            "newton",
            residual,
            {
                "abstol": self.options.tolerance / 10,
                "abstolStep": 1e-15,
                "max_iter": self.options.max_iterations,
                "error_on_fail": False,
            },
        )

    @cached_property
    def _rootfinder(self) -> ca.Function:
        return self._rootfinder_of(self.residual, "rod_dynamics_newton")

    def _solve(self, z0: np.ndarray, P: np.ndarray, H: np.ndarray):
        if self._compiled is not None:
            return self._newton(z0, P, H)
        z = np.asarray(self._rootfinder(z0, P, H)).ravel()
        out = self._evaluate(z, P, H)
        norm = float(np.linalg.norm(out[0]))
        iterations = int(self._rootfinder.stats().get("iter_count", 0))
        return z, out, iterations, bool(np.isfinite(norm) and norm <= self.options.tolerance)

    def _straight(self) -> np.ndarray:
        """Unknowns of the straight, unloaded rod at rest."""
        z = np.zeros(self.n_unknowns)
        R = np.asarray(matrix_from_quat(np.asarray(self.arm.base_orientation), check=False))
        for j in range(1, self.intervals):
            x = np.zeros(STATE_SIZE)
            x[0:3] = np.asarray(self.arm.base_position) + self.s[self.cuts[j]] * R[:, 2]
            x[3:7] = self.arm.base_orientation
            z[6 + STATE_SIZE * (j - 1) : 6 + STATE_SIZE * j] = x
        return z

    # ----------------------------------------------------------------- public API

    def load_vector(self, loads: Loads | np.ndarray) -> np.ndarray:
        """``P`` of ``loads`` (a :class:`~optikin.physics.Loads` or a vector ``(n_P,)``)."""
        if isinstance(loads, Loads):
            return load_vector(self.arm, loads)
        P = np.asarray(loads, dtype=float).ravel()
        if P.shape != (self.n_loads,):
            raise InputDataError(f"expected a load vector of {self.n_loads} entries, got {P.size}", field="loads")
        return P

    def rest(self, loads: Loads | np.ndarray, max_ramp_steps: int = 256) -> DynamicState:
        """The rod at rest in its equilibrium under ``loads`` (held since ever): the start of a simulation.

        The equilibrium of the same discrete equations without time derivatives, the loads
        ramped from zero (1, 2, 4, ... steps) until Newton converges at each.

        Raises
        ------
        optikin.errors.SolverError
            When no equilibrium is found.
        """
        P = self.load_vector(loads)
        zero = np.zeros((HISTORY_ROWS, self.columns))
        rf = self._rootfinder_of(self._static_residual, "rod_rest_newton")
        steps, r = 1, np.inf
        while steps <= max_ramp_steps:
            z, ok = self._straight(), True
            for frac in np.arange(1, steps + 1) / steps:
                z = np.asarray(rf(z, frac * P)).ravel()
                r = float(np.linalg.norm(np.asarray(self._static_residual(z, frac * P)).ravel()))
                ok = bool(np.isfinite(r) and r <= self.options.tolerance)
                if not ok:
                    break
            if ok:
                break
            steps *= 2
        else:
            raise SolverError(f"no equilibrium at rest under the start loads (residual {r:.3g})")
        residual, E, Y, states = self._evaluate(z, P, zero, rest=True)
        for i in range(STAGES):
            Y[RATE_SIZE * i + 6 : RATE_SIZE * (i + 1)] = 0.0
        return DynamicState(
            t=0.0,
            step=0,
            history=-self.coefficients.c0 * Y,
            rates=Y,
            unknowns=z,
            previous_unknowns=z,
            older_unknowns=z,
            states=states,
            energy=np.array([0.0, E[1], E[2]]),
            residual=float(np.linalg.norm(residual)),
        )

    def advance(self, Y: np.ndarray, state: DynamicState) -> np.ndarray:
        """The next history ``c1 y + c2 y_prev + d1 (c0 y + H)`` after stage values ``Y`` from ``state``."""
        c = self.coefficients
        return c.c1 * Y + c.c2 * state.rates + c.d1 * (c.c0 * Y + state.history)

    @staticmethod
    def prediction(state: DynamicState) -> np.ndarray:
        """The next step's start: the unknowns extrapolated quadratically from the last three steps."""
        return 3 * state.unknowns - 3 * state.previous_unknowns + state.older_unknowns

    def step(self, state: DynamicState, loads: Loads | np.ndarray) -> DynamicState:
        """One time step from ``state`` under ``loads`` (those at the new time).

        Raises
        ------
        StepError
            When Newton does not converge, from the extrapolated unknowns nor from the previous ones.
        """
        P = self.load_vector(loads)
        guess = self.prediction(state)
        z, out, iterations, ok = self._solve(guess, P, state.history)
        if not ok:
            self._jacobian_inverse = None
            z, out, more, ok = self._solve(state.unknowns, P, state.history)
            iterations += more
        r, E, Y, states = out
        t = state.t + self.options.dt
        if not ok:
            raise StepError(state.step + 1, t, float(np.linalg.norm(r)), self.options.tolerance)
        return DynamicState(
            t=t,
            step=state.step + 1,
            history=self.advance(Y, state),
            rates=Y,
            unknowns=z,
            previous_unknowns=state.unknowns,
            older_unknowns=state.previous_unknowns,
            states=states,
            energy=E,
            residual=float(np.linalg.norm(r)),
            iterations=iterations,
        )

    def simulate(self, state: DynamicState, loads: np.ndarray, keep_shapes: bool = True) -> Trajectory:
        """Steps from ``state`` under one load vector per step, stopping at the first that does not converge.

        Parameters
        ----------
        state : DynamicState
            The start.
        loads : numpy.ndarray
            ``(T, n_P)`` the loads of steps ``1 .. T``.
        keep_shapes : bool
            Keep every centre line (else only the start's and the last's).

        Returns
        -------
        Trajectory
            The start and every converged step; ``failure`` names the step that did not converge.
        """
        loads = np.asarray(loads, dtype=float)
        if loads.ndim != 2 or loads.shape[1] != self.n_loads:
            raise InputDataError(f"expected (steps, {self.n_loads}) loads, got {loads.shape}", field="loads")
        states, failure = [state], None
        for row in loads:
            try:
                state = self.step(state, row)
            except StepError as exc:
                failure = exc
                break
            states.append(state if keep_shapes else replace(state, states=state.states[:, -1:]))
        shapes = [s.positions for s in states] if keep_shapes else [states[0].positions, state.positions]
        return Trajectory(
            t=np.array([s.t for s in states]),
            tip=np.array([s.states[0:3, -1] for s in states]),
            positions=np.array(shapes),
            energy=np.array([s.energy for s in states]),
            residual=np.array([s.residual for s in states]),
            iterations=np.array([s.iterations for s in states]),
            final=state,
            failure=failure,
        )

    # ----------------------------------------------------------------- derivatives

    @cached_property
    def step_function(self) -> ca.Function:
        """``(z_guess, x, P) -> (x_next, tip)``, differentiable: ``x`` the :attr:`DynamicState.vector`.

        The shooting unknowns are CasADi's rootfinder of the residual, so derivatives follow the
        implicit function theorem.
        """
        m = HISTORY_ROWS * self.columns
        guess, x, P = ca.MX.sym("z0", self.n_unknowns), ca.MX.sym("x", 2 * m), ca.MX.sym("P", self.n_loads)
        H, Yp = ca.reshape(x[:m], HISTORY_ROWS, self.columns), ca.reshape(x[m:], HISTORY_ROWS, self.columns)
        w = self._rootfinder(guess, P, H)
        states, _, Y, _ = self.shape(w, P, H)
        c = self.coefficients
        Hn = c.c1 * Y + c.c2 * Yp + c.d1 * (c.c0 * Y + H)
        return ca.Function(
            "rod_dynamics_step",
            [guess, x, P],
            [ca.vertcat(ca.vec(Hn), ca.vec(Y)), states[0:3, -1]],
            ["z0", "x", "P"],
            ["x_next", "tip"],
        )

    @cached_property
    def _derivative_functions(self) -> tuple[ca.Function, ca.Function]:
        f = self.step_function
        guess, x, P = ca.MX.sym("z0", self.n_unknowns), ca.MX.sym("x", f.nnz_in(1)), ca.MX.sym("P", self.n_loads)
        xn, tip = f(guess, x, P)
        small = ca.Function(
            "rod_dynamics_step_jac_small",
            [guess, x, P],
            [ca.jacobian(xn, P), ca.jacobian(tip, x), ca.jacobian(tip, P)],
        )
        full = ca.Function("rod_dynamics_step_jac_state", [guess, x, P], [ca.jacobian(xn, x)])
        return small, full

    def derivatives(self, state: DynamicState, loads: Loads | np.ndarray, wrt_state: bool = False) -> StepDerivatives:
        """Derivatives of the step from ``state`` under ``loads``.

        Parameters
        ----------
        state : DynamicState
            Where to differentiate.
        loads : Loads or numpy.ndarray
            The step's loads.
        wrt_state : bool
            Also the dense ``(n_x, n_x)`` Jacobian of the next state (large: 3840 x 3840 at 40 points).

        Returns
        -------
        StepDerivatives
        """
        P = self.load_vector(loads)
        small, full = self._derivative_functions
        args = (self.prediction(state), state.vector, P)
        dx_dP, dtip_dx, dtip_dP = (np.asarray(a) for a in small(*args))
        return StepDerivatives(
            wrt_state=np.asarray(full(*args)) if wrt_state else None,
            wrt_loads=dx_dP,
            tip_wrt_state=dtip_dx,
            tip_wrt_loads=dtip_dP,
        )
