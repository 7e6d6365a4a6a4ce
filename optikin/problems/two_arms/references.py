"""References of the ``two_arms`` kind (data family ``two_arm_references``).

``rope_loop``
    The skipping-rope motion of the rope's lowest point: a closed loop in the vertical plane
    spanned by ``sideways`` and gravity, starting at its top,

        P(t) = c + s(t) (r_side sin(w t) e_side - r_down (1 - cos(w t)) up),   w = 2 pi / period,

    (down through the bottom at half a period, up the other side), ``c`` the start's lowest
    point (or ``center``), ``s(t)`` a minimum-jerk ramp from 0 to 1 over the first ``ramp``
    seconds so the reference starts at rest; ``cycles`` loops, then ``hold`` seconds at rest.
``tip_waypoints``
    Each arm's tip along the forward kinematics of its own minimum-jerk configuration path
    (:func:`optikin.control.reference.minimum_jerk_path`) through waypoints written in the
    problem file, in the shared frame (the kind places it); the run starts at the first waypoints.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import Field, PositiveFloat

from optikin.arms.base import ArmModel
from optikin.control.reference import minimum_jerk_path
from optikin.data.sources import register_source
from optikin.errors import SpecError
from optikin.options import Options
from optikin.spec import DataSpec

FAMILY = "two_arm_references"


@dataclass(frozen=True)
class RopeLoop:
    """The lowest point's offsets from the loop's centre and their rates, ``(N, 3)`` [m, m/s], at times ``t``."""

    t: np.ndarray
    offset: np.ndarray
    rate: np.ndarray
    center: tuple[float, float, float] | None


@dataclass(frozen=True)
class TipPaths:
    """Each arm's configuration path ``(N, n)`` and rate, at times ``t``."""

    t: np.ndarray
    configurations: tuple[np.ndarray, np.ndarray]
    rates: tuple[np.ndarray, np.ndarray]


class RopeLoopParams(Options):
    """The loop of the rope's lowest point."""

    rate: float = Field(500.0, ge=100.0, le=1000.0, description="control rate [Hz]")
    period: PositiveFloat = Field(1.0, description="seconds per loop")
    cycles: int = Field(2, ge=1, le=100, description="loops")
    radii: tuple[PositiveFloat, PositiveFloat] = Field(
        (0.04, 0.03), description="half the loop's width sideways and half its depth [m]"
    )
    sideways: tuple[float, float, float] = Field(
        (0.0, 1.0, 0.0), description="the loop's sideways direction (made perpendicular to gravity)"
    )
    gravity: tuple[float, float, float] = Field((0.0, 0.0, -1.0), description="direction of gravity")
    ramp: float = Field(0.5, ge=0.0, description="seconds over which the loop grows from rest (minimum jerk)")
    hold: float = Field(0.2, ge=0.0, description="seconds at rest after the loops")
    center: tuple[float, float, float] | None = Field(
        None, description="the loop's top [m]; null: the lowest point of the start configuration"
    )


class TipWaypointParams(Options):
    """Per arm, minimum-jerk segments through configurations."""

    rate: float = Field(500.0, ge=100.0, le=1000.0, description="control rate [Hz]")
    waypoints: list[list[list[float]]] = Field(
        description="per arm, its waypoints [[q, ...], [q, ...]] (SI units); both arms the same count"
    )
    segment_time: PositiveFloat = Field(1.5, description="seconds per segment")
    hold: float = Field(0.5, ge=0.0, description="seconds at the last waypoints")


def _ramp(t: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-jerk ``s(t)`` from 0 to 1 over ``duration`` and its rate."""
    if duration <= 0:
        return np.ones_like(t), np.zeros_like(t)
    tau = np.clip(t / duration, 0.0, 1.0)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    ds = np.where(t < duration, 30 * tau**2 * (1 - tau) ** 2 / duration, 0.0)
    return s, ds


@register_source(FAMILY, "rope_loop", "the rope's lowest point around a skipping-rope loop", params=RopeLoopParams)
def rope_loop(arm: ArmModel | None, data: DataSpec, params: RopeLoopParams, path: Path) -> RopeLoop:
    """The loop's offsets and rates (module docstring)."""
    g = np.asarray(params.gravity, dtype=float)
    if not np.linalg.norm(g) > 0:
        raise SpecError(str(path), "data.params.gravity", "gravity has zero length")
    up = -g / np.linalg.norm(g)
    side = np.asarray(params.sideways, dtype=float)
    side = side - (side @ up) * up
    if not np.linalg.norm(side) > 1e-9:
        raise SpecError(str(path), "data.params.sideways", "parallel to gravity: the loop needs a sideways direction")
    side /= np.linalg.norm(side)
    loops = params.cycles * params.period
    t = np.arange(int(round((loops + params.hold) * params.rate)) + 1) / params.rate
    w = 2.0 * np.pi / params.period
    phase = w * np.minimum(t, loops)
    moving = (t < loops).astype(float)
    s, ds = _ramp(t, params.ramp)
    r_side, r_down = params.radii
    shape = np.outer(r_side * np.sin(phase), side) - np.outer(r_down * (1.0 - np.cos(phase)), up)
    shape_rate = w * moving[:, None] * (np.outer(r_side * np.cos(phase), side) - np.outer(r_down * np.sin(phase), up))
    return RopeLoop(t, s[:, None] * shape, ds[:, None] * shape + s[:, None] * shape_rate, params.center)


@register_source(FAMILY, "tip_waypoints", "each arm's tip along its own minimum-jerk path", params=TipWaypointParams)
def tip_waypoints(arm: ArmModel, data: DataSpec, params: TipWaypointParams, path: Path) -> TipPaths:
    """Both arms' configuration paths (module docstring)."""
    where = "data.params.waypoints"
    if len(params.waypoints) != 2:
        raise SpecError(str(path), where, f"one list of waypoints per arm (two), got {len(params.waypoints)}")
    paths = []
    for k, rows in enumerate(params.waypoints):
        W = np.asarray(rows, dtype=float) if all(len(r) == arm.n_config for r in rows) else None
        if W is None or W.ndim != 2 or len(W) < 2:
            raise SpecError(
                str(path), f"{where}.{k}", f"two or more waypoints of {arm.n_config} values each ({arm.name})"
            )
        paths.append(minimum_jerk_path(W, params.segment_time, params.rate, params.hold))
    if len(paths[0][0]) != len(paths[1][0]):
        raise SpecError(str(path), where, "both arms need the same number of waypoints")
    return TipPaths(paths[0][0], (paths[0][1], paths[1][1]), (paths[0][2], paths[1][2]))
