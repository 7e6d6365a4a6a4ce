"""Inverse-kinematics targets: tip positions or tip poses, with the configurations that made them.

Every source takes the arm, the problem file's ``data`` section, its path and
the target kind (``position`` or ``pose``) and returns :class:`Targets`.

``random``      forward kinematics of configurations drawn uniformly inside the
                bounds (reachable by construction); ``params.unreachable`` adds
                that many targets placed outside the workspace.
``trajectory``  forward kinematics of the smooth configuration motion of
                :func:`optikin.data.configurations.smooth_trajectory` (same
                params), to be solved in order, warm-started.
``csv``         targets read from a file (``params.file``, relative to the problem
                file) with columns ``x, y, z`` in metres, plus ``qw, qx, qy, qz`` for
                poses and optionally ``t``.

Unreachable targets lie beyond the arm's reach bound (:func:`reach_bound`) by a
factor drawn from ``params.margin`` (default ``[1.1, 1.5]``), in a uniformly random
direction (and, for poses, with a uniformly random orientation).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from optikin.algebra import dq_from_rotation_translation, dq_translation, quat_normalize
from optikin.arms.base import ArmModel
from optikin.arms.constant_curvature import ConstantCurvatureArm
from optikin.data.configurations import _params, read_configuration_csv, smooth_trajectory
from optikin.errors import InputDataError, SpecError
from optikin.registry import Registry
from optikin.spec import DataSpec

TARGET_KINDS = ("position", "pose", "legs")
"""Tip position (3), tip pose as a unit dual quaternion (8), or the leg lengths of a CBHA (48)."""


@dataclass
class Targets:
    """``values`` are ``(N, 3)`` positions, ``(N, 8)`` unit dual quaternions or ``(N, 48)`` CBHA leg lengths.

    ``configurations`` holds the configuration each target was made from (NaN rows when
    unknown), ``reachable`` whether the target is known to be reachable (True), known to be
    outside the workspace (False); ``t`` the sample times of a trajectory (else None).
    """

    kind: str
    values: np.ndarray
    configurations: np.ndarray
    reachable: np.ndarray
    t: np.ndarray | None = None
    trajectory: bool = False

    def __len__(self) -> int:
        return len(self.values)

    @property
    def positions(self) -> np.ndarray:
        return self.values if self.kind == "position" else dq_translation(self.values)


TargetSource = Callable[[ArmModel, DataSpec, Path, str], Targets]
TARGET_SOURCES: Registry[TargetSource] = Registry("target source")


def reach_bound(arm: ArmModel) -> float:
    """An upper bound of the distance base-tip.

    Constant-curvature arm: a section's chord is at most its arc length, so the tip lies
    within ``sum S_max``. Other arms: twice the largest distance over 20,000 random
    configurations (an estimate, not a proof).
    """
    if isinstance(arm, ConstantCurvatureArm):
        return float(arm.section_lengths.sum() * arm.length_range[1])
    Q = arm.sample_configurations(20_000, np.random.default_rng(0))
    return 2.0 * float(np.linalg.norm(arm.evaluate("fk_position", Q), axis=1).max())


def forward_targets(arm: ArmModel, Q: np.ndarray, kind: str) -> np.ndarray:
    """Tip positions ``(N, 3)``, tip dual quaternions ``(N, 8)`` or leg lengths of configurations ``Q``."""
    if kind == "legs":
        return arm.evaluate("leg_lengths", Q).reshape(len(Q), -1)
    return arm.evaluate("fk_position" if kind == "position" else "fk_dq", Q)


def unreachable_targets(arm: ArmModel, count: int, kind: str, rng: np.random.Generator,
                        margin: tuple[float, float]) -> np.ndarray:
    """``count`` targets farther from the base than :func:`reach_bound` times a factor in ``margin``."""
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    position = direction * reach_bound(arm) * rng.uniform(*margin, size=(count, 1))
    if kind == "position":
        return position
    orientation = quat_normalize(rng.normal(size=(count, 4)))
    orientation *= np.where(orientation[:, :1] < 0, -1.0, 1.0)
    return dq_from_rotation_translation(orientation, position)


@TARGET_SOURCES.register("random")
def random_targets(arm: ArmModel, data: DataSpec, path: Path, kind: str) -> Targets:
    """Forward kinematics of uniform random configurations, plus ``params.unreachable`` targets outside."""
    p = _params(data, path, {"unreachable": 0, "margin": [1.1, 1.5]})
    extra = p["unreachable"]
    if isinstance(extra, bool) or not isinstance(extra, int) or extra < 0:
        raise SpecError(path, "data.params.unreachable", f"expected a count >= 0, got {extra!r}")
    margin = tuple(float(v) for v in p["margin"])
    if len(margin) != 2 or not 1.0 < margin[0] <= margin[1]:
        raise SpecError(path, "data.params.margin", f"expected [low, high] with 1 < low <= high, got {p['margin']}")
    rng = np.random.default_rng(data.seed)
    Q = arm.sample_configurations(data.samples, rng)
    values = forward_targets(arm, Q, kind)
    reachable = np.ones(len(Q), dtype=bool)
    if extra and kind == "legs":
        raise SpecError(path, "data.params.unreachable", "leg-length targets have no unreachable variant")
    if extra:
        values = np.concatenate([values, unreachable_targets(arm, extra, kind, rng, margin)])
        Q = np.concatenate([Q, np.full((extra, arm.n_config), np.nan)])
        reachable = np.concatenate([reachable, np.zeros(extra, dtype=bool)])
    return Targets(kind, values, Q, reachable)


@TARGET_SOURCES.register("trajectory")
def trajectory_targets(arm: ArmModel, data: DataSpec, path: Path, kind: str) -> Targets:
    """Forward kinematics of a smooth configuration motion (see ``smooth_trajectory``)."""
    Q, t = smooth_trajectory(arm, data, path)
    values = forward_targets(arm, Q, kind)
    return Targets(kind, values, Q, np.ones(len(Q), dtype=bool), t=t, trajectory=True)


@TARGET_SOURCES.register("csv")
def csv_targets(arm: ArmModel, data: DataSpec, path: Path, kind: str) -> Targets:
    """Targets from a CSV file with a header row (module docstring); reachability unknown (treated as reachable)."""
    p = _params(data, path, {"file": None, "trajectory": False})
    if not p["file"]:
        raise SpecError(path, "data.params.file", "required by source 'csv'")
    csv_path = (Path(path).parent / str(p["file"])).resolve()
    names = ("x", "y", "z") if kind == "position" else ("x", "y", "z", "qw", "qx", "qy", "qz")
    values, t = read_configuration_csv(csv_path, names)
    values, t = values[: data.samples], (None if t is None else t[: data.samples])
    if kind == "pose":
        norms = np.linalg.norm(values[:, 3:], axis=1)
        bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-6)
        if bad.size:
            raise InputDataError(f"quaternion norm {norms[bad[0]]:.6g} is not 1", source=str(csv_path),
                                 sample=int(bad[0]), field="qw")
        values = dq_from_rotation_translation(values[:, 3:], values[:, :3])
    configurations = np.full((len(values), arm.n_config), np.nan)
    return Targets(kind, values, configurations, np.ones(len(values), dtype=bool), t=t,
                   trajectory=bool(p["trajectory"]))
