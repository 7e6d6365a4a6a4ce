"""The shared recording type and the readers of the lab formats (Motive CSV, C3D, ROS 2 bag, plain CSV).

Frame and unit conversion is checked against rotations written out by hand and against
scipy's; gap, NaN and swap notes against recordings built with known faults.
"""

from __future__ import annotations

import csv
import importlib.util
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from optikin.data.readers import PlainCsvParams, read_c3d, read_motive_csv, read_plain_csv, read_rosbag
from optikin.data.recording import (
    FrameOptions,
    ImuTrack,
    Recording,
    RigidBodyTrack,
    convert_quaternions,
    frame_matrix,
    inspect_frames,
    to_base_frame,
)
from optikin.data.sources import DATA_SOURCES, source_of
from optikin.errors import InputDataError, SpecError
from optikin.options import validate_options
from optikin.spec import DataSpec


def _wxyz(rotation: Rotation) -> np.ndarray:
    xyzw = rotation.as_quat()
    return np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1)


# ------------------------------------------------------------------------------ frame and units
def test_y_up_is_plus_90_degrees_about_x():
    """``up: y``: (x, y, z) -> (x, -z, y), the rotation by +90 degrees about x."""
    a = frame_matrix(FrameOptions(up="y"))
    np.testing.assert_allclose(a, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=0)
    np.testing.assert_allclose(a, Rotation.from_euler("x", 90, degrees=True).as_matrix(), atol=1e-15)


def test_x_up_and_forward_and_left_handed():
    np.testing.assert_allclose(frame_matrix(FrameOptions(up="x")), [[0, 0, -1], [0, 1, 0], [1, 0, 0]], atol=0)
    np.testing.assert_allclose(frame_matrix(FrameOptions(up="z")), np.eye(3), atol=0)
    # y up, z forward (Motive's calibration-square convention read as "z is forward")
    a = frame_matrix(FrameOptions(up="y", forward="z"))
    np.testing.assert_allclose(a @ [0, 0, 1], [1, 0, 0], atol=0)
    np.testing.assert_allclose(a @ [0, 1, 0], [0, 0, 1], atol=0)
    assert np.linalg.det(a) == pytest.approx(1.0)
    # Unity's left-handed y-up frame: x right, y up, z forward -> optikin x forward, y left, z up
    left = frame_matrix(FrameOptions(up="y", forward="z", handedness="left"))
    np.testing.assert_allclose(left, [[0, 0, 1], [-1, 0, 0], [0, 1, 0]], atol=0)
    assert np.linalg.det(left) == pytest.approx(-1.0)
    with pytest.raises(ValueError, match="perpendicular"):
        FrameOptions(up="y", forward="-y")


@pytest.mark.parametrize("handedness", ["right", "left"])
def test_quaternions_convert_as_a_r_a_transposed(handedness):
    """``(w, det(A) A v)`` equals ``A R A^T`` computed by scipy on the matrices."""
    a = frame_matrix(FrameOptions(up="y", forward="z", handedness=handedness))
    rotations = Rotation.random(20, random_state=3)
    converted = convert_quaternions(_wxyz(rotations), a)
    expected = a @ rotations.as_matrix() @ a.T
    got = Rotation.from_quat(np.concatenate([converted[:, 1:], converted[:, :1]], axis=1)).as_matrix()
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_to_base_frame_scales_lengths_only():
    time = np.array([0.0, 0.01])
    rec = Recording(
        time,
        markers={"m": np.array([[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan]])},
        bodies={"b": RigidBodyTrack(np.array([[0.0, 1000.0, 0.0]] * 2), np.array([[1.0, 0, 0, 0]] * 2))},
        imu={"i": ImuTrack(time, np.array([[0.0, 1.0, 0.0]] * 2), np.array([[0.0, 9.81, 0.0]] * 2))},
        actuators={"tendon": np.array([0.1, 0.2])},
    )
    out = to_base_frame(rec, FrameOptions(up="y"), "mm")
    np.testing.assert_allclose(out.markers["m"][0], [1e-3, -3e-3, 2e-3], rtol=1e-15)
    assert np.isnan(out.markers["m"][1]).all()
    np.testing.assert_allclose(out.bodies["b"].positions[0], [0, 0, 1.0], atol=1e-15)
    np.testing.assert_allclose(out.bodies["b"].quaternions, rec.bodies["b"].quaternions)
    np.testing.assert_allclose(out.imu["i"].angular_velocity[0], [0, 0, 1.0], atol=1e-15)
    np.testing.assert_allclose(out.imu["i"].linear_acceleration[0], [0, 0, 9.81], atol=1e-15)
    np.testing.assert_array_equal(out.actuators["tendon"], [0.1, 0.2])


# ------------------------------------------------------------------------------ notes
def _walk(n: int = 10) -> dict[str, np.ndarray]:
    t = np.arange(n)[:, None] * 0.01
    return {
        "a": np.hstack([t, 0 * t, 0 * t]),
        "b": np.hstack([t, 0 * t + 0.5, 0 * t]),
        "c": np.hstack([0 * t, t, 0 * t + 1.0]),
    }


def test_nan_swap_and_gap_notes_and_dropping():
    markers = _walk()
    markers["a"][3, 1] = np.nan  # a NaN cell
    markers["a"][6:8], markers["b"][6:8] = markers["b"][6:8].copy(), markers["a"][6:8].copy()  # swapped twice
    frames = np.array([0, 1, 2, 3, 4, 7, 8, 9, 10, 11])  # frames 5, 6 dropped by the recorder
    rec = inspect_frames(Recording(frames / 100.0, markers=markers, frames=frames), numbered=True)
    by_kind = {k: [(n.frame, n.detail) for n in rec.notes if n.what == k] for k in ("gap", "nan", "swap")}
    assert by_kind["gap"] == [(7, "2 frame(s) missing before it")]
    assert by_kind["nan"] == [(3, "marker a missing")]
    assert [f for f, _ in by_kind["swap"]] == [8, 9]
    assert all("a and b" in d for _, d in by_kind["swap"])
    kept = rec.drop_incomplete()
    np.testing.assert_array_equal(kept.frame_index, [0, 1, 2, 4, 7, 10, 11])
    dropped = {n.frame: n.detail for n in kept.notes if n.what == "dropped"}
    assert dropped == {3: "missing a", 8: "labels swapped", 9: "labels swapped"}
    assert kept.marker_array(["a", "c"]).shape == (7, 2, 3)
    with pytest.raises(KeyError, match="'z'"):
        kept.marker_array(["z"])


def test_gap_by_time_without_frame_numbers():
    time = np.array([0.0, 0.01, 0.02, 0.05, 0.06])
    rec = inspect_frames(Recording(time, markers={"a": np.zeros((5, 3))}))
    assert [(n.frame, n.what) for n in rec.notes] == [(3, "gap")]
    assert "about 2 frame(s)" in rec.notes[0].detail


# ------------------------------------------------------------------------------ the shipped recordings
ROOT = Path(__file__).resolve().parents[1]
RECORDINGS = ROOT / "problems" / "data" / "recordings"
Y_UP = FrameOptions(up="y")
METRE = 1e-9
"""Round-trip tolerance on lengths [m]."""


@pytest.fixture(scope="module")
def tool():
    """tools/make_recordings.py, the script that wrote the recordings from the constant-curvature model."""
    spec = importlib.util.spec_from_file_location("make_recordings", ROOT / "tools" / "make_recordings.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def truth(tool) -> Recording:
    return tool.trunk_truth()


def assert_same(got: Recording, want: Recording, length: float = METRE, angle: float = 1e-9, sign: bool = False):
    """Every track of ``got`` equals ``want`` (lengths to ``length`` m, unitless to ``angle``); ``sign``: q ~ -q."""
    np.testing.assert_allclose(got.time, want.time, atol=1e-12)
    for name, xyz in got.markers.items():
        np.testing.assert_allclose(xyz, want.markers[name], atol=length, rtol=0, err_msg=name)
    for name, body in got.bodies.items():
        np.testing.assert_allclose(body.positions, want.bodies[name].positions, atol=length, rtol=0, err_msg=name)
        q, ref = body.quaternions, want.bodies[name].quaternions
        if sign:
            q = q * np.where(np.sum(q * ref, axis=1) < 0, -1.0, 1.0)[:, None]
        np.testing.assert_allclose(q, ref, atol=angle, rtol=0, err_msg=name)
    for name, track in got.imu.items():
        ref = want.imu[name]
        np.testing.assert_allclose(track.time, ref.time, atol=1e-12)
        np.testing.assert_allclose(track.angular_velocity, ref.angular_velocity, atol=angle, rtol=0)
        np.testing.assert_allclose(track.linear_acceleration, ref.linear_acceleration, atol=angle, rtol=0)
        assert track.orientation is not None and ref.orientation is not None
        np.testing.assert_allclose(track.orientation, ref.orientation, atol=angle, rtol=0)
    for name, values in got.actuators.items():
        np.testing.assert_allclose(values, want.actuators[name], atol=length, rtol=0, err_msg=name)


def test_the_trunk_hangs_down(truth):
    """The model's disks hang below the 1.2 m mount, one section length (0.1 m) apart along the bent backbone."""
    heights = [truth.bodies[b].positions[:, 2] for b in ("disk1", "disk2", "disk3")]
    assert (heights[0] < 1.2).all() and (heights[1] < heights[0]).all() and (heights[2] < heights[1]).all()
    assert (1.2 - heights[2] > 0.2).all()  # three 0.1 m sections bent by less than 0.4 rad each
    gaps = np.linalg.norm(truth.bodies["disk2"].positions - truth.bodies["disk1"].positions, axis=1)
    assert ((gaps < 0.1) & (gaps > 0.09)).all()  # a chord of a 0.1 m arc


def test_motive_round_trip(truth):
    rec = read_motive_csv(RECORDINGS / "trunk_motive.csv", Y_UP)
    assert sorted(rec.markers) == sorted(truth.markers) and sorted(rec.bodies) == sorted(truth.bodies)
    assert rec.notes == [] and not rec.imu and not rec.actuators
    assert_same(rec, truth)
    np.testing.assert_array_equal(rec.frame_index, np.arange(40))


def test_motive_cells_read_as_written():
    """One rigid body's cells, read with the csv module: Motive's X, Y, Z (mm, y up) -> optikin's x, -z... in m."""
    rows = list(csv.reader(open(RECORDINGS / "trunk_motive.csv", newline="")))
    assert rows[0][:2] == ["Format Version", "1.25"] and rows[1] == []
    assert [r[1] for r in rows[2:6]] == ["Type", "Name", "ID", "Parent"]
    assert rows[7][:2] == ["Frame", "Time (Seconds)"]
    j = rows[3].index("disk2")
    assert rows[6][j : j + 7] == ["Rotation"] * 4 + ["Position"] * 3 and rows[7][j : j + 7] == list("XYZWXYZ")
    qx, qy, qz, qw, x, y, z = (float(c) for c in rows[8 + 17][j : j + 7])
    rec = read_motive_csv(RECORDINGS / "trunk_motive.csv", Y_UP)
    np.testing.assert_allclose(rec.bodies["disk2"].positions[17], [x * 1e-3, -z * 1e-3, y * 1e-3], atol=1e-15)
    np.testing.assert_allclose(rec.bodies["disk2"].quaternions[17], [qw, qx, -qz, qy], atol=1e-11)


def test_motive_gaps_are_noted_per_frame_and_dropped_not_filled():
    rec = read_motive_csv(RECORDINGS / "trunk_motive_faults.csv", Y_UP)
    assert [(n.frame, n.what) for n in rec.notes] == [(5, "nan"), (14, "gap"), (20, "swap"), (21, "swap")]
    assert "disk2:Marker3" in rec.notes[0].detail and rec.notes[1].detail.startswith("2 frame(s) missing")
    assert "disk1 and disk2" in rec.notes[2].detail
    assert np.isnan(rec.markers["disk2:Marker3"][5]).all() and not np.isnan(rec.markers["disk2:Marker2"][5]).any()
    kept = rec.drop_incomplete()
    assert [(n.frame, n.detail) for n in kept.notes if n.what == "dropped"] == [
        (5, "missing disk2:Marker3"),
        (20, "labels swapped"),
        (21, "labels swapped"),
    ]
    expected = [f for f in range(40) if f not in (5, 12, 13, 20, 21)]
    np.testing.assert_array_equal(kept.frame_index, expected)
    markers_only = rec.drop_incomplete(bodies=["disk3"])  # the swapped bodies are not asked for
    np.testing.assert_array_equal(markers_only.frame_index, [f for f in range(40) if f not in (5, 12, 13)])
    assert not np.isnan(kept.marker_array(sorted(kept.markers))).any()


def test_plain_csv_round_trip(truth):
    mapping = yaml.safe_load((RECORDINGS / "trunk_plain.yaml").read_text())
    rec = read_plain_csv(RECORDINGS / "trunk_plain.csv", PlainCsvParams(path="trunk_plain.csv", **mapping))
    assert sorted(rec.actuators) == sorted(truth.actuators) and sorted(rec.imu) == ["tip_imu"]
    assert rec.notes == []
    assert_same(rec, truth)


def test_c3d_round_trip(tool, truth):
    """C3D keeps single-precision floats: the reader gives back exactly the float32 numbers the file holds."""
    pytest.importorskip("ezc3d")
    rec = read_c3d(RECORDINGS / "trunk.c3d", Y_UP)
    assert sorted(rec.markers) == sorted(truth.markers) and sorted(rec.bodies) == sorted(truth.bodies)
    assert sorted(rec.actuators) == sorted(truth.actuators) and rec.notes == []
    stored = tool.file_frame(truth)
    as_float32 = Recording(
        truth.time,
        markers={k: v.astype(np.float32).astype(float) for k, v in stored.markers.items()},
        bodies={
            k: RigidBodyTrack(b.positions.astype(np.float32).astype(float), b.quaternions)
            for k, b in stored.bodies.items()
        },
        actuators={k: v.astype(np.float32).astype(float) for k, v in stored.actuators.items()},
    )
    expected = to_base_frame(as_float32, Y_UP, "mm")
    assert_same(rec, expected, angle=1e-6, sign=True)
    assert_same(rec, truth, length=1e-6, angle=1e-6, sign=True)  # and float32 is within 1e-6 m of the model


@pytest.mark.parametrize("bag", ["trunk_bag", "trunk_mcap"])
def test_rosbag_round_trip(truth, bag):
    pytest.importorskip("rosbags")
    rec = read_rosbag(RECORDINGS / bag, Y_UP, "mm")
    assert sorted(rec.bodies) == sorted(truth.bodies) and sorted(rec.imu) == ["tip_imu"]
    assert sorted(rec.actuators) == sorted(truth.actuators) and rec.notes == []
    assert_same(rec, truth)


def test_the_script_writes_the_shipped_files(tool, tmp_path):
    """Running tools/make_recordings.py again gives the shipped text files byte for byte, and C3D and bags
    holding the same numbers (their bytes carry the writing library's version)."""
    pytest.importorskip("ezc3d")
    pytest.importorskip("rosbags")
    tool.main(["--out", str(tmp_path)])
    shipped = sorted(p.relative_to(RECORDINGS) for p in RECORDINGS.rglob("*") if p.is_file() and p.name != "README.md")
    assert shipped == sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    for rel in shipped:
        if rel.suffix in (".csv", ".yaml") and rel.parent == Path("."):
            assert (tmp_path / rel).read_bytes() == (RECORDINGS / rel).read_bytes(), rel
    assert_same(read_c3d(tmp_path / "trunk.c3d", Y_UP), read_c3d(RECORDINGS / "trunk.c3d", Y_UP), 0.0, 0.0)
    for bag in ("trunk_bag", "trunk_mcap"):
        assert_same(read_rosbag(tmp_path / bag, Y_UP, "mm"), read_rosbag(RECORDINGS / bag, Y_UP, "mm"), 0.0, 0.0)


# ------------------------------------------------------------------------------ the data sources
def test_sources_are_registered_and_apply_the_problem_file(tmp_path):
    problem = tmp_path / "calibrate.yaml"
    shutil.copy(RECORDINGS / "trunk_motive_faults.csv", tmp_path / "take.csv")
    assert {"motive", "c3d", "rosbag", "csv"} <= set(DATA_SOURCES["recordings"].names())
    source = source_of("recordings", "motive", problem)
    raw = {"file": "take.csv", "frame": {"up": "y"}, "units": "mm", "markers": ["disk1:Marker1"]}
    params = validate_options(source.params, raw, problem, "data.params")
    rec = source.load(None, DataSpec(source="motive"), params, problem)
    assert list(rec.markers) == ["disk1:Marker1"] and len(rec) == 40 - 2 - 2  # frames 20 and 21: swapped bodies
    assert [n.frame for n in rec.notes if n.what == "dropped"] == [20, 21]
    few = source.load(None, DataSpec(source="motive", samples=5), params, problem)
    np.testing.assert_array_equal(few.frame_index, np.arange(5))
    with pytest.raises(SpecError, match=r"data\.params\.frame\.up"):
        validate_options(source.params, {**raw, "frame": {"up": "w"}}, problem, "data.params")
    wrong_units = validate_options(source.params, {**raw, "units": "m"}, problem, "data.params")
    with pytest.raises(InputDataError, match="take.csv: Length Units: the file declares its lengths in 'Millimeters'"):
        source.load(None, DataSpec(source="motive"), wrong_units, problem)
    missing = validate_options(source.params, {**raw, "markers": ["tip"]}, problem, "data.params")
    with pytest.raises(InputDataError, match=r"take.csv: markers.tip: no marker 'tip' in the file"):
        source.load(None, DataSpec(source="motive"), missing, problem)


def test_plain_csv_source(tmp_path):
    problem = tmp_path / "p.yaml"
    shutil.copy(RECORDINGS / "trunk_plain.csv", tmp_path / "trunk_plain.csv")
    mapping = yaml.safe_load((RECORDINGS / "trunk_plain.yaml").read_text())
    source = source_of("recordings", "csv", problem)
    params = validate_options(source.params, {"file": "trunk_plain.csv", **mapping}, problem, "data.params")
    rec = source.load(None, DataSpec(source="csv"), params, problem)
    assert len(rec) == 40 and len(rec.markers) == 9


# ------------------------------------------------------------------------------ malformed files
def _edit_cell(text: str, line: int, column: int, value: str) -> str:
    lines = text.split("\n")
    cells = lines[line - 1].split(",")
    cells[column] = value
    lines[line - 1] = ",".join(cells)
    return "\n".join(lines)


def test_malformed_motive_names_file_row_frame_and_column(tmp_path):
    text = (RECORDINGS / "trunk_motive.csv").read_text()
    header = text.split("\n")
    j = header[3].split(",").index("disk2") + 5  # disk2 Position Y
    bad = tmp_path / "bad.csv"
    bad.write_text(_edit_cell(text, 9 + 7, j, "1.2.3"))  # line 16: data row 7, frame 7
    with pytest.raises(InputDataError) as info:
        read_motive_csv(bad, Y_UP)
    assert (info.value.source, info.value.sample, info.value.field) == (str(bad), 7, "disk2 Position Y")
    assert "'1.2.3' is not a finite number (line 16, frame 7)" in str(info.value)
    bad.write_text(_edit_cell(text, 9 + 3, j - 2, "0.9"))  # disk2 Rotation W of frame 3
    with pytest.raises(InputDataError, match=r"bad.csv: sample 3: disk2 Rotation: norm .* \(line 12, frame 3\)"):
        read_motive_csv(bad, Y_UP)
    bad.write_text("\n".join(header[:4] + header[5:]))  # no ID row: still read; no Name row: refused
    assert len(read_motive_csv(bad, Y_UP)) == 40
    bad.write_text("\n".join(header[:3] + header[4:]))
    with pytest.raises(InputDataError, match="bad.csv: Name: header row Name missing before line 7"):
        read_motive_csv(bad, Y_UP)
    bad.write_text(text.replace("Rotation Type,Quaternion", "Rotation Type,XYZ"))
    with pytest.raises(InputDataError, match="bad.csv: Rotation Type: rotation type 'XYZ'"):
        read_motive_csv(bad, Y_UP)
    bad.write_text(text.replace("\n20,", "\n19,", 1))
    with pytest.raises(InputDataError, match="bad.csv: sample 20: Frame: frame numbers must increase strictly"):
        read_motive_csv(bad, Y_UP)
    header[3] = header[3].replace("disk3:Marker3", "Unlabeled 1003")
    bad.write_text("\n".join(header))  # an unlabelled marker: skipped unless asked for
    assert "Unlabeled 1003" not in read_motive_csv(bad, Y_UP).markers
    assert "Unlabeled 1003" in read_motive_csv(bad, Y_UP, unlabeled=True).markers
    bad.write_text("t,x\n0,1\n")
    with pytest.raises(InputDataError, match="bad.csv: Format Version: not a Motive CSV export"):
        read_motive_csv(bad, Y_UP)


def test_malformed_plain_csv_names_file_row_and_column(tmp_path):
    mapping = yaml.safe_load((RECORDINGS / "trunk_plain.yaml").read_text())
    params = PlainCsvParams(path="bad.csv", **mapping)
    text = (RECORDINGS / "trunk_plain.csv").read_text()
    j = text.split("\n")[0].split(",").index("disk3_qz")
    bad = tmp_path / "bad.csv"
    bad.write_text(_edit_cell(text, 1 + 4, j, "oops"))
    with pytest.raises(InputDataError) as info:
        read_plain_csv(bad, params)
    assert (info.value.source, info.value.sample, info.value.field) == (str(bad), 3, "disk3_qz")
    assert "line 5" in str(info.value)
    bad.write_text(_edit_cell(text, 1 + 4, j, "0.5"))
    with pytest.raises(InputDataError, match=r"bad.csv: sample 3: disk3_qw, disk3_qx, disk3_qy, disk3_qz: norm"):
        read_plain_csv(bad, params)
    k = text.split("\n")[0].split(",").index("tendon_23_mm")
    bad.write_text(_edit_cell(text, 1 + 9, k, "nan"))
    with pytest.raises(InputDataError, match=r"bad.csv: sample 8: tendon_23_mm: 'nan' is not a finite number"):
        read_plain_csv(bad, params)


def _c3d(path: Path, points: np.ndarray, rotations: np.ndarray | None = None) -> Path:
    import ezc3d

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [50]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = [f"m{k}" for k in range(points.shape[1])]
    c3d.add_parameter("POINT", "UNITS", "m")
    c3d["data"]["points"] = np.concatenate([points, np.ones((1, *points.shape[1:]))])
    if rotations is not None:
        c3d.add_parameter("ROTATION", "USED", rotations.shape[2])
        c3d.add_parameter("ROTATION", "RATE", 50.0)
        c3d.add_parameter("ROTATION", "RATIO", 1)
        c3d.add_parameter("ROTATION", "DATA_START", 3)
        c3d.add_parameter("ROTATION", "LABELS", [f"b{k}" for k in range(rotations.shape[2])])
        c3d["data"]["rotations"] = rotations
    c3d.write(str(path))
    return path


def test_malformed_c3d_names_file_frame_and_channel(tmp_path):
    pytest.importorskip("ezc3d")
    points = np.zeros((3, 2, 6))
    points[:, 1, :] = 0.5
    points[2, 1, 4] = np.inf
    bad = _c3d(tmp_path / "bad.c3d", points)
    with pytest.raises(InputDataError) as info:
        read_c3d(bad)
    assert (info.value.source, info.value.sample, info.value.field) == (str(bad), 4, "m1")
    rotations = np.tile(np.eye(4)[:, :, None, None], (1, 1, 1, 6))
    rotations[0, 0, 0, 2] = 2.0  # frame 2 of b0 stretches x
    points[2, 1, 4] = 0.5
    bad = _c3d(tmp_path / "rot.c3d", points, rotations)
    with pytest.raises(InputDataError, match=r"rot.c3d: sample 2: b0: not a rotation matrix"):
        read_c3d(bad)
    points[0, 0, 3] = np.nan  # m0 not seen in frame 3: noted, not an error
    ok = _c3d(tmp_path / "ok.c3d", points, np.tile(np.eye(4)[:, :, None, None], (1, 1, 1, 6)))
    rec = read_c3d(ok, units="m")
    np.testing.assert_allclose(rec.bodies["b0"].quaternions, np.tile([1.0, 0, 0, 0], (6, 1)))
    assert [str(n) for n in rec.notes] == ["frame 3: nan: marker m0 missing"]
    assert np.isnan(rec.markers["m0"][3]).all() and len(rec.drop_incomplete()) == 5
    with pytest.raises(InputDataError, match="ok.c3d: POINT:UNITS: the file declares its lengths in 'm'"):
        read_c3d(ok, units="mm")
    truncated = tmp_path / "truncated.c3d"
    truncated.write_bytes((RECORDINGS / "trunk.c3d").read_bytes()[:700])
    with pytest.raises(InputDataError, match="truncated.c3d: truncated: the header declares 40 frames, the file ends"):
        read_c3d(truncated)


def _bag(path: Path, poses: list[tuple[float, float, float, float]], joints: list[list[float]] | None = None) -> Path:
    """A bag with PoseStamped ``/arm/pose`` (x and quaternion w per message) and JointState ``/joints``."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    with Writer(path, version=9) as writer:
        pose = writer.add_connection("/arm/pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        joint = writer.add_connection("/joints", "sensor_msgs/msg/JointState", typestore=store)
        for i, (x, qw, qx, qy) in enumerate(poses):
            stamp = 10**9 + i * 10**7
            header = t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="w"
            )
            msg = t["geometry_msgs/msg/PoseStamped"](
                header=header,
                pose=t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
                    orientation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=0.0, w=qw),
                ),
            )
            writer.write(pose, stamp, store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
            if joints is not None:
                msg = t["sensor_msgs/msg/JointState"](
                    header=header,
                    name=["a", "b"],
                    position=np.array(joints[i]),
                    velocity=np.zeros(0),
                    effort=np.zeros(0),
                )
                writer.write(joint, stamp, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    return path


def test_malformed_rosbag_names_bag_message_and_topic(tmp_path):
    pytest.importorskip("rosbags")
    good = [(0.01 * i, 1.0, 0.0, 0.0) for i in range(6)]
    rec = read_rosbag(_bag(tmp_path / "good", good, [[0.1, 0.2]] * 6))
    np.testing.assert_allclose(rec.bodies["arm"].positions[:, 0], 0.01 * np.arange(6), atol=1e-15)
    np.testing.assert_allclose(rec.time, 0.01 * np.arange(6), atol=1e-12)
    np.testing.assert_allclose(rec.actuators["b"], 0.2)
    nan = good[:3] + [(np.nan, 1.0, 0.0, 0.0)] + good[4:]
    with pytest.raises(InputDataError) as info:
        read_rosbag(_bag(tmp_path / "nan", nan))
    assert (info.value.source, info.value.sample, info.value.field) == (str(tmp_path / "nan"), 3, "/arm/pose")
    assert "message 3 of /arm/pose, stamp 1.030000000 s" in str(info.value)
    skew = good[:2] + [(0.02, 0.8, 0.0, 0.0)] + good[3:]
    with pytest.raises(InputDataError, match=r"skew: sample 2: /arm/pose: norm 0.8: not a unit quaternion"):
        read_rosbag(_bag(tmp_path / "skew", skew))
    with pytest.raises(InputDataError, match=r"joints: sample 4: /joints:b: a value is not a finite number"):
        read_rosbag(_bag(tmp_path / "joints", good, [[0.1, 0.2]] * 4 + [[0.1, np.inf], [0.1, 0.2]]))
    with pytest.raises(InputDataError, match=r"good: /tf: no topic '/tf' in the bag"):
        read_rosbag(tmp_path / "good", topics=("/tf",))
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputDataError, match="empty: not a readable ROS 2 bag"):
        read_rosbag(tmp_path / "empty")


@pytest.mark.parametrize(
    ("module", "read", "extra"),
    [
        ("ezc3d", lambda: read_c3d(RECORDINGS / "trunk.c3d"), "optikin[c3d]"),
        ("rosbags", lambda: read_rosbag(RECORDINGS / "trunk_bag"), "optikin[rosbag]"),
    ],
)
def test_a_missing_optional_dependency_names_the_extra(monkeypatch, module, read, extra):
    for name in [m for m in sys.modules if m == module or m.startswith(module + ".")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, module, None)
    with pytest.raises(ImportError, match=re.escape(f"pip install {extra}")):
        read()


def test_plain_csv_without_a_time_column_numbers_its_postures(tmp_path):
    header, *rows = (RECORDINGS / "trunk_plain.csv").read_text().splitlines()
    assert header.startswith("t,")
    (tmp_path / "postures.csv").write_text("\n".join(line.split(",", 1)[1] for line in [header, *rows]) + "\n")
    mapping = yaml.safe_load((RECORDINGS / "trunk_plain.yaml").read_text()) | {"time": None, "imu_columns": {}}
    rec = read_plain_csv(tmp_path / "postures.csv", PlainCsvParams(file="postures.csv", **mapping))
    timed = read_plain_csv(
        RECORDINGS / "trunk_plain.csv", PlainCsvParams(file="trunk_plain.csv", **mapping | {"time": "t"})
    )
    np.testing.assert_array_equal(rec.time, np.arange(len(rows)))
    for name, positions in timed.markers.items():
        np.testing.assert_array_equal(rec.markers[name], positions)


def test_plain_csv_without_a_time_column_takes_no_imu(tmp_path):
    imu = {"angular_velocity": ["a", "b", "c"], "linear_acceleration": ["d", "e", "f"]}
    with pytest.raises(ValueError, match="imu_columns need a time column"):
        PlainCsvParams(file="x.csv", time=None, imu_columns={"imu": imu})
