"""The options of the ``tracking`` kind: controller gains and limits, the simulated plant, MRAC, the convergence check.

Vectors whose length depends on the arm (``start``, ``start_offset``,
``plant.disturbance``, ``plant.configuration_noise``, ``plant.length_scale``)
are checked against it when the run starts, naming the field.
"""

from __future__ import annotations

import re
from typing import Annotated, Literal

from pydantic import AfterValidator, Field, NonNegativeFloat, PositiveFloat, field_validator

from optikin.options import Options


def _rate_limit_key(key: str) -> str:
    if not re.fullmatch(r"(S|theta|phi)([1-9][0-9]*)?", key):
        raise ValueError(
            f"unknown variable or prefix {key[:40]!r}: expected S, theta or phi, or a variable (S1, theta2, phi1, ...)"
        )
    return key


RateLimitKey = Annotated[str, AfterValidator(_rate_limit_key)]
"""A key of ``rate_limits``: a variable prefix (S, theta, phi) or a variable name (S1, theta2, ...)."""


class CosseratPlantOptions(Options):
    """A CBHA-like pneumatic Cosserat rod as the plant (:mod:`optikin.control.rod_plant`).

    Defaults: the two-section CBHA of ``problems/cosserat-cbha-fk.yaml`` (sizes from seed 004,
    stiffness, density and chamber bore stated assumptions there); rest length: the CC
    arm's shortest section length, so every command stretches the rod.
    """

    type: Literal["cosserat"] = Field("cosserat", description="the rod model (static Cosserat rod)")
    youngs_modulus: PositiveFloat = Field(40.0e3, description="effective Young's modulus E [Pa]")
    poisson_ratio: float = Field(0.5, gt=-1.0, le=0.5, description="nu, G = E / (2 (1 + nu))")
    density: NonNegativeFloat = Field(150.0, description="effective density of the rod [kg/m^3]")
    radius: list[PositiveFloat] = Field(
        [0.045, 0.040], description="radius of each section's solid equivalent cross-section [m]"
    )
    chamber_offset: list[PositiveFloat] = Field(
        [0.03725, 0.03175], description="distance of each section's three chambers from the backbone [m]"
    )
    chamber_area: PositiveFloat = Field(3.1416e-4, description="pressurised area of every chamber [m^2]")
    rest_length: list[PositiveFloat] | None = Field(
        None, description="unpressurised length of each section [m]; null: the CC arm's lower S limits"
    )
    gravity: bool = Field(True, description="the rod's weight and the payload's act")
    gravity_vector: tuple[float, float, float] = Field(
        (0.0, 0.0, -9.81), description="gravitational acceleration in the base frame (base pointing up) [m/s^2]"
    )
    payload: NonNegativeFloat = Field(0.0, description="mass hanging at the tip [kg]")
    steps_per_segment: int = Field(20, ge=1, le=1000, description="RK4 steps per section of the shooting grid")
    compiled: bool = Field(True, description="Newton on C-compiled residual and Jacobian (else the CasADi VM)")


class PlantOptions(Options):
    """How the simulated arm differs from the controller's model, what disturbs it and how it is measured."""

    length_scale: PositiveFloat | list[PositiveFloat] = Field(
        1.0, description="true / modelled arc length: one value, or one per section"
    )
    disturbance: list[float] | None = Field(
        None, description="configuration offset added over disturbance_window, one per variable [SI units]"
    )
    disturbance_window: tuple[float, float] | None = Field(
        None, description="[t_on, t_off) of the disturbance [s]; null: the whole run"
    )
    configuration_noise: NonNegativeFloat | list[NonNegativeFloat] = Field(
        0.0, description="standard deviation of the configuration sensor: one value, or one per variable [SI units]"
    )
    tip_position_noise: float = Field(0.0, ge=0.0, description="standard deviation of the tip position sensor [m]")
    tip_angle_noise: float = Field(0.0, ge=0.0, description="standard deviation of the tip orientation sensor [rad]")
    feedback: Literal["tip", "model"] = Field(
        "tip", description="tip: the tip is measured; model: computed by the model from the measured configuration"
    )
    physics: CosseratPlantOptions | None = Field(
        None, description="a Cosserat rod as the plant, actuated by the nominal map of the CC command; null: CC"
    )

    @field_validator("disturbance_window")
    @classmethod
    def _window_in_order(cls, value: tuple[float, float] | None) -> tuple[float, float] | None:
        if value is not None and not value[0] < value[1]:
            raise ValueError(f"the start t_on = {value[0]:g} s is not before the end t_off = {value[1]:g} s")
        return value


class MracOptions(Options):
    """The MRAC baselines (Seleem et al. 2020, eqs. 32-35): ``mrac`` from ``gain``, ``mrac_seed`` from the paper's K."""

    gain: NonNegativeFloat | list[NonNegativeFloat] | None = Field(
        None,
        description="initial K of mrac, one value or one per task row [1/s]; null: options.gain, the task gain of "
        "every controller (baseline mrac_seed starts from the paper's optimised K)",
    )
    adaptation: NonNegativeFloat | list[NonNegativeFloat] | None = Field(
        None,
        description="adaptation rates gamma_a, one value or one per task row; "
        "null: the paper's for position, 50 for the pose",
    )
    gain_limit: PositiveFloat | list[PositiveFloat] = Field(
        100.0, description="saturation of the adapted gains, one value or one per task row [1/s]"
    )
    natural_frequency: float = Field(10.0, gt=0.0, description="w_n of the second-order reference model [rad/s]")
    damping_ratio: float = Field(1.0, gt=0.0, description="zeta of the second-order reference model")


class ToleranceOptions(Options):
    """Convergence check: mean errors over the last 10 % of the run below these."""

    position_mm: float = Field(0.05, gt=0.0, description="tip position error [mm]")
    orientation_deg: float = Field(0.05, gt=0.0, description="tip orientation error [deg] (pose task)")


Vector3 = tuple[float, float, float]


class ObstacleOptions(Options):
    """One obstacle (:class:`optikin.control.obstacles.Obstacle`): a shape, its geometry (base frame, m), a path."""

    type: Literal["sphere", "capsule", "box", "halfspace"] = Field(description="the shape")
    center: Vector3 | None = Field(None, description="centre of a sphere or box [m]")
    radius: PositiveFloat | None = Field(None, description="radius of a sphere or capsule [m]")
    a: Vector3 | None = Field(None, description="one end of a capsule's axis [m]")
    b: Vector3 | None = Field(None, description="the other end of a capsule's axis [m]")
    half_extents: tuple[PositiveFloat, PositiveFloat, PositiveFloat] | None = Field(
        None, description="half side lengths of an axis-aligned box [m]"
    )
    point: Vector3 | None = Field(None, description="a point on a half-space's plane [m]")
    normal: Vector3 | None = Field(None, description="a half-space's normal, pointing out of the obstacle")
    path: list[tuple[float, float, float, float]] | None = Field(
        None,
        description="rows [t, dx, dy, dz]: offset added to the geometry, linear in between [s, m]; null: static",
    )


class BarrierOptions(Options):
    """The backbone barrier of the QP (:class:`optikin.control.obstacles.BarrierRows`)."""

    margin: PositiveFloat = Field(0.01, description="d_safe, the distance every backbone sample keeps [m]")
    gamma: PositiveFloat = Field(20.0, description="barrier rate: d_dot >= -gamma (d - d_safe) [1/s]; gamma dt <= 1")
    points_per_obstacle: int = Field(3, ge=1, description="backbone samples per obstacle in the QP (the nearest)")
    points_per_section: int | None = Field(
        None, ge=1, description="backbone samples per section; null: ceil(S_max / margin), spacing <= margin"
    )


class MPCOptions(Options):
    """The MPC controllers (:mod:`optikin.control.mpc`, :mod:`optikin.control.mpc_nlp`), run when in ``baselines``.

    ``mpc`` is the controller of ``solver`` (the sparse QP by OSQP, or the nonlinear horizon by
    IPOPT), ``mpc_ipopt`` always the IPOPT reference; both share the horizon, the weights and the
    QP's gain, limits and barrier.
    """

    horizon: int = Field(20, ge=1, le=500, description="N, the control steps predicted")
    effort_weight: NonNegativeFloat | None = Field(
        None,
        description="lambda, the weight of ||u_j||^2 against the task slacks (task velocities); "
        "null: options.damping, so that N = 1 without obstacles is the QP's step",
    )
    solver: Literal["osqp", "ipopt"] = Field(
        "osqp", description="the controller of baseline mpc: osqp (one sparse QP per step) or ipopt (nonlinear)"
    )
    preview: bool = Field(True, description="the reference's rates ahead enter the target; false: present rate held")
    eps: PositiveFloat = Field(1e-3, description="OSQP's absolute and relative tolerance")
    rho: PositiveFloat = Field(0.1, description="OSQP's ADMM step size")
    max_iter: int = Field(4000, ge=1, description="OSQP's iterations per step before the horizon counts as failed")
    polishing: bool = Field(False, description="OSQP's active-set polishing of each answer")
    ipopt_tolerance: PositiveFloat = Field(1e-8, description="IPOPT's tol")
    ipopt_max_iter: int = Field(200, ge=1, description="IPOPT's iterations per step")


class TrackingOptions(Options):
    """Options of the ``tracking`` kind."""

    start: list[float] | None = Field(None, description="initial configuration; null: where the reference starts")
    start_offset: list[float] | None = Field(None, description="added to the initial configuration [SI units]")
    gain: NonNegativeFloat | list[NonNegativeFloat] = Field(
        10.0, description="K of the QP, pseudo-inverse and DLS: one value or one per task row [1/s]"
    )
    damping: float = Field(1e-4, ge=0.0, description="lambda, the weight of ||qdot||^2 in the QP and DLS")
    rate_limits: dict[RateLimitKey, PositiveFloat] | list[PositiveFloat] | None = Field(
        None,
        description="rate limits by variable name or prefix (S, theta, phi), or one per variable [m/s, rad/s]; "
        "null: S 0.1, theta pi, phi 2 pi",
    )
    limit_margin: NonNegativeFloat | list[NonNegativeFloat] = Field(
        1e-9, description="distance the QP keeps from the configuration limits: one value or one per variable"
    )
    limit_gain: float = Field(
        1.0, gt=0.0, le=1.0, description="fraction of the distance to a limit one step may cover (pink: 0.5)"
    )
    fallback: Literal["hold", "damped_least_squares"] = Field(
        "hold", description="command applied when the QP solver fails"
    )
    compiled: bool = Field(False, description="compile the per-step CasADi Function with a C compiler")
    plant: PlantOptions = Field(default_factory=PlantOptions, description="the simulated arm and its sensors")
    mrac: MracOptions = Field(default_factory=MracOptions, description="the MRAC baseline")
    tolerance: ToleranceOptions = Field(default_factory=ToleranceOptions, description="the convergence check")
    obstacles: list[ObstacleOptions] = Field(
        default_factory=list, description="obstacles the QP keeps the whole backbone away from (baselines ignore them)"
    )
    barrier: BarrierOptions = Field(default_factory=BarrierOptions, description="the QP's backbone barrier")
    mpc: MPCOptions = Field(default_factory=MPCOptions, description="the MPC baselines mpc and mpc_ipopt")
