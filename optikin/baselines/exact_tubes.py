"""Exact CBHA tube lengths from the section ends, fast: Newton on the 48 x 48 system by block elimination.

The ``newton-raphson`` comparator of :mod:`optikin.baselines.ph_comparators` solves, per
posture, the square system of :func:`~optikin.baselines.ph_comparators.newton_raphson_problem`
in the 48 platform variables ``x_k = (Z_k, theta_k, psi_k)``, ``k = 1..16``: 6 rows of the section
end positions ``p_s(x) - p_s*`` and 42 rows of seed 004's elongation distribution
(:mod:`optikin.ik.cbha`), ``q_k(x_k) - a_k - b_k S_s(x)`` for every platform but the last of
its section ``s``, with ``q_k`` the three leg lengths of platform ``k`` (depending on ``x_k``
only) and ``S_s = sum_{j in s} q_j`` the section's tube lengths. This module solves the same
system with the same Newton iterates, at a fraction of the cost, from its structure:

Write ``A_k = dq_k/dx_k`` (3 x 3), ``r_k`` the distribution row of platform ``k`` and
``dS_s = sum_{j in s} A_j dx_j`` the change of the section's tube lengths. The Newton
equations of the distribution rows read ``A_k dx_k = -r_k + b_k dS_s``; summing them over the
section and using ``sum_{k in s} b_k = 1`` gives the same equation for the last platform with
``r_last = -sum_{k in s, k != last} r_k``. So

    dx_k = -u_k + V_k dS_s,    u_k = A_k^-1 r_k,    V_k = b_k A_k^-1,

and the 6 end rows ``r_e + P dx = 0`` (``P = dp/dx``, 6 x 48) become a 6 x 6 system in the
tube-length changes,

    (sum_k P_k V_k E_s(k)) dS = -r_e + sum_k P_k u_k,

(``P_k`` the three columns of platform ``k``, ``E_s`` placing section ``s``'s three
unknowns), after which ``dx`` follows platform by platform: sixteen 3 x 3 solves and one 6 x 6
solve instead of a 48 x 48 one. Mathematically this is the Newton step of the full system
whenever the platform Jacobians ``A_k`` are regular (the leg lengths determine the platform,
as seed 004's forward model assumes); the tests compare it with the dense step. ``P`` is the
geometric Jacobian of the chain of seed 004 eq. (5): with ``R_k`` the orientation of vertebra
``k`` and ``p_{k+1}`` the centre of vertebra ``k + 1``, an end point ``e`` beyond platform ``k``
moves by ``R_k e_z`` per unit of ``Z_k`` and rotates about the axes ``R_k e_y`` (``theta_k``)
and ``R_{k+1} e_x`` (``psi_k``) through ``p_{k+1}``: ``dp/dtheta_k = R_k e_y x (e - p_{k+1})``.

One CasADi SX Function evaluates, at ``x``, the step, ``max |r|``, ``||r||``, how far ``x`` and
its legs are outside their bounds (relative, as
:meth:`~optikin.solvers.nonlinear.LeastSquaresProblem.check`) and the whole tube lengths
``L_1..L_3`` (both sections' legs summed); it is compiled to C (:mod:`optikin.codegen`) and
called in place (``Function.buffer``). A posture first gets :data:`FIXED_STEPS` full Newton steps
in one call (a loop in the generated C, CasADi's ``mapaccum``), kept if they meet the tolerance
within the bounds, which they do along a trajectory. Otherwise the iteration of the ``newton``
preset (CasADi rootfinder with line search) runs from the start, one compiled step per call:
stop at ``max |r| <= 1e-12`` or a step of max-norm ``<= 1e-14``; a full step that does not lower
``||r||`` is halved until it does, and every step is clipped to the bounds of ``x`` (the
rootfinder knows none; inside them the iterates are the same). A posture starts from the
previous postures' solutions (:meth:`ExactTubeLengths.track`: their linear extrapolation) or the
straight configuration. The status follows the rule of :mod:`optikin.solvers.nonlinear` on
``||r|| <= 1e-9`` m (:data:`~optikin.baselines.ph_comparators.NR_TOLERANCE`), the bounds and
Table I, and a posture that is neither ``ok`` nor outside them is classified by the
problem's own check.
"""

from __future__ import annotations

import math
import time
from typing import Any, Callable, NamedTuple, cast

import casadi as ca
import numpy as np

from optikin.arms.cbha import CBHAArm
from optikin.baselines.ph_comparators import NR_ELONGATION, ComparatorRun, newton_raphson_problem
from optikin.codegen import compile_function
from optikin.ik.cbha import distribution_coefficients, section_slices
from optikin.ik.formulation import rest_configuration
from optikin.interrupt import calls_casadi
from optikin.solvers.nonlinear import BOUND_TOLERANCE
from optikin.status import Status

ROOT_TOLERANCE = 1e-12
"""``max |r|`` [m] at which the iteration stops (the ``newton`` preset's ``abstol``)."""
STEP_TOLERANCE = 1e-14
"""Max-norm of a step at or below which the iteration stops (the ``newton`` preset's ``abstolStep``)."""
MAX_ITERATIONS = 50
"""Step evaluations per posture (the ``newton`` preset's ``max_iter``)."""
FINAL_STEP_RESIDUAL = 1e-8
"""``max |r|`` [m] below which the Newton point is checked without a Jacobian (:meth:`ExactTubeLengths.solve`):
from there the residual falls to about ``1e-15`` (measured: 2.7e-7 went to 1.1e-12)."""
FIXED_STEPS = 3
"""Newton steps of the first attempt, one compiled call (:meth:`ExactTubeLengths.solve`): from the previous
postures of the recording of ``cbha-ph-shape`` (sections moving up to 10 mm between postures) three reach
``max |r| <= 1e-12``."""
SMALLEST_STEP = 2.0**-20
"""The line search gives up (``not_converged``) when the step fraction falls below this."""


def _columns(quat: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``R e_x, R e_y, R e_z`` of the unit quaternion ``(w, x, y, z)``."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    return (
        ca.vertcat(1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)),
        ca.vertcat(2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)),
        ca.vertcat(2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)),
    )


def section_ends_jacobian(arm: CBHAArm, x: ca.SX) -> tuple[ca.SX, ca.SX]:
    """End positions of the sections ``(3 S,)`` [m] and their geometric Jacobian ``(3 S, 3 (N - 1))``.

    Parameters
    ----------
    arm:
        The CBHA (its :meth:`~optikin.arms.cbha.CBHAArm.section_frames`, tool offset included).
    x:
        Configuration ``3 (N - 1) x 1`` (SX).

    Returns
    -------
    tuple of casadi.SX
        The stacked end positions of :meth:`~optikin.arms.cbha.CBHAArm.section_frames` and
        ``d ends / d x`` by the rotation axes of seed 004 eq. (5) (module docstring).
    """
    chain = arm.vertebra_chain(x)
    frames = arm.section_frames(x)
    ends = [pos for _, pos in frames]
    last = arm.section_end_vertebrae
    rows = []
    for s, e in enumerate(ends):
        columns = []
        for k in range(arm.geometry.n_platforms):
            if k >= last[s]:
                columns.append(ca.SX.zeros(3, 3))
                continue
            _, y_axis, z_axis = _columns(chain[k][0])
            x_axis = _columns(chain[k + 1][0])[0]
            arm_to_end = e - chain[k + 1][1]
            columns.append(ca.horzcat(z_axis, ca.cross(y_axis, arm_to_end), ca.cross(x_axis, arm_to_end)))
        rows.append(ca.horzcat(*columns))
    return ca.vertcat(*ends), ca.vertcat(*rows)


def newton_step_function(arm: CBHAArm, elongation: str = NR_ELONGATION, step: bool = True) -> ca.Function:
    """``[x; ends] -> [x_new; max|r|; ||r||; max|x_new - x|; outside; L_1..L_3]`` at ``x`` (module docstring).

    Parameters
    ----------
    arm:
        The CBHA.
    elongation:
        The reading of seed 004's distribution (:data:`optikin.ik.cbha.DISTRIBUTIONS`).
    step:
        False: only the checks of ``x`` (no Jacobian, no ``x_new``; the step size reads 0).

    Returns
    -------
    casadi.Function
        One packed input ``(3 (N - 1) + 3 S,)``: the configuration, then the measured section
        ends [m] in the base frame; one packed output: the Newton step's end point clipped to the
        bounds of ``x``, ``max |r|`` and ``||r||`` [m], the max-norm of the (clipped) step, the
        largest relative bound or Table I violation of ``x`` (negative inside) and the whole tube
        lengths [m] of ``x``.
    """
    geometry = arm.geometry
    n = arm.n_config
    x = ca.SX.sym("x", n)
    measured = ca.SX.sym("ends", 3 * arm.n_sections)
    a, b = distribution_coefficients(geometry, elongation)
    legs = [arm.leg_length_expressions(x)[3 * k : 3 * k + 3] for k in range(geometry.n_platforms)]
    lower, upper = arm.leg_limits()
    span = ca.DM(arm.upper - arm.lower)
    all_legs = ca.vertcat(*legs)
    outside = ca.mmax(
        ca.vertcat(
            ca.fmax(ca.DM(arm.lower) - x, x - ca.DM(arm.upper)) / span,
            ca.fmax(ca.DM(lower) - all_legs, all_legs - ca.DM(upper)) / ca.DM(np.maximum(upper - lower, 1e-300)),
        )
    )
    slices = section_slices(geometry)
    tubes = [sum(legs[k] for k in range(platforms.start, platforms.stop)) for platforms in slices]
    section_rows = [
        [legs[k] - a[k] - b[k] * tube for k in range(platforms.start, platforms.stop - 1)]
        for platforms, tube in zip(slices, tubes)
    ]
    rows = [row for own in section_rows for row in own]
    name = f"{arm.name}_sections_newton_{'step' if step else 'check'}"
    if not step:
        ends = ca.vertcat(*[pos for _, pos in arm.section_frames(x)])
        r = ca.vertcat(ends - measured, *rows)
        out = ca.vertcat(ca.norm_inf(r), ca.norm_2(r), 0.0, outside, sum(tubes))
        return ca.Function(name, [ca.vertcat(x, measured)], [out], ["x_ends"], ["check"], {"cse": True})
    ends, P = section_ends_jacobian(arm, x)
    r_ends = ends - measured
    u, V, section_of = [], [], []
    for s, (platforms, own) in enumerate(zip(slices, section_rows)):
        for k, r_k in zip(range(platforms.start, platforms.stop), own + [-sum(own)]):
            A_k = ca.jacobian(legs[k], x[3 * k : 3 * k + 3])
            solved = ca.solve(A_k, ca.horzcat(r_k, b[k] * ca.SX.eye(3)))
            u.append(solved[:, 0])
            V.append(solved[:, 1:])
            section_of.append(s)
    m = 3 * arm.n_sections
    M = ca.SX.zeros(m, m)
    rhs = -r_ends
    for k, s in enumerate(section_of):
        P_k = P[:, 3 * k : 3 * k + 3]
        M[:, 3 * s : 3 * s + 3] += ca.mtimes(P_k, V[k])
        rhs += ca.mtimes(P_k, u[k])
    dS = ca.solve(M, rhs)
    dx = ca.vertcat(*[-u[k] + ca.mtimes(V[k], dS[3 * s : 3 * s + 3]) for k, s in enumerate(section_of)])
    r = ca.vertcat(r_ends, *rows)
    x_new = ca.fmin(ca.fmax(x + dx, ca.DM(arm.lower)), ca.DM(arm.upper))
    out = ca.vertcat(x_new, ca.norm_inf(r), ca.norm_2(r), ca.norm_inf(x_new - x), outside, sum(tubes))
    return ca.Function(name, [ca.vertcat(x, measured)], [out], ["x_ends"], ["step"], {"cse": True})


def fixed_newton_function(arm: CBHAArm, steps: int = FIXED_STEPS, elongation: str = NR_ELONGATION) -> ca.Function:
    """``[x0; ends] -> [x_steps; max|r|; ||r||; 0; outside; L_1..L_3]``: ``steps`` full Newton steps of
    :func:`newton_step_function` in one call (a loop in the generated C), then the checks of the last point.

    Parameters
    ----------
    arm:
        The CBHA.
    steps:
        Newton steps, each clipped to the bounds, without a line search.
    elongation:
        The reading of seed 004's distribution (:data:`optikin.ik.cbha.DISTRIBUTIONS`).

    Returns
    -------
    casadi.Function
        Input as :func:`newton_step_function`; output the last point ``(3 (N - 1),)`` then the
        check-only output of :func:`newton_step_function` at it.
    """
    n, m = arm.n_config, 3 * arm.n_sections
    step = newton_step_function(arm, elongation)
    x, ends = ca.MX.sym("x", n), ca.MX.sym("ends", m)
    core = ca.Function("newton_point", [x, ends], [step(ca.vertcat(x, ends))[:n]])
    packed = ca.MX.sym("x_ends", n + m)
    last = core.mapaccum("newton_steps", steps)(packed[:n], ca.repmat(packed[n:], 1, steps))[:, -1]
    checks = newton_step_function(arm, elongation, step=False)(ca.vertcat(last, packed[n:]))
    return ca.Function(f"{arm.name}_sections_newton_{steps}", [packed], [ca.vertcat(last, checks)], ["x_ends"], ["x"])


class Posture(NamedTuple):
    """One posture's answer: configuration ``(48,)``, whole tube lengths ``(3,)`` [m] (NaN unless ``ok``),
    status, message, step evaluations and ``||r||`` [m]."""

    x: np.ndarray
    lengths: np.ndarray
    status: str
    message: str
    iterations: int
    residual: float


class ExactTubeLengths:
    """Exact tube lengths of a CBHA from its section ends, one posture per call (module docstring).

    Parameters
    ----------
    arm:
        The CBHA.
    compiled:
        Code-generate the step and check Functions and compile them (cached on disk by content);
        else CasADi's SX virtual machine.
    """

    def __init__(self, arm: CBHAArm, compiled: bool = True):
        if arm.periodic.any():
            raise ValueError(f"{arm.name}: the exact tube lengths assume no wrapping angle")
        self.arm = arm
        self.problem = newton_raphson_problem(arm)
        self.rest = rest_configuration(arm)
        n = self.n = arm.n_config
        self._packed = np.zeros(n + 3 * arm.n_sections)  # [x; ends], the input of both Functions
        self._x, self._ends = self._packed[:n], self._packed[n:]
        self._step_out = np.zeros(n + 7)
        self._check_out = np.zeros(7)
        self._previous = np.zeros(n)
        self._full = np.zeros(n)
        self._buffers: list[tuple[ca.Function, Any]] = []
        self._step = self._bind(newton_step_function(arm), self._step_out, compiled)
        self._check = self._bind(newton_step_function(arm, step=False), self._check_out, compiled)
        self._fixed_out = np.zeros(n + 7)
        self._fixed = self._bind(fixed_newton_function(arm), self._fixed_out, compiled)
        self._track: list[np.ndarray] = []

    def _bind(self, f: ca.Function, out: np.ndarray, compiled: bool) -> Callable[[], None]:
        """``f`` evaluated in place from :attr:`_packed` into ``out`` (``Function.buffer``)."""
        function = compile_function(f) if compiled else f
        buffer, evaluate = function.buffer()
        handle = cast(Any, buffer)  # CasADi's stub asks for a byte count its binding does not take
        handle.set_arg(0, self._packed.data)
        handle.set_res(0, out.data)
        self._buffers.append((function, handle))  # alive as long as self
        return evaluate

    @calls_casadi
    def solve(self, ends: np.ndarray, start: np.ndarray | None = None) -> Posture:
        """The posture whose section ends (base frame, ``(3 S,)`` [m], base to tip) are ``ends``.

        Newton from ``start`` (default: the straight configuration); see the module docstring.
        First :data:`FIXED_STEPS` full steps in one compiled call; if they do not reach the
        tolerance within the bounds, the iteration with its line search from ``start``, one
        compiled step per call. Once ``max |r| <= FINAL_STEP_RESIDUAL`` the next point is checked
        by the cheaper Function without the Jacobian (quadratic convergence puts it far below the
        tolerance); should it not be converged, the iteration goes on from it.
        """
        n = self.n
        self._ends[:] = ends
        self._x[:] = self.rest if start is None else start
        self._fixed()
        fixed = self._fixed_out
        if fixed[n] <= ROOT_TOLERANCE and fixed[n + 3] <= BOUND_TOLERANCE:
            self._x[:] = fixed[:n]
            return self._verdict(FIXED_STEPS + 1, fixed[n:])
        self._x[:] = self.rest if start is None else start
        step, check, x, previous, full = self._step, self._check, self._x, self._previous, self._full
        out = self._step_out
        step()
        iterations = FIXED_STEPS + 2
        info = out[n:]
        while info[0] > ROOT_TOLERANCE and info[2] > STEP_TOLERANCE and iterations < MAX_ITERATIONS:
            rn, final = info[1], info[0] <= FINAL_STEP_RESIDUAL
            previous[:] = x
            full[:] = out[:n]
            x[:] = full
            (check if final else step)()
            iterations += 1
            info = self._check_out if final else out[n:]
            if info[1] < rn or info[0] <= ROOT_TOLERANCE:
                if final and info[0] > ROOT_TOLERANCE:  # not converged after all: the step from here
                    step()
                    iterations += 1
                    info = out[n:]
                continue
            accepted, t = False, 0.5  # backtrack along the (clipped) step: stays within the bounds
            while iterations < MAX_ITERATIONS and t >= SMALLEST_STEP:
                x[:] = previous + t * (full - previous)
                step()
                iterations += 1
                info = out[n:]
                if info[1] < rn:
                    accepted = True
                    break
                t *= 0.5
            if not accepted:  # back to the best point, whose checks the verdict reads
                x[:] = previous
                step()
                info = out[n:]
                break
        return self._verdict(iterations, info)

    def track(self, ends: np.ndarray) -> Posture:
        """The next posture of a trajectory: Newton from the linear extrapolation of the last two ``ok``
        solutions (clipped to the bounds; from the last one, or the straight configuration, before
        there are two). :meth:`reset` starts a new trajectory."""
        if len(self._track) == 2:
            start: np.ndarray | None = np.clip(2.0 * self._track[1] - self._track[0], self.arm.lower, self.arm.upper)
        else:
            start = self._track[-1] if self._track else None
        posture = self.solve(ends, start)
        if posture.status == Status.OK:
            self._track = [*self._track[-1:], posture.x]
        return posture

    def reset(self) -> None:
        """Forget the trajectory of :meth:`track`."""
        self._track = []

    def _verdict(self, iterations: int, info: np.ndarray) -> Posture:
        """The status of the point in the input buffer, whose checks are ``info``."""
        x = self._x.copy()
        rn, outside = float(info[1]), float(info[3])
        lengths = info[4:7].copy()
        if not math.isfinite(rn):
            return Posture(x, np.full(3, np.nan), Status.FAILED, "non-finite solution", iterations, rn)
        if outside > BOUND_TOLERANCE:
            message = self.problem.violation_message(x)
            return Posture(x, np.full(3, np.nan), Status.FAILED, message, iterations, rn)
        if rn <= self.problem.tolerance:
            return Posture(x, lengths, Status.OK, "", iterations, rn)
        status, rn, message = self.problem.classify(x, self._ends.copy(), 0.0, np.inf)
        return Posture(x, lengths if status == Status.OK else np.full(3, np.nan), status, message, iterations, rn)

    def run(self, targets: np.ndarray) -> ComparatorRun:
        """The postures ``targets`` ``(N, 3 S)`` in order by :meth:`track` (a new trajectory), timed one by one:
        the ``newton-raphson`` comparator's contract."""
        targets = np.atleast_2d(np.asarray(targets, dtype=float))
        lengths, seconds = np.full((len(targets), 3), np.nan), np.zeros(len(targets))
        status, messages = [], []
        self.reset()
        for i, measured in enumerate(targets):
            tic = time.perf_counter()
            posture = self.track(measured)
            seconds[i] = time.perf_counter() - tic
            lengths[i] = posture.lengths
            status.append(posture.status)
            messages.append(posture.message)
        return ComparatorRun(lengths, seconds, status, messages)
