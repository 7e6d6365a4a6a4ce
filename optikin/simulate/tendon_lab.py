"""A synthetic lab: steady-state recordings of a hanging tendon-driven trunk, with what real recordings have and
the calibration's models do not. Source ``tendon_lab`` of data family ``recordings``.

The trunk (every value in :class:`TendonLabParams`):

* **physics**: three sections of a Kirchhoff rod (:mod:`optikin.physics`: Cosserat-rod statics by shooting,
  Rucker & Webster 2011 tendon loads), a nitinol backbone with massless disks, six tendons at 60 degrees
  from each other around it, two ending at each section's end disk (motors 1-2: section 1, 3-4: section 2, 5-6:
  section 3), gravity and a tip **payload**; the shape is the rod's equilibrium, not a constant-curvature one;
* **motor inputs**: a grid of ``levels`` per motor (``levels^6`` postures, or a seeded subset of ``samples``
  of them), visited in boustrophedon order (one motor steps at a time, as a lab sweeps a grid);
* **friction and hysteresis** (not in any model): the tension a tendon carries is the motor input less
  ``friction + hysteresis * input`` when the motor last pulled in, plus it when the motor last paid out
  (zero for a slack motor): an offset that depends on the input and on the direction it was reached from;
* **mount offset**: the backbone starts at ``mount_offset`` from the mount point and leaves tilted by
  ``mount_tilt_deg`` from straight down;
* **tracked bodies off the backbone**: one rigid body per end disk, its centroid at ``marker_offsets`` in the
  disk's material frame;
* **measurement**: Gaussian noise of ``noise`` per coordinate, a share ``occlusion`` of the bodies lost
  (NaN rows), positions only, in the lab's **y-up** frame (converted as a file's ``frame:`` says, default
  ``{up: y}``); the motor inputs as channels ``motor1`` ... ``motor6`` [N].

The truth travels with the recording (:class:`LabRecording`): the section lengths, the base pose of the
backbone and the bodies' offsets as a :class:`~optikin.calibration.synthetic.CalibrationTruth` (its
``configurations`` the constant-curvature angles of each section's end rotation), the tensions and the disk
frames. The equilibria are cached on disk (the per-user cache, :func:`optikin.codegen.cache_dir`), keyed by
everything they depend on; those of the shipped problem's grid and of the tests' corner grid come with the
package (``optikin/simulate/equilibria/``, found under the same key, so a change of the lab's physics falls
back to solving); noise, occlusions and offsets are drawn on each load.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, StrictFloat, StrictInt

from optikin.algebra import matrix_from_quat, quat_from_matrix
from optikin.arms.base import ArmModel
from optikin.calibration.synthetic import FAMILY, CalibrationTruth
from optikin.codegen import cache_dir
from optikin.data.recording import FrameOptions, Recording, frame_matrix, to_base_frame
from optikin.data.sources import register_source
from optikin.errors import InputDataError, SpecError
from optikin.options import Options
from optikin.spec import DataSpec

MOTORS = 6
"""Tendons (and motors): two per section."""
GRAVITY = 9.81
"""[m/s^2]."""
CACHE_VERSION = 1
"""Part of the cache key: raised when the physics of the lab changes."""


class TendonLabParams(Options):
    """``data.params`` of source ``tendon_lab`` (module docstring)."""

    section_lengths: list[StrictFloat] = Field(
        [0.110, 0.099, 0.118], min_length=3, max_length=3, description="true section lengths [m]"
    )
    backbone_radius: StrictFloat = Field(7e-4, gt=0, le=0.005, description="radius of the nitinol backbone [m]")
    youngs_modulus: StrictFloat = Field(60e9, gt=0, le=1e12, description="of the backbone [Pa]")
    density: StrictFloat = Field(6450.0, ge=0, le=1e5, description="of the backbone [kg/m^3]")
    tendon_offset: StrictFloat = Field(
        0.012, gt=0, le=0.05, description="distance of the tendons from the backbone [m]"
    )
    payload: StrictFloat = Field(0.2, ge=0, le=5.0, description="mass at the tip [kg]")
    levels: list[StrictFloat] = Field(
        [0.0, 2.5, 5.0], min_length=2, max_length=6, description="the grid of motor inputs (commanded tension) [N]"
    )
    friction: StrictFloat = Field(0.3, ge=0, le=10.0, description="tension lost (or held) by friction [N]")
    hysteresis: StrictFloat = Field(0.08, ge=0, lt=1, description="share of the input lost pulling in, held paying out")
    mount_offset: list[StrictFloat] = Field(
        [0.0025, -0.004, 0.0015],
        min_length=3,
        max_length=3,
        description="the backbone's start from the mount point, in the lab's y-up frame [m]",
    )
    mount_tilt_deg: list[StrictFloat] = Field(
        [1.5, -1.0],
        min_length=2,
        max_length=2,
        description="tilt of the exit direction from straight down, about the lab's x and z axes [deg]",
    )
    marker_offsets: list[list[StrictFloat]] = Field(
        [[0.015, 0.0, 0.005], [0.0, 0.015, 0.005], [-0.012, 0.008, 0.005]],
        min_length=3,
        max_length=3,
        description="centroid of each disk's tracked body in the disk's frame [m]",
    )
    noise: StrictFloat = Field(0.3e-3, ge=0, le=0.01, description="marker noise per coordinate [m]")
    occlusion: StrictFloat = Field(0.03, ge=0, lt=0.5, description="share of body samples lost (NaN)")
    steps_per_segment: StrictInt = Field(20, ge=5, le=200, description="RK4 steps per section of the shooting")
    frame: FrameOptions = Field(
        default_factory=lambda: FrameOptions(up="y"),
        description="the axes of the lab's frame as a file's frame: the lab records y up",
    )


@dataclass(frozen=True)
class LabTruth:
    """What the lab did: inputs, tensions, disk frames (optikin's frame)."""

    inputs: np.ndarray
    tensions: np.ndarray
    disk_positions: np.ndarray
    disk_rotations: np.ndarray


@dataclass(frozen=True)
class LabRecording(Recording):
    """A recording of the lab with its truth."""

    truth: CalibrationTruth | None = field(default=None)
    lab: LabTruth | None = field(default=None)


def boustrophedon(levels: int, motors: int) -> np.ndarray:
    """``(levels^motors, motors)`` grid indices, each row one step of one motor from the last (reflected
    mixed-radix Gray order)."""
    rows = np.array(list(itertools.product(range(levels), repeat=motors)), dtype=int)
    out = rows.copy()
    for k in range(1, motors):
        flip = rows[:, :k].sum(axis=1) % 2 == 1
        out[flip, k] = levels - 1 - rows[flip, k]
    return out


def tensions_of(inputs: np.ndarray, friction: float, hysteresis: float) -> np.ndarray:
    """``(N, 6)`` tensions from the motor inputs in visiting order (module docstring: friction, hysteresis)."""
    direction = np.ones(inputs.shape[1])
    out = np.empty_like(inputs)
    previous = np.zeros(inputs.shape[1])
    for k, u in enumerate(inputs):
        moved = np.sign(u - previous)
        direction = np.where(moved != 0, moved, direction)
        out[k] = np.where(u > 0, np.maximum(0.0, u - direction * (friction + hysteresis * u)), 0.0)
        previous = u
    return out


def exit_pose(params: TendonLabParams) -> tuple[np.ndarray, np.ndarray]:
    """The backbone's start ``(3,)`` [m] and base rotation ``(3, 3)`` (z along the backbone) in optikin's frame."""
    A = frame_matrix(FrameOptions(up="y"))
    ax, az = np.radians(params.mount_tilt_deg)
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    z = A @ (Rx @ Rz @ np.array([0.0, -1.0, 0.0]))
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    x /= np.linalg.norm(x)
    return A @ np.array(params.mount_offset), np.stack([x, np.cross(z, x), z], axis=1)


def equilibria(params: TendonLabParams, tensions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Disk positions ``(N, 3, 3)`` and rotations ``(N, 3, 3, 3)`` of the trunk under ``tensions`` (optikin's
    frame), from the cache or by shooting (each by continuation from the solved posture of the nearest tensions).

    Raises
    ------
    InputDataError
        When an equilibrium is not found (naming the posture and its tensions).
    """
    p0, R0 = exit_pose(params)
    key = json.dumps(
        {
            "version": CACHE_VERSION,
            "physics": params.model_dump(exclude={"noise", "occlusion", "marker_offsets", "frame"}),
            "tensions": np.round(tensions, 12).tolist(),
        },
        sort_keys=True,
    )
    name = f"{hashlib.sha256(key.encode()).hexdigest()[:32]}.npz"
    shipped = resources.files("optikin.simulate").joinpath("equilibria", name)
    path = cache_dir() / "tendon_lab" / name
    for stored_at in (shipped, path):
        if stored_at.is_file():
            with stored_at.open("rb") as handle, np.load(handle, allow_pickle=False) as stored:
                return stored["positions"], stored["rotations"]
    from optikin.physics.model import Loads, RodArm, Segment
    from optikin.physics.rod import Rod
    from optikin.physics.shooting import ShootingOptions, ShootingSolver
    from optikin.physics.tendons import Tendon

    r = params.backbone_radius
    outer = max(2.0 * params.tendon_offset, params.tendon_offset + 0.005)
    segments = []
    for k, length in enumerate(params.section_lengths):
        rod = Rod(
            length=length,
            area=np.pi * r**2,
            second_moment=np.pi * r**4 / 4,
            polar_moment=np.pi * r**4 / 2,
            outer_radius=outer,
            youngs_modulus=params.youngs_modulus,
            poisson_ratio=0.33,
            density=params.density,
            model="kirchhoff",
            gravity=(0.0, 0.0, -GRAVITY),
        )
        tendons = tuple(Tendon(offset=params.tendon_offset, angle=np.radians(60.0 * (2 * k + j))) for j in range(2))
        segments.append(Segment(rod=rod, tendons=tendons))
    q0 = quat_from_matrix(R0)
    arm = RodArm(segments=tuple(segments), base_position=tuple(p0), base_orientation=tuple(q0 / np.linalg.norm(q0)))
    solver = ShootingSolver(arm, ShootingOptions(steps_per_segment=params.steps_per_segment))
    weight = (0.0, 0.0, -params.payload * GRAVITY)
    loads = [Loads(tip_force=weight, actuation=tuple(float(v) for v in t)) for t in tensions]
    nodes = [(k + 1) * params.steps_per_segment for k in range(3)]
    positions = np.empty((len(tensions), 3, 3))
    rotations = np.empty((len(tensions), 3, 3, 3))
    wrenches = np.empty((len(tensions), 6))
    vectors = np.array([solver.load_vector(item) for item in loads])
    for k, item in enumerate(loads):
        found = None
        if k:
            j = int(np.argmin(np.sum((tensions[:k] - tensions[k]) ** 2, axis=1)))
            found = continuation(solver, vectors[j], wrenches[j], vectors[k])
        if found is None:
            solution = solver.solve(item)
            if not solution.ok:
                raise InputDataError(
                    f"no equilibrium of the lab's trunk at tensions {tensions[k].round(3).tolist()} N "
                    f"({solution.message})",
                    sample=k,
                )
            found = solution.base_wrench, solution.positions, solution.orientations
        wrenches[k], node_positions, node_orientations = found
        positions[k] = node_positions[nodes]
        rotations[k] = matrix_from_quat(node_orientations[nodes], check=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.stem}-{os.getpid()}.npz")
    np.savez(partial, positions=positions, rotations=rotations)
    os.replace(partial, path)
    return positions, rotations


CONTINUATION_STEPS = (1, 4, 16)
"""Equal load steps tried, in turn, from a solved posture to the next (:func:`continuation`)."""


def continuation(
    solver: Any, P_from: np.ndarray, w_from: np.ndarray, P_to: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The equilibrium at loads ``P_to`` by Newton steps along the straight path from a solved one at ``P_from``
    (base wrench ``w_from``), in :data:`CONTINUATION_STEPS` equal steps: ``(w, positions (K, 3), orientations
    (K, 4))``, or None when no number of steps converges (the caller then ramps from zero load)."""
    tolerance = solver.options.tolerance
    for steps in CONTINUATION_STEPS:
        w = np.array(w_from, dtype=float)
        for a in np.arange(1, steps + 1) / steps:
            P = P_from + a * (P_to - P_from)
            w = np.asarray(solver.rootfinder(w, P), dtype=float).ravel()
            residual = float(np.linalg.norm(np.asarray(solver.residual(w, P), dtype=float)))
            if not (np.isfinite(residual) and residual <= tolerance):
                break
        else:
            states = np.asarray(solver.shape(w, P_to)[0], dtype=float)
            return w, states[0:3].T.copy(), states[3:7].T.copy()
    return None


def cc_configurations(lengths: np.ndarray, R0: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """``(N, 9)`` ``(S, theta, phi)`` per section: the bend and bending plane of each section's end rotation
    relative to its start (the constant-curvature reading of the rod's disks)."""
    N = len(rotations)
    out = np.empty((N, 3, 3))
    start = np.broadcast_to(R0, (N, 3, 3))
    for i in range(3):
        relative = np.einsum("nji,njk->nik", start, rotations[:, i])
        z = relative[:, :, 2]
        out[:, i] = np.stack(
            [np.full(N, lengths[i]), np.arccos(np.clip(z[:, 2], -1, 1)), np.arctan2(z[:, 1], z[:, 0])], 1
        )
        start = rotations[:, i]
    return out.reshape(N, 9)


def lab_recording(params: TendonLabParams, samples: int, rng: np.random.Generator, source: str = "tendon_lab"):
    """A recording of the lab (module docstring): ``samples`` postures of the grid (all when it has no more).

    Returns
    -------
    LabRecording
        Bodies ``disk1 ... disk3`` as markers [m] in optikin's frame (converted from the lab's y-up frame as
        ``params.frame`` says), channels ``motor1 ... motor6`` [N], the truth.
    """
    n_levels = len(params.levels)
    order = boustrophedon(n_levels, MOTORS)
    if samples < len(order):
        order = order[np.sort(rng.choice(len(order), size=samples, replace=False))]
    inputs = np.asarray(params.levels, dtype=float)[order]
    tensions = tensions_of(inputs, params.friction, params.hysteresis)
    positions, rotations = equilibria(params, tensions)
    offsets = np.asarray(params.marker_offsets, dtype=float)
    clean = positions + np.einsum("nsij,sj->nsi", rotations, offsets)
    measured = clean + rng.normal(0.0, params.noise, size=clean.shape)
    measured[rng.random(measured.shape[:2]) < params.occlusion] = np.nan
    A = frame_matrix(FrameOptions(up="y"))
    lab_frame = measured @ A  # the lab's y-up coordinates: A^T p
    raw = Recording(
        time=np.arange(len(inputs), dtype=float),
        markers={f"disk{s + 1}": lab_frame[:, s].copy() for s in range(3)},
        actuators={f"motor{j + 1}": inputs[:, j].copy() for j in range(MOTORS)},
        source=source,
    )
    converted = to_base_frame(raw, params.frame, "m")
    lengths = np.asarray(params.section_lengths, dtype=float)
    p0, R0 = exit_pose(params)
    truth = CalibrationTruth(
        lengths,
        p0,
        R0,
        offsets.copy(),
        cc_configurations(lengths, R0, rotations),
        clean,
        np.zeros(len(inputs), dtype=bool),
    )
    return LabRecording(
        time=converted.time,
        markers=converted.markers,
        actuators=converted.actuators,
        source=source,
        truth=truth,
        lab=LabTruth(inputs, tensions, positions, rotations),
    )


@register_source(
    FAMILY,
    "tendon_lab",
    "a hanging tendon-driven Cosserat trunk with payload, friction, mount offset, bodies off the backbone (y up)",
    TendonLabParams,
)
def load_tendon_lab(arm: ArmModel, data: DataSpec, params: TendonLabParams, path: Path, **_: Any) -> LabRecording:
    """:func:`lab_recording` of ``data.samples`` postures (seed ``data.seed``)."""
    grid = len(params.levels) ** MOTORS
    if len(set(params.levels)) != len(params.levels) or min(params.levels) < 0:
        raise SpecError(path, "data.params.levels", f"expected distinct non-negative tensions, got {params.levels}")
    if any(length <= 0 or length > 1.0 for length in params.section_lengths):
        raise SpecError(path, "data.params.section_lengths", "expected lengths in (0, 1] m")
    return lab_recording(params, min(data.samples, grid), np.random.default_rng([data.seed, 0]), Path(path).name)
