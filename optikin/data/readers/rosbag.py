"""ROS 2 bags (sqlite3 or mcap storage) through ``rosbags`` (``pip install optikin[rosbag]``).

The message types read, each by its header stamp (``header.stamp``, not the bag's
receive time):

=====================================  ==========================================================
``sensor_msgs/msg/Imu``                an :class:`~optikin.data.recording.ImuTrack` named after the
                                       topic (leading ``/`` dropped); the orientation is kept unless
                                       its covariance starts with -1 (REP-145: "no orientation")
``geometry_msgs/msg/PoseStamped``      a rigid body named after the topic, a last ``/pose``
                                       dropped (``/disk1/pose``: ``disk1``)
``geometry_msgs/msg/TransformStamped`` a rigid body named after ``child_frame_id``
``tf2_msgs/msg/TFMessage``             (``/tf``) each of its transforms, as above
``sensor_msgs/msg/JointState``         one actuator channel per joint name: its ``position``
                                       (m or rad, SI by REP-103)
=====================================  ==========================================================

Other topics are skipped (``topics`` selects some; naming one of another type is an error).
The frame times are the union of the stamps of the pose, transform and joint-state
messages, relative to the earliest stamp of any message read (IMU included, whose
times are on the same clock); a body or channel without a message at a frame time is
NaN there (noted, never interpolated). Gaps are time steps over 1.5 median steps.

Errors (:class:`~optikin.errors.InputDataError`) name the bag, the message (``sample``:
its index on its topic, from 0; the message gives its stamp) and the channel (``field``:
the topic, or ``topic:joint``).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from optikin.data.readers.common import FAMILY, RecordingParams, finish, load_recording, normalised_quaternions
from optikin.data.recording import FrameOptions, ImuTrack, Recording, RigidBodyTrack, Units
from optikin.data.sources import register_source
from optikin.errors import InputDataError
from optikin.spec import DataSpec

IMU = "sensor_msgs/msg/Imu"
POSE = "geometry_msgs/msg/PoseStamped"
TRANSFORM = "geometry_msgs/msg/TransformStamped"
TF = "tf2_msgs/msg/TFMessage"
JOINTS = "sensor_msgs/msg/JointState"
READ_TYPES = (IMU, POSE, TRANSFORM, TF, JOINTS)
"""The message types read."""


def _rosbags() -> tuple[Any, Any]:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise ImportError(
            "reading ROS 2 bags needs rosbags: pip install optikin[rosbag] (or pip install rosbags)"
        ) from None
    return AnyReader, get_typestore(Stores.ROS2_HUMBLE)


def _stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


@dataclass
class _Series:
    """Samples of one channel: stamps [ns] and rows of values, with the message index of each."""

    topic: str
    stamps: list[int] = field(default_factory=list)
    rows: list[list[float]] = field(default_factory=list)
    index: list[int] = field(default_factory=list)


class _Bag:
    """The channels of a bag as they are read, with the checks that name topic and message."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.bodies: dict[str, _Series] = {}
        self.imu: dict[str, _Series] = {}
        self.joints: dict[str, _Series] = {}

    def error(self, message: str, topic: str, index: int, stamp: int, channel: str = "") -> InputDataError:
        return InputDataError(
            f"{message} (message {index} of {topic}, stamp {stamp * 1e-9:.9f} s)",
            source=self.source,
            sample=index,
            field=f"{topic}:{channel}" if channel else topic,
        )

    def add(
        self,
        table: dict[str, _Series],
        name: str,
        topic: str,
        index: int,
        stamp: int,
        row: list[float],
        channel: str = "",
        checked: int | None = None,
    ) -> None:
        """Append ``row`` to ``table[name]``; the first ``checked`` values (all by default) must be finite."""
        series = table.setdefault(name, _Series(topic))
        if series.topic != topic:
            raise self.error(f"{name!r} is also published on {series.topic}", topic, index, stamp, channel)
        if not np.isfinite(row[:checked]).all():
            raise self.error("a value is not a finite number", topic, index, stamp, channel)
        if series.stamps and stamp <= series.stamps[-1]:
            raise self.error(
                f"stamps must increase strictly, got {stamp * 1e-9:.9f} s after {series.stamps[-1] * 1e-9:.9f} s",
                topic,
                index,
                stamp,
                channel,
            )
        series.stamps.append(stamp)
        series.rows.append(row)
        series.index.append(index)

    def pose(self, name: str, topic: str, index: int, stamp: int, p: Any, q: Any) -> None:
        self.add(self.bodies, name, topic, index, stamp, [p.x, p.y, p.z, q.w, q.x, q.y, q.z])

    def message(self, topic: str, msgtype: str, index: int, msg: Any) -> None:
        if msgtype == TF:
            for transform in msg.transforms:
                self.message(topic, TRANSFORM, index, transform)
            return
        stamp = _stamp(msg)
        if msgtype == POSE:
            name = topic.strip("/").removesuffix("/pose") or topic
            self.pose(name, topic, index, stamp, msg.pose.position, msg.pose.orientation)
        elif msgtype == TRANSFORM:
            t = msg.transform
            self.pose(msg.child_frame_id, topic, index, stamp, t.translation, t.rotation)
        elif msgtype == IMU:
            w, a, q = msg.angular_velocity, msg.linear_acceleration, msg.orientation
            has_q = float(msg.orientation_covariance[0]) != -1.0
            row = [w.x, w.y, w.z, a.x, a.y, a.z] + ([q.w, q.x, q.y, q.z] if has_q else [np.nan] * 4)
            self.add(self.imu, topic.lstrip("/"), topic, index, stamp, row, checked=None if has_q else 6)
        elif msgtype == JOINTS:
            names, positions = list(msg.name), list(msg.position)
            if len(positions) != len(names):
                raise self.error(f"{len(names)} joint names but {len(positions)} positions", topic, index, stamp)
            for name, value in zip(names, positions):
                self.add(self.joints, name, topic, index, stamp, [float(value)], name)


def read_rosbag(
    path: str | Path, frame: FrameOptions | None = None, units: Units | None = None, topics: tuple[str, ...] = ()
) -> Recording:
    """Read a ROS 2 bag (folder with ``metadata.yaml``; sqlite3 or mcap) into a :class:`Recording`.

    Parameters
    ----------
    path:
        The bag folder (or its single storage file).
    frame:
        The axes of the poses (ROS: z-up, REP-103; the default).
    units:
        The length unit of the positions (ROS: metres, the default).
    topics:
        Topics to read (default: every topic of a type in :data:`READ_TYPES`).

    Returns
    -------
    Recording
        Bodies and actuators on the frame times, IMUs on their own (module docstring); in SI
        and optikin's base frame, with notes for gaps, missing samples and label swaps.

    Raises
    ------
    ImportError
        Without rosbags (``pip install optikin[rosbag]``).
    InputDataError
        Naming the bag, the message and the topic (or ``topic:joint``): a bag rosbags cannot
        open or a message it cannot decode, a topic of ``topics`` absent or of another
        type, a non-finite value, a non-unit quaternion, stamps that do not increase on a
        topic, joint names and positions of different lengths, no frames.
    """
    any_reader, typestore = _rosbags()
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise InputDataError("cannot read: no such bag", source=source)
    bag = _Bag(source)
    try:
        with any_reader([path], default_typestore=typestore) as reader:
            types = {c.topic: c.msgtype for c in reader.connections}
            for topic in topics:
                if topic not in types:
                    raise InputDataError(f"no topic {topic!r} in the bag", source=source, field=topic)
                if types[topic] not in READ_TYPES:
                    raise InputDataError(
                        f"topic type {types[topic]} is not read (only {', '.join(READ_TYPES)})",
                        source=source,
                        field=topic,
                    )
            wanted = [c for c in reader.connections if c.msgtype in READ_TYPES and (not topics or c.topic in topics)]
            counts: dict[str, int] = defaultdict(int)
            for connection, _, raw in reader.messages(connections=wanted):
                index = counts[connection.topic]
                counts[connection.topic] += 1
                try:
                    msg = reader.deserialize(raw, connection.msgtype)
                except Exception as exc:  # rosbags raises several types on a corrupt message
                    raise InputDataError(
                        f"cannot decode the message ({type(exc).__name__})",
                        source=source,
                        sample=index,
                        field=connection.topic,
                    ) from None
                bag.message(connection.topic, connection.msgtype, index, msg)
    except InputDataError:
        raise
    except Exception as exc:  # rosbags' own errors on a folder that is not a bag
        raise InputDataError(
            f"not a readable ROS 2 bag ({type(exc).__name__}: {str(exc)[:80]})", source=source
        ) from None
    return finish(_assemble(bag), frame or FrameOptions(), units or "m", numbered=False)


def _assemble(bag: _Bag) -> Recording:
    framed = list(bag.bodies.values()) + list(bag.joints.values())
    stamps = sorted({s for series in framed for s in series.stamps})
    if not stamps:
        raise InputDataError("no pose, transform or joint-state messages", source=bag.source)
    t0 = min([stamps[0]] + [s.stamps[0] for s in bag.imu.values()])
    column = {s: k for k, s in enumerate(stamps)}
    time = (np.asarray(stamps, dtype=np.int64) - t0) * 1e-9

    def on_frames(series: _Series, width: int) -> np.ndarray:
        out = np.full((len(stamps), width), np.nan)
        out[[column[s] for s in series.stamps]] = np.asarray(series.rows, dtype=float)
        return out

    bodies = {}
    for name, series in bag.bodies.items():
        pose = on_frames(series, 7)

        def where(row: int, series: _Series = series) -> tuple[int, str]:
            k = series.stamps.index(stamps[row])
            return series.index[k], f" (message {series.index[k]} of {series.topic}, stamp {stamps[row] * 1e-9:.9f} s)"

        q = normalised_quaternions(pose[:, 3:], bag.source, series.topic, where)
        bodies[name] = RigidBodyTrack(pose[:, :3], q)
    imu = {}
    for name, series in bag.imu.items():
        rows = np.asarray(series.rows, dtype=float)
        has_q = not np.isnan(rows[:, 6:]).all()
        orientation = None
        if has_q:
            stamps_imu = series.stamps
            index = series.index
            topic = series.topic

            def where_imu(row: int) -> tuple[int, str]:
                return index[row], f" (message {index[row]} of {topic}, stamp {stamps_imu[row] * 1e-9:.9f} s)"

            orientation = normalised_quaternions(rows[:, 6:], bag.source, topic, where_imu)
        imu[name] = ImuTrack(
            (np.asarray(series.stamps, dtype=np.int64) - t0) * 1e-9, rows[:, :3], rows[:, 3:6], orientation
        )
    actuators = {name: on_frames(series, 1)[:, 0] for name, series in bag.joints.items()}
    return Recording(time, bodies=bodies, imu=imu, actuators=actuators, source=bag.source)


class RosbagParams(RecordingParams):
    """``data.params`` of source ``rosbag`` (family ``recordings``)."""

    topics: tuple[str, ...] = Field((), description="topics to read (default: every topic of a type read)")


def _read(path: Path, params: RosbagParams) -> Recording:
    return read_rosbag(path, params.frame, params.units, params.topics)


@register_source(
    FAMILY,
    "rosbag",
    "a ROS 2 bag: Imu, PoseStamped, TransformStamped, TFMessage, JointState (needs rosbags: optikin[rosbag])",
    params=RosbagParams,
)
def rosbag_source(arm: object, data: DataSpec, params: RosbagParams, path: Path) -> Recording:
    """:func:`read_rosbag` of ``params.file``, then the steps of :mod:`optikin.data.readers.common`."""
    return load_recording(_read, data, params, path)
