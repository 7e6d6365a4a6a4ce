"""One in-memory recording type for every lab format, in optikin's SI, z-up base frame.

Every reader of :mod:`optikin.data.readers` (OptiTrack Motive CSV, C3D, ROS 2 bags,
plain CSV) returns a :class:`Recording`: time, named markers and rigid bodies
(positions, optional orientations), IMU samples and actuator channels, with the frame
notes that the reader found (dropped frames, NaN cells, swapped labels).

A lab's file is in the lab's frame and units; the problem file declares them
(``frame: {up: y}``, ``units: mm``, a :class:`FrameOptions` and a :data:`Units`) and
:func:`to_base_frame` converts the recording once, in one place:

* lengths (marker and rigid-body positions) are multiplied by :data:`UNIT_SCALE`
  (``mm``: 1e-3); IMU rates and accelerations and actuator channels are taken as SI
  already (ROS messages are SI by REP-103; plain CSV columns carry their own scale);
* every vector ``v`` of the file (positions, angular velocities, accelerations) becomes
  ``A v`` and every orientation, a rotation matrix ``R`` of the file's convention,
  becomes ``A R A^T``, with ``A`` the matrix of :func:`frame_matrix`. The body's own
  axes are thus read in the same convention as the world's: a rigid body created
  aligned with a y-up world (as Motive does) has the identity orientation before and
  after the conversion. On unit quaternions ``q = (w, v)`` this is
  ``(w, det(A) A v)``: exact, and no sign flip between frames.

For ``up: y`` (OptiTrack Motive's default, right-handed) ``A`` is the rotation by
+90 degrees about x, ``(x, y, z) -> (x, -z, y)``: the file's y becomes optikin's z
and the file's z becomes optikin's -y.

Gaps are found, never filled: :func:`inspect_frames` notes frame-time gaps (dropped
frames), NaN cells and swapped labels per frame; :meth:`Recording.drop_incomplete`
drops the frames with a missing marker or a swap, each with a note. Nothing is
interpolated.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal, Mapping, Sequence

import numpy as np
from pydantic import Field, model_validator

from optikin.algebra import quat_from_matrix, quat_multiply
from optikin.options import Options

Axis = Literal["x", "y", "z"]
SignedAxis = Literal["x", "y", "z", "-x", "-y", "-z"]
Units = Literal["m", "mm", "cm"]
"""Length units of a file."""
UNIT_SCALE: dict[str, float] = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
"""Metres per unit of each :data:`Units`."""
NoteKind = Literal["dropped", "gap", "swap", "nan"]

GAP_FACTOR = 1.5
"""A time step longer than this many median steps is a gap (frames dropped by the recorder)."""

_AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}
_DEFAULT_FORWARD = {"x": "-z", "y": "x", "z": "x"}
"""For each ``up``, the file axis that the default conversion maps to optikin's x."""


class FrameOptions(Options):
    """The axes of a file's frame, as a problem file declares them (``frame: {up: y}``).

    ``up`` is the file's axis that points up (optikin's +z); ``forward`` the file's
    (signed) axis that becomes optikin's +x, perpendicular to ``up``. Without it the
    smallest rotation is used: for ``up: z`` the identity, for ``up: y`` the rotation by
    +90 degrees about x, ``(x, y, z) -> (x, -z, y)``, for ``up: x`` the rotation by -90
    degrees about y, ``(x, y, z) -> (-z, y, x)``. ``handedness`` is the file's: ``left``
    (Unity, some game-engine exports) mirrors the remaining axis, so the conversion
    matrix has determinant -1 (checked).
    """

    up: Axis = Field("z", description="the file's axis pointing up (becomes optikin's +z)")
    forward: SignedAxis | None = Field(
        None, description="the file's axis that becomes optikin's +x (default: the smallest rotation)"
    )
    handedness: Literal["right", "left"] = Field("right", description="handedness of the file's frame")

    @model_validator(mode="after")
    def _forward_not_up(self) -> "FrameOptions":
        if self.forward is not None and self.forward[-1] == self.up:
            raise ValueError(f"forward ({self.forward}) must be perpendicular to up ({self.up})")
        return self


def _signed(axis: str) -> np.ndarray:
    return -_AXES[axis[-1]] if axis.startswith("-") else _AXES[axis]


def frame_matrix(frame: FrameOptions) -> np.ndarray:
    """The matrix ``A`` ``(3, 3)`` taking a file's coordinates to optikin's base frame, ``v_base = A v_file``.

    Its rows are the file's coordinates of optikin's x, y and z axes: ``z = up``,
    ``x = forward`` and ``y = z x x`` for a right-handed file (``det A = +1``), ``y = x x z``
    for a left-handed one (``det A = -1``).

    Raises
    ------
    ValueError
        If the rows are not orthonormal with the declared handedness (cannot happen for
        a validated :class:`FrameOptions`; kept as the handedness check).
    """
    z = _AXES[frame.up]
    x = _signed(frame.forward or _DEFAULT_FORWARD[frame.up])
    y = np.cross(z, x) if frame.handedness == "right" else np.cross(x, z)
    matrix = np.vstack([x, y, z])
    expected = 1.0 if frame.handedness == "right" else -1.0
    if not np.allclose(matrix @ matrix.T, np.eye(3)) or not np.isclose(np.linalg.det(matrix), expected):
        raise ValueError(f"frame {frame} does not give a {frame.handedness}-handed orthonormal basis")
    return matrix


def convert_vectors(vectors: np.ndarray, matrix: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """``scale * A v`` for each row ``v`` of ``vectors`` ``(..., 3)``; NaN rows stay NaN."""
    return scale * (np.asarray(vectors, dtype=float) @ matrix.T)


def convert_quaternions(quaternions: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Orientations ``R`` ``(..., 4)`` (``w, x, y, z``) expressed in the base frame: ``A R A^T``.

    On a unit quaternion ``(w, v)`` that is ``(w, det(A) A v)`` (a rotation by the same
    angle about the converted axis; a mirror reverses the sense of rotation).
    """
    q = np.asarray(quaternions, dtype=float)
    sign = float(np.sign(np.linalg.det(matrix)))
    return np.concatenate([q[..., :1], sign * (q[..., 1:] @ matrix.T)], axis=-1)


def convert_body_orientations(quaternions: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Orientations ``R`` ``(..., 4)`` (``w, x, y, z``) of frames whose own axes the body defines (an arm's base
    or tip frame: z along the backbone), given in a file's axes, in optikin's axes: ``A R``, the quaternion of
    ``A`` times each.

    Unlike :func:`convert_quaternions` (``A R A^T``, for rigid bodies created aligned with the file's world, as
    Motive's are), the body's own axes are kept.

    Raises
    ------
    ValueError
        For a left-handed file frame (``det A = -1``): ``A R`` is then not a rotation.
    """
    if np.linalg.det(matrix) < 0:
        raise ValueError("a left-handed frame cannot carry orientations of an arm's frames")
    q = np.asarray(quaternions, dtype=float)
    a = quat_from_matrix(matrix)
    return np.asarray(quat_multiply(np.broadcast_to(a, q.shape), q))


@dataclass(frozen=True)
class FrameNote:
    """Something a reader found at one frame.

    Attributes
    ----------
    frame:
        The file's number of the frame (:attr:`Recording.frames`: the file's own frame
        numbers where it has them, else the 0-based index of the frame in the file).
    what:
        ``dropped`` (the frame was removed), ``gap`` (frames missing before this one),
        ``swap`` (two labels exchanged their tracks), ``nan`` (a NaN or empty cell).
    detail:
        Which markers, bodies or channels, in words.
    tracks:
        The markers or bodies concerned, where the note is about some (a ``swap``: the two).
    """

    frame: int
    what: NoteKind
    detail: str
    tracks: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"frame {self.frame}: {self.what}: {self.detail}"


@dataclass(frozen=True)
class RigidBodyTrack:
    """A tracked rigid body: ``positions`` ``(T, 3)`` [m] and ``quaternions`` ``(T, 4)`` (``w, x, y, z``).

    NaN rows where the body was not tracked.
    """

    positions: np.ndarray
    quaternions: np.ndarray

    def seen_all(self) -> np.ndarray:
        """``(T,)`` whether the body's position and orientation are both known at each frame."""
        return ~(np.isnan(self.positions).any(axis=1) | np.isnan(self.quaternions).any(axis=1))

    def take(self, index: np.ndarray) -> "RigidBodyTrack":
        """The frames ``index``."""
        return RigidBodyTrack(self.positions[index], self.quaternions[index])


@dataclass(frozen=True)
class ImuTrack:
    """IMU samples on their own clock.

    Attributes
    ----------
    time:
        ``(K,)`` seconds, on the recording's clock.
    angular_velocity:
        ``(K, 3)`` rad/s, in the sensor's frame.
    linear_acceleration:
        ``(K, 3)`` m/s^2, in the sensor's frame (gravity included, as IMUs measure it).
    orientation:
        ``(K, 4)`` unit quaternions ``(w, x, y, z)`` of the sensor in the world frame, or None
        when the IMU gives none.
    """

    time: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray
    orientation: np.ndarray | None = None


@dataclass(frozen=True)
class Recording:
    """A recording in SI units and optikin's z-up base frame.

    Attributes
    ----------
    time:
        ``(T,)`` frame times [s].
    markers:
        Marker name -> positions ``(T, 3)`` [m], NaN where the marker was not seen.
    bodies:
        Rigid-body name -> :class:`RigidBodyTrack`.
    imu:
        IMU name -> :class:`ImuTrack` (its own time base).
    actuators:
        Channel name -> ``(T,)`` readings in SI (m, rad, N, ...), on the frame times.
    notes:
        What the reader found, per frame (:class:`FrameNote`).
    source:
        The file read.
    frames:
        ``(T,)`` the file's number of each frame: its own frame numbers where it has them
        (Motive's ``Frame`` column, C3D's first frame + index), else the 0-based index in the
        file; None means ``arange(T)``. Dropping frames keeps the numbers of those left.
    """

    time: np.ndarray
    markers: dict[str, np.ndarray] = field(default_factory=dict)
    bodies: dict[str, RigidBodyTrack] = field(default_factory=dict)
    imu: dict[str, ImuTrack] = field(default_factory=dict)
    actuators: dict[str, np.ndarray] = field(default_factory=dict)
    notes: list[FrameNote] = field(default_factory=list)
    source: str = ""
    frames: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.frames is None:
            object.__setattr__(self, "frames", np.arange(len(self.time)))

    def __len__(self) -> int:
        return len(self.time)

    @property
    def frame_index(self) -> np.ndarray:
        """``(T,)`` the file's number of each frame (:attr:`frames`, never None)."""
        assert self.frames is not None
        return self.frames

    def marker_array(self, names: Sequence[str]) -> np.ndarray:
        """The markers ``names`` side by side, ``(T, len(names), 3)`` [m].

        Raises
        ------
        KeyError
            Naming the first marker the recording lacks, and those it has.
        """
        missing = [n for n in names if n not in self.markers]
        if missing:
            raise KeyError(f"no marker {missing[0]!r} in {self.source or 'the recording'}; has {sorted(self.markers)}")
        if not names:
            return np.zeros((len(self), 0, 3))
        return np.stack([self.markers[n] for n in names], axis=1)

    def take(self, index: np.ndarray) -> "Recording":
        """The frames ``index`` (IMU tracks, on their own clock, are kept whole)."""
        return replace(
            self,
            time=self.time[index],
            markers={k: v[index] for k, v in self.markers.items()},
            bodies={k: b.take(index) for k, b in self.bodies.items()},
            actuators={k: v[index] for k, v in self.actuators.items()},
            frames=self.frame_index[index],
            notes=list(self.notes),
        )

    def missing(self, markers: Sequence[str], bodies: Sequence[str]) -> np.ndarray:
        """``(T, len(markers) + len(bodies))``: where each marker (any NaN coordinate) or body pose is missing."""
        columns = [np.isnan(self.markers[n]).any(axis=1) for n in markers]
        columns += [~self.bodies[b].seen_all() for b in bodies]
        return np.stack(columns, axis=1) if columns else np.zeros((len(self), 0), dtype=bool)

    def drop_incomplete(
        self, markers: Sequence[str] | None = None, bodies: Sequence[str] | None = None, swaps: bool = True
    ) -> "Recording":
        """The recording without the frames where a marker or body is missing (or, with ``swaps``, swapped).

        Parameters
        ----------
        markers:
            The markers that must be present (default: all).
        bodies:
            The rigid bodies whose pose (position and orientation) must be present (default: all).
        swaps:
            Also drop the frames noted ``swap`` between two of the markers or bodies asked for
            (labels exchanged: the tracks are wrong there).

        Returns
        -------
        Recording
            The kept frames; its notes are this recording's plus one ``dropped`` note per
            dropped frame naming what was missing.
        """
        names = list(self.markers) if markers is None else list(markers)
        body_names = list(self.bodies) if bodies is None else list(bodies)
        self.marker_array(names)
        missing_bodies = [b for b in body_names if b not in self.bodies]
        if missing_bodies:
            raise KeyError(f"no rigid body {missing_bodies[0]!r} in {self.source or 'the recording'}")
        frames = self.frame_index
        every = names + body_names
        swapped = {n.frame for n in self.notes if n.what == "swap" and set(n.tracks) & set(every)} if swaps else set()
        missing = self.missing(names, body_names)
        keep = ~missing.any(axis=1) & ~np.isin(frames, list(swapped))
        notes = list(self.notes)
        for i in np.flatnonzero(~keep):
            absent = [every[k] for k in np.flatnonzero(missing[i])]
            reasons = []
            if absent:
                reasons.append("missing " + ", ".join(absent))
            if int(frames[i]) in swapped:
                reasons.append("labels swapped")
            notes.append(FrameNote(int(frames[i]), "dropped", "; ".join(reasons)))
        kept = self.take(np.flatnonzero(keep))
        return replace(kept, notes=sorted(notes, key=lambda n: n.frame))


def to_base_frame(recording: Recording, frame: FrameOptions, units: Units) -> Recording:
    """``recording`` (in the file's frame and units) in SI and optikin's base frame.

    Parameters
    ----------
    recording:
        As read from the file: positions in ``units``, vectors and orientations in ``frame``.
    frame:
        The file's axes (:class:`FrameOptions`).
    units:
        The file's length unit (:data:`Units`).

    Returns
    -------
    Recording
        Positions ``UNIT_SCALE[units] * A p``, orientations ``A R A^T``, IMU vectors ``A v``
        (module docstring), with ``A`` from :func:`frame_matrix`; time and actuators as they are.
    """
    matrix = frame_matrix(frame)
    scale = UNIT_SCALE[units]
    imu = {
        name: ImuTrack(
            track.time,
            convert_vectors(track.angular_velocity, matrix),
            convert_vectors(track.linear_acceleration, matrix),
            None if track.orientation is None else convert_quaternions(track.orientation, matrix),
        )
        for name, track in recording.imu.items()
    }
    return replace(
        recording,
        markers={k: convert_vectors(v, matrix, scale) for k, v in recording.markers.items()},
        bodies={
            k: RigidBodyTrack(convert_vectors(b.positions, matrix, scale), convert_quaternions(b.quaternions, matrix))
            for k, b in recording.bodies.items()
        },
        imu=imu,
    )


def gap_notes(recording: Recording, numbered: bool = False) -> list[FrameNote]:
    """A ``gap`` note on each frame that follows missing frames.

    With ``numbered`` (the file numbers its frames: Motive, C3D, and :attr:`Recording.frames`
    holds those numbers) a jump in the numbers is the gap; otherwise a time step over
    :data:`GAP_FACTOR` median steps is.
    """
    notes: list[FrameNote] = []
    time, frames = recording.time, recording.frame_index
    if len(time) < 2:
        return notes
    steps = np.diff(time)
    if numbered:
        jumps = np.diff(frames)
        for k in np.flatnonzero(jumps > 1):
            notes.append(FrameNote(int(frames[k + 1]), "gap", f"{int(jumps[k]) - 1} frame(s) missing before it"))
        return notes
    if len(time) < 3:
        return notes
    typical = float(np.median(steps))
    for k in np.flatnonzero(steps > GAP_FACTOR * typical):
        missing = int(round(steps[k] / typical)) - 1
        notes.append(
            FrameNote(int(frames[k + 1]), "gap", f"about {missing} frame(s) missing before it ({steps[k]:.6g} s step)")
        )
    return notes


def nan_notes(recording: Recording) -> list[FrameNote]:
    """A ``nan`` note on each frame where a marker or a body's pose is (partly) NaN, naming them."""
    labels = [f"marker {k}" for k in recording.markers] + [f"body {k}" for k in recording.bodies]
    missing = recording.missing(list(recording.markers), list(recording.bodies))
    return [
        FrameNote(
            int(recording.frame_index[i]), "nan", ", ".join(labels[k] for k in np.flatnonzero(missing[i])) + " missing"
        )
        for i in np.flatnonzero(missing.any(axis=1))
    ]


def swap_notes(tracks: Mapping[str, np.ndarray], frames: np.ndarray) -> list[FrameNote]:
    """A ``swap`` note on each frame where two tracks ``(T, 3)`` exchanged labels.

    Tracks ``a`` and ``b`` swap at frame ``i`` when, from the last frame where both were
    seen, exchanging them at ``i`` shortens the total jump to less than half of itself:
    ``|a_i - b_j| + |b_i - a_j| < 0.5 (|a_i - a_j| + |b_i - b_j|)``. The labels stay
    swapped until they swap back (each frame of the swapped run is noted).
    """
    names = list(tracks)
    notes = []
    for u in range(len(names)):
        for w in range(u + 1, len(names)):
            a, b = tracks[names[u]], tracks[names[w]]
            seen = np.flatnonzero(~(np.isnan(a).any(axis=1) | np.isnan(b).any(axis=1)))
            if len(seen) < 2:
                continue
            pa, pb = a[seen], b[seen]
            straight = np.linalg.norm(pa[1:] - pa[:-1], axis=1) + np.linalg.norm(pb[1:] - pb[:-1], axis=1)
            crossed = np.linalg.norm(pa[1:] - pb[:-1], axis=1) + np.linalg.norm(pb[1:] - pa[:-1], axis=1)
            swapped = np.cumsum(crossed < 0.5 * straight) % 2 == 1
            detail, pair = f"{names[u]} and {names[w]} exchanged", (names[u], names[w])
            notes += [FrameNote(int(frames[i]), "swap", detail, pair) for i in seen[1:][swapped]]
    return notes


def inspect_frames(recording: Recording, numbered: bool = False) -> Recording:
    """``recording`` with its ``gap``, ``nan`` and ``swap`` notes added, sorted by frame.

    Swaps are looked for among the markers and, separately, among the rigid bodies.
    ``numbered``: :attr:`Recording.frames` holds the file's own frame numbers (:func:`gap_notes`).
    """
    frames = recording.frame_index
    notes = list(recording.notes) + gap_notes(recording, numbered) + nan_notes(recording)
    notes += swap_notes(recording.markers, frames)
    notes += swap_notes({k: b.positions for k, b in recording.bodies.items()}, frames)
    return replace(recording, notes=sorted(notes, key=lambda n: n.frame))
