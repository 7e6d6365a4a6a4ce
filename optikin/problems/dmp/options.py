"""The options of the ``dmp`` kind: one model, a nested model per section.

Every default is the value the kind used before its options were typed; the
gains default to :class:`optikin.dmp.Gains` (movement_primitives' values).
Checks that need the demonstration (a goal switch within ``3 tau``, a
disturbed component within the DMP's dimension) or two sections together (the
goal scenario of the tuning needs goal switches) are made in
:mod:`optikin.problems.dmp.run`.
"""

from __future__ import annotations

from typing import Annotated, Literal, get_args

from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from optikin.dmp import Gains
from optikin.dmp.canonical import PhaseStopping
from optikin.dmp.gains import GainName
from optikin.dmp.regression import Method
from optikin.dmp.tuning import Scenario
from optikin.options import Options

Variant = Literal[
    "seed", "seed-qd-start", "dual-quaternion", "cartesian", "quaternion", "koutras-doulgeri", "rpy", "position"
]
"""A DMP representation: the pose DMPs of :mod:`optikin.dmp.pose` (``seed-qd-start``: the seed's with ``|Q_d|``
from the demonstration's start rather than its goal), a unit-quaternion DMP on the orientation
(Seleem et al. 2020, eqs. 17-23, Ude et al.'s form), Koutras & Doulgeri's orientation DMP in the logarithm of the
rotation to the goal (:class:`optikin.dmp.GoalLogQuaternion`), per-angle DMPs on roll-pitch-yaw (eqs. 11-16) or a
translation DMP on the position."""
VARIANTS: tuple[Variant, ...] = get_args(Variant)

_GAINS = Gains()
Rate = Annotated[float, Field(allow_inf_nan=True)]
"""A goal-filter rate: ``inf`` allowed (the goal jumps); NaN and negative rates are refused by the model."""


class GainOptions(Options):
    """The gains of every DMP of the run (:class:`optikin.dmp.Gains`)."""

    beta: float = Field(_GAINS.beta, gt=0, description="damping of the transformation system (eqs. 11, 17)")
    gamma: float = Field(_GAINS.gamma, gt=0, description="spring to damping ratio (eqs. 11, 17)")
    zeta: float = Field(_GAINS.zeta, gt=0, description="decay rate of the phase (eq. 15)")
    beta_g0: Rate | tuple[Rate, ...] = Field(
        _GAINS.beta_g0,
        description="rate of the goal filter (eq. 24), or one rate per gap component (the diagonal); .inf: the "
        "goal jumps",
    )

    @field_validator("beta_g0")
    @classmethod
    def _rates_non_negative(cls, value: Rate | tuple[Rate, ...]) -> Rate | tuple[Rate, ...]:
        rates = value if isinstance(value, tuple) else (value,)
        if not rates or any(not r >= 0 for r in rates):
            raise PydanticCustomError("negative_rate", "every rate of beta_g0 must be >= 0 (.inf: the goal jumps)")
        return value

    alpha_s: float = Field(_GAINS.alpha_s, ge=0, description="coupling to the goal and reference gaps (eqs. 26-27)")
    alpha: float = Field(_GAINS.alpha, ge=0, description="phase stopping by the gaps (eqs. 25, 28)")

    def gains(self) -> Gains:
        """These gains as :class:`optikin.dmp.Gains`."""
        return Gains(**self.model_dump())


class RegressionOptions(Options):
    """How the forcing-term weights are fitted (:mod:`optikin.dmp.regression`)."""

    method: Method = Field("cvxpy", description="cvxpy (all weights at once), lstsq (closed form) or lwr")
    ridge: float = Field(0.0, ge=0, description="weight of the ridge term |W|^2 (lstsq, cvxpy)")
    bound: float | None = Field(None, gt=0, description="bound |w| <= bound on every weight (cvxpy only)")

    @field_validator("bound")
    @classmethod
    def _bound_needs_cvxpy(cls, bound: float | None, info: ValidationInfo) -> float | None:
        if bound is not None and info.data.get("method") != "cvxpy":
            raise PydanticCustomError("bound_needs_cvxpy", "bounds on the weights need method cvxpy")
        return bound


class GoalSwitch(Options):
    """A new goal, relative to the goal before it (the demonstration's for the first)."""

    time: float = Field(ge=0, description="when the goal switches [s] (at most 3 tau)")
    rotate: tuple[float, ...] = Field(
        (0.0, 0.0, 0.0), min_length=3, max_length=3, description="rotation vector applied to the orientation [rad]"
    )
    translate: tuple[float, ...] = Field(
        (0.0, 0.0, 0.0), min_length=3, max_length=3, description="translation added to the position [m]"
    )


DisturbanceKind = Literal["output", "force"]
"""How a step disturbance acts (:class:`Disturbance`)."""


class Disturbance(Options):
    """A step disturbance on one gap component, on during ``[start, stop)``.

    ``output`` (default; Seleem et al. 2020 call it an "output step disturbance", sec. V): the DMP's pose is
    displaced by ``amplitude`` gap units (rad about an axis, or m) and held there, the DMP integrating on from
    the displaced pose, and released at ``stop``. ``force``: ``amplitude`` is a force added to eq. (17) (gap
    units per s^2, scaled by ``tau^2``), the reading optikin used first; on the 10 s IMU demonstration its
    effect is two orders of magnitude below what Figs. 20-21 show (about 7 mrad against a pose pushed by 1).
    """

    kind: DisturbanceKind = Field("output", description="output (the pose displaced and held) or force (eq. 17)")
    start: float = Field(5.0, description="the disturbance starts [s]")
    stop: float = Field(7.0, description="the disturbance stops [s]")
    amplitude: float = Field(
        1.0, description="the displacement (output: rad | m) or the force (force: gap units per s^2, scaled by tau^2)"
    )
    component: int = Field(0, ge=0, description="the gap component pushed (below the DMP's dimension)")

    @model_validator(mode="after")
    def _window_in_order(self) -> Disturbance:
        if not self.start < self.stop:
            raise ValueError(f"start = {self.start:g} s is not before stop = {self.stop:g} s")
        return self


class Coupling(Options):
    """A DMP coupled to the demonstration (eq. 27), run against the plain one under the disturbance."""

    phase_stopping: PhaseStopping = Field(
        "tracking", description="the error that slows the phase (optikin.dmp.canonical): tracking or seed"
    )
    alpha_s: float = Field(0.0, ge=0, description="coupling gain (eqs. 26-27)")
    alpha: float = Field(0.0, ge=0, description="phase-stopping gain (eqs. 25, 28); > 0 needs phase_stopping: seed")

    @field_validator("alpha")
    @classmethod
    def _stopping_needs_seed(cls, alpha: float, info: ValidationInfo) -> float:
        if alpha > 0 and info.data.get("phase_stopping") == "tracking":
            raise PydanticCustomError(
                "tracking_against_demonstration",
                "phase stopping on the tracking error needs the robot's pose as the reference; here the DMP is "
                "coupled to the demonstration (eq. 27), which runs on in time, so the lag the stopping creates "
                "would feed itself (optikin.dmp.canonical): use phase_stopping: seed (eq. 28) or alpha: 0",
            )
        return alpha


SeedTerm = Literal["Q_r", "Q_d"]
"""A term of the seed's dual quaternion ``Q_r + eps Q_d`` (eq. 9) with its own quaternion DMP."""


class Tuning(Options):
    """Gain tuning by minimising eq. (29): multi-start IPOPT, and the genetic algorithm when it is a baseline."""

    gains: tuple[GainName, ...] = Field(("beta", "gamma", "zeta"), min_length=1, description="the gains tuned")
    variant: Variant | None = Field(None, description="the DMP tuned; null: the first of variants")
    scenario: Scenario = Field("reproduction", description="reproduction, or goal (the first goal switch)")
    max_iterations: int = Field(60, ge=1, description="IPOPT iterations per start")
    screen: int = Field(16, ge=0, description="Latin-hypercube points screened for the starts")
    starts: int = Field(2, ge=1, description="IPOPT runs, from the best screened points")
    population: int = Field(20, ge=3, description="GA population (its 2 best survive each generation)")
    generations: int = Field(15, ge=0, description="GA generations (unless budget is set)")
    budget: int | None = Field(
        None,
        ge=4,
        description="objective evaluations for IPOPT (runs from the screened points until spent); the GA and the "
        "multi-start L-BFGS-B then get the count IPOPT used; null: starts x max_iterations, and no multi-start",
    )
    seeds: int = Field(1, ge=1, description="GA and multi-start runs, seeded data.seed, data.seed + 1, ...")
    goal_diagonal: bool = Field(
        False,
        description="tune beta_g0 (when in gains) as one rate per gap component, the diagonal of eq. (24) that "
        "the seed reports (Figs. 18-19), not one scalar",
    )
    terms: tuple[SeedTerm, ...] = Field(
        (),
        description="tune the seed's quaternion DMP on these terms of (Q_r, Q_d) (Figs. 5a, 5b) instead of variant",
    )
    reference: dict[str, dict[GainName, float]] = Field(
        default_factory=dict,
        description="gains evaluated on the same eq. (29), per tuned target (a term or the variant), e.g. "
        "the seed's {Q_r: {beta: 348.348, gamma: 977.24}}",
    )


class Tolerance(Options):
    """How close a goal-switch roll-out must end to its last goal to count as converged."""

    position_mm: float = Field(0.01, ge=0, description="position [mm]")
    orientation_mrad: float = Field(0.01, ge=0, description="orientation [mrad]")


def _default_couplings() -> dict[str, Coupling]:
    return {"coupled": Coupling(alpha_s=5.0)}


class DmpOptions(Options):
    """``options:`` of the ``dmp`` kind."""

    variants: tuple[Variant, ...] = Field(("cartesian",), min_length=1, description="the DMPs learned and compared")
    n_basis: int = Field(50, ge=2, description="Gaussian basis functions per gap component (eq. 13)")
    smoothing: float | None = Field(
        None, gt=0, description="cutoff [Hz] of the low-pass applied to the demonstration before learning; null: none"
    )
    gains: GainOptions = Field(default_factory=GainOptions)
    regression: RegressionOptions = Field(default_factory=RegressionOptions)
    goal_switches: tuple[GoalSwitch, ...] = Field((), description="new goals, each relative to the one before")
    disturbance: Disturbance | None = Field(
        None, description="a step disturbance (output displacement or force on eq. 17); null: no perturbation"
    )
    couplings: dict[str, Coupling] = Field(
        default_factory=_default_couplings,
        min_length=1,
        description="label -> coupled DMP run against the plain one under the disturbance",
    )
    tuning: Tuning | None = Field(None, description="gain tuning; null: none")
    settle: float = Field(5.0, gt=0, description="goal-switch roll-outs last settle x tau")
    origin_shift: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0),
        description="where the world origin is moved, in the recording's frame [m]: every variant learns the "
        "positions p - origin_shift (the seed variants' error moves with it, the others' does not)",
    )
    tolerance: Tolerance = Field(default_factory=Tolerance)
