"""Backbone shapes from end poses by the physics: the tip wrench whose equilibrium reaches the measured tip.

Given a rod arm's stiffness and (reference) length, the measured base pose (where it
is clamped) and the measured tip pose, the unknown is the wrench at the tip, force
``F`` and couple ``C`` (6), optionally with a uniform distributed force ``f`` (3 more).
Its equilibrium is the static Cosserat rod of :mod:`optikin.physics.rod` (gravity and
actuation as given, fixed); the reconstruction is the least-squares problem

    min over (F, C[, f])   |p(L) - p_meas|^2 + ell^2 |e(q(L), q_meas)|^2,

with ``e = 2 w v`` of ``q_meas^-1 q(L) = (w, v)`` (``sin(theta)`` times the rotation axis:
zero exactly when the orientations agree, sign-free in the quaternion) and ``ell`` a
length (default: the arm's length) that makes an orientation error comparable with a
position error. For a rod loaded at its tip only this has the true shape as its
zero-residual solution, up to the model's error.

How it is solved. A tip wrench and a base wrench ``w = (n(0), m(0))`` determine each
other one-to-one through the equilibrium with the other loads fixed (integrate from
the clamp with ``w``; the tip wrench is ``(n(L), m(L))`` less the point loads of
actuators ending at the tip), so the problem is posed over ``w``: each evaluation is
one RK4 integration from the clamp (the initial-value problem of the shooting
method, :mod:`optikin.physics.shooting`, without its Newton loop on the tip
residual), and its Jacobian ``d (p(L), e) / d w`` comes from CasADi's forward
derivatives through the integration. That is the Jacobian of the same residual with
respect to the tip wrench that the implicit function theorem gives
(:meth:`~optikin.physics.ShootingSolver.jacobian_wrt_loads`) times the invertible
``d (F, C) / d w``, so the Gauss-Newton steps find the same minimiser, without a
nested boundary-value solve per iteration. Levenberg-Marquardt (Marquardt 1963;
Nocedal & Wright, *Numerical Optimization*, 2nd ed., section 10.3) with a diagonal
damping that adapts to the gain ratio does the minimisation; the start is the
previous sample's base wrench (:meth:`ShapeReconstructor.reconstruct_sequence`) or
the straight rod's (zero).

With the distributed force the problem has 9 unknowns and 6 residuals: the damped
steps pick one of the many exact solutions (near the start), not the true load.

The reference length may be set per call (``length``): every segment is scaled by
``length / arm.length``, the stiffnesses kept. That is how a backbone length
estimated from the end poses alone (as the PH method of
:mod:`optikin.curves.min_energy` uses) enters without a new integrator per sample.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Literal, Sequence

import casadi as ca
import numpy as np
from pydantic import Field

from optikin.algebra import matrix_from_quat, quat_conjugate, quat_multiply, quat_slerp
from optikin.options import Options
from optikin.physics.model import STATE_SIZE, ArmEquations, Loads, RodArm, load_vector
from optikin.physics.solution import RodSolution

Pose = tuple[np.ndarray, np.ndarray]
"""``(position (3,) [m], unit quaternion (4,) (w, x, y, z))``."""
Start = Callable[[int, np.ndarray | None], np.ndarray | None]
"""``start(i, previous) -> guess`` of :meth:`ShapeReconstructor.reconstruct_sequence`."""


class ReconstructionOptions(Options):
    """Settings of :class:`ShapeReconstructor`."""

    steps_per_segment: int = Field(100, ge=1, description="RK4 steps per segment")
    distributed_force: bool = Field(False, strict=True, description="also fit a uniform distributed force [N/m]")
    orientation_length: float | None = Field(
        None, gt=0, description="length ell scaling the orientation residual [m]; None: the reference length"
    )
    tolerance: float = Field(1e-11, gt=0, description="residual norm at which the fit stops [m]")
    max_iterations: int = Field(60, ge=1, description="Levenberg-Marquardt iterations")
    continuation_steps: int = Field(
        8,
        ge=1,
        description="without a start (or when it fails): targets from the unknowns-zero tip to the measured one "
        "in this many steps, doubled up to 3 times until the fit converges",
    )


@dataclass(frozen=True)
class Reconstruction:
    """One reconstructed shape.

    Attributes
    ----------
    solution : RodSolution
        The equilibrium under the fitted loads (its tip residual is zero by construction).
    wrench : numpy.ndarray
        ``(6,)`` or ``(9,)``: tip force [N] and couple [N m] in the arm's tip frames
        (``tip_force_frame``, ``tip_couple_frame``), then the distributed force [N/m] if fitted.
    residual : numpy.ndarray
        ``(6,)`` tip position error [m] and ``ell`` times the orientation error [m].
    status : str
        ``"ok"`` when ``|residual| <= tolerance``, else ``"not_converged"``.
    iterations : int
        Levenberg-Marquardt iterations.
    seconds : float
        Wall time of the fit [s].
    """

    solution: RodSolution
    wrench: np.ndarray
    residual: np.ndarray
    status: Literal["ok", "not_converged"]
    iterations: int
    seconds: float


class ShapeReconstructor:
    """Tip wrenches (and shapes) of an arm from its end poses (module docstring).

    Parameters
    ----------
    arm : RodArm
        Stiffness, lengths, actuators and tip-load frames; its base pose is replaced by the measured one.
    options : ReconstructionOptions
        Grid, unknowns, residual scaling and stopping.
    loads : Loads, optional
        The loads held fixed (gravity, actuation, and the distributed force when it is not
        fitted); tip force and couple are ignored. Default: the rods' gravity only.
    """

    def __init__(self, arm: RodArm, options: ReconstructionOptions | None = None, loads: Loads | None = None) -> None:
        self.arm = arm
        self.options = options or ReconstructionOptions()
        self.n_unknowns = 9 if self.options.distributed_force else 6
        P_fixed = load_vector(arm, loads or Loads(actuation=(0.0,) * len(arm.actuator_names)))
        P_fixed[0:6] = 0.0
        self.P_fixed = P_fixed
        eq = ArmEquations(arm)
        n, bounds = self.options.steps_per_segment, arm.boundaries
        z = ca.MX.sym("z", self.n_unknowns)
        p0, q0, scale = ca.MX.sym("p0", 3), ca.MX.sym("q0", 4), ca.MX.sym("scale")
        target_p, target_q, ell = ca.MX.sym("p1", 3), ca.MX.sym("q1", 4), ca.MX.sym("ell")
        P = ca.MX(ca.DM(P_fixed))
        if self.options.distributed_force:
            P = ca.vertcat(P[0:6], z[6:9], P[9:])
        xs, ss, hs, Ps = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("s"), ca.SX.sym("h"), ca.SX.sym("P", eq.n_loads)
        x = ca.vertcat(p0, q0, z[0:6])
        columns, s_nodes = [x], [0.0]
        for k in range(len(arm.segments)):
            k1 = eq.rhs(k, ss, xs, Ps)
            k2 = eq.rhs(k, ss + hs / 2, xs + hs / 2 * k1, Ps)
            k3 = eq.rhs(k, ss + hs / 2, xs + hs / 2 * k2, Ps)
            k4 = eq.rhs(k, ss + hs, xs + hs * k3, Ps)
            xn = xs + hs / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            xn = ca.vertcat(xn[0:3], xn[3:7] / ca.norm_2(xn[3:7]), xn[7:13])
            step = ca.Function(f"reconstruction_rk4_{k}", [xs, ss, hs, Ps], [xn]).mapaccum(n)
            h = (bounds[k + 1] - bounds[k]) / n
            s_row = bounds[k] + h * np.arange(n)
            X = step(x, scale * ca.DM(s_row).T, scale * h * ca.DM.ones(1, n), ca.repmat(P, 1, n))
            x = X[:, -1]
            if k < len(arm.segments) - 1:
                x = eq.junction_function(k)(x, P)
                X = ca.horzcat(X[:, :-1], x)
            columns.append(X)
            s_nodes += list(bounds[k] + h * np.arange(1, n + 1))
        states = ca.horzcat(*columns)
        tip_wrench = eq.tip_residual_function(x, P)  # n(L), m(L) plus the point loads ending there: the tip load
        R = matrix_from_quat(x[3:7], check=False)
        force = R.T @ tip_wrench[0:3] if arm.tip_force_frame == "follower" else tip_wrench[0:3]
        couple = R.T @ tip_wrench[3:6] if arm.tip_couple_frame == "follower" else tip_wrench[3:6]
        loads_out = ca.vertcat(force, couple, z[6:9]) if self.options.distributed_force else ca.vertcat(force, couple)
        dq = quat_multiply(quat_conjugate(target_q), x[3:7])
        residual = ca.vertcat(x[0:3] - target_p, ell * 2 * dq[0] * dq[1:4])
        inputs = [z, p0, q0, scale, target_p, target_q, ell]
        self._residual = ca.Function("reconstruction_residual", inputs, [residual, ca.jacobian(residual, z)])
        self._shape = ca.Function("reconstruction_shape", inputs, [states, loads_out])
        self.s = np.array(s_nodes)

    def _pose_inputs(self, base: Pose, tip: Pose, length: float | None) -> list[np.ndarray | float]:
        scale = 1.0 if length is None else float(length) / self.arm.length
        ell = self.options.orientation_length or scale * self.arm.length
        q0 = np.asarray(base[1], dtype=float)
        q1 = np.asarray(tip[1], dtype=float)
        return [np.asarray(base[0], float), q0 / np.linalg.norm(q0), scale, np.asarray(tip[0], float), q1, ell]

    def _fit(
        self, z: np.ndarray, args: list, tol: float, max_iterations: int
    ) -> tuple[np.ndarray, np.ndarray, float, int]:
        """Levenberg-Marquardt from ``z``: ``(z, residual, cost, iterations)`` (``tol`` 0: ``max_iterations`` steps)."""
        r, J = (np.asarray(a) for a in self._residual(z, *args))
        r = r.ravel()
        cost = float(r @ r)
        damping, nu, iterations = None, 2.0, 0
        while iterations < max_iterations and np.isfinite(cost) and np.sqrt(cost) > tol:
            iterations += 1
            A, g = J.T @ J, J.T @ r
            scaling = np.maximum(np.diag(A), 1e-300)
            if damping is None:
                damping = 1e-9
            step = np.linalg.solve(A + damping * np.diag(scaling), -g)
            r_new, J_new = (np.asarray(a) for a in self._residual(z + step, *args))
            r_new = r_new.ravel()
            new = float(r_new @ r_new)
            predicted = float(-(2 * g @ step + step @ A @ step))
            if np.isfinite(new) and new < cost:
                rho = (cost - new) / max(predicted, 1e-300)
                z, r, J, cost = z + step, r_new, J_new, new
                damping *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
            else:
                damping *= nu
                nu *= 2.0
            if float(np.linalg.norm(step)) <= 1e-15 * (1.0 + float(np.linalg.norm(z))):
                break
        return z, r, cost, iterations

    def _continuation(self, args: list, steps: int) -> tuple[np.ndarray, np.ndarray, float, int]:
        """From the unknowns zero, targets moved from that tip pose to the measured one in ``steps`` steps."""
        z = np.zeros(self.n_unknowns)
        states = np.asarray(self._shape(z, *args)[0])
        start_p, start_q = states[0:3, -1], states[3:7, -1]
        iterations = 0
        for t in np.arange(1, steps) / steps:
            target = [*args[:3], start_p + t * (args[3] - start_p), quat_slerp(start_q, args[4], t), args[5]]
            z, _, _, more = self._fit(z, target, 0.0, 4)
            iterations += more
        z, r, cost, more = self._fit(z, args, self.options.tolerance, self.options.max_iterations)
        return z, r, cost, iterations + more

    def reconstruct(
        self, base_pose: Pose, tip_pose: Pose, length: float | None = None, guess: np.ndarray | None = None
    ) -> tuple[Reconstruction, np.ndarray]:
        """One shape: ``(reconstruction, base-and-load unknowns)`` (the second starts the next sample's fit).

        Parameters
        ----------
        base_pose, tip_pose : tuple of numpy.ndarray
            Measured ``(position (3,) [m], quaternion (4,))`` of the clamp and the tip.
        length : float, optional
            Reference length of the arm [m]; None: the arm's own.
        guess : numpy.ndarray, optional
            ``(6,)`` or ``(9,)`` start: base wrench (then distributed force); default zero.
        """
        tic = time.perf_counter()
        args = self._pose_inputs(base_pose, tip_pose, length)
        iterations, tol = 0, self.options.tolerance
        if guess is not None:
            z, r, cost, iterations = self._fit(np.array(guess, dtype=float), args, tol, self.options.max_iterations)
        steps = self.options.continuation_steps
        while guess is None or not np.sqrt(cost) <= tol:
            z, r, cost, more = self._continuation(args, steps)
            iterations += more
            if np.sqrt(cost) <= tol or steps >= 8 * self.options.continuation_steps:
                break
            steps *= 2
        states, loads = (np.asarray(a) for a in self._shape(z, *args))
        solution = RodSolution.from_states(self.s * float(args[2]), states, 0.0, np.inf, iterations)
        status: Literal["ok", "not_converged"] = "ok" if np.sqrt(cost) <= tol else "not_converged"
        result = Reconstruction(solution, loads.ravel(), r, status, iterations, time.perf_counter() - tic)
        return result, z

    def reconstruct_sequence(
        self,
        base_poses: Sequence[Pose],
        tip_poses: Sequence[Pose],
        lengths: Sequence[float] | np.ndarray | None = None,
        start: Start | None = None,
    ) -> list[Reconstruction]:
        """Shapes along a recording, each fit started from ``start`` (default: the previous sample's solution).

        Parameters
        ----------
        base_poses, tip_poses : sequence of pose
            One per sample.
        lengths : sequence of float, optional
            Reference length per sample [m]; None: the arm's own.
        start : callable, optional
            ``start(i, previous) -> guess``: the start of sample ``i``'s fit from ``previous``,
            the unknowns ``(6,)`` or ``(9,)`` (base wrench, then distributed force) the fit of
            sample ``i - 1`` ended at (None for the first sample and after a non-finite one);
            a None guess starts from the unknowns zero by continuation (:meth:`reconstruct`).
            Default: ``previous`` itself.
        """
        out: list[Reconstruction] = []
        previous: np.ndarray | None = None
        for i, (base, tip) in enumerate(zip(base_poses, tip_poses)):
            guess = previous if start is None else start(i, previous)
            result, z = self.reconstruct(base, tip, None if lengths is None else float(lengths[i]), guess)
            out.append(result)
            previous = z if np.all(np.isfinite(z)) else None
        return out


def reconstruct_shape(
    rod_arm: RodArm,
    base_pose: Pose,
    tip_pose: Pose,
    *,
    length: float | None = None,
    loads: Loads | None = None,
    options: ReconstructionOptions | None = None,
    guess: np.ndarray | None = None,
) -> tuple[RodSolution, np.ndarray, np.ndarray, str]:
    """The equilibrium of ``rod_arm`` clamped at ``base_pose`` whose tip reaches ``tip_pose`` (module docstring).

    Parameters
    ----------
    rod_arm : RodArm
        Stiffness and length of the rod (its base pose is replaced by ``base_pose``).
    base_pose, tip_pose : tuple of numpy.ndarray
        ``(position (3,) [m], unit quaternion (4,) (w, x, y, z))``.
    length : float, optional
        Reference length [m] (every segment scaled); None: the arm's.
    loads : Loads, optional
        Fixed loads (gravity, actuation); default the rods' gravity.
    options : ReconstructionOptions, optional
        Grid, unknowns, residual scaling.
    guess : numpy.ndarray, optional
        Start: base wrench ``(6,)`` (then the distributed force).

    Returns
    -------
    solution : RodSolution
        The shape.
    wrench : numpy.ndarray
        ``(6,)`` tip force [N] and couple [N m] (``(9,)`` with the distributed force [N/m]).
    residual : numpy.ndarray
        ``(6,)`` tip position error [m] and scaled orientation error [m].
    status : str
        ``"ok"`` or ``"not_converged"``.
    """
    result, _ = ShapeReconstructor(rod_arm, options, loads).reconstruct(base_pose, tip_pose, length, guess)
    return result.solution, result.wrench, result.residual, result.status


__all__ = ["Reconstruction", "ReconstructionOptions", "ShapeReconstructor", "reconstruct_shape"]
