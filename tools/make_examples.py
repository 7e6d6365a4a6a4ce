"""The example data files of ``examples/data/``: one small file per reader, written from optikin's models.

=============================  ======================================================================
``demo-pose.csv``              a demonstration of tip poses ``t,x,y,z,qw,qx,qy,qz`` [s, m, -]: the
                               two-section arm (2 x 0.18 m) along a minimum-jerk path through three
                               configurations in 2 s, recorded at 30 Hz with time-stamp jitter
                               (+-2 ms) and sensor noise (0.1 mm, 0.05 degrees per axis)
``demo-position.csv``          the same motion, tip positions only ``t,x,y,z`` [s, m]
``demo-configurations.csv``    the same motion as configurations ``t,S1,theta1,phi1,S2,theta2,phi2``
                               [s, m, rad], noise-free
``configurations.csv``         20 configurations of that arm drawn inside its bounds (no ``t``)
``targets.csv``                10 tip-pose targets ``x,y,z,qw,qx,qy,qz`` (forward kinematics of
                               configurations drawn inside the bounds)
``markers.csv``                8 postures of the CBHA recorded by motion capture (synthetic source of
                               :mod:`optikin.data.markers`, 0.3 mm marker noise)
``motive.csv``                 an OptiTrack Motive CSV export (y up, mm) of the hanging three-section
                               trunk of ``tools/make_recordings.py``, 12 frames at 5 Hz
``trunk.c3d``, ``trunk_bag/``  the same 12 frames as a C3D file and a ROS 2 bag (sqlite3 storage),
                               by the writers of ``tools/make_recordings.py`` (they need ezc3d and
                               rosbags)
=============================  ======================================================================

Run ``python tools/make_examples.py`` (``--out`` another folder); every draw is seeded, so the files
are the same on every run.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import sys
from pathlib import Path

import numpy as np

from optikin.algebra import dq_rotation, dq_translation, quat_exp, quat_hemisphere_continuous, quat_multiply
from optikin.arms.cbha import CBHAArm
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.control.reference import minimum_jerk_path
from optikin.data.markers import synthetic_recording, write_marker_csv

ROOT = Path(__file__).resolve().parents[1]
ARM = ConstantCurvatureArm(section_lengths=(0.18, 0.18))
WAYPOINTS = np.array(
    [
        [0.180, 0.6, 0.3, 0.180, 0.5, -1.0],
        [0.170, 1.0, 0.8, 0.190, -0.4, -0.5],
        [0.185, 0.3, 1.5, 0.175, 0.8, 0.2],
    ]
)
"""The demonstration's configurations, 1 s apart [m, rad]."""
RATE = 30.0
"""Sample rate of the demonstration files [Hz]."""
JITTER = 0.002
"""Largest time-stamp error of a demonstration sample [s]."""
POSITION_NOISE = 1e-4
"""Standard deviation of the demonstration's tip positions per axis [m]."""
ANGLE_NOISE_DEG = 0.05
"""Standard deviation of the demonstration's tip orientation per axis [deg]."""
MOTIVE_FRAMES = 12
"""Frames of the recording examples (Motive, C3D, bag)."""
MOTIVE_RATE = 5.0
"""Frame rate of the recording examples [Hz]: their 12 frames span 2.4 s of the trunk's motion."""


def write_rows(path: Path, header: list[str], rows: np.ndarray, digits: int = 6) -> None:
    """``rows`` under ``header``, each number with ``digits`` decimals."""
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(header)
        writer.writerows([[f"{v:.{digits}f}" for v in row] for row in rows])


def demonstrations(out: Path) -> None:
    """``demo-pose.csv``, ``demo-position.csv`` and ``demo-configurations.csv`` (module docstring)."""
    rng = np.random.default_rng(2026)
    t, Q, _ = minimum_jerk_path(WAYPOINTS, 1.0, RATE)
    stamps = t + rng.uniform(-JITTER, JITTER, t.size)
    stamps[0] = 0.0
    dq = ARM.evaluate("fk_dq", Q)
    position = dq_translation(dq) + rng.normal(0.0, POSITION_NOISE, (t.size, 3))
    turn = quat_exp(0.5 * np.deg2rad(ANGLE_NOISE_DEG) * rng.normal(size=(t.size, 3)))
    quaternion = quat_hemisphere_continuous(quat_multiply(turn, dq_rotation(dq)))
    write_rows(
        out / "demo-pose.csv",
        ["t", "x", "y", "z", "qw", "qx", "qy", "qz"],
        np.column_stack([stamps, position, quaternion]),
    )
    write_rows(out / "demo-position.csv", ["t", "x", "y", "z"], np.column_stack([stamps, position]))
    write_rows(out / "demo-configurations.csv", ["t", *ARM.config_names], np.column_stack([t, Q]))


def samples(out: Path) -> None:
    """``configurations.csv``, ``targets.csv`` and ``markers.csv`` (module docstring)."""
    rng = np.random.default_rng(7)
    write_rows(out / "configurations.csv", list(ARM.config_names), ARM.sample_configurations(20, rng))
    dq = ARM.evaluate("fk_dq", ARM.sample_configurations(10, rng))
    poses = np.column_stack([dq_translation(dq), dq_rotation(dq)])
    write_rows(out / "targets.csv", ["x", "y", "z", "qw", "qx", "qy", "qz"], poses, digits=12)  # on the 5-D pose set
    write_marker_csv(synthetic_recording(CBHAArm(), 8, np.random.default_rng([2018, 0])), out / "markers.csv")


def recordings(out: Path) -> None:
    """``motive.csv``, ``trunk.c3d`` and ``trunk_bag/``: 12 frames at 5 Hz by ``tools/make_recordings.py``."""
    spec = importlib.util.spec_from_file_location("make_recordings", ROOT / "tools" / "make_recordings.py")
    assert spec is not None and spec.loader is not None
    make_recordings = importlib.util.module_from_spec(spec)
    sys.modules["make_recordings"] = make_recordings
    spec.loader.exec_module(make_recordings)
    make_recordings.FRAMES, make_recordings.RATE = MOTIVE_FRAMES, MOTIVE_RATE  # read by its writers when called
    make_recordings.write_motive_csv(out / "motive.csv")
    make_recordings.write_c3d(out / "trunk.c3d")
    make_recordings.write_bag(out / "trunk_bag")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "examples" / "data")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    demonstrations(args.out)
    samples(args.out)
    recordings(args.out)


if __name__ == "__main__":
    main()
