"""Model reference adaptive kinematic control (Seleem et al. 2020, section V, eqs. 32-35) with Fig. 12's saturation.

Control law (eq. 34):  ``qdot = J_d^+ (xdot_ref + K e)``, ``e = x_ref - x``, with
``J_d`` the Jacobian of the tip dual quaternion (eq. 33; the position
Jacobian for position tracking, as in the seed's Kinect experiment, Figs. 26-27)
and ``K = diag(k)``.

Adaptation (eq. 35, derived again because the extraction is garbled): the
printed ``K = int gamma_a |e_1' Qbar| dt`` has a scalar inside the integral but
a diagonal ``K`` and a diagonal ``gamma_a`` outside, so it is read component-wise,

    k_i(t) = k_i(0) + int_0^t gamma_i |e_1,i x_i| dt,      e_1 = x_m - x,

where ``x`` is the measured task value (the seed's "actual behaviour"
``Qbar_dual``) and ``x_m`` is the output of the reference model. Because of the
absolute value the gains can only grow, so each is saturated at
``gain_limit`` as Fig. 12 prescribes; :attr:`MRACController.saturated` flags the
saturated components after every step and the simulator counts them.

Reference model (the seed says only "a second-order transfer function"):
per component ``x_m'' = w_n^2 (x_ref - x_m) - 2 zeta w_n x_m'``, started at the
measured task value (it describes how the loop should move from where the arm
is to the reference), discretised exactly for a reference held over each step.

Defaults. ``gain``: the seed's optimised ``K`` (section VII: diag(7.45, 3.43,
3.70, 3.02, 9.62, 5.06, 4.69, 8.15) for the dual quaternion; diag(87.77, 1.12,
51.59) for position). The ``tracking`` kind starts its ``mrac`` baseline from the
task gain every other controller uses (``options.gain``) instead, so that the
comparison is between control laws and not between gains; :class:`SeedGainMRACController`
(baseline ``mrac_seed``) is the same controller labelled as starting from the seed's ``K``.
``adaptation``: the seed's ``gamma_a`` = diag(0.0863,
0.0864, 0.0146) for position; Table 1 with the pose values is lost, so 50 per
component (an assumption). ``gain_limit`` 100 1/s (an assumption: Euler
integration of ``e' = -k e`` needs ``k dt < 2``, so 100 keeps a factor 2 at the
slowest control rate, 100 Hz). ``w_n = 10`` rad/s, ``zeta = 1`` (assumed).

Stability (Seleem et al. 2020 section VI, eqs. 36-39). With ``V = e'e/2`` the seed writes
``Vdot = -e'Ke``, which needs ``J J^+ = I``. For the 8-row pose Jacobian
``J J^+`` is a projector of rank 5 (:mod:`optikin.baselines.pseudo_inverse`),
so ``Vdot = e'(I - J J^+) xdot_ref - e' J J^+ K e``: monotone decrease is
guaranteed only for a position task (3 rows, rank 3) or a static reference with
an isotropic ``K`` and an exact model, and only up to the step size; the
simulator reports where ``V`` grows.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from optikin.arms.base import ArmModel
from optikin.baselines.pseudo_inverse import PINV_RCOND
from optikin.control.base import Controller, gain_vector
from optikin.control.task import Task, task_dimension

SEED_GAIN = {"pose": (7.45, 3.43, 3.70, 3.02, 9.62, 5.06, 4.69, 8.15), "position": (87.77, 1.12, 51.59)}
"""Seed 000 section VII: the optimised K for the dual-quaternion (Figs. 22-23) and position (Fig. 26) tracking."""
SEED_ADAPTATION = {"pose": (50.0,) * 8, "position": (0.0863, 0.0864, 0.0146)}
"""gamma_a: Seleem et al. 2020 section VII for position; assumed for the pose (Table 1 lost)."""


class SecondOrderReferenceModel:
    """``x_m'' = w_n^2 (r - x_m) - 2 zeta w_n x_m'`` per component, exact for ``r`` held over each step."""

    def __init__(self, dt: float, natural_frequency: float = 10.0, damping_ratio: float = 1.0):
        if not natural_frequency > 0 or not damping_ratio > 0:
            raise ValueError("natural_frequency and damping_ratio must be positive")
        wn, zeta = float(natural_frequency), float(damping_ratio)
        augmented = np.array([[0.0, 1.0, 0.0], [-wn * wn, -2.0 * zeta * wn, wn * wn], [0.0, 0.0, 0.0]])
        step = expm(augmented * dt)
        self.transition, self.input = step[:2, :2], step[:2, 2]
        self.value = np.zeros(0)
        self.rate = np.zeros(0)

    def reset(self, x: np.ndarray) -> None:
        self.value, self.rate = np.array(x, dtype=float), np.zeros(len(x))

    def step(self, reference: np.ndarray) -> None:
        (a, b), (c, d) = self.transition
        value = a * self.value + b * self.rate + self.input[0] * reference
        self.rate = c * self.value + d * self.rate + self.input[1] * reference
        self.value = value


class MRACController(Controller):
    """Seed 000 MRAC: pseudo-inverse tracking with gains adapted by eq. (35) and saturated (Fig. 12)."""

    name = "mrac"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        gain=None,
        adaptation=None,
        gain_limit=100.0,
        natural_frequency: float = 10.0,
        damping_ratio: float = 1.0,
        rcond: float = PINV_RCOND,
        compiled: bool = False,
    ):
        super().__init__(arm, dt, task, SEED_GAIN[task] if gain is None else gain, compiled)
        m = task_dimension(task)
        self.initial_gain = self.gain.copy()
        self.adaptation = gain_vector(SEED_ADAPTATION[task] if adaptation is None else adaptation, m, "adaptation")
        self.gain_limit = gain_vector(gain_limit, m, "gain_limit")
        if np.any(self.initial_gain > self.gain_limit):
            raise ValueError("initial gain above gain_limit")
        self.reference_model = SecondOrderReferenceModel(dt, natural_frequency, damping_ratio)
        self.rcond = float(rcond)
        self.saturated = np.zeros(m, dtype=bool)

    def reset(self, q: np.ndarray, x: np.ndarray) -> None:
        super().reset(q, x)
        self.gain = self.initial_gain.copy()
        self.saturated[:] = False
        self.reference_model.reset(x)

    def command(self, q: np.ndarray, x: np.ndarray, x_ref: np.ndarray, xdot_ref: np.ndarray) -> np.ndarray:
        x_model = self.reference_model.value
        if self.task == "pose" and x_model[:4] @ x[:4] < 0:
            x_model = -x_model
        self.gain += self.dt * self.adaptation * np.abs((x_model - x) * x)
        np.minimum(self.gain, self.gain_limit, out=self.gain)
        self.saturated = self.gain >= self.gain_limit
        self.model.set_gains(self.gain)
        self.model.evaluate(q, x, x_ref, xdot_ref)
        qdot = np.linalg.pinv(self.model.J, rcond=self.rcond) @ self.model.v
        reference = x_ref if self.task != "pose" or x_ref[:4] @ self.reference_model.value[:4] >= 0 else -x_ref
        self.reference_model.step(reference)
        return self.saturated_command(qdot)


class SeedGainMRACController(MRACController):
    """:class:`MRACController` from the seed's optimised ``K`` (:data:`SEED_GAIN`), labelled as such in comparisons."""

    name = "mrac (seed gains)"

    def __init__(
        self,
        arm: ArmModel,
        dt: float,
        task: Task = "pose",
        adaptation=None,
        gain_limit=100.0,
        natural_frequency: float = 10.0,
        damping_ratio: float = 1.0,
        rcond: float = PINV_RCOND,
        compiled: bool = False,
    ):
        super().__init__(
            arm, dt, task, SEED_GAIN[task], adaptation, gain_limit, natural_frequency, damping_ratio, rcond, compiled
        )
