"""Small test recordings of a hanging tendon trunk, in every format optikin.data.readers reads.

The trunk is a 3-section constant-curvature arm (:class:`optikin.arms.constant_curvature.ConstantCurvatureArm`,
sections of 0.1 m) hanging from a mount 1.2 m above the floor, its base z axis pointing down. Over
:data:`FRAMES` frames at :data:`RATE` Hz each section bends and turns smoothly. Tracked: three disks at
the section ends (rigid bodies ``disk1..3``, each with three markers ``diskN:Marker1..3`` on a 15 mm circle
in the disk plane), an IMU at the tip (``tip_imu``: body-frame angular velocity and specific force from
finite differences of the model, and its orientation), and the nine tendon lengths ``tendon_<section><k>``
(tendon ``k`` at 10 mm from the backbone at angle ``2 pi k / 3``; ``l = sum_j (S_j - r theta_j cos(phi_j -
alpha_k))``, Webster & Jones 2010, IJRR 29(13), eq. 20).

The lab frame of every file is a motion-capture frame: y up, right-handed, lengths in millimetres
(:func:`file_frame`); IMU rates and accelerations and the tendon lengths stay SI, except in the plain CSV
where the tendons are written in mm (its mapping scales them by 0.001). Files written under ``--out``
(default ``problems/data/recordings``, where the problem files and the tests read them):

=============================  ==================================================================
``trunk_motive.csv``           OptiTrack Motive CSV export (format 1.25, full header), rigid bodies,
                               expected rigid-body markers and labelled markers
``trunk_motive_faults.csv``    the same with faults: frames 12 and 13 dropped, an empty cell
                               (``disk2:Marker3`` Y at frame 5), rigid bodies ``disk1`` and ``disk2``
                               swapped at frames 20 and 21
``trunk.c3d``                  C3D (ezc3d): points, ROTATION matrices of the disks, tendon analogs
``trunk_bag/``                 ROS 2 bag, sqlite3 storage (rosbags): PoseStamped ``/disk1/pose``,
                               ``/disk2/pose``, TransformStamped ``/disk3/transform``, Imu ``/tip_imu``,
                               JointState ``/tendons``
``trunk_mcap/``                the same bag in mcap storage
``trunk_plain.csv``            plain CSV (column mapping in ``trunk_plain.yaml``)
=============================  ==================================================================

Run ``python tools/make_recordings.py`` (needs ezc3d and rosbags for the C3D file and the bags).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np
import yaml

from optikin.algebra import quat_multiply, quat_rotate
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.data.recording import FrameOptions, ImuTrack, Recording, RigidBodyTrack, frame_matrix

FRAMES = 40
RATE = 100.0
SECTION_LENGTH = 0.1
MOUNT_POSITION = np.array([0.0, 0.0, 1.2])
MOUNT_QUATERNION = np.array([0.0, 1.0, 0.0, 0.0])
"""The base frame turned by pi about x: its z axis points down."""
MARKER_RADIUS = 0.015
TENDON_RADIUS = 0.01
GRAVITY = 9.81
FILE_FRAME = FrameOptions(up="y")
"""The files' frame: y up, right-handed; lengths in mm."""
FAULT_DROPPED = (12, 13)
FAULT_NAN = (5, "disk2:Marker3", 1)
FAULT_SWAP = (20, 21)
ROOT = Path(__file__).resolve().parents[1]

ARM = ConstantCurvatureArm(section_lengths=(SECTION_LENGTH,) * 3)
BODIES = ("disk1", "disk2", "disk3")
MARKERS = tuple(f"{b}:Marker{k + 1}" for b in BODIES for k in range(3))
TENDONS = tuple(f"tendon_{i + 1}{k + 1}" for i in range(3) for k in range(3))


def configurations(t: np.ndarray) -> np.ndarray:
    """``(len(t), 9)`` configurations ``(S_i, theta_i, phi_i)``: a slow, smooth bend and turn of each section."""
    q = np.zeros((len(t), 9))
    for i in range(3):
        q[:, 3 * i] = SECTION_LENGTH
        q[:, 3 * i + 1] = 0.25 + 0.15 * np.sin(2 * np.pi * 0.5 * t + i)
        q[:, 3 * i + 2] = 0.6 * i + 0.8 * np.sin(2 * np.pi * 0.3 * t)
    return q


def disk_poses(t: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(quaternion (T, 4), position (T, 3))`` of each disk in the world frame (z up, metres)."""
    frames = ARM.section_frames(configurations(t))
    return [
        (quat_multiply(MOUNT_QUATERNION, q), MOUNT_POSITION + quat_rotate(MOUNT_QUATERNION, p, check=False))
        for q, p in frames
    ]


def _imu(t: np.ndarray) -> ImuTrack:
    """The tip IMU: body-frame ``omega = 2 vec(q* dq/dt)`` and specific force ``R^T (a + g e_z)``, by differences."""
    h = 1e-5
    q_minus, _ = disk_poses(t - h)[2]
    q_plus, _ = disk_poses(t + h)[2]
    q, p = disk_poses(t)[2]
    dq = (q_plus - q_minus) / (2 * h)
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    omega = 2.0 * quat_multiply(conj, dq)[:, 1:]
    g = 1e-3
    p_minus, p_plus = disk_poses(t - g)[2][1], disk_poses(t + g)[2][1]
    acceleration = (p_plus - 2 * p + p_minus) / g**2 + np.array([0.0, 0.0, GRAVITY])
    force = quat_rotate(conj, acceleration, check=False)
    return ImuTrack(t.copy(), omega, force, q)


def tendon_lengths(t: np.ndarray) -> dict[str, np.ndarray]:
    """Each tendon's length [m] from the base to the end of its section."""
    q = configurations(t)
    out = {}
    for i in range(3):
        for k in range(3):
            alpha = 2 * np.pi * k / 3
            s, theta, phi = q[:, 0 : 3 * i + 3 : 3], q[:, 1 : 3 * i + 3 : 3], q[:, 2 : 3 * i + 3 : 3]
            out[f"tendon_{i + 1}{k + 1}"] = np.sum(s - TENDON_RADIUS * theta * np.cos(phi - alpha), axis=1)
    return out


def trunk_truth() -> Recording:
    """The recording the files hold, in optikin's frame (z up) and SI units, without faults."""
    t = np.arange(FRAMES) / RATE
    poses = disk_poses(t)
    bodies, markers = {}, {}
    for name, (q, p) in zip(BODIES, poses):
        bodies[name] = RigidBodyTrack(p, q)
        for k in range(3):
            beta = 2 * np.pi * k / 3 + 0.3
            local = MARKER_RADIUS * np.array([np.cos(beta), np.sin(beta), 0.0])
            markers[f"{name}:Marker{k + 1}"] = p + quat_rotate(q, local, check=False)
    return Recording(
        t, markers=markers, bodies=bodies, imu={"tip_imu": _imu(t)}, actuators=tendon_lengths(t), source="model"
    )


def file_frame(truth: Recording) -> Recording:
    """``truth`` in the files' frame: y up (``v_file = A^T v``, ``A`` of ``frame: {up: y}``), lengths in mm."""
    a = frame_matrix(FILE_FRAME)

    def vec(v: np.ndarray, scale: float = 1.0) -> np.ndarray:
        return scale * (v @ a)

    def quat(q: np.ndarray) -> np.ndarray:
        return np.concatenate([q[:, :1], q[:, 1:] @ a], axis=1)

    imu = {
        k: ImuTrack(i.time, vec(i.angular_velocity), vec(i.linear_acceleration), quat(i.orientation))
        for k, i in truth.imu.items()
        if i.orientation is not None
    }
    return Recording(
        truth.time,
        markers={k: vec(v, 1e3) for k, v in truth.markers.items()},
        bodies={k: RigidBodyTrack(vec(b.positions, 1e3), quat(b.quaternions)) for k, b in truth.bodies.items()},
        imu=imu,
        actuators=truth.actuators,
    )


# ------------------------------------------------------------------------------ Motive CSV
def write_motive_csv(path: Path, faults: bool = False) -> None:
    """A Motive 1.25 CSV export (millimetres, quaternions) of the trunk, with the faults when asked."""
    rec = file_frame(trunk_truth())
    bodies = {k: (b.positions.copy(), b.quaternions.copy()) for k, b in rec.bodies.items()}
    if faults:
        for i in FAULT_SWAP:
            for part in (0, 1):
                bodies["disk1"][part][i], bodies["disk2"][part][i] = (
                    bodies["disk2"][part][i].copy(),
                    bodies["disk1"][part][i].copy(),
                )
    header = [["", r] for r in ("Type", "Name", "ID", "Parent", "", "")]
    header[5][:2] = ["Frame", "Time (Seconds)"]
    columns: list[tuple[str, int | None]] = []  # what fills each cell: (source, component index)

    def column(labels: tuple[str, str, str, str, str, str], what: str, index: int | None) -> None:
        for row, label in zip(header, labels):
            row.append(label)
        columns.append((what, index))

    for n, body in enumerate(BODIES, start=1):
        for a in "XYZW":
            column(("Rigid Body", body, str(n), "", "Rotation", a), f"{body}|Rotation", "XYZW".index(a))
        for a in "XYZ":
            column(("Rigid Body", body, str(n), "", "Position", a), f"{body}|Position", "XYZ".index(a))
        column(("Rigid Body", body, str(n), "", "Mean Marker Error", ""), "error", None)
        for k in range(3):
            name, marker_id = f"{body}:Marker{k + 1}", f"{n}:{k + 1}"
            for a in "XYZ":
                column(("Rigid Body Marker", name, marker_id, body, "Position", a), name, "XYZ".index(a))
            column(("Rigid Body Marker", name, marker_id, body, "Marker Quality", ""), "quality", None)
    for n, marker in enumerate(MARKERS):
        for a in "XYZ":
            labels = ("Marker", marker, f"{1 + n // 3}:{1 + n % 3}", marker.split(":")[0], "Position", a)
            column(labels, f"marker|{marker}", "XYZ".index(a))
    total = FRAMES - (len(FAULT_DROPPED) if faults else 0)
    meta = (
        f"Format Version,1.25,Take Name,trunk,Take Notes,,Capture Frame Rate,{RATE:.6f},Export Frame Rate,"
        f"{RATE:.6f},Capture Start Time,2026-12-01 09.00.00.000 PM,Capture Start Frame,0,Total Frames in Take,"
        f"{FRAMES},Total Exported Frames,{total},Rotation Type,Quaternion,Length Units,Millimeters,"
        "Coordinate Space,Global"
    )
    lines = [meta, "", *(",".join(r) for r in header)]
    for i in range(FRAMES):
        if faults and i in FAULT_DROPPED:
            continue
        cells = [str(i), f"{rec.time[i]:.6f}"]
        for what, j in columns:
            if what == "error":
                cells.append("0.000000")
            elif what == "quality":
                cells.append("1.000000")
            elif what.startswith("marker|"):
                name = what.split("|")[1]
                if faults and (i, name, j) == FAULT_NAN:
                    cells.append("")
                else:
                    cells.append(f"{rec.markers[name][i, j]:.9f}")
            elif "|" in what:
                body, comp = what.split("|")
                if comp == "Rotation":
                    q = bodies[body][1][i]
                    cells.append(f"{np.r_[q[1:], q[:1]][j]:.12f}")
                else:
                    cells.append(f"{bodies[body][0][i, j]:.9f}")
            else:  # expected rigid-body marker: the solved position, which is the truth here
                cells.append(f"{rec.markers[what][i, j]:.9f}")
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


# ------------------------------------------------------------------------------ C3D
def write_c3d(path: Path) -> None:
    """A C3D file (ezc3d): the markers as points, the disks as ROTATION matrices, the tendons as analogs."""
    import ezc3d

    rec = file_frame(trunk_truth())
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [RATE]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = list(MARKERS)
    c3d.add_parameter("POINT", "UNITS", "mm")
    points = np.ones((4, len(MARKERS), FRAMES))
    points[:3] = np.stack([rec.markers[m].T for m in MARKERS], axis=1)
    c3d["data"]["points"] = points
    c3d["parameters"]["ANALOG"]["RATE"]["value"] = [RATE]
    c3d["parameters"]["ANALOG"]["LABELS"]["value"] = list(TENDONS)
    c3d["parameters"]["ANALOG"]["UNITS"]["value"] = ["m"] * len(TENDONS)
    c3d["data"]["analogs"] = np.stack([rec.actuators[k] for k in TENDONS])[None]
    c3d.add_parameter("ROTATION", "USED", len(BODIES))
    c3d.add_parameter("ROTATION", "RATE", RATE)
    c3d.add_parameter("ROTATION", "RATIO", 1)
    c3d.add_parameter("ROTATION", "DATA_START", 3)
    c3d.add_parameter("ROTATION", "LABELS", list(BODIES))
    rotations = np.zeros((4, 4, len(BODIES), FRAMES))
    for k, body in enumerate(BODIES):
        w, x, y, z = rec.bodies[body].quaternions.T
        matrix = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        rotations[:3, :3, k] = matrix
        rotations[:3, 3, k] = rec.bodies[body].positions.T
        rotations[3, 3, k] = 1.0
    c3d["data"]["rotations"] = rotations
    c3d.write(str(path))


# ------------------------------------------------------------------------------ ROS 2 bags
START_NS = 1_764_622_800_000_000_000
"""Stamp of frame 0 [ns] (2026-12-01 21:00 UTC)."""


def write_bag(path: Path, storage: str = "sqlite3") -> None:
    """A ROS 2 bag (rosbags): PoseStamped, TransformStamped, Imu and JointState topics of the trunk."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    Header, Time = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    Point, Quaternion, Vector3 = (
        types["geometry_msgs/msg/Point"],
        types["geometry_msgs/msg/Quaternion"],
        types["geometry_msgs/msg/Vector3"],
    )
    Pose, PoseStamped = types["geometry_msgs/msg/Pose"], types["geometry_msgs/msg/PoseStamped"]
    Transform, TransformStamped = types["geometry_msgs/msg/Transform"], types["geometry_msgs/msg/TransformStamped"]
    Imu, JointState = types["sensor_msgs/msg/Imu"], types["sensor_msgs/msg/JointState"]
    rec = file_frame(trunk_truth())
    if path.exists():
        shutil.rmtree(path)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        poses = {b: writer.add_connection(f"/{b}/pose", PoseStamped.__msgtype__, typestore=store) for b in BODIES[:2]}
        transform = writer.add_connection("/disk3/transform", TransformStamped.__msgtype__, typestore=store)
        imu = writer.add_connection("/tip_imu", Imu.__msgtype__, typestore=store)
        joints = writer.add_connection("/tendons", JointState.__msgtype__, typestore=store)
        for i in range(FRAMES):
            stamp = START_NS + round(rec.time[i] * 1e9)
            header = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="mocap")

            def pose_of(body: str) -> tuple[np.ndarray, np.ndarray]:
                return rec.bodies[body].positions[i], rec.bodies[body].quaternions[i]

            for body, connection in poses.items():
                p, q = pose_of(body)
                msg = PoseStamped(
                    header=header,
                    pose=Pose(
                        position=Point(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(x=q[1], y=q[2], z=q[3], w=q[0])
                    ),
                )
                writer.write(connection, stamp, store.serialize_cdr(msg, PoseStamped.__msgtype__))
            p, q = pose_of("disk3")
            msg = TransformStamped(
                header=header,
                child_frame_id="disk3",
                transform=Transform(
                    translation=Vector3(x=p[0], y=p[1], z=p[2]), rotation=Quaternion(x=q[1], y=q[2], z=q[3], w=q[0])
                ),
            )
            writer.write(transform, stamp, store.serialize_cdr(msg, TransformStamped.__msgtype__))
            track = rec.imu["tip_imu"]
            assert track.orientation is not None
            w, a, q = track.angular_velocity[i], track.linear_acceleration[i], track.orientation[i]
            msg = Imu(
                header=header,
                orientation=Quaternion(x=q[1], y=q[2], z=q[3], w=q[0]),
                orientation_covariance=np.zeros(9),
                angular_velocity=Vector3(x=w[0], y=w[1], z=w[2]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vector3(x=a[0], y=a[1], z=a[2]),
                linear_acceleration_covariance=np.zeros(9),
            )
            writer.write(imu, stamp, store.serialize_cdr(msg, Imu.__msgtype__))
            msg = JointState(
                header=header,
                name=list(TENDONS),
                position=np.array([rec.actuators[k][i] for k in TENDONS]),
                velocity=np.zeros(0),
                effort=np.zeros(0),
            )
            writer.write(joints, stamp, store.serialize_cdr(msg, JointState.__msgtype__))


# ------------------------------------------------------------------------------ plain CSV
def plain_mapping() -> dict:
    """The ``data.params`` column mapping of ``trunk_plain.csv`` (without ``file``)."""
    return {
        "frame": {"up": "y"},
        "units": "mm",
        "time": "t",
        "marker_columns": {m: [f"{m}_{a}" for a in "xyz"] for m in MARKERS},
        "body_columns": {
            b: {"position": [f"{b}_{a}" for a in "xyz"], "quaternion": [f"{b}_q{a}" for a in "wxyz"]} for b in BODIES
        },
        "imu_columns": {
            "tip_imu": {
                "angular_velocity": [f"gyro_{a}" for a in "xyz"],
                "linear_acceleration": [f"accel_{a}" for a in "xyz"],
                "orientation": [f"imu_q{a}" for a in "wxyz"],
            }
        },
        "actuator_columns": {k: {"column": f"{k}_mm", "scale": 0.001} for k in TENDONS},
    }


def write_plain_csv(path: Path) -> None:
    """The plain CSV of :func:`plain_mapping` (tendons in mm), and its mapping beside it as ``<stem>.yaml``."""
    rec = file_frame(trunk_truth())
    mapping = plain_mapping()
    columns: list[tuple[str, np.ndarray, str]] = [("t", rec.time, "%.6f")]
    for m, names in mapping["marker_columns"].items():
        columns += [(n, rec.markers[m][:, j], "%.9f") for j, n in enumerate(names)]
    for b, spec in mapping["body_columns"].items():
        columns += [(n, rec.bodies[b].positions[:, j], "%.9f") for j, n in enumerate(spec["position"])]
        columns += [(n, rec.bodies[b].quaternions[:, j], "%.12f") for j, n in enumerate(spec["quaternion"])]
    track = rec.imu["tip_imu"]
    assert track.orientation is not None
    spec = mapping["imu_columns"]["tip_imu"]
    columns += [(n, track.angular_velocity[:, j], "%.12f") for j, n in enumerate(spec["angular_velocity"])]
    columns += [(n, track.linear_acceleration[:, j], "%.12f") for j, n in enumerate(spec["linear_acceleration"])]
    columns += [(n, track.orientation[:, j], "%.12f") for j, n in enumerate(spec["orientation"])]
    columns += [(s["column"], 1e3 * rec.actuators[k], "%.9f") for k, s in mapping["actuator_columns"].items()]
    lines = [",".join(c[0] for c in columns)]
    lines += [",".join(fmt % values[i] for _, values, fmt in columns) for i in range(FRAMES)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    path.with_suffix(".yaml").write_text(yaml.safe_dump(mapping, sort_keys=False), encoding="utf-8")


def main(argv: list[str] | None = None) -> None:
    """Write every recording under ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "problems" / "data" / "recordings")
    args = parser.parse_args(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    write_motive_csv(out / "trunk_motive.csv")
    write_motive_csv(out / "trunk_motive_faults.csv", faults=True)
    write_plain_csv(out / "trunk_plain.csv")
    write_c3d(out / "trunk.c3d")
    write_bag(out / "trunk_bag", "sqlite3")
    write_bag(out / "trunk_mcap", "mcap")
    print(f"wrote the trunk recordings under {out}")


if __name__ == "__main__":
    main()
