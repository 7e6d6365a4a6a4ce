"""A user's own data files: the examples of ``examples/data/`` read and solved, one key (``file``) for a
data file everywhere, and bad demonstration files refused with exit 2 naming the file, row and column."""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from optikin.algebra import dq_translation
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.cli import EXIT_BAD_INPUT, EXIT_OK, main
from optikin.control.reference import minimum_jerk_path
from optikin.data.demonstrations import read_demonstration
from optikin.data.markers import read_marker_csv
from optikin.data.readers.motive_csv import read_motive_csv
from optikin.data.recording import FrameOptions
from optikin.errors import SpecError
from optikin.runner import prepare, solve

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
DATA = EXAMPLES / "data"
PROBLEMS = ROOT / "problems"
ARM = ConstantCurvatureArm(section_lengths=(0.18, 0.18))
WAYPOINTS = [
    [0.180, 0.6, 0.3, 0.180, 0.5, -1.0],
    [0.170, 1.0, 0.8, 0.190, -0.4, -0.5],
    [0.185, 0.3, 1.5, 0.175, 0.8, 0.2],
]
"""The path the demonstration examples record (tools/make_examples.py), 1 s per segment."""
POSE_HEADER = "t,x,y,z,qw,qx,qy,qz"


def write_problem(tmp_path: Path, spec: dict[str, Any], name: str) -> Path:
    spec = {**spec, "name": name}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def tracking(tmp_path: Path, file: Path | str, name: str = "track-file", **params: Any) -> Path:
    """A small tracking problem (QP only, 100 Hz) on the demonstration file ``file``."""
    spec = {
        "title": "track a file",
        "kind": "tracking",
        "arm": {"type": "constant_curvature", "params": {"section_lengths": [0.18, 0.18]}},
        "data": {"source": "csv", "seed": 1, "params": {"file": str(file), "rate": 100, "hold": 0.3, **params}},
        "solver": "qp-osqp",
        "baselines": [],
        "options": {"tolerance": {"position_mm": 1.0, "orientation_deg": 0.5}},
    }
    return write_problem(tmp_path, spec, name)


def shipped(name: str, tmp_path: Path, data: dict[str, Any], **top: Any) -> Path:
    """The shipped (or example) problem ``name`` with its ``data`` section replaced (and top-level fields ``top``)."""
    folder = EXAMPLES if (EXAMPLES / f"{name}.yaml").is_file() else PROBLEMS
    spec = yaml.safe_load((folder / f"{name}.yaml").read_text())
    spec["data"] = data
    spec.update(top)
    return write_problem(tmp_path, spec, name)


def reference_of(problem: Path):
    _, ctx = prepare(str(problem))
    return ctx.load_data()


# ------------------------------------------------------------------------------ the examples, read and solved
def test_the_demonstration_examples_record_one_motion():
    """The pose and position files are the arm's forward kinematics of the configuration file, to their noise."""
    pose = read_demonstration(DATA / "demo-pose.csv")
    position = read_demonstration(DATA / "demo-position.csv")
    config = read_demonstration(DATA / "demo-configurations.csv", names=ARM.config_names)
    assert (pose.content, position.content, config.content) == ("pose", "position", "configuration")
    assert len(pose.t) == len(position.t) == len(config.t) == 61
    np.testing.assert_array_equal(pose.position, position.position)
    assert config.configuration is not None and pose.position is not None
    tip = dq_translation(ARM.evaluate("fk_dq", config.configuration))
    assert np.max(np.abs(pose.position - tip)) < 5e-4  # 0.1 mm noise per axis: 5 sigma
    assert np.max(np.abs(pose.t - config.t)) <= 0.002 + 1e-6  # time-stamp jitter


def test_a_configuration_file_is_tracked_along_the_interpolated_path(tmp_path):
    """The reference at 100 Hz from the 30 Hz file matches the minimum-jerk path it samples (closed form)."""
    source = reference_of(tracking(tmp_path, DATA / "demo-configurations.csv", task="position", hold=0.0))
    t, Q, _ = minimum_jerk_path(np.array(WAYPOINTS), 1.0, 100.0)
    assert source.reference.t.shape == t.shape and source.reference.dt == pytest.approx(0.01)
    np.testing.assert_allclose(source.reference.value, ARM.evaluate("fk_position", Q), atol=2e-4)
    np.testing.assert_allclose(source.start, WAYPOINTS[0])


@pytest.mark.parametrize(
    "file, params",
    [
        ("demo-pose.csv", {"task": "pose"}),
        ("demo-pose.csv", {"task": "pose", "dmp": {"variant": "cartesian", "basis": 20}}),
        ("demo-position.csv", {"task": "position"}),
        ("demo-position.csv", {"task": "position", "dmp": {"variant": "position", "basis": 20}}),
        ("demo-configurations.csv", {"task": "pose", "dmp": {"variant": "dual-quaternion", "basis": 20}}),
    ],
)
def test_each_demonstration_file_is_tracked(tmp_path, file, params):
    result, _ = solve(str(tracking(tmp_path, DATA / file, **params)), figures=False)
    assert result.succeeded, result.notes
    if "dmp" not in params:  # tracked as recorded: the reference passes through the file's first sample
        first = read_demonstration(DATA / file).position
        assert first is not None
        np.testing.assert_allclose(
            reference_of(tracking(tmp_path, DATA / file, **params)).reference.position[0], first[0]
        )


def test_the_example_problem_files_solve(tmp_path):
    for name in ("track-my-demo", "dmp-my-demo"):
        assert main(["solve", str(EXAMPLES / f"{name}.yaml"), "--out", str(tmp_path), "--no-figures"]) == EXIT_OK


@pytest.mark.parametrize("file", ["demo-pose.csv", "demo-configurations.csv"])
def test_the_dmp_kind_learns_a_demonstration_file(tmp_path, file):
    data = {"source": "csv", "params": {"file": str(DATA / file)}}
    problem = shipped("dmp-my-demo", tmp_path, data, baselines=[])
    result, _ = solve(str(problem), figures=False)
    assert result.succeeded and result.metrics["demonstration samples"] == 61


def test_the_configurations_targets_and_markers_examples_solve(tmp_path):
    fk = shipped("cc-two-section-fk", tmp_path, {"source": "csv", "params": {"file": str(DATA / "configurations.csv")}})
    assert solve(str(fk), figures=False)[0].succeeded
    ik = shipped("cc-ik-pose", tmp_path, {"source": "csv", "params": {"file": str(DATA / "targets.csv")}}, baselines=[])
    result, _ = solve(str(ik), figures=False)
    assert result.succeeded and len(result.status) == 10
    assert len(read_marker_csv(DATA / "markers.csv")) == 8
    ph = shipped(
        "cbha-ph-shape", tmp_path, {"source": "csv", "params": {"file": str(DATA / "markers.csv")}}, baselines=[]
    )
    assert solve(str(ph), figures=False)[0].succeeded


def test_the_recording_examples_are_read_and_the_motive_one_calibrates(tmp_path):
    assert len(read_motive_csv(DATA / "motive.csv", FrameOptions(up="y"))) == 12
    spec = yaml.safe_load((PROBLEMS / "trunk-calibrate-motive.yaml").read_text())
    spec["data"]["params"]["file"] = str(DATA / "motive.csv")
    spec["options"]["holdout"] = {"method": "kfold", "folds": 3}
    result, _ = solve(str(write_problem(tmp_path, spec, "trunk-calibrate-motive")), figures=False)
    assert result.succeeded, result.notes


def assert_same_disks(recording, motive) -> None:
    """The three disks of ``recording`` where the Motive export has them: positions to its 1e-6 mm rounding
    (C3D stores float32: 0.1 micrometre), orientations to rounding."""
    assert sorted(recording.bodies) == sorted(motive.bodies) == ["disk1", "disk2", "disk3"]
    for name, body in motive.bodies.items():
        np.testing.assert_allclose(recording.bodies[name].positions, body.positions, atol=1e-7)
        agreement = np.abs(np.sum(recording.bodies[name].quaternions * body.quaternions, axis=1))
        np.testing.assert_allclose(agreement, 1.0, atol=1e-12)


@pytest.mark.parametrize("reader", ["c3d", "rosbag"])
def test_the_c3d_and_bag_examples_hold_the_motive_examples_frames(reader):
    """Three formats written independently (Motive text, C3D floats, ROS messages) read back as one recording."""
    pytest.importorskip("ezc3d" if reader == "c3d" else "rosbags")
    from optikin.data.readers.c3d import read_c3d
    from optikin.data.readers.rosbag import read_rosbag

    y_up = FrameOptions(up="y")
    motive = read_motive_csv(DATA / "motive.csv", y_up)
    read = read_c3d(DATA / "trunk.c3d", y_up, "mm") if reader == "c3d" else read_rosbag(DATA / "trunk_bag", y_up, "mm")
    assert len(read) == len(motive) == 12
    np.testing.assert_allclose(read.time, motive.time, atol=1e-9)
    assert_same_disks(read, motive)


def test_every_example_file_is_listed_in_the_examples_readme():
    listed = (EXAMPLES / "README.md").read_text()
    for path in DATA.iterdir():
        assert f"`data/{path.name}" in listed, path.name


# ------------------------------------------------------------------------------ one key: file
def test_no_shipped_or_example_problem_names_its_data_file_path():
    for problem in [*PROBLEMS.glob("*.yaml"), *EXAMPLES.glob("*.yaml")]:
        params = (yaml.safe_load(problem.read_text()).get("data") or {}).get("params") or {}
        assert "path" not in params, problem.name


@pytest.mark.parametrize("kind", ["dmp", "tracking", "recordings"])
def test_the_former_key_path_still_reads_the_file_with_a_warning(tmp_path, kind):
    if kind == "recordings":
        spec = yaml.safe_load((PROBLEMS / "trunk-calibrate-motive.yaml").read_text())
        spec["data"]["params"] = {"path": str(DATA / "motive.csv"), "frame": {"up": "y"}}
        problem = write_problem(tmp_path, spec, "trunk-calibrate-motive")
    elif kind == "dmp":
        problem = shipped("dmp-my-demo", tmp_path, {"source": "csv", "params": {"path": str(DATA / "demo-pose.csv")}})
    else:
        problem = tracking(tmp_path, DATA / "demo-pose.csv")
        spec = yaml.safe_load(problem.read_text())
        spec["data"]["params"]["path"] = spec["data"]["params"].pop("file")
        problem.write_text(yaml.safe_dump(spec))
    _, ctx = prepare(str(problem))
    assert Path(ctx.data_params.file).name in ("motive.csv", "demo-pose.csv")
    with pytest.warns(FutureWarning, match=r"data\.params\.path is deprecated: .*data\.params\.file") as caught:
        loaded = ctx.load_data()
    (warning,) = [w for w in caught if w.category is FutureWarning]
    line = problem.read_text().splitlines()[warning.lineno - 1]
    assert warning.filename == str(problem) and re.search(r"\bpath:", line), line
    rows = {
        "recordings": lambda: len(loaded),
        "dmp": lambda: len(loaded.t),
        "tracking": lambda: len(loaded.reference.t),
    }
    assert rows[kind]() > 0


def test_file_and_path_together_are_refused(tmp_path):
    both = {"file": str(DATA / "demo-pose.csv"), "path": str(DATA / "demo-pose.csv")}
    problem = shipped("dmp-my-demo", tmp_path, {"source": "csv", "params": both})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SpecError, match="give the file once, as file") as info:
            prepare(str(problem))
    assert info.value.field == "data.params"


def test_a_relative_file_is_read_from_the_problem_files_folder(tmp_path, monkeypatch):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "demo.csv").write_text((DATA / "demo-position.csv").read_text())
    problem = tracking(tmp_path / "in", "demo.csv", task="position")
    monkeypatch.chdir(tmp_path)
    assert reference_of(problem).reference.task == "position"


# ------------------------------------------------------------------------------ bad files: exit 2, file, row, column
def pose_rows() -> list[str]:
    return (DATA / "demo-pose.csv").read_text().splitlines()[1:]


def edited(rows: list[str], row: int, column: int, value: str) -> list[str]:
    cells = rows[row].split(",")
    cells[column] = value
    return [*rows[:row], ",".join(cells), *rows[row + 1 :]]


def shifted_times(rows: list[str], row: int, by: float) -> list[str]:
    out = []
    for i, line in enumerate(rows):
        t, rest = line.split(",", 1)
        out.append(f"{float(t) + (by if i >= row else 0.0):.6f},{rest}")
    return out


def scaled(rows: list[str], columns: slice, factor: float) -> list[str]:
    out = []
    for line in rows:
        cells = line.split(",")
        cells[columns] = [f"{float(v) * factor:.6f}" for v in cells[columns]]
        out.append(",".join(cells))
    return out


def without(rows: list[str], column: int) -> list[str]:
    return [",".join(c for j, c in enumerate(line.split(",")) if j != column) for line in rows]


BAD_FILES = {
    "nan": (POSE_HEADER, lambda r: edited(r, 17, 2, "nan"), r"sample 17: y: nan is not a finite number \(line 19\)"),
    "decimal comma": (POSE_HEADER, lambda r: edited(r, 4, 5, "0,9"), r"sample 4: qz: 9 cells, the header has 8 names"),
    "short row": (POSE_HEADER, lambda r: [*r[:30], r[30].rsplit(",", 1)[0], *r[31:]], r"sample 30: qz: a missing cell"),
    "time backwards": (POSE_HEADER, lambda r: edited(r, 9, 0, "0.2"), r"sample 9: t: times must increase strictly"),
    "missing column": ("t,x,y,qw,qx,qy,qz", lambda r: without(r, 3), r"z: missing column\(s\) z \(a pose file"),
    "gap": (POSE_HEADER, lambda r: shifted_times(r, 40, 0.5), r"sample 40: t: 0\.5\d* s since the previous row"),
    "milliseconds": (POSE_HEADER, lambda r: scaled(r, slice(0, 1), 1000.0), r"sample 60: t: .* \(are the times in ms"),
    "millimetres": (
        POSE_HEADER,
        lambda r: scaled(r, slice(1, 4), 1000.0),
        r"sample 0: x: coordinate 165\.133 m is beyond 10 m.*values look like millimetres: set data\.params\.units: mm",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_bad_demonstration_file_exits_2_naming_file_row_and_column(tmp_path, capsys, case):
    header, edit, message = BAD_FILES[case]
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([header, *edit(pose_rows())]) + "\n")
    assert (
        main(["solve", str(tracking(tmp_path, bad)), "--out", str(tmp_path / "out"), "--no-figures"]) == EXIT_BAD_INPUT
    )
    err = capsys.readouterr().err
    assert f"{bad}: " in err and "Traceback" not in err
    assert any(re.search(message, line) for line in err.splitlines()), err
    assert not (tmp_path / "out").exists()


def test_a_position_file_cannot_be_tracked_as_poses_or_learned_by_the_dmp_kind(tmp_path, capsys):
    problem = tracking(tmp_path, DATA / "demo-position.csv", task="pose")
    assert main(["solve", str(problem), "--out", str(tmp_path / "out")]) == EXIT_BAD_INPUT
    assert "data.params.task: " in capsys.readouterr().err
    dmp = shipped("dmp-my-demo", tmp_path, {"source": "csv", "params": {"file": str(DATA / "demo-position.csv")}})
    with pytest.raises(SpecError, match="tip positions only") as info:
        solve(str(dmp), figures=False)
    assert info.value.field == "data.params.content"


@pytest.mark.slow
def test_the_command_line_prints_one_line_for_a_bad_file(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([POSE_HEADER, *edited(pose_rows(), 17, 2, "nan")]) + "\n")
    run = subprocess.run(
        [sys.executable, "-m", "optikin.cli", "solve", str(tracking(tmp_path, bad)), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == EXIT_BAD_INPUT
    assert run.stderr.startswith(f"optikin: error: {bad}: sample 17: y: nan is not a finite number"), run.stderr


# ------------------------------------------------------------------------------ interpolation, units, content
def circle_file(path: Path, rate: float, unit: float = 1.0) -> Path:
    """A pose file at ``rate`` Hz over 1 s: the tip on a 2 cm circle about (0.1, 0, 0.3) m, turning about z
    at 1 rad/s (positions written in metres times ``1 / unit``)."""
    t = np.arange(int(rate) + 1) / rate
    angle = 0.5 * t
    rows = [
        [ti, (0.1 + 0.02 * np.cos(ti)) / unit, 0.02 * np.sin(ti) / unit, 0.3 / unit, np.cos(a), 0.0, 0.0, np.sin(a)]
        for ti, a in zip(t, angle)
    ]
    path.write_text(POSE_HEADER + "\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in rows) + "\n")
    return path


def test_a_pose_file_is_interpolated_on_the_circle_and_the_rotation_it_samples(tmp_path):
    """At 100 Hz from a 50 Hz file: slerp between orientations is exact for a turn about one axis, the spline's
    positions and velocities lie on the circle (closed forms), the pose rate is the dual quaternion's derivative."""
    file = circle_file(tmp_path / "circle.csv", 50.0)
    pose = reference_of(tracking(tmp_path, file, task="pose", hold=0.0)).reference
    position = reference_of(tracking(tmp_path, file, "circle-position", task="position", hold=0.0)).reference
    t = pose.t
    assert t.shape == (101,) and pose.dt == pytest.approx(0.01)
    circle = np.column_stack([0.1 + 0.02 * np.cos(t), 0.02 * np.sin(t), np.full_like(t, 0.3)])
    speed = np.column_stack([-0.02 * np.sin(t), 0.02 * np.cos(t), 0 * t])
    np.testing.assert_allclose(pose.position, circle, atol=2e-8)
    np.testing.assert_allclose(position.value, circle, atol=2e-8)
    np.testing.assert_allclose(position.rate[1:-1], speed[1:-1], atol=2e-7)  # clamped-free ends: looser there
    turn = np.column_stack([np.cos(t / 2), 0 * t, 0 * t, np.sin(t / 2)])
    np.testing.assert_allclose(pose.orientation, turn, atol=1e-12)
    # d/dt q_r of q_r = (cos t/2, 0, 0, sin t/2), against central differences of the slerped orientations
    np.testing.assert_allclose(
        pose.rate[1:-1, :4], 0.5 * np.column_stack([-turn[:, 3], 0 * t, 0 * t, turn[:, 0]])[1:-1], atol=1e-5
    )


def test_units_and_content_are_read_as_declared(tmp_path):
    metres = reference_of(tracking(tmp_path, circle_file(tmp_path / "m.csv", 50.0), task="position", hold=0.0))
    millimetres = tracking(tmp_path, circle_file(tmp_path / "mm.csv", 50.0, 1e-3), "mm", task="position", hold=0.0)
    spec = yaml.safe_load(millimetres.read_text())
    spec["data"]["params"]["units"] = "mm"
    millimetres.write_text(yaml.safe_dump(spec))
    np.testing.assert_allclose(reference_of(millimetres).reference.value, metres.reference.value, atol=1e-12)
    positions = read_demonstration(DATA / "demo-pose.csv", content="position")
    assert positions.content == "position" and positions.quaternion is None


def test_ik_targets_in_a_y_up_file_are_read_with_frame_up_y(tmp_path):
    from optikin.data.targets import CsvParams, csv_targets
    from optikin.ik.points import MeasuredPoint, PointSet
    from optikin.spec import DataSpec

    header, *rows = (PROBLEMS / "trunk-points.csv").read_text().splitlines()
    y_up = []
    for row in rows:
        xyz = np.array(row.split(","), dtype=float).reshape(-1, 3)
        y_up.append(",".join(repr(float(v)) for v in np.column_stack([xyz[:, 0], xyz[:, 2], -xyz[:, 1]]).ravel()))
    (tmp_path / "y-up.csv").write_text("\n".join([header, *y_up]) + "\n")
    (tmp_path / "z-up.csv").write_text((PROBLEMS / "trunk-points.csv").read_text())
    points = PointSet(tuple(MeasuredPoint(f"disk{k}", section=k) for k in (1, 2, 3)))
    data = DataSpec(source="csv", samples=5)

    def read(file: str, **extra: Any) -> np.ndarray:
        params = CsvParams(file=file, **extra)
        return csv_targets(ARM, data, params, tmp_path / "p.yaml", "points", points).values

    np.testing.assert_allclose(read("y-up.csv", frame={"up": "y"}), read("z-up.csv"), atol=1e-15)
    assert not np.allclose(read("y-up.csv"), read("z-up.csv"))


def test_a_pose_demonstration_in_a_y_up_file_is_read_with_frame_up_y(tmp_path):
    from optikin.algebra import quat_conjugate, quat_from_matrix, quat_multiply
    from optikin.data.demonstrations import CsvParams, read_params_file
    from optikin.data.recording import frame_matrix

    matrix = frame_matrix(FrameOptions(up="y"))
    header, *rows = (DATA / "demo-pose.csv").read_text().splitlines()
    values = np.array([row.split(",") for row in rows], dtype=float)
    position = values[:, 1:4] @ matrix  # A^T p, row-wise
    quaternion = quat_multiply(
        np.broadcast_to(quat_conjugate(quat_from_matrix(matrix)), (len(values), 4)), values[:, 4:]
    )
    y_up = np.column_stack([values[:, 0], position, quaternion])
    (tmp_path / "y-up.csv").write_text(header + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in y_up))
    (tmp_path / "z-up.csv").write_text((DATA / "demo-pose.csv").read_text())
    problem = tmp_path / "p.yaml"
    converted = read_params_file(None, CsvParams(file="y-up.csv", frame={"up": "y"}), problem)
    original = read_params_file(None, CsvParams(file="z-up.csv"), problem)
    np.testing.assert_allclose(converted.position, original.position, atol=1e-12)
    np.testing.assert_allclose(converted.quaternion, original.quaternion, atol=1e-12)


def test_inverse_statics_targets_are_read_in_their_units_and_frame(tmp_path):
    from optikin.data.actuations import TargetCsvParams, csv_targets
    from optikin.spec import DataSpec

    header, *rows = (DATA / "targets.csv").read_text().splitlines()
    names = header.split(",")
    xyz = [names.index(c) for c in "xyz"]
    y_up_mm = []
    for row in rows:
        cells = row.split(",")
        x, y, z = (float(cells[k]) * 1e3 for k in xyz)
        for k, v in zip(xyz, (x, z, -y)):
            cells[k] = repr(v)
        y_up_mm.append(",".join(cells))
    (tmp_path / "y-up-mm.csv").write_text("\n".join([header, *y_up_mm]) + "\n")
    (tmp_path / "m.csv").write_text((DATA / "targets.csv").read_text())
    data, problem = DataSpec(source="target_csv"), tmp_path / "p.yaml"
    converted = csv_targets(ARM, data, TargetCsvParams(file="y-up-mm.csv", units="mm", frame={"up": "y"}), problem)
    original = csv_targets(ARM, data, TargetCsvParams(file="m.csv"), problem)
    assert converted.targets is not None and original.targets is not None
    np.testing.assert_allclose(converted.targets, original.targets, atol=1e-12)
