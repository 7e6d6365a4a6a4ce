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
damping that adapts to the gain ratio does the minimisation.

Which equilibrium. More than one equilibrium can reach the same end poses: besides the
gently bent rod, stretched, sheared, coiled ones under tip forces of hundreds of newtons
(from another rod's fit, 24-135 mm off the truth with 1000 times its elastic energy, in
``tests/test_physics_reconstruction.py``). A fit converges to the one nearest its start, so
the start decides. Every fit of :meth:`ShapeReconstructor.reconstruct_sequence` therefore
starts from the circular arc of its own end poses (:meth:`ShapeReconstructor.arc_start`);
the previous sample's fit is tried as a second candidate only, and of the candidates that
reach the tolerance the one of lowest elastic energy is kept. When two of them reach it with
shapes more than ``ambiguity_distance`` apart, the result says ``ambiguous`` and reports the
spread, the fitted wrench and the energy. Without a start, :meth:`ShapeReconstructor.reconstruct`
moves the target from the unloaded rod's tip by continuation.

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

from optikin.algebra import matrix_from_quat, quat_conjugate, quat_multiply, quat_rotate, quat_slerp
from optikin.options import Options
from optikin.physics.model import STATE_SIZE, ArmEquations, Loads, RodArm, load_vector
from optikin.physics.solution import RodSolution
from optikin.status import Status

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
    ambiguity_distance: float = Field(
        1e-3,
        gt=0,
        description="two candidate fits within tolerance whose shapes differ by more than this at some node mark "
        "the reconstruction ambiguous [m]",
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
        Levenberg-Marquardt iterations of the kept candidate.
    seconds : float
        Wall time of the fit, every candidate [s].
    energy : float
        Elastic energy of the kept shape [J] (:meth:`ShapeReconstructor.elastic_energy`).
    candidates : int
        Candidate fits that reached the tolerance (the kept one among them).
    spread : float
        Largest node distance between the kept shape and another candidate within tolerance [m] (0 for one).
    ambiguous : bool
        ``spread`` exceeds the options' ``ambiguity_distance``: other equilibria reach the same end
        poses, and the kept one is only the lowest in elastic energy.
    """

    solution: RodSolution
    wrench: np.ndarray
    residual: np.ndarray
    status: Literal[Status.OK, Status.NOT_CONVERGED]
    iterations: int
    seconds: float
    energy: float = float("nan")
    candidates: int = 1
    spread: float = 0.0
    ambiguous: bool = False


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
        segment = np.concatenate([[0], np.repeat(np.arange(len(arm.segments)), n)])
        rods = [seg.rod for seg in arm.segments]
        self._bending = np.stack([1.0 / rods[k].K_bt for k in segment], axis=1)  # (3, S) compliances
        self._shear = np.stack(
            [np.zeros(3) if rods[k].model == "kirchhoff" else 1.0 / rods[k].K_se for k in segment], axis=1
        )

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

    def elastic_energy(self, states: np.ndarray, scale: float = 1.0) -> float:
        """Elastic energy [J] of a shape ``states`` ``(13, S)`` on this reconstructor's nodes.

        ``int 1/2 (m_b . K_bt^-1 m_b + n_b . K_se^-1 n_b) ds`` with ``n_b, m_b`` the internal force and
        moment in the material frame (the constitutive law of :mod:`optikin.physics.rod` inverted),
        trapezoidal over the nodes at ``scale`` times their reference arc length; a Kirchhoff
        segment has no shear-extension term (its ``n`` is a constraint force).
        """
        to_material = quat_conjugate(states[3:7].T)
        n_b = quat_rotate(to_material, states[7:10].T, check=False).T
        m_b = quat_rotate(to_material, states[10:13].T, check=False).T
        density = 0.5 * (np.sum(m_b**2 * self._bending, axis=0) + np.sum(n_b**2 * self._shear, axis=0))
        s = self.s * float(scale)
        return float(np.sum(0.5 * (density[1:] + density[:-1]) * np.diff(s)))

    def arc_start(self, base_pose: Pose, tip_pose: Pose, length: float | None = None) -> np.ndarray:
        """The unknowns of the circular arc of the end poses: the start every fit should have.

        A pure couple ``E I theta / L`` about ``t0 x t1`` (``theta`` the angle between the end
        tangents, ``E I`` the first segment's) bends a weightless rod into that arc (Euler's
        elastica under an end couple); the clamp force ``n(0) = int rho A g ds`` carries the rods'
        weight (``n' + f = 0``, free tip); a fitted distributed force starts at zero.
        """
        t0 = matrix_from_quat(np.asarray(base_pose[1], dtype=float), check=False)[:, 2]
        t1 = matrix_from_quat(np.asarray(tip_pose[1], dtype=float), check=False)[:, 2]
        scale = 1.0 if length is None else float(length) / self.arm.length
        axis = np.cross(t0, t1)
        sine = float(np.linalg.norm(axis))
        theta = float(np.arctan2(sine, float(t0 @ t1)))
        bending = self.arm.segments[0].rod.EI
        L = scale * self.arm.length
        couple = bending * theta / L * axis / sine if sine > 1e-12 else np.zeros(3)
        mass = sum(seg.rod.density * seg.rod.A * seg.rod.length for seg in self.arm.segments) * scale
        force = mass * np.asarray(self.P_fixed[9:12], dtype=float)
        return np.concatenate([force, couple] + ([np.zeros(3)] if self.options.distributed_force else []))

    def _start_fit(self, args: list, guess: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float, int]:
        """The fit from ``guess``, or by continuation from the unknowns zero when there is none or it fails."""
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
        return z, r, cost, iterations

    def reconstruct(
        self,
        base_pose: Pose,
        tip_pose: Pose,
        length: float | None = None,
        guess: np.ndarray | None = None,
        candidates: Sequence[np.ndarray] = (),
    ) -> tuple[Reconstruction, np.ndarray]:
        """One shape: ``(reconstruction, base-and-load unknowns)`` (the second can be a candidate of the next fit).

        The fit from ``guess`` (by continuation when it has none or fails) and one plain fit from
        each of ``candidates``; of those reaching the tolerance, the shape of lowest elastic energy
        (:meth:`elastic_energy`) is kept, the one from ``guess`` unless another is lower by more than
        a millionth. Equilibria other than the intended one can reach the same end poses (a coiled,
        stretched rod under a tip force of a hundred newtons), so a candidate carried over from
        another posture must not win by having been tried first; when two candidates within
        tolerance differ by more than ``ambiguity_distance`` at some node the result is marked
        ``ambiguous``.

        Parameters
        ----------
        base_pose, tip_pose : tuple of numpy.ndarray
            Measured ``(position (3,) [m], quaternion (4,))`` of the clamp and the tip.
        length : float, optional
            Reference length of the arm [m]; None: the arm's own.
        guess : numpy.ndarray, optional
            ``(6,)`` or ``(9,)`` start: base wrench (then distributed force); default: by continuation
            from zero (:meth:`arc_start` is the better start for a bent rod).
        candidates : sequence of numpy.ndarray
            More starts of the same layout (e.g. the previous posture's fit).
        """
        tic = time.perf_counter()
        args = self._pose_inputs(base_pose, tip_pose, length)
        tol = self.options.tolerance
        fits = [self._start_fit(args, guess)]
        fits += [self._fit(np.array(c, dtype=float), args, tol, self.options.max_iterations) for c in candidates]
        shapes = []
        for z, r, cost, iterations in fits:
            states, loads = (np.asarray(a) for a in self._shape(z, *args))
            energy = self.elastic_energy(states, float(args[2])) if np.all(np.isfinite(states)) else np.inf
            shapes.append((z, r, cost, iterations, states, loads, energy))
        within = [f for f in shapes if np.sqrt(f[2]) <= tol]
        spread = 0.0
        if within:
            kept = within[0]
            for other in within[1:]:
                if other[6] < kept[6] - 1e-6 * abs(kept[6]):
                    kept = other
            for other in within:
                spread = max(spread, float(np.max(np.linalg.norm(other[4][0:3] - kept[4][0:3], axis=0))))
        else:
            kept = min(shapes, key=lambda f: f[2] if np.isfinite(f[2]) else np.inf)
        z, r, cost, iterations, states, loads, energy = kept
        solution = RodSolution.from_states(self.s * float(args[2]), states, 0.0, np.inf, iterations)
        status: Literal[Status.OK, Status.NOT_CONVERGED] = Status.OK if np.sqrt(cost) <= tol else Status.NOT_CONVERGED
        result = Reconstruction(
            solution,
            loads.ravel(),
            r,
            status,
            iterations,
            time.perf_counter() - tic,
            energy,
            len(within),
            spread,
            spread > self.options.ambiguity_distance,
        )
        return result, z

    def reconstruct_sequence(
        self,
        base_poses: Sequence[Pose],
        tip_poses: Sequence[Pose],
        lengths: Sequence[float] | np.ndarray | None = None,
        start: Start | None = None,
        previous_candidate: bool = True,
    ) -> list[Reconstruction]:
        """Shapes along a recording, each fit started from ``start`` (default: the arc of its own end poses).

        Parameters
        ----------
        base_poses, tip_poses : sequence of pose
            One per sample.
        lengths : sequence of float, optional
            Reference length per sample [m]; None: the arm's own.
        start : callable, optional
            ``start(i, previous) -> guess``: the start of sample ``i``'s fit given ``previous``,
            the unknowns ``(6,)`` or ``(9,)`` (base wrench, then distributed force) the fit of
            sample ``i - 1`` ended at (None for the first sample and after a non-finite one);
            a None guess starts from the unknowns zero by continuation (:meth:`reconstruct`).
            Default: :meth:`arc_start` of the sample's end poses.
        previous_candidate : bool
            Also fit from ``previous`` and keep it only if its shape has less elastic energy
            (:meth:`reconstruct`): never as the only start, since the last posture's equilibrium
            branch need not be this one's.
        """
        out: list[Reconstruction] = []
        previous: np.ndarray | None = None
        for i, (base, tip) in enumerate(zip(base_poses, tip_poses)):
            length = None if lengths is None else float(lengths[i])
            guess = self.arc_start(base, tip, length) if start is None else start(i, previous)
            extra = [previous] if previous_candidate and previous is not None else []
            result, z = self.reconstruct(base, tip, length, guess, extra)
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
