"""Closed-loop simulation of a tracking controller on a (possibly different) plant, and its metrics.

Per control step ``k`` (period ``dt`` of the reference, 100 Hz to 1 kHz):

1. the plant's configuration is ``q_k = z_k + d(t_k)``: the integrated
   commands ``z`` plus an optional step disturbance ``d`` (a configuration offset
   switched on over ``[t_on, t_off)``, like the step of Seleem et al. 2020, Figs. 20-21);
2. the plant's tip is ``fk(q_k)`` of the arm with every arc length scaled by
   ``length_scale`` (model mismatch: the controller's model keeps the nominal
   lengths), or, with a rod plant (``Plant.rod``, :mod:`optikin.control.rod_plant`),
   the tip of the Cosserat rod whose chamber pressures the nominal map makes of
   ``q_k``, under gravity and a payload (the controller keeps its CC model);
3. sensors: the configuration with Gaussian noise; the tip either measured
   directly (``feedback="tip"``, e.g. motion capture: position noise in metres,
   orientation noise as a rotation angle) or computed by the controller's model
   from the measured configuration (``feedback="model"``, e.g. the IMUs of Seleem et al. 2020);
4. the controller commands ``qdot_k`` (timed: wall time of ``command``,
   Jacobian evaluation included), held over the step: ``z_{k+1} = z_k + dt qdot_k``;
   periodic variables are wrapped.

The plant is never clipped at the limits: :class:`TrackingRun` measures how
far each controller takes it outside.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import numpy as np

from optikin.algebra import (
    dq_from_rotation_translation,
    dq_rotation,
    dq_translation,
    quat_angle,
    quat_conjugate,
    quat_exp,
    quat_multiply,
)
from optikin.arms.base import ArmModel
from optikin.control.base import Controller
from optikin.fastcall import BufferedFunction
from optikin.interrupt import check_interrupted
from optikin.control.limits import limit_excess, periodic_mask, wrap_periodic
from optikin.control.reference import Reference
from optikin.control.rod_plant import RodPlantSimulator
from optikin.control.task import TASK_FUNCTIONS
from optikin.status import Status

MM, DEG = 1e3, 180.0 / np.pi


@dataclass(frozen=True)
class Plant:
    """How the simulated arm differs from the controller's model, what disturbs it and how it is measured.

    ``length_scale``: true arc length / modelled arc length, one value or one per
    section (variables named ``S*``). ``disturbance``: configuration offset
    (``n`` values, SI) applied over ``disturbance_window`` ``(t_on, t_off)`` seconds.
    ``configuration_noise``: standard deviation per variable (one value or ``n``).
    ``tip_position_noise`` (m) and ``tip_angle_noise`` (rad): standard deviations of the tip sensor.
    ``rod``: the Cosserat rod plant that gives the true tip instead of the scaled forward kinematics.
    """

    length_scale: float | tuple[float, ...] = 1.0
    disturbance: tuple[float, ...] | None = None
    disturbance_window: tuple[float, float] = (0.0, np.inf)
    configuration_noise: float | tuple[float, ...] = 0.0
    tip_position_noise: float = 0.0
    tip_angle_noise: float = 0.0
    feedback: Literal["tip", "model"] = "tip"
    rod: RodPlantSimulator | None = None

    def length_factors(self, arm: ArmModel) -> np.ndarray:
        """Per-variable factor applied to the configuration before the plant's forward kinematics."""
        lengths = [i for i, name in enumerate(arm.config_names) if name.startswith("S")]
        scale = np.asarray(self.length_scale, dtype=float)
        if not lengths and np.any(scale != 1.0):
            raise ValueError(f"{arm.name} has no length variables S* to scale")
        if scale.ndim and scale.shape != (len(lengths),):
            raise ValueError(f"length_scale needs 1 or {len(lengths)} values, got {scale.shape[0]}")
        if self.rod is not None and np.any(scale != 1.0):
            raise ValueError("length_scale is a mismatch of the kinematic plant; a rod plant has its own lengths")
        factors = np.ones(arm.n_config)
        factors[lengths] = scale
        return factors

    def offset(self, arm: ArmModel, t: float) -> np.ndarray:
        if self.disturbance is None or not self.disturbance_window[0] <= t < self.disturbance_window[1]:
            return np.zeros(arm.n_config)
        return np.asarray(self.disturbance, dtype=float)


@dataclass
class TrackingRun:
    """Everything recorded along one closed-loop run (``N`` control steps)."""

    controller: str
    arm: ArmModel
    reference: Reference
    q: np.ndarray  # (N, n) plant configuration at each step
    qdot: np.ndarray  # (N, n) commanded rates
    x: np.ndarray  # (N, m) true tip (position or dual quaternion)
    excess_after_command: np.ndarray  # (N, n) limit excess of q_k + dt qdot_k (disturbance held)
    step_time: np.ndarray  # (N,) wall time of each command [s]
    status: list[str]  # per step: Status.OK or "fallback ...: reason"
    slip: np.ndarray  # (N,) bound violation removed from the QP solution (0 for others)
    gains: np.ndarray | None = None  # (N, m) MRAC gains
    saturated: np.ndarray | None = None  # (N, m) MRAC gain saturated
    notes: list[str] = field(default_factory=list)
    plant_failures: int | None = None  # steps whose rod equilibrium did not converge (None: kinematic plant)

    @property
    def t(self) -> np.ndarray:
        return self.reference.t

    @property
    def error(self) -> np.ndarray:
        """``e = x_ref - x`` (reference flipped into the tip's hemisphere for the pose task), ``(N, m)``."""
        ref = self.reference.value
        if self.reference.task == "pose":
            ref = np.where((np.sum(ref[:, :4] * self.x[:, :4], axis=1) < 0)[:, None], -ref, ref)
        return ref - self.x

    @property
    def lyapunov(self) -> np.ndarray:
        """``V(e) = e'e / 2`` (Seleem et al. 2020 eq. 36 with P = I) along the run."""
        return 0.5 * np.sum(self.error**2, axis=1)

    @property
    def position(self) -> np.ndarray:
        """True tip positions ``(N, 3)`` [m]."""
        return self.x if self.reference.task == "position" else dq_translation(self.x)

    @property
    def position_error(self) -> np.ndarray:
        """Distance between reference and true tip positions [m]."""
        return np.linalg.norm(self.reference.position - self.position, axis=1)

    @property
    def orientation_error(self) -> np.ndarray | None:
        """Angle between reference and true tip orientations [rad] (pose task)."""
        if self.reference.task != "pose":
            return None
        return quat_angle(quat_multiply(quat_conjugate(self.reference.orientation), dq_rotation(self.x)))

    def settling_time(self, after: float, position: float, orientation: float | None = None) -> float | None:
        """Seconds from ``after`` until the errors enter a band they keep to the end of the run.

        Parameters
        ----------
        after:
            Start of the count [s], e.g. the end of a disturbance.
        position:
            Half-width of the band on the position error [m].
        orientation:
            Half-width on the orientation error [rad] (pose task; ``None``: position only).

        Returns
        -------
        float or None
            ``t_s - after`` with ``t_s`` the first sample at or after ``after`` from which every
            error stays in the band; ``None`` when the last sample is outside it (not settled
            by the end of the run, the time-out).
        """
        inside = self.position_error <= position
        angle = self.orientation_error
        if angle is not None and orientation is not None:
            inside &= angle <= orientation
        first = int(np.searchsorted(self.t, after - 1e-9 * self.reference.dt))
        if first >= len(self.t) or not inside[-1]:
            return None
        outside = np.flatnonzero(~inside[first:])
        k = first if outside.size == 0 else first + int(outside[-1]) + 1
        return float(self.t[k] - after)

    @property
    def excess(self) -> np.ndarray:
        """How far each sample's configuration lies outside the limits, ``(N, n)``."""
        return limit_excess(self.arm, self.q)

    def metrics(self, tail: float = 0.1, lyapunov_floor: float = 1e-10) -> dict[str, Any]:
        """Summary numbers; ``final`` values are means over the last ``tail`` fraction of the run.

        ``V increasing steps`` counts steps where ``V`` grows to a value above
        ``lyapunov_floor`` (1e-10: an error of about 1e-5 in every component), below
        which the O(dt^2) terms of the discrete loop and rounding make it wander.
        """
        names = self.arm.config_names
        last = max(1, int(round(tail * len(self.t))))
        out: dict[str, Any] = {}
        pos = self.position_error * MM
        out |= {
            "position error rms [mm]": _rms(pos),
            "position error max [mm]": float(pos.max()),
            "position error final [mm]": float(pos[-last:].mean()),
        }
        angle = self.orientation_error
        if angle is not None:
            angle = angle * DEG
            out |= {
                "orientation error rms [deg]": _rms(angle),
                "orientation error max [deg]": float(angle.max()),
                "orientation error final [deg]": float(angle[-last:].mean()),
            }
        excess = self.excess
        controller_made = (self.excess_after_command > 0) & (self.excess_after_command >= excess)
        out |= {
            "samples outside limits": int(np.any(excess > 0, axis=1).sum()),
            "steps the controller kept or took outside": int(np.any(controller_made, axis=1).sum()),
        }
        for prefix, unit, scale in (("S", "mm", MM), ("theta", "deg", DEG)):
            cols = [i for i, n in enumerate(names) if n.startswith(prefix)]
            if cols:
                out[f"max limit excess {prefix} [{unit}]"] = float(excess[:, cols].max() * scale)
        for prefix, unit, scale in (("S", "mm/s", MM), ("theta", "deg/s", DEG), ("phi", "deg/s", DEG)):
            cols = [i for i, n in enumerate(names) if n.startswith(prefix)]
            if cols:
                out[f"rms rate {prefix} [{unit}]"] = _rms(self.qdot[:, cols] * scale)
        out["control effort int |qdot|^2 dt"] = float(np.sum(self.qdot**2) * self.reference.dt)
        V = self.lyapunov
        out |= {
            "V initial": float(V[0]),
            "V final": float(V[-last:].mean()),
            "V increasing steps": int(np.sum((np.diff(V) > 0) & (V[1:] > lyapunov_floor))),
        }
        us = self.step_time * 1e6
        out |= {
            "step time median [us]": float(np.median(us)),
            "step time p95 [us]": float(np.percentile(us, 95)),
            "step time max [us]": float(us.max()),
        }
        fallbacks = [i for i, s in enumerate(self.status) if s != Status.OK]
        out["fallback steps"] = len(fallbacks)
        if fallbacks:
            out["first fallback"] = f"t = {self.t[fallbacks[0]]:.4g} s: {self.status[fallbacks[0]]}"
        out["max bound slip removed"] = float(self.slip.max())
        if self.plant_failures is not None:
            out["plant equilibrium failures"] = self.plant_failures
        if self.saturated is not None and self.gains is not None:
            steps = np.any(self.saturated, axis=1)
            out["gain saturation steps"] = int(steps.sum())
            out["first gain saturation [s]"] = float(self.t[np.argmax(steps)]) if steps.any() else None
            out["final gains"] = self.gains[-1].tolist()
        return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def simulate(
    controller: Controller, reference: Reference, q0: np.ndarray, plant: Plant = Plant(), seed: int = 0
) -> TrackingRun:
    """Run ``controller`` along ``reference`` from configuration ``q0`` on ``plant`` (see the module docstring)."""
    arm = controller.arm
    if reference.task != controller.task:
        raise ValueError(f"reference is a {reference.task} task, controller tracks {controller.task}")
    dt = reference.dt
    if abs(dt - controller.dt) > 1e-9 * dt:
        raise ValueError(f"reference period {dt} s differs from the controller's {controller.dt} s")
    rng = np.random.default_rng(seed)
    n, N = arm.n_config, len(reference.t)
    fk = arm.function(TASK_FUNCTIONS[reference.task][0])
    q_sym = ca.SX.sym("q", n)
    plant_fk = BufferedFunction(ca.Function("plant_fk", [q_sym], [fk(q_sym * plant.length_factors(arm))]))
    model_fk = BufferedFunction(fk)
    config_noise = np.broadcast_to(np.asarray(plant.configuration_noise, dtype=float), (n,))
    wrapped = periodic_mask(arm)

    Q, Qdot, X = np.empty((N, n)), np.empty((N, n)), np.empty((N, reference.value.shape[1]))
    after, step_time, slip = np.empty((N, n)), np.empty(N), np.zeros(N)
    status: list[str] = []
    adaptive = hasattr(controller, "saturated")
    gains = np.empty((N, len(controller.gain))) if adaptive else None
    saturated = np.zeros((N, len(controller.gain)), dtype=bool) if adaptive else None

    if plant.rod is not None:
        plant.rod.reset()
    z = np.array(q0, dtype=float)
    for k, t in enumerate(reference.t):
        check_interrupted()
        q = z + plant.offset(arm, t)
        if plant.rod is not None:
            x_true = plant.rod.tip(q, reference.task)
        else:
            plant_fk.inputs[0][:] = q
            plant_fk()
            x_true = plant_fk.outputs[0].copy()
        q_meas = q + config_noise * rng.standard_normal(n) if config_noise.any() else q
        if plant.feedback == "model":
            model_fk.inputs[0][:] = q_meas
            model_fk()
            x_meas = model_fk.outputs[0].copy()
        else:
            x_meas = _noisy_tip(x_true, reference.task, plant, rng)
        if k == 0:
            controller.reset(q_meas, x_meas)
        start = time.perf_counter()
        qdot = controller.command(q_meas, x_meas, reference.value[k], reference.rate[k])
        step_time[k] = time.perf_counter() - start
        Q[k], Qdot[k], X[k] = q, qdot, x_true
        after[k] = q + dt * qdot
        status.append(controller.status)
        slip[k] = getattr(controller, "slip", 0.0)
        if gains is not None and saturated is not None:
            gains[k], saturated[k] = controller.gain, getattr(controller, "saturated")
        z = wrap_periodic(z + dt * qdot, wrapped)
    run = TrackingRun(
        controller.name, arm, reference, Q, Qdot, X, limit_excess(arm, after), step_time, status, slip, gains, saturated
    )
    if plant.rod is not None:
        run.plant_failures = plant.rod.failures
        low, high = plant.rod.pressure_range
        run.notes.append(
            f"rod plant: {plant.rod.iterations / N:.2g} Newton iterations per step, "
            f"pressures {low:.4g} to {high:.4g} Pa"
        )
    return run


def _noisy_tip(x: np.ndarray, task: str, plant: Plant, rng: np.random.Generator) -> np.ndarray:
    """The tip sensor: position noise (m) and a random small rotation (angle std in rad)."""
    if plant.tip_position_noise == 0 and plant.tip_angle_noise == 0:
        return x
    if task == "position":
        return x + plant.tip_position_noise * rng.standard_normal(3)
    rotation = quat_multiply(quat_exp(0.5 * plant.tip_angle_noise * rng.standard_normal(3)), dq_rotation(x))
    return dq_from_rotation_translation(
        rotation, dq_translation(x) + plant.tip_position_noise * rng.standard_normal(3), check=False
    )
