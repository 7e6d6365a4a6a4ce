"""The calibrated arm as a problem-file ``arm:`` section, the calibration facts that go with it, and the
recording re-expressed for the next steps of a workflow (inverse kinematics, PH backbones).

:func:`arm_section` gives ``{"type": "constant_curvature", "params": {...}}`` with the
estimated section lengths (an extensible arm: the median lengths, with the
``length_range`` covering every posture's length), ready for the ``arm:`` field
of other problem files. :func:`write_arm_file` writes it as YAML under the key
``arm``, next to a ``calibration`` mapping holding what an arm section cannot carry:
the base pose in the recording frame, the marker offsets, the standard deviations
and the held-out error. :func:`write_folds_csv` writes the held-out test's fold of every posture.

:func:`write_points_csv` writes the measured points of every marker in optikin's frame (the
recording after its source's ``frame:`` and ``units:``), with the recording row of each posture,
in the columns of the point targets of the ``ik`` kind (:mod:`optikin.ik.points`), to be read with
the calibrated base pose as ``data.params.base``.
:func:`write_target_csv` writes the measured points of one marker in the calibrated
arm's base frame, in the columns of the ``csv`` source of family ``targets``
(:mod:`optikin.data.targets`: ``t, x, y, z``): tip-position targets of the ``ik`` kind
on the calibrated arm. :func:`marker_recording` gives, for the kept postures, the end
poses of the calibrated arm (the base pose, and the tip pose of each posture's fitted
configuration) with the measured intermediate disks, the
:class:`~optikin.data.markers.MarkerRecording` of the ``ph_shape`` kind
(:func:`optikin.data.markers.write_marker_csv` writes it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from optikin.algebra import matrix_from_quat, quat_from_matrix
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.calibration.calibrate import Calibration, HeldOut
from optikin.data.markers import MarkerRecording
from optikin.data.recording import Recording


def arm_section(calibration: Calibration, nominal: ConstantCurvatureArm) -> dict[str, Any]:
    """The ``arm:`` section of the calibrated arm.

    Parameters
    ----------
    calibration : Calibration
        The calibration.
    nominal : ConstantCurvatureArm
        The arm the calibration started from (its bound on ``theta`` is kept). The lengths of a
        calibrated arm are fixed (``length_range: [1, 1]``); an extensible arm's range covers every
        posture's fitted length.

    Returns
    -------
    dict
        ``{"type": "constant_curvature", "params": {section_lengths, length_range, theta_max, name}}``.
    """
    lengths = calibration.lengths
    lo, hi = 1.0, 1.0
    if calibration.layout.extensible:
        ranges = calibration.length_ranges / lengths[:, None]
        lo, hi = float(ranges[:, 0].min()), float(ranges[:, 1].max())
    return {
        "type": "constant_curvature",
        "params": {
            "section_lengths": [round(float(v), 7) for v in lengths],
            "length_range": [round(float(lo), 6), round(float(hi), 6)],
            "theta_max": float(nominal.theta_max),
            "name": f"{nominal.name}_calibrated",
        },
    }


def calibration_facts(calibration: Calibration, test: HeldOut | None = None) -> dict[str, Any]:
    """The base pose [m, unit quaternion (w, x, y, z)], marker offsets [m], standard deviations of the geometry,
    the identifiability verdict and the held-out error.

    With a held-out test: ``held_out_largest_marker_error`` (median, p95, max [m] of each posture's largest
    least-squares marker error, every tested posture) and ``noise_level`` [m], the 95th percentile of each
    tested posture's RMS marker error: a posture another run fits within it is within what the calibration
    itself leaves on 95 % of the postures it did not see (the ``fit`` level of kind ``ik``, ``noise: calibrated``).
    """
    names = calibration.names
    std = calibration.fit.std
    facts: dict[str, Any] = {
        "base_position": [round(float(v), 7) for v in calibration.base_position],
        "base_quaternion": [round(float(v), 9) for v in quat_from_matrix(calibration.base_rotation)],
        "marker_offsets": {
            name: [round(float(v), 7) for v in offset]
            for name, offset in zip(calibration.marker_names, calibration.offsets)
        },
        "std": {n: float(f"{s:.3g}") for n, s in zip(names, std) if s > 0 and not n.startswith("map_")},
        "postures_used": int(len(calibration.kept)),
        "postures_rejected": len(calibration.outliers),
        "median_marker_error": float(f"{np.nanmedian(least_squares_errors(calibration)):.4g}"),
    }
    facts["verdict"] = str(calibration.verdict)
    if test is not None:
        headline = test.headline()
        facts["held_out_largest_marker_error"] = {k: float(f"{v:.4g}") for k, v in headline.items()}
        rms = test.posture_rms[test.tested]
        rms = rms[np.isfinite(rms)]
        if len(rms):
            facts["noise_level"] = float(f"{np.percentile(rms, 95):.4g}")
    return facts


def least_squares_errors(calibration: Calibration) -> np.ndarray:
    """``(N, M)`` the least-squares marker errors of every posture with the final geometry [m]."""
    fit = calibration.least_squares if calibration.least_squares is not None else calibration.fit
    return fit.errors


def write_arm_file(path: Path, section: dict[str, Any], facts: dict[str, Any], origin: str) -> None:
    """Write ``{"arm": section, "calibration": facts}`` as YAML to ``path``, with a header naming ``origin``."""
    text = yaml.safe_dump({"arm": section, "calibration": facts}, sort_keys=False)
    header = f"# calibrated arm written by optikin (kind calibrate) from {origin}; lengths in metres\n"
    Path(path).write_text(header + text)


def base_frame_points(calibration: Calibration, points: np.ndarray) -> np.ndarray:
    """Points ``(..., 3)`` [m] of the recording frame in the calibrated base frame: ``R0^T (p - p0)``."""
    return (np.asarray(points, dtype=float) - calibration.base_position) @ calibration.base_rotation


def write_target_csv(path: Path, t: np.ndarray, points: np.ndarray, postures: np.ndarray) -> Path:
    """Write tip-position targets ``points (N, 3)`` [m] at times ``t (N,)`` [s] as columns ``posture, t, x, y, z``
    (``posture``: the row of the recording each target comes from)."""
    lines = ["posture,t,x,y,z"] + [
        ",".join([str(int(i)), *(repr(float(v)) for v in (ti, *p))]) for i, ti, p in zip(postures, t, points)
    ]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def write_points_csv(path: Path, names: list[str], points: np.ndarray, postures: np.ndarray) -> Path:
    """Write measured points ``(N, M, 3)`` [m] named ``names`` as columns ``posture, <name>_x, <name>_y, ...``:
    the point targets of the ``ik`` kind (:mod:`optikin.ik.points`), independent postures (no time column), in
    optikin's frame (z up, metres: the recording after its source's ``frame:`` and ``units:``); ``posture`` is the
    row of the recording each one comes from."""
    n = len(points)
    table = np.asarray(points, dtype=float).reshape(n, -1)
    header = ["posture", *(f"{name}_{a}" for name in names for a in "xyz")]
    lines = [",".join(header)] + [
        ",".join([str(int(i)), *(repr(float(v)) for v in row)]) for i, row in zip(postures, table)
    ]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def write_folds_csv(path: Path, fold: np.ndarray) -> Path:
    """Write the fold of every posture as columns ``posture, fold`` (``-1``: never tested), so that another
    model can be scored on the same split."""
    lines = ["posture,fold"] + [f"{i},{int(f)}" for i, f in enumerate(fold)]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def marker_recording(calibration: Calibration, recording: Recording, intermediate: np.ndarray) -> MarkerRecording:
    """The kept postures as end poses of the calibrated arm and measured intermediate markers (module docstring).

    Parameters
    ----------
    calibration : Calibration
        The calibration.
    recording : Recording
        The recording it was made from (time stamps, markers).
    intermediate : numpy.ndarray
        ``(N, K, 3)`` the points kept as intermediate markers, in the recording frame [m].

    Returns
    -------
    MarkerRecording
        Base pose (constant), tip pose of each kept posture's fitted configuration, in the recording frame.
    """
    kept = calibration.kept
    n = len(kept)
    lengths = calibration.lengths
    arm = ConstantCurvatureArm(tuple(float(v) for v in lengths), (0.5, 2.0), np.pi, "calibrated")
    quat, position = arm.section_frames(calibration.configurations())[-1]
    R0, p0 = calibration.base_rotation, calibration.base_position
    tip_position = p0 + position @ R0.T
    tip_rotation = np.einsum("ij,njk->nik", R0, matrix_from_quat(quat, check=False))
    q0 = quat_from_matrix(R0)
    return MarkerRecording(
        t=np.asarray(recording.time, dtype=float)[kept],
        base_position=np.repeat(p0[None], n, axis=0),
        base_orientation=np.repeat(q0[None], n, axis=0),
        tip_position=tip_position,
        tip_orientation=quat_from_matrix(tip_rotation),
        markers=np.asarray(intermediate, dtype=float)[kept],
        source=f"{recording.source or 'recording'} (end poses of the calibrated arm)",
    )
