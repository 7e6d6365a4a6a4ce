"""Motion capture of a CBHA simulated as a static Cosserat rod: a ground truth no compared method shares.

The source ``synthetic`` of :mod:`optikin.data.markers` records the CBHA vertebra
model (seed 004), which is also the model of the Newton-Raphson comparator and of the
hybrid networks' database; its markers sit on the backbone; it has no gravity and is
about half the real arm's size. The source ``cosserat`` (family ``markers``) records
instead an arm of :mod:`optikin.physics`, which none of the compared methods uses:

* **arm** (:func:`cosserat_cbha_arm`): two pneumatic bending sections in series,
  clamped at the base, each a uniform elastic rod (Cosserat: extensible and shearable)
  with three chambers 120 degrees apart (:func:`optikin.physics.cbha_chambers`, at the
  angles of the CBHA's tubes ``u_1, u_2, u_3``, :data:`optikin.curves.tubes.CBHA_TUBE_ANGLES`).
  Each section is split into ``segments_per_section`` rods so that the chambers' offset
  follows the CBHA's taper piecewise (each segment's chambers at the taper's mean over
  the segment); the tubes themselves (markers, potentiometers) follow the linear taper
  ``rho(s) = rho_base + (rho_tip - rho_base) s / L`` in reference arc length. Gravity acts on
  the rod's mass and on an optional tip payload (a point mass at the tip centre). Every
  number's value and source is in :class:`CosseratMarkerParams`;
* **motion**: each tube's pressure is ``p_min + f (p_max - p_min)`` with the seeded
  sinusoidal fraction ``f(t)`` of :func:`optikin.data.markers.tube_fractions`
  (random frequency and phase per tube), the same pressure in every segment of the
  section; the equilibria are found by the compiled :class:`~optikin.physics.ShootingSolver`
  along the trajectory, each warm-started from the ones before. A posture whose
  equilibrium is not found is an :class:`~optikin.errors.InputDataError` naming it;
* **frames**: 240 Hz; one posture every ``stride`` frames, time-stamped ``frame / 240``;
* **rigid bodies**: the base and tip poses are the material frames at ``s = 0`` and
  ``s = L`` (the disks, z along ``d3``, x along ``d1``: the reference of the tube angles),
  measured with ``pose_noise`` [m] per coordinate and ``orientation_noise`` [rad] per axis
  (a rotation vector in the body frame);
* **tube markers** (seed 002 section IV.A: "five markers are attached to each tube ...
  at starting point, at ending point and three intermediate points"): tube ``m`` at the
  station of reference arc length ``s_j`` is ``p(s_j) + rho(s_j) R(s_j) u_m``, at the tube's
  offset, not on the backbone; stations at the base, the three ``intermediate`` ones
  (in sections: 1.0 is the end of section 1) and the tip; ``marker_noise`` per coordinate;
* **backbone markers** (``markers``): at each intermediate station the centroid of the
  three tubes' markers, as motion-capture software reports a rigid body of three markers
  (seed 004 section VI.A: "three reflective markers are attached to each head of its two
  sections"): the three ``u_m`` add up to zero, so the noise-free centroid is the backbone
  point. ``marker_vertebrae``: the CBHA model's vertebra at the same place
  (``1 + 8 x`` for station ``x``, 8 platforms per section), so the comparators find the
  end of section 1;
* **tube lengths** (the six wire potentiometers of seed 002 section IV.A): the arc length of
  each tube's offset curve over section 1 and over the whole arm, with ``length_noise``;
* **truth** (:class:`CosseratTruth`): pressures, the backbone at every solver node, its
  arc length, the noise-free markers, poses and tube lengths.

Arc lengths are the polylines through the solver's nodes extrapolated to zero spacing
(Richardson, every node and every other node): the node spacing enters at fourth order.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import cast

import numpy as np
from pydantic import Field, field_validator, model_validator

from optikin.algebra import quat_exp, quat_multiply, quat_normalize, quat_rotate
from optikin.arms.base import ArmModel
from optikin.arms.cbha import LEG_DIRECTIONS
from optikin.checks import check_quaternion
from optikin.curves.tubes import CBHA_TUBE_ANGLES
from optikin.data.markers import FRAME_RATE, MARKER_NOISE, CBHATruth, MarkerRecording, tube_fractions
from optikin.data.sources import register_source
from optikin.errors import InputDataError, SpecError
from optikin.options import Options
from optikin.physics import Loads, Rod, RodArm, RodSolution, Segment, ShootingOptions, ShootingSolver, cbha_chambers
from optikin.spec import DataSpec

REFERENCE_MODULUS = 1.0e6
"""Nominal Young's modulus [Pa] of the rods: only the products ``E A``, ``E I``, ``G A``, ``G J`` and ``rho A``
enter the equations, so the section's area and moments are set from the stiffnesses given."""
PLATFORMS_PER_SECTION = 8
"""Platforms per section of the CBHA vertebra model (seed 004 section IV-A): maps a station to a vertebra."""


# ------------------------------------------------------------------------------ parameters
class CosseratMarkerParams(Options):
    """``data.params`` of source ``cosserat`` (family ``markers``): the arm, its motion and the recorder.

    Seed 002 and seed 004 give the arm's length, the tracker and the sensors, not its
    mechanics; every other value is an assumption, chosen so that the arm spans the real
    CBHA's size and its sections bend as far as the vertebra model's Table I lets them.
    """

    section_lengths: tuple[float, float] = Field(
        (0.18, 0.18),
        description="unpressurised length of section 1 and 2 [m]; assumed equal, 0.36 m in total: seed 004 "
        "section VI gives 8 mm as 2.2 % of the CBHA's length (0.36 m), its Table IV 0.50 m",
    )
    tube_radius: tuple[float, float] = Field(
        (0.040, 0.029),
        description="[base, tip] offset of the tubes from the backbone [m], linear in reference arc length; "
        "optikin's CBHA r_max, r_min (optikin.arms.cbha.CBHAGeometry: assumptions, no seed gives them)",
    )
    segments_per_section: int = Field(
        2, ge=1, le=8, description="rods per section, each with its chambers at the taper's mean offset [-]"
    )
    chamber_area: float = Field(
        3.8e-4, gt=0, description="pressurised area of each tube [m^2]; assumed: a 22 mm bore (no seed gives it)"
    )
    pressure_range: tuple[float, float] = Field(
        (0.0, 1.2e5),
        description="[low, high] gauge pressure of a tube [Pa]; assumed 0-1.2 bar (seed 004 gives no value)",
    )
    axial_stiffness: float = Field(
        415.0,
        gt=0,
        description="E A of a section [N]; assumed: all tubes at the high pressure stretch the arm by a third, "
        "0.36 to 0.48 m (seed 004 Table IV: 0.50 m)",
    )
    bending_stiffness: float = Field(
        0.19,
        gt=0,
        description="E I of a section [N m^2]; assumed: one tube at the high pressure bends a section about "
        "90 degrees, as Table I lets the vertebra model's (optikin.arms.cbha.CBHAGeometry)",
    )
    shear_stiffness: float = Field(1500.0, gt=0, description="G A of a section [N]; assumed")
    torsion_stiffness: float = Field(
        1.0,
        gt=0,
        description="G J of a section [N m^2]; assumed stiff: the CBHA cannot twist (seed 002 section IV.A)",
    )
    mass_per_length: float = Field(
        0.5, ge=0, description="mass of the arm per unpressurised length [kg/m]; assumed (no seed gives it)"
    )
    gravity: tuple[float, float, float] = Field(
        (0.0, 0.0, -9.81), description="gravitational acceleration in the world frame [m/s^2]"
    )
    base_orientation: tuple[float, float, float, float] = Field(
        (1.0, 0.0, 0.0, 0.0),
        description="clamped base frame in the world, unit quaternion (w, x, y, z) [-]; default upright (z up)",
    )
    payload: float = Field(0.0, ge=0, description="point mass at the tip [kg]")
    steps_per_segment: int = Field(12, ge=2, le=400, description="RK4 steps of the shooting per rod [-], even")
    noise: float = Field(
        MARKER_NOISE,
        ge=0,
        description="standard deviation of each tube-marker coordinate [m]; 0.3 mm: seed 004 section VI.A",
    )
    pose_noise: float = Field(
        MARKER_NOISE, ge=0, description="standard deviation of each rigid-body position coordinate [m]"
    )
    orientation_noise: float = Field(
        0.005,
        ge=0,
        description="standard deviation of each rigid-body rotation-vector component [rad]; assumed (the "
        "synthetic source's three-marker fits give 6-8 mrad)",
    )
    length_noise: float = Field(
        2.0e-4, ge=0, description="standard deviation of each potentiometer reading [m]; assumed"
    )
    rate: float = Field(FRAME_RATE, gt=0, description="camera frame rate [Hz]; 240: seed 002 section IV")
    stride: int = Field(24, ge=1, description="frames between kept postures [-]")
    frequency: tuple[float, float] = Field((0.05, 0.2), description="[low, high] pressure frequencies [Hz]")
    amplitude: float = Field(0.9, ge=0, le=1, description="pressure amplitude, fraction of pressure_range [-]")
    intermediate: tuple[float, float, float] = Field(
        (0.5, 1.0, 1.5),
        description="the three intermediate marker stations, in sections from the base (1.0: the end of section 1) [-]",
    )

    @field_validator("pressure_range", "frequency")
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not 0 <= value[0] <= value[1]:
            raise ValueError("must be [low, high] with 0 <= low <= high")
        return value

    @field_validator("section_lengths", "tube_radius")
    @classmethod
    def _positive(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not all(v > 0 for v in value):
            raise ValueError("must be positive")
        return value

    @field_validator("steps_per_segment")
    @classmethod
    def _even(cls, value: int) -> int:
        if value % 2:
            raise ValueError("must be even (the arc lengths are extrapolated from every other node)")
        return value

    @field_validator("base_orientation")
    @classmethod
    def _unit(cls, value: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        check_quaternion(value, name="base_orientation")
        return value

    @model_validator(mode="after")
    def _stations_on_nodes(self) -> CosseratMarkerParams:
        per_section = self.segments_per_section * self.steps_per_segment
        for i, x in enumerate(self.intermediate):
            if not 0 < x < len(self.section_lengths):
                raise ValueError(f"intermediate.{i}: {x} is not strictly between the base (0) and the tip (2)")
            if abs(x * per_section - round(x * per_section)) > 1e-9:
                raise ValueError(
                    f"intermediate.{i}: station {x} is not on the solver's nodes (multiples of 1/{per_section} "
                    "section: segments_per_section x steps_per_segment)"
                )
        if list(self.intermediate) != sorted(self.intermediate):
            raise ValueError("intermediate: stations must go from the base to the tip")
        return self

    @property
    def length(self) -> float:
        """Unpressurised length of the arm [m]."""
        return float(sum(self.section_lengths))

    def tube_offset(self, s: float | np.ndarray) -> np.ndarray:
        """``rho(s)`` [m] at reference arc lengths ``s`` [m] (linear taper)."""
        r0, r1 = self.tube_radius
        return r0 + (r1 - r0) * np.asarray(s, dtype=float) / self.length


# ------------------------------------------------------------------------------ the arm
def cosserat_cbha_arm(params: CosseratMarkerParams) -> RodArm:
    """The two-section pneumatic arm of ``params`` (module docstring).

    Each rod has ``E = REFERENCE_MODULUS`` and the area, moments and density that give the
    stiffnesses and mass per length of ``params``; its outer radius (which the chambers must
    be inside) is 1.5 times the largest tube offset.
    """
    E = REFERENCE_MODULUS
    area = params.axial_stiffness / E
    G = params.shear_stiffness / area
    outer = 1.5 * max(params.tube_radius)
    n = params.segments_per_section
    segments = []
    start = 0.0
    for length in params.section_lengths:
        h = length / n
        for j in range(n):
            offset = float(params.tube_offset(start + (j + 0.5) * h))
            c = cbha_chambers(offset, params.chamber_area, phase=CBHA_TUBE_ANGLES[0])
            chambers = (c[0], c[2], c[1])  # angles pi, pi/3, -pi/3: the order of u_1, u_2, u_3
            rod = Rod(
                length=h,
                area=area,
                second_moment=params.bending_stiffness / E,
                polar_moment=params.torsion_stiffness / G,
                outer_radius=outer,
                youngs_modulus=E,
                shear_modulus=G,
                density=params.mass_per_length / area,
                gravity=params.gravity,
            )
            segments.append(Segment(rod=rod, chambers=chambers))
        start += length
    return RodArm(segments=tuple(segments), base_orientation=params.base_orientation)


def actuation(params: CosseratMarkerParams, pressures: np.ndarray) -> np.ndarray:
    """The actuation vectors ``(N, n_segments * 3)`` [Pa] of tube pressures ``(N, sections, 3)``."""
    return np.repeat(pressures, params.segments_per_section, axis=1).reshape(len(pressures), -1)


def richardson_lengths(points: np.ndarray, upto: list[int]) -> np.ndarray:
    """Arc lengths of curves through equally spaced nodes up to each node index in ``upto`` (even).

    ``points`` ``(..., K, 3)``; the polyline through every node (``l_h``) and through every
    other node (``l_2h``) give ``(4 l_h - l_2h) / 3``, exact to fourth order in the spacing
    when every rod has an even number of steps. Returns ``(..., len(upto))``.
    """
    fine = np.concatenate(
        [np.zeros(points.shape[:-2] + (1,)), np.cumsum(np.linalg.norm(np.diff(points, axis=-2), axis=-1), -1)], -1
    )
    even = points[..., ::2, :]
    coarse = np.concatenate(
        [np.zeros(even.shape[:-2] + (1,)), np.cumsum(np.linalg.norm(np.diff(even, axis=-2), axis=-1), -1)], -1
    )
    return np.stack([(4.0 * fine[..., j] - coarse[..., j // 2]) / 3.0 for j in upto], axis=-1)


# ------------------------------------------------------------------------------ the recording
@dataclass
class CosseratTruth(CBHATruth):
    """What the Cosserat recorder knows and a real recording does not.

    The fields of :class:`~optikin.data.markers.CBHATruth` hold: ``configurations`` the tube
    pressures ``(N, 6)`` [Pa] (section 1's three, then section 2's), ``vertebrae`` the backbone
    at every solver node ``(N, K, 3)`` [m], ``backbone_length`` its arc length ``(N,)`` [m],
    ``marker_truth`` the backbone at the intermediate stations ``(N, 3, 3)`` [m].
    """

    s: np.ndarray  # (K,) reference arc length of the nodes [m]
    orientations: np.ndarray  # (N, K, 4) material frames
    tube_markers: np.ndarray  # (N, 3 tubes, 5 stations, 3) [m]
    tube_lengths: np.ndarray  # (N, 3) whole tubes [m]
    section_tube_lengths: np.ndarray  # (N, 3) section 1 [m]
    base_orientation: np.ndarray  # (N, 4)
    tip_position: np.ndarray  # (N, 3) [m]
    tip_orientation: np.ndarray  # (N, 4)
    iterations: np.ndarray  # (N,) Newton iterations of each equilibrium

    def take(self, index) -> CosseratTruth:
        """The postures ``index``."""
        per_posture = {
            name: getattr(self, name)[index]
            for name in (
                "configurations",
                "vertebrae",
                "backbone_length",
                "marker_truth",
                "orientations",
                "tube_markers",
                "tube_lengths",
                "section_tube_lengths",
                "base_orientation",
                "tip_position",
                "tip_orientation",
                "iterations",
            )
        }
        return CosseratTruth(s=self.s, **per_posture)


@dataclass
class CosseratRecording(MarkerRecording):
    """A :class:`~optikin.data.markers.MarkerRecording` with the tube markers of seed 002 section IV.A.

    ``tube_markers`` ``(N, 3, S, 3)`` [m]: tube ``m``'s markers at the ``S`` stations (base,
    intermediate, tip), at ``tube_marker_offsets`` ``(S,)`` [m] from the backbone, at the
    angles ``tube_angles`` [rad] about it from the base x axis; ``tube_radius``: the offset
    at the base and the tip [m] (linear in arc length between). ``markers`` are the
    backbone points the three tubes' markers give at each intermediate station.
    """

    tube_markers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 0, 3)))
    tube_marker_offsets: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tube_angles: tuple[float, ...] = CBHA_TUBE_ANGLES
    tube_radius: tuple[float, float] = (0.040, 0.029)

    def take(self, index) -> CosseratRecording:
        """The postures ``index`` (a slice or an index array)."""
        base = cast(CosseratRecording, MarkerRecording.take(replace(self, truth=None), index))
        truth = self.truth.take(index) if isinstance(self.truth, CosseratTruth) else None
        return replace(base, tube_markers=self.tube_markers[index], truth=truth)


def _posture_error(solutions: list[RodSolution], source: str) -> InputDataError | None:
    for i, sol in enumerate(solutions):
        if not sol.ok:
            return InputDataError(f"no equilibrium of the Cosserat arm: {sol.message}", source=source, sample=i)
    return None


def cosserat_recording(
    params: CosseratMarkerParams,
    samples: int,
    rng: np.random.Generator,
    source: str = "cosserat CBHA recording",
) -> CosseratRecording:
    """Record ``samples`` postures of the Cosserat CBHA of ``params`` (module docstring).

    Parameters
    ----------
    params : CosseratMarkerParams
        The arm, its motion and the recorder.
    samples : int
        Postures.
    rng : numpy.random.Generator
        Draws the motion, then the noise.
    source : str
        Names the recording (and the data in errors).

    Returns
    -------
    CosseratRecording

    Raises
    ------
    optikin.errors.InputDataError
        Naming the first posture whose equilibrium the shooting does not find.
    """
    arm = cosserat_cbha_arm(params)
    n_sections = len(params.section_lengths)
    t = np.arange(samples) * params.stride / params.rate
    fractions = tube_fractions(n_sections, t, rng, params.frequency, params.amplitude)
    low, high = params.pressure_range
    pressures = low + fractions * (high - low)  # (N, section, tube)
    gravity = np.asarray(params.gravity, dtype=float)
    tip_force = tuple(float(v) for v in params.payload * gravity)
    solver = ShootingSolver(arm, ShootingOptions(steps_per_segment=params.steps_per_segment, compiled=True))
    loads = [Loads(tip_force=tip_force, actuation=tuple(a)) for a in actuation(params, pressures)]
    solutions = solver.solve_sequence(loads)
    error = _posture_error(solutions, source)
    if error is not None:
        raise error
    return record_arm(params, solutions, solver.s, t, pressures, rng, source)


def record_arm(
    params: CosseratMarkerParams,
    solutions: list[RodSolution],
    s: np.ndarray,
    t: np.ndarray,
    pressures: np.ndarray,
    rng: np.random.Generator,
    source: str,
) -> CosseratRecording:
    """The motion capture of the equilibria ``solutions`` of one arm, as the ``cosserat`` marker source records.

    Parameters
    ----------
    params:
        The arm and the recorder.
    solutions:
        One equilibrium per posture, in the world frame.
    s:
        Reference arc length of the solver's nodes ``(K,)`` [m].
    t:
        Time stamps ``(N,)`` [s].
    pressures:
        Tube pressures ``(N, sections, 3)`` [Pa].
    rng:
        Draws the noise (tube markers, base pose, tip pose, potentiometers, in this order).
    source:
        Names the recording.
    """
    samples, n_sections = len(solutions), len(params.section_lengths)
    backbone = np.stack([sol.positions for sol in solutions])  # (N, K, 3)
    frames = quat_normalize(np.stack([sol.orientations for sol in solutions]), check=False)  # (N, K, 4)
    per_section = params.segments_per_section * params.steps_per_segment
    stations = [0, *(int(round(x * per_section)) for x in params.intermediate), n_sections * per_section]
    rho = params.tube_offset(s)  # (K,)
    directions = quat_rotate(frames[:, :, None, :], LEG_DIRECTIONS[None, None, :, :], check=False)  # (N, K, tube, 3)
    tubes = (backbone[:, :, None, :] + rho[None, :, None, None] * directions).transpose(0, 2, 1, 3)  # (N, tube, K, 3)
    tube_marker_truth = tubes[:, :, stations, :]  # (N, tube, station, 3)
    lengths = richardson_lengths(tubes, [per_section, len(s) - 1])  # (N, tube, 2)
    backbone_length = richardson_lengths(backbone, [len(s) - 1])[:, 0]

    tube_markers = tube_marker_truth + params.noise * rng.standard_normal(tube_marker_truth.shape)
    markers = tube_markers[:, :, 1:-1, :].mean(axis=1)  # (N, station, 3): centroids of the three tubes

    def pose(index: int) -> tuple[np.ndarray, np.ndarray]:
        p = backbone[:, index] + params.pose_noise * rng.standard_normal((samples, 3))
        turn = quat_exp(0.5 * params.orientation_noise * rng.standard_normal((samples, 3)))
        return p, quat_normalize(quat_multiply(frames[:, index], turn), check=False)

    base_p, base_q = pose(0)
    tip_p, tip_q = pose(len(s) - 1)
    noisy_lengths = lengths + params.length_noise * rng.standard_normal(lengths.shape)
    vertebrae = tuple(1 + PLATFORMS_PER_SECTION * x for x in params.intermediate)
    on_vertebrae = all(abs(v - round(v)) < 1e-9 for v in vertebrae)
    truth = CosseratTruth(
        configurations=pressures.reshape(samples, -1),
        vertebrae=backbone,
        backbone_length=backbone_length,
        marker_truth=backbone[:, stations[1:-1]],
        s=s,
        orientations=frames,
        tube_markers=tube_marker_truth,
        tube_lengths=lengths[:, :, 1],
        section_tube_lengths=lengths[:, :, 0],
        base_orientation=frames[:, 0],
        tip_position=backbone[:, -1],
        tip_orientation=frames[:, -1],
        iterations=np.array([sol.iterations for sol in solutions]),
    )
    return CosseratRecording(
        t=t,
        base_position=base_p,
        base_orientation=base_q,
        tip_position=tip_p,
        tip_orientation=tip_q,
        markers=markers,
        tube_lengths=noisy_lengths[:, :, 1],
        section_tube_lengths=noisy_lengths[:, :, 0],
        source=source,
        truth=truth,
        marker_vertebrae=tuple(int(round(v)) for v in vertebrae) if on_vertebrae else (),
        tube_markers=tube_markers,
        tube_marker_offsets=rho[stations],
        tube_angles=CBHA_TUBE_ANGLES,
        tube_radius=params.tube_radius,
    )


@register_source(
    "markers",
    "cosserat",
    "a two-section pneumatic Cosserat-rod CBHA (real size, gravity, payload) recorded by motion capture: "
    "tube markers, rigid bodies, potentiometers",
    params=CosseratMarkerParams,
)
def cosserat_source(arm: ArmModel, data: DataSpec, params: CosseratMarkerParams, path: Path) -> CosseratRecording:
    """:func:`cosserat_recording` of ``data.samples`` postures seeded by ``data.seed``.

    The recorded arm is the one of ``params``; the problem's ``arm`` is the model the
    comparators use (a CBHA vertebra model for the Newton-Raphson and hybrid rows).
    """
    try:
        return cosserat_recording(
            params, data.samples, np.random.default_rng([data.seed, 0]), source=f"{Path(path).name}: cosserat"
        )
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
