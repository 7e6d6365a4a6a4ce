"""The backbone of a two-section arm as two PH quintics joined with C1 continuity (Singh et al. 2018, Fig. 2).

Seed 002 (section III.A, eqs. 15-18) concatenates PH curves when one curve cannot
follow an arm of several sections: ``r_1`` from the base ``A`` to the end of section 1
``B``, ``r_2`` from ``B`` to the tip ``C``, sharing the point and the derivative at
``B``: ``r_1'(1) = r_2'(0) = d_m``. The CBHA carries a rigid body at the head of each
section (seed 004 section VI.A); here the joint pose ``(B, t_m)`` is that of the three
tube markers at the end of section 1 (:func:`joint_poses`: their least-squares rigid fit,
as motion-capture software does, the position their centroid, which is on the backbone),
and each section is the minimum-energy PH quintic of its end poses (given speeds).

Speeds: section ``k``'s length ``L_k`` is estimated from its end poses (the circular
arc, :func:`optikin.curves.arc_length_estimate`, as the single curve's ``length: arc``);
the derivative at the base is ``L_1 t_0``, at the tip ``L_2 t_1``, and at the joint both
sections share ``(L_1 + L_2) / 2 t_m`` (with equal sections, each section's own length:
the seed's setting of a speed equal to the length).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optikin.algebra import quat_from_matrix, quat_rotate
from optikin.arms.cbha import LEG_DIRECTIONS
from optikin.curves import ShapeData, arc_length_estimate
from optikin.curves.chain import c1_links, check_joints
from optikin.data.cosserat_markers import CosseratRecording
from optikin.data.markers import MarkerRecording, kabsch_rotation
from optikin.errors import InputDataError
from optikin.problems.ph_shared import MethodRun, distances_to_curves

SECTIONS = ("section 1", "section 2")
"""The links of the chain, from the base."""
JOINT_VERTEBRA = 9
"""The CBHA vertebra model's vertebra that ends section 1 (8 platforms per section, seed 004)."""


@dataclass
class C1Chain:
    """The C1 chain of every posture with every method.

    Attributes
    ----------
    joint_position, joint_orientation:
        The measured pose at the end of section 1 ``(N, 3)`` [m], ``(N, 4)`` (z along the backbone).
    joint_marker:
        Index of the backbone marker at the joint (the centroid of the same tube markers).
    links:
        Per section, the end data of each posture.
    runs:
        Per section, every method (the solver first), by preset name.
    """

    joint_position: np.ndarray
    joint_orientation: np.ndarray
    joint_marker: int
    links: dict[str, list[ShapeData]]
    runs: dict[str, dict[str, MethodRun]]

    def distances(self, method: str, points: np.ndarray) -> np.ndarray:
        """Distance of each point ``(N, K, 3)`` to the chain of ``method`` (the nearer section): ``(N, K)`` [m]."""
        return np.minimum(*(distances_to_curves(self.runs[name][method].curves, points) for name in SECTIONS))

    def points(self, method: str, t: np.ndarray) -> np.ndarray:
        """Points of both sections at parameters ``t`` ``(T,)``: ``(N, 2, T, 3)`` [m]."""
        return np.stack([self.runs[name][method].curves.point(t) for name in SECTIONS], axis=1)


def joint_poses(recording: MarkerRecording, source: str) -> tuple[np.ndarray, np.ndarray, int]:
    """The pose at the end of section 1 of every posture, from the three tube markers there.

    Parameters
    ----------
    recording:
        A recording with tube markers (:class:`~optikin.data.cosserat_markers.CosseratRecording`)
        and a station at the end of section 1 (``marker_vertebrae`` holding vertebra 9).
    source:
        Names the data in errors.

    Returns
    -------
    position, orientation, marker:
        ``(N, 3)`` [m], unit quaternions ``(N, 4)`` (z along the backbone, x the reference of
        the tube angles), and the index of the backbone marker at that station.

    Raises
    ------
    InputDataError
        The recording has no tube markers, or none at the end of section 1.
    """
    if not isinstance(recording, CosseratRecording):
        raise InputDataError(
            "a C1 joint needs the rigid body at the end of section 1: tube markers there (source cosserat)",
            source=source,
            field="c1_joint",
        )
    if JOINT_VERTEBRA not in recording.marker_vertebrae:
        raise InputDataError(
            f"no marker station at the end of section 1 (stations at vertebrae {recording.marker_vertebrae}; "
            "data.params.intermediate must hold 1.0)",
            source=source,
            field="c1_joint",
        )
    marker = recording.marker_vertebrae.index(JOINT_VERTEBRA)
    station = marker + 1  # tube-marker stations: base, the intermediate ones, tip
    local = recording.tube_marker_offsets[station] * LEG_DIRECTIONS  # (tube, xyz), centred
    R, p = kabsch_rotation(local, recording.tube_markers[:, :, station, :])
    return p, quat_from_matrix(R), marker


def c1_chain_data(
    base: tuple[np.ndarray, np.ndarray],
    joint: tuple[np.ndarray, np.ndarray],
    tip: tuple[np.ndarray, np.ndarray],
    source: str,
) -> dict[str, list[ShapeData]]:
    """End data of both sections of every posture, joined with C1 continuity (module docstring).

    Parameters
    ----------
    base, joint, tip:
        Positions ``(N, 3)`` [m] and unit tangents ``(N, 3)`` at the base, the end of section 1
        and the tip.
    source:
        Names the data in errors.

    Raises
    ------
    InputDataError
        Naming the posture and field of unusable end data (checked like a single curve's, and the
        joint for C1, seed 002 eqs. 15-18).
    """
    (p0, t0), (pm, tm), (p1, t1) = base, joint, tip
    lengths = [arc_length_estimate(p0, t0, pm, tm), arc_length_estimate(pm, tm, p1, t1)]
    links: dict[str, list[ShapeData]] = {name: [] for name in SECTIONS}
    for i in range(len(p0)):
        L1 = max(float(lengths[0][i]), float(np.linalg.norm(pm[i] - p0[i])) * (1 + 1e-9))
        L2 = max(float(lengths[1][i]), float(np.linalg.norm(p1[i] - pm[i])) * (1 + 1e-9))
        pair = c1_links(
            np.stack([p0[i], pm[i], p1[i]]),
            np.stack([t0[i], tm[i], t1[i]]),
            np.array([L1, 0.5 * (L1 + L2), L2]),
            source=f"{source}: sample {i}",
        )
        check_joints(pair, "C1", source=f"{source}: sample {i}")
        for name, data in zip(SECTIONS, pair):
            links[name].append(data)
    return links


def joint_tangents(orientation: np.ndarray) -> np.ndarray:
    """The z axes ``(N, 3)`` of unit quaternions ``(N, 4)``."""
    return quat_rotate(orientation, np.array([0.0, 0.0, 1.0]), check=False)
