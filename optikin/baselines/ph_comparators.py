"""The comparators of the PH tube lengths in seed 002 Tables II-III: Newton-Raphson IK and the hybrid networks.

Seed 002 (section V.B) measures its PH tube lengths against the Newton-Raphson
inverse kinematics of the CBHA (its ref. [11]; Table II: 6.4 / 3.9 / 6.2 mm mean
errors; Table III: 233 ms per sample) and against the hybrid approach of seed 004
(Table III: 12 ms per sample). Each comparator here returns, per recorded posture,
the whole tube lengths ``L1, L2, L3`` (the legs summed over both sections, as the
recording's potentiometers), the seconds it took and a status; a posture that is
not ``ok`` is counted and gets no lengths, never dropped.

``newton-raphson``
    Newton's method (``newton`` preset, CasADi rootfinder) on a square system of
    48 rows in the 48 platform variables (:mod:`optikin.ik.formulation`,
    target ``sections``, ``elongation: affine``): the end positions of both sections,
    the inputs of seed 004's inverse model (section V: the tip and the end of the
    first section), measured relative to the base rigid body by the tip rigid body
    and the intermediate marker on the vertebra that ends section 1 (vertebra 9; which
    vertebra each marker is on is the data's ``intermediate`` parameter, of the
    synthetic source or of a CSV recording), plus 42
    rows of seed 004's elongation distribution in its affine reading
    (:mod:`optikin.ik.cbha`), which keeps every leg within Table I whenever
    the tube lengths are within their ranges.
``newton-raphson-pose``
    The same Newton on the data the PH rows use: the tip pose relative to the base
    (6 rows: position, and ``2 L vec(q*^-1 q)`` with ``L`` the arm's reach) plus the
    same 42 distribution rows. The like-for-like comparison, and an ill-posed one (below).
``hybrid``, ``hybrid-coupled``
    :func:`optikin.baselines.hybrid_tubes.hybrid_tube_lengths`: the shipped networks
    NN1-NN4 from the tip position relative to the base, trained on seed 004's Fig. 7
    database (``cbha-nn-ikm``: independent platforms, the seed's) or on the database
    whose sections bend as one (``cbha-nn-ikm-coupled``). Each uses the arm its networks were
    trained on (Table I unscaled, :func:`networks_arm`), whatever the problem's arm: on a
    recording of another arm (``cbha-ph-ik-cosserat``, 1.8 times the size) they extrapolate,
    and the fairness manifest labels them "another arm".

Both Newton rows solve the postures in order, each from the last solution that was
``ok``; before the first, from the straight configuration (``newton-raphson``), or from
the ``lm`` preset's least-squares solution from there (``newton-raphson-pose``: at the
straight configuration its Jacobian is singular, no twist to first order). A
posture's time is the Newton solve (and that first least-squares solve) plus one
call of ``arm.tube_lengths``.

Why the section ends (measured on the 100 postures of ``cbha-ph-ik``): with the tip
pose the 48 x 48 Jacobian has condition numbers of 770 (median) to 2.3e4 over the
noise-free postures: the twist about the backbone hardly depends on the tubes. The
0.3 mm marker noise makes the tip rigid body's orientation err by 6-8 mrad rms per
axis, which moves the root's section tube lengths by 10 mm (median, 60 mm at the
90th percentile): started from the true configuration, 54 of 100 roots leave Table I.
Dropping the twist row (tip position and direction, 47 rows) leaves one direction of
the tubes that the pose does not see: Newton's closest-to-previous choice drifts along
it (only 47 of 100 noise-free postures ``ok``). With the section ends the condition
number is 446-473, the linearised tube-length error from the marker noise at most
1 mm (standard deviation). The affine reading of the distribution rather than the
mid-range one (``distributed``) because it is the synthetic recording's rule:
noise-free postures then give the recorded tube lengths to 1.5e-12 m (mid-range:
0.16 mm mean error); with noise both give 0.4-0.6 mm. So ``newton-raphson`` answers
from a different, better-conditioned measurement than the PH rows (one intermediate
marker, no tip orientation) and with the recording's own distribution: its small
errors are partly by construction.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from optikin.algebra import dq_from_rotation_translation, quat_conjugate, quat_multiply, quat_rotate
from optikin.arms.cbha import CBHAArm, CBHAGeometry
from optikin.codegen import cache_dir
from optikin.data.markers import MarkerRecording
from optikin.data.targets import reach_bound
from optikin.errors import InputDataError
from optikin.ik.formulation import Formulation, build_problem, rest_configuration
from optikin.baselines.hybrid_tubes import SHIPPED_STORES, hybrid_tube_lengths, load_hybrid_models
from optikin.baselines.nn_database import DatabaseSpec, build_database
from optikin.baselines.nn_store import read_metadata
from optikin.solvers import build_preset
from optikin.solvers.nonlinear import LeastSquaresProblem, NonlinearAdapter
from optikin.solvers.base import Solution
from optikin.status import Status

NEWTON_RAPHSON = "newton-raphson"
NEWTON_RAPHSON_POSE = "newton-raphson-pose"
HYBRID = "hybrid"
NR_TARGETS = {NEWTON_RAPHSON: "sections", NEWTON_RAPHSON_POSE: "pose"}
"""The Newton-Raphson comparators and the target each solves for (module docstring)."""
HYBRID_STORES = {HYBRID: SHIPPED_STORES["cbha-nn-ikm"], "hybrid-coupled": SHIPPED_STORES["cbha-nn-ikm-coupled"]}
"""The hybrid comparators and the shipped networks each uses (module docstring)."""
COMPARATORS = (*NR_TARGETS, *HYBRID_STORES)
NR_PRESET = "newton"
"""The Newton-Raphson comparators' solver preset: CasADi rootfinder on the square system."""
NR_FIRST_START = "lm"
"""The least-squares preset that finds ``newton-raphson-pose``'s start until a posture is ``ok``."""
NR_TOLERANCE = 1e-9
"""``||r||`` [m] at which a recorded posture counts as reached by a Newton-Raphson comparator."""
NR_ELONGATION = "affine"
"""The comparators' reading of seed 004's elongation distribution (:mod:`optikin.ik.cbha`)."""


class ComparatorRun(NamedTuple):
    """Per posture: tube lengths ``(N, 3)`` [m] (NaN unless ``ok``), seconds, status and message."""

    lengths: np.ndarray
    seconds: np.ndarray
    status: list[str]
    messages: list[str]


def section_end_markers(arm: CBHAArm, recording: MarkerRecording, source: str) -> list[int]:
    """Indices of the intermediate markers on the vertebrae that end every section but the last
    (the recording's ``marker_vertebrae``: the data's ``intermediate`` parameter)."""
    wanted = [end + 1 for end in arm.section_end_vertebrae[:-1]]  # 1-based, as the layout
    layout = recording.marker_vertebrae
    if not layout:
        raise InputDataError(
            f"newton-raphson needs a marker on vertebrae {wanted} (the section ends); the recording "
            f"does not say which vertebrae its {recording.markers.shape[1]} markers are on: give "
            "data.params.intermediate",
            source=source,
            field="data.params.intermediate",
        )
    if not set(wanted) <= set(layout):
        raise InputDataError(
            f"newton-raphson needs a marker on vertebrae {wanted} (the section ends); the "
            f"recording's markers are on vertebrae {list(layout)}",
            source=source,
            field="data.params.intermediate",
        )
    return [layout.index(v) for v in wanted]


def relative_section_ends(recording: MarkerRecording, markers: list[int]) -> np.ndarray:
    """``(N, 3 (len(markers) + 1))``: the ``markers`` then the tip rigid body, positions in the base rigid
    body's frame."""
    to_base = quat_conjugate(recording.base_orientation)
    points = np.concatenate([recording.markers[:, markers], recording.tip_position[:, None]], axis=1)
    relative = quat_rotate(to_base[:, None], points - recording.base_position[:, None], check=False)
    return relative.reshape(len(recording), -1)


def relative_tip_poses(recording: MarkerRecording) -> np.ndarray:
    """Unit dual quaternions ``(N, 8)`` of the tip rigid bodies in the base rigid bodies' frames."""
    to_base = quat_conjugate(recording.base_orientation)
    rotation = quat_multiply(to_base, recording.tip_orientation)
    translation = quat_rotate(to_base, recording.tip_position - recording.base_position, check=False)
    return dq_from_rotation_translation(rotation, translation, check=False)


def newton_raphson_problem(arm: CBHAArm, target: str = "sections") -> LeastSquaresProblem:
    """A comparator's square system: ``target`` (``sections`` or ``pose``) and the affine distribution."""
    formulation = Formulation(
        target=target,
        redundancy="previous",
        rest=rest_configuration(arm),
        weights=1.0 / (arm.upper - arm.lower),
        tolerance=NR_TOLERANCE,
        orientation_length=reach_bound(arm),
        elongation=NR_ELONGATION,
    )
    problem = build_problem(arm, formulation)
    assert isinstance(problem, LeastSquaresProblem), "a sections or pose target builds one problem"
    return problem


def newton_raphson_targets(arm: CBHAArm, recording: MarkerRecording, target: str, source: str) -> np.ndarray:
    """The measurements a comparator solves for, one row per posture (module docstring); ``source`` names the
    data in errors."""
    if target == "pose":
        return relative_tip_poses(recording)
    return relative_section_ends(recording, section_end_markers(arm, recording, source))


def newton_raphson_step(
    arm: CBHAArm, newton: NonlinearAdapter, problem: LeastSquaresProblem, start: np.ndarray, target: np.ndarray
) -> tuple[Solution, np.ndarray, float]:
    """One posture: the Newton report, the whole tube lengths ``(3,)`` (NaN unless ``ok``) and the seconds
    of the solve plus the tube lengths."""
    report = newton.solve(problem, start, target)
    if report.status != Status.OK:
        return report, np.full(3, np.nan), report.seconds
    tic = time.perf_counter()
    lengths = np.asarray(arm.tube_lengths(report.x)).sum(axis=0)  # (section, tube) -> whole tubes
    return report, lengths, report.seconds + time.perf_counter() - tic


def newton_raphson_tube_lengths(
    arm: CBHAArm, recording: MarkerRecording, target: str, source: str = ""
) -> ComparatorRun:
    """A Newton-Raphson comparator along the recording (module docstring)."""
    targets = newton_raphson_targets(arm, recording, target, source)
    problem, newton = newton_raphson_problem(arm, target), build_preset(NR_PRESET)
    first = build_preset(NR_FIRST_START) if target == "pose" else None
    rest = rest_configuration(arm)
    newton.solve(problem, rest, targets[0])  # build the rootfinder before timing
    lengths, seconds = np.full((len(targets), 3), np.nan), np.zeros(len(targets))
    status, messages, start = [], [], None
    for i, measured in enumerate(targets):
        extra = 0.0
        if start is None and first is not None:
            found = first.solve(problem, rest, measured)
            begin, extra = found.x, found.seconds
        else:
            begin = rest if start is None else start
        report, lengths[i], seconds[i] = newton_raphson_step(arm, newton, problem, begin, measured)
        seconds[i] += extra
        status.append(report.status)
        messages.append(report.message)
        if report.status == Status.OK:
            start = report.x
    return ComparatorRun(lengths, seconds, status, messages)


def networks_arm(store: Path) -> CBHAArm:
    """The CBHA whose database the networks of ``store`` were trained on (the geometry of its metadata)."""
    return CBHAArm(read_metadata(store)["geometry"])


def training_tips(store: Path) -> np.ndarray:
    """``(n, 3)`` tips [m] of the training split the networks of ``store`` learnt from.

    Their database is redrawn from the store's metadata (30-50 s for the shipped ones) once,
    then read from the per-user cache (:func:`optikin.codegen.cache_dir`), keyed by the
    store's checksum and database settings.
    """
    metadata = read_metadata(store)
    key = hashlib.sha256(json.dumps([metadata["sha256"], metadata["database"]], sort_keys=True).encode()).hexdigest()
    cached = cache_dir() / f"training-tips-{key[:32]}.npy"
    if cached.is_file():
        return np.load(cached, allow_pickle=False)
    database = build_database(CBHAGeometry(**metadata["geometry"]), DatabaseSpec(**metadata["database"]))
    tips = database.tip[database.train]
    partial = cached.with_suffix(f".{os.getpid()}.tmp.npy")
    np.save(partial, tips, allow_pickle=False)
    os.replace(partial, cached)
    return tips


def hybrid_inputs(recording: MarkerRecording) -> np.ndarray:
    """``(N, 3)`` the hybrid networks' inputs: the tip positions relative to the base."""
    return relative_section_ends(recording, [])


def hybrid_run(store: Path, recording: MarkerRecording) -> ComparatorRun:
    """The hybrid networks of ``store`` from the tip position relative to the base, on their own arm
    (:func:`networks_arm`, module docstring)."""
    arm = networks_arm(store)
    lengths, seconds = hybrid_tube_lengths(arm, hybrid_inputs(recording), load_hybrid_models(arm, store))
    finite = np.all(np.isfinite(lengths), axis=1)
    return ComparatorRun(
        np.where(finite[:, None], lengths, np.nan),
        seconds,
        [Status.OK if f else Status.FAILED for f in finite],
        ["" if f else "non-finite prediction" for f in finite],
    )


def run_comparator(arm: CBHAArm, name: str, recording: MarkerRecording, source: str = "") -> ComparatorRun:
    """The comparator ``name`` (one of :data:`COMPARATORS`) on the recording of a CBHA.

    Parameters
    ----------
    arm:
        The CBHA the Newton-Raphson rows solve on; the hybrid rows use their networks' own
        (:func:`networks_arm`), which the fairness manifest labels when it is another.
    name:
        One of :data:`COMPARATORS`.
    recording:
        The postures, in order (the Newton-Raphson rows warm-start along them).
    source:
        Names the data in errors (e.g. ``"problem.yaml: data"``).
    """
    if name in HYBRID_STORES:
        return hybrid_run(HYBRID_STORES[name], recording)
    return newton_raphson_tube_lengths(arm, recording, NR_TARGETS[name], source)
