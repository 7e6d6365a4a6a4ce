"""Sensors on the Cosserat CBHA: a gyro-integrated IMU and a depth camera, and the data sources they make.

The arm is the real-size pneumatic CBHA simulated as a static Cosserat rod with gravity
(:func:`optikin.data.cosserat_markers.cosserat_cbha_arm`), driven through the seeded
sinusoidal tube pressures of that module, solved along the motion by the compiled
shooting (each equilibrium warm-started from the ones before). None of the compared
methods (constant curvature, the vertebra model, the networks) shares it, so its
sensors give data no model fits by construction. Two small sensor models:

**IMU** (:class:`ImuModel`, :func:`gyro_readings`, :func:`integrate_gyro`): a strapdown
orientation integrated from a three-axis gyroscope at ``rate`` (100 Hz, the sample rate
of the interface of Seleem et al. 2020, sec. III-A). Between two samples the body rate
is taken constant, the one that carries the true orientation of one sample into the
next (:func:`body_rates`), so integrating the noise-free gyro reproduces the truth at
the samples. The gyro adds, per axis, white noise of density ``noise_density`` (the
angle random walk) and a bias that starts at ``N(0, initial_bias^2)`` and performs a
random walk of density ``bias_random_walk`` (the rate random walk); IEEE Std 952-1997
and Woodman (2007, sec. 3) for both terms. The white noise averaged over a sample
interval ``dt`` has standard deviation ``noise_density / sqrt(dt)``; the bias
increment over ``dt`` has ``bias_random_walk sqrt(dt)``, so the bias variance grows
like ``bias_random_walk^2 t``. Without an accelerometer or magnetometer nothing
corrects the integrated orientation: it drifts about every axis.

**Depth camera** (:class:`DepthCameraModel`, :func:`depth_camera_readings`): a
Kinect-like tracker of a point (the tip centre) at ``rate`` (30 frames/s), with the
noise model of Nguyen, Izadi & Lovell (2012) for a Kinect: axial (along the optical
axis) ``sigma_z(z) = a + b (z - z_0)^2`` and lateral ``sigma_L(z) = c z`` at depth
``z``, independent per frame.

What they record:

:func:`cosserat_sensor_recording`
    The interface of seed 000 on the Cosserat CBHA: an IMU at the end of each section,
    each integrated from its gyro; the relative quaternions (eq. 7) give the section
    angles (eq. 8) and the constant-curvature tip pose at the nominal section lengths,
    the demonstration (a :class:`~optikin.data.demonstrations.PoseDemonstration`); the
    depth camera's tip positions and the truth are kept (:class:`CosseratSensorRecording`,
    parameters :class:`CosseratSensorParams`).
data source ``cosserat`` of families ``targets`` and ``actuations`` (registered here; the
module is imported by :mod:`optikin.problems.statics`, so the sources exist once the kinds are loaded)
    Tip positions or poses (unit dual quaternions) of the Cosserat CBHA along its
    motion (:func:`cosserat_tips`), for the ``ik`` kind and for inverse ``statics``:
    targets that no IK model shares; the positions optionally measured by the depth
    camera (:class:`CosseratTargetParams`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import Field

from optikin.algebra import (
    dq_from_rotation_translation,
    quat_conjugate,
    quat_exp,
    quat_hemisphere_continuous,
    quat_log,
    quat_multiply,
    quat_normalize,
)
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import (
    ConstantCurvatureArm,
    relative_section_quaternions,
    section_angles_from_quaternion,
)
from optikin.data.actuations import FAMILY as ACTUATIONS
from optikin.data.actuations import Actuations
from optikin.data.cosserat_markers import CosseratMarkerParams, actuation, cosserat_cbha_arm
from optikin.data.demonstrations import PoseDemonstration
from optikin.data.markers import tube_fractions
from optikin.data.sources import register_source
from optikin.data.targets import FAMILY as TARGETS
from optikin.data.targets import Targets
from optikin.errors import InputDataError, SpecError
from optikin.ik.points import PointSet
from optikin.options import Options
from optikin.physics import Loads, ShootingOptions, ShootingSolver
from optikin.spec import DataSpec

Vector3 = tuple[float, float, float]


# ------------------------------------------------------------------------------ the IMU
class ImuModel(Options):
    """A three-axis gyroscope integrated into an orientation (module docstring).

    Defaults: the MPU-6050 of the interface of Seleem et al. (2020); its rate noise
    spectral density is 0.005 deg/s/sqrt(Hz) (InvenSense, MPU-6000/MPU-6050 Product
    Specification PS-MPU-6000A-00 rev. 3.4, 2013, sec. 6.1). The datasheet gives no bias
    stability; the rate random walk is an assumption, chosen so that the bias after 10 s
    is about 0.02 deg/s, the yaw drift rate of the ``imu`` demonstrations source.
    """

    rate: float = Field(100.0, gt=0, description="sample rate [Hz]; 100: Seleem et al. 2020, sec. III-A")
    noise_density: float = Field(
        float(np.deg2rad(0.005)),
        ge=0,
        description="white rate noise density per axis [rad/s/sqrt(Hz)]; MPU-6050 datasheet, 0.005 deg/s/sqrt(Hz)",
    )
    bias_random_walk: float = Field(
        1.0e-4, ge=0, description="rate random walk of the bias per axis [rad/s/sqrt(s)]; assumed"
    )
    initial_bias: float = Field(
        0.0, ge=0, description="standard deviation of the bias at t = 0 per axis [rad/s]; 0: calibrated at rest"
    )


def body_rates(q: np.ndarray, dt: float) -> np.ndarray:
    """Constant body rates ``(N - 1, ..., 3)`` [rad/s] carrying each orientation of ``q (N, ..., 4)`` into the next.

    ``omega_k = 2 log(q_k^-1 q_{k+1}) / dt`` (in the body frame of ``q_k``; the shorter of the
    two rotations), so that ``q_{k+1} = q_k exp(omega_k dt / 2)`` exactly (:func:`integrate_gyro`).
    """
    step = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    step = np.where(step[..., :1] < 0, -step, step)
    return 2.0 * quat_log(quat_normalize(step, check=False), check=False) / dt


def integrate_gyro(q0: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
    """Orientations ``(N, ..., 4)`` from ``q0 (..., 4)`` and body rates ``(N - 1, ..., 3)`` held over each ``dt``.

    ``q_{k+1} = q_k exp(omega_k dt / 2)``, the exact rotation of a constant body rate over the
    interval (the zeroth-order-hold strapdown update, Savage 1998), renormalised.
    """
    steps = quat_exp(0.5 * dt * np.asarray(rates, dtype=float))
    out = np.empty((len(steps) + 1,) + np.shape(q0))
    out[0] = q0
    for k, step in enumerate(steps):
        out[k + 1] = quat_normalize(quat_multiply(out[k], step), check=False)
    return out


def gyro_readings(
    rates: np.ndarray, dt: float, model: ImuModel, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """What the gyro reports for true body rates ``(N, ..., 3)`` [rad/s] held over intervals ``dt`` [s].

    Returns
    -------
    measured : numpy.ndarray
        ``(N, ..., 3)`` true rate + bias + white noise of standard deviation
        ``noise_density / sqrt(dt)`` [rad/s].
    bias : numpy.ndarray
        ``(N, ..., 3)`` the bias during each interval [rad/s]: ``b_0 ~ N(0, initial_bias^2)``,
        ``b_{k+1} = b_k + bias_random_walk sqrt(dt) xi_k``.
    """
    rates = np.asarray(rates, dtype=float)
    shape = rates.shape
    increments = model.bias_random_walk * np.sqrt(dt) * rng.standard_normal(shape)
    increments[0] = model.initial_bias * rng.standard_normal(shape[1:])
    bias = np.cumsum(increments, axis=0)
    white = model.noise_density / np.sqrt(dt) * rng.standard_normal(shape)
    return rates + bias + white, bias


# ------------------------------------------------------------------------------ the depth camera
class DepthCameraModel(Options):
    """A Kinect-like point tracker (module docstring).

    Noise defaults: Nguyen, Izadi & Lovell (2012), eqs. for a Kinect at surface angles of
    10-60 degrees: ``sigma_z = 1.2 mm + 1.9 mm/m^2 (z - 0.4 m)^2`` and a lateral 0.8 px at a
    focal length of 585 px, ``sigma_L = 1.37e-3 z``. Frame rate: the 30 frames/s of the
    Kinect v2 capture of Seleem et al. (2020, sec. IV).
    """

    rate: float = Field(30.0, gt=0, description="frame rate [frames/s]")
    position: Vector3 = Field((1.2, 0.0, 0.2), description="optical centre in the world frame [m]")
    look_at: Vector3 = Field((0.0, 0.0, 0.2), description="a point on the optical axis, world frame [m]")
    axial_noise: float = Field(1.2e-3, ge=0, description="a: axial standard deviation at z_0 [m]")
    axial_growth: float = Field(1.9e-3, ge=0, description="b: axial growth with (z - z_0)^2 [1/m]")
    reference_depth: float = Field(0.4, ge=0, description="z_0: depth of the least axial noise [m]")
    lateral_noise: float = Field(
        0.8 / 585.0, ge=0, description="c: lateral standard deviation per metre of depth [m/m] (0.8 px / 585 px)"
    )

    def axis(self) -> np.ndarray:
        """Unit optical axis (3) in the world frame.

        Raises
        ------
        ValueError
            When ``look_at`` is the optical centre.
        """
        d = np.asarray(self.look_at, dtype=float) - np.asarray(self.position, dtype=float)
        norm = float(np.linalg.norm(d))
        if norm == 0:
            raise ValueError("camera.look_at: the same point as camera.position")
        return d / norm

    def sigmas(self, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(sigma_axial, sigma_lateral)`` [m] at depths ``depth`` [m] (module docstring)."""
        depth = np.asarray(depth, dtype=float)
        return self.axial_noise + self.axial_growth * (depth - self.reference_depth) ** 2, self.lateral_noise * depth


def depth_camera_readings(points: np.ndarray, model: DepthCameraModel, rng: np.random.Generator) -> np.ndarray:
    """Measured positions ``(N, 3)`` [m] of true points ``(N, 3)`` [m], world frame.

    Each point's error is Gaussian with ``sigma_axial(z)`` along the optical axis and
    ``sigma_lateral(z)`` along each of two perpendicular directions, ``z`` the point's depth
    (distance along the optical axis from the optical centre), independent per frame.
    """
    points = np.asarray(points, dtype=float)
    axis = model.axis()
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    depth = (points - np.asarray(model.position)) @ axis
    axial, lateral = model.sigmas(depth)
    e = rng.standard_normal((len(points), 3))
    return (
        points + (axial * e[:, 0])[:, None] * axis + (lateral * e[:, 1])[:, None] * u + (lateral * e[:, 2])[:, None] * v
    )


# ------------------------------------------------------------------------------ the truth
@dataclass(frozen=True)
class CosseratMotion:
    """The Cosserat CBHA along its motion, noise-free.

    ``t (N,)`` [s]; ``pressures (N, sections, 3)`` [Pa]; ``tip_position (N, 3)`` [m];
    ``frames (N, S, 4)`` the material frames at the ``S`` stations asked for (unit quaternions,
    hemisphere-continuous along the motion).
    """

    t: np.ndarray
    pressures: np.ndarray
    tip_position: np.ndarray
    frames: np.ndarray


def cosserat_motion(
    cbha: CosseratMarkerParams, t: np.ndarray, stations: tuple[float, ...], rng: np.random.Generator, source: str
) -> CosseratMotion:
    """Equilibria of the Cosserat CBHA of ``cbha`` at times ``t`` (increasing) along its seeded tube pressures.

    Parameters
    ----------
    cbha : CosseratMarkerParams
        The arm and its motion (its recorder fields are not used).
    t : numpy.ndarray
        ``(N,)`` times [s].
    stations : tuple of float
        Where the frames are read, in sections from the base (1.0: the end of section 1).
    rng : numpy.random.Generator
        Draws the pressures' frequencies and phases.
    source : str
        Names the data in errors.

    Raises
    ------
    optikin.errors.InputDataError
        Naming the first time whose equilibrium the shooting does not find.
    ValueError
        When a station is not on the solver's nodes.
    """
    arm = cosserat_cbha_arm(cbha)
    n_sections = len(cbha.section_lengths)
    per_section = cbha.segments_per_section * cbha.steps_per_segment
    nodes = []
    for i, x in enumerate(stations):
        if not 0 <= x <= n_sections or abs(x * per_section - round(x * per_section)) > 1e-9:
            raise ValueError(f"stations.{i}: {x} is not on the solver's nodes between 0 and {n_sections}")
        nodes.append(int(round(x * per_section)))
    low, high = cbha.pressure_range
    pressures = low + tube_fractions(n_sections, t, rng, cbha.frequency, cbha.amplitude) * (high - low)
    tip_force = tuple(float(v) for v in cbha.payload * np.asarray(cbha.gravity, dtype=float))
    solver = ShootingSolver(arm, ShootingOptions(steps_per_segment=cbha.steps_per_segment, compiled=True))
    solutions = solver.solve_sequence(
        [Loads(tip_force=tip_force, actuation=tuple(a)) for a in actuation(cbha, pressures)]
    )
    for i, solution in enumerate(solutions):
        if not solution.ok:
            raise InputDataError(f"no equilibrium of the Cosserat arm: {solution.message}", source=source, sample=i)
    frames = np.stack([s.orientations[nodes] for s in solutions])  # (N, S, 4)
    frames = np.stack([quat_hemisphere_continuous(frames[:, j]) for j in range(len(nodes))], axis=1)
    return CosseratMotion(t, pressures, np.stack([s.positions[-1] for s in solutions]), frames)


# ------------------------------------------------------------------------------ demonstrations: cosserat-imu
class CosseratSensorParams(Options):
    """Parameters of :func:`cosserat_sensor_recording`: the arm and its motion, the IMUs' gyros, the depth camera."""

    cbha: CosseratMarkerParams = Field(
        default_factory=CosseratMarkerParams,
        description="the Cosserat CBHA and its pressure motion (optikin.data.cosserat_markers; recorder fields unused)",
    )
    imu: ImuModel = Field(default_factory=ImuModel, description="the gyroscope of each IMU")
    camera: DepthCameraModel = Field(default_factory=DepthCameraModel, description="the depth camera on the tip")


@dataclass(frozen=True)
class CosseratSensorRecording:
    """IMUs and a depth camera on the Cosserat CBHA (module docstring).

    ``t (N,)`` IMU sample times [s]; ``imu (N, 2, 4)`` the integrated orientations of the IMUs
    at the end of section 1 and at the tip, world frame; ``gyro (N - 1, 2, 3)`` the gyro readings
    [rad/s] and ``bias (N - 1, 2, 3)`` their biases; ``relative (N, 2, 4)`` each section relative
    to its base (eq. 7); ``angles (N, 2, 2)`` the measured ``(theta, phi)`` per section;
    ``camera_t (M,)`` [s] and ``camera_position (M, 3)`` [m] the depth camera's tip positions;
    ``truth`` the motion at the IMU times and ``camera_truth`` at the camera's;
    ``demonstration`` the constant-curvature tip pose of the measured angles.
    """

    t: np.ndarray
    imu: np.ndarray
    gyro: np.ndarray
    bias: np.ndarray
    relative: np.ndarray
    angles: np.ndarray
    camera_t: np.ndarray
    camera_position: np.ndarray
    truth: CosseratMotion
    camera_truth: CosseratMotion
    demonstration: PoseDemonstration


def cosserat_sensor_recording(
    params: CosseratSensorParams, samples: int, rng: np.random.Generator, source: str = "cosserat sensors"
) -> CosseratSensorRecording:
    """Record ``samples`` IMU samples (and the camera frames over the same time) of the Cosserat CBHA.

    The motion's pressures are drawn first from ``rng``, then the gyro noise, then the camera
    noise. The equilibria are solved once at the union of the IMU and camera times.

    Raises
    ------
    optikin.errors.InputDataError
        Naming the first time whose equilibrium the shooting does not find.
    ValueError
        When ``samples < 2`` or the camera looks from its own position.
    """
    if samples < 2:
        raise ValueError(f"samples: {samples}; an IMU recording needs at least 2")
    dt = 1.0 / params.imu.rate
    t = np.arange(samples) * dt
    camera_t = np.arange(int(np.floor(t[-1] * params.camera.rate + 1e-9)) + 1) / params.camera.rate
    times, inverse = np.unique(np.concatenate([t, camera_t]), return_inverse=True)
    motion = cosserat_motion(params.cbha, times, (1.0, 2.0), rng, source)

    def at(rows: np.ndarray) -> CosseratMotion:
        return CosseratMotion(times[rows], motion.pressures[rows], motion.tip_position[rows], motion.frames[rows])

    truth, camera_truth = at(inverse[:samples]), at(inverse[samples:])
    gyro, bias = gyro_readings(body_rates(truth.frames, dt), dt, params.imu, rng)
    imu = integrate_gyro(truth.frames[0], gyro, dt)
    camera_position = depth_camera_readings(camera_truth.tip_position, params.camera, rng)

    relative = relative_section_quaternions(imu, source=source)
    theta, phi = section_angles_from_quaternion(relative)
    angles = np.stack([theta, phi], axis=-1)  # (N, 2, 2)
    lengths = params.cbha.section_lengths
    phi = np.unwrap(phi, axis=0)
    q = np.column_stack([np.full(samples, lengths[0]), theta[:, 0], phi[:, 0], np.full(samples, lengths[1])])
    q = np.column_stack([q, theta[:, 1], phi[:, 1]])
    tip_q, tip_p = ConstantCurvatureArm(section_lengths=lengths).section_frames(q)[-1]
    demo = PoseDemonstration(t=t, position=tip_p, quaternion=quat_hemisphere_continuous(tip_q))
    return CosseratSensorRecording(
        t=t,
        imu=imu,
        gyro=gyro,
        bias=bias,
        relative=relative,
        angles=angles,
        camera_t=camera_t,
        camera_position=camera_position,
        truth=truth,
        camera_truth=camera_truth,
        demonstration=demo,
    )


# ------------------------------------------------------------------------------ targets: cosserat
class CosseratTargetParams(Options):
    """``data.params`` of source ``cosserat`` (family ``targets``)."""

    cbha: CosseratMarkerParams = Field(
        default_factory=CosseratMarkerParams,
        description="the Cosserat CBHA and its pressure motion (optikin.data.cosserat_markers; recorder fields unused)",
    )
    rate: float = Field(5.0, gt=0, description="targets per second along the motion [Hz]")
    measured: bool = Field(False, description="tip positions as the depth camera measures them, else exact")
    camera: DepthCameraModel = Field(default_factory=DepthCameraModel, description="the depth camera (measured)")


def cosserat_tips(params: CosseratTargetParams, data: DataSpec, path: Path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """``data.samples`` tips at ``params.rate`` along the motion: ``(values, t)``.

    ``values`` ``(N, 3)`` positions [m] (measured by the depth camera when ``params.measured``)
    for ``kind`` ``position``, or ``(N, 8)`` unit dual quaternions (the orientation exact) for
    ``pose``; ``t`` ``(N,)`` [s].

    Raises
    ------
    optikin.errors.SpecError
        On ``data.source`` for another target kind, on ``data.params`` for a camera without an axis.
    """
    if kind not in ("position", "pose"):
        raise SpecError(path, "data.source", f"source cosserat gives position or pose targets, not {kind}")
    source = f"{Path(path).name}: cosserat"
    t = np.arange(data.samples) / params.rate
    try:
        motion = cosserat_motion(params.cbha, t, (2.0,), np.random.default_rng([data.seed, 0]), source)
        p = motion.tip_position
        if params.measured:
            p = depth_camera_readings(p, params.camera, np.random.default_rng([data.seed, 1]))
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
    return (p if kind == "position" else dq_from_rotation_translation(motion.frames[:, 0], p, check=False)), t


@register_source(
    TARGETS,
    "cosserat",
    "tips of the Cosserat-rod CBHA (real size, gravity) along a pressure motion, optionally by a depth camera",
    params=CosseratTargetParams,
)
def cosserat_targets(
    arm: ArmModel,
    data: DataSpec,
    params: CosseratTargetParams,
    path: Path,
    kind: str = "position",
    points: PointSet | None = None,
) -> Targets:
    """:func:`cosserat_tips` as a trajectory of targets (solved in order, each from the previous answer).

    The configurations that made them are unknown to the problem's arm (NaN); reachability
    too (treated as reachable). Tip positions or poses only: measured points along the arm are
    refused naming ``options.target``.
    """
    if kind not in ("position", "pose"):
        raise SpecError(path, "options.target", f"source cosserat gives tip positions or poses, not {kind} targets")
    values, t = cosserat_tips(params, data, path, kind)
    configurations = np.full((len(t), arm.n_config), np.nan)
    return Targets(kind, values, configurations, np.ones(len(t), dtype=bool), t=t, trajectory=True, points=points)


@register_source(
    ACTUATIONS,
    "cosserat",
    "inverse statics: tips of the Cosserat-rod CBHA (real size, gravity) along a pressure motion, optionally "
    "by a depth camera",
    params=CosseratTargetParams,
)
def cosserat_statics_targets(
    arm: ArmModel, data: DataSpec, params: CosseratTargetParams, path: Path, kind: str = "position"
) -> Actuations:
    """:func:`cosserat_tips` as the tip targets of inverse statics, a trajectory (no actuations)."""
    values, t = cosserat_tips(params, data, path, kind)
    return Actuations(None, targets=values, t=t, trajectory=True)


@register_source(
    "demonstrations",
    "cosserat-imu",
    "seed 000's IMU interface on the Cosserat-rod CBHA: gyro-integrated IMUs (noise, bias drift), a depth camera",
    params=CosseratSensorParams,
)
def cosserat_imu_demonstration(
    arm: ArmModel | None, data: DataSpec, params: CosseratSensorParams, path: Path
) -> CosseratSensorRecording:
    """:func:`cosserat_sensor_recording` of ``data.samples`` IMU samples, seeded by ``data.seed``; the
    ``dmp`` kind learns from its :attr:`~CosseratSensorRecording.demonstration`."""
    try:
        return cosserat_sensor_recording(
            params, data.samples, np.random.default_rng([data.seed, 0]), source=f"{Path(path).name}: cosserat-imu"
        )
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
