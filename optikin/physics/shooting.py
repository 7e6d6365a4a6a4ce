"""The static BVP of a rod arm solved by shooting: RK4 on a fixed grid, Newton on the base wrench.

The unknown is the rod's wrench at the clamp, ``w = (n(0), m(0))`` (6). From it and
the clamped pose, classical RK4 (``steps_per_segment`` equal steps per segment,
the quaternion renormalised after each step) integrates the state to the tip,
crossing each disk by :meth:`~optikin.physics.model.ArmEquations.junction`; the
residual is ``(N(L) - F_tip, M(L) - C_tip)``. The integration is one CasADi
Function of ``(w, P)`` (a ``mapaccum`` of the SX step per segment), and the
residual's root is found by CasADi's ``rootfinder`` (plugin ``newton``) or, with
``compiled=True``, by a Newton iteration in numpy on two C-compiled Functions
(:class:`optikin.codegen.CompiledFunction`; an ``external`` Function has no
derivatives, so ``rootfinder`` cannot drive it): the shape with its residual, and
the residual's Jacobian, whose forward sensitivities are carried along the RK4
steps. The compiled iteration keeps the last Jacobian while the residual falls at
least tenfold per iteration (a simplified Newton, which along slowly varying loads
needs the Jacobian seldom) and refreshes it otherwise.

Along a sequence of loads each solve starts from the previous solution, linearly
extrapolated from the two before (:meth:`ShootingSolver.solve_sequence`). A solve
without a usable start ramps the loads from zero (where the straight rod is the
exact solution) in more and more steps until Newton converges at every one. The
derivatives of the equilibrium with respect to the loads come from the implicit
function theorem applied to the residual, which CasADi's rootfinder provides
(:meth:`ShootingSolver.jacobian_wrt_loads`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import casadi as ca
import numpy as np
from pydantic import Field

from optikin.algebra import matrix_from_quat, quat_conjugate, quat_multiply
from optikin.codegen import CompiledFunction, CompilerFlag
from optikin.errors import SolverError
from optikin.options import Options
from optikin.physics.model import STATE_SIZE, ArmEquations, Loads, RodArm, load_vector
from optikin.physics.solution import RodSolution


class ShootingOptions(Options):
    """Settings of :class:`ShootingSolver`."""

    steps_per_segment: int = Field(100, ge=1, description="RK4 steps per segment")
    tolerance: float = Field(1e-10, gt=0, description="largest accepted norm of the tip residual [N, N m]")
    max_iterations: int = Field(30, ge=1, description="Newton iterations per solve")
    max_ramp_steps: int = Field(256, ge=1, description="most load steps of the continuation from zero load")
    compiled: bool = Field(False, description="Newton on C-compiled residual and Jacobian instead of the VM")
    flags: tuple[CompilerFlag, ...] = Field(("-O3",), description="compiler flags when compiled")


@dataclass(frozen=True)
class LoadSensitivity:
    """Derivatives of an equilibrium with respect to the load vector ``P`` (implicit function theorem).

    Attributes
    ----------
    names : tuple of str
        The entries of ``P`` (:attr:`~optikin.physics.model.RodArm.load_names`), ``(n_P,)``.
    positions : numpy.ndarray
        ``(K, 3, n_P)`` d p(s_k) / d P [m per unit load].
    orientations : numpy.ndarray
        ``(K, 4, n_P)`` d q(s_k) / d P.
    base_wrench : numpy.ndarray
        ``(6, n_P)`` d (n(0), m(0)) / d P.
    solution : RodSolution
        The equilibrium they are taken at.
    """

    names: tuple[str, ...]
    positions: np.ndarray
    orientations: np.ndarray
    base_wrench: np.ndarray
    solution: RodSolution


class ShootingSolver:
    """Equilibria of a :class:`~optikin.physics.model.RodArm` by shooting.

    Parameters
    ----------
    arm : RodArm
        The arm.
    options : ShootingOptions
        Grid, tolerance, VM or compiled Newton.

    Attributes
    ----------
    s : numpy.ndarray
        ``(K,)`` arc length of the nodes, ``K = n_segments * steps_per_segment + 1``.
    shape : casadi.Function
        ``(w, P) -> (states 13 x K, residual 6)``.
    residual : casadi.Function
        ``(w, P) -> residual``.
    rootfinder : casadi.Function
        ``(w_guess, P) -> w``, Newton on :attr:`residual`.

    Raises
    ------
    optikin.errors.SolverError
        With ``compiled=True``, when compiling fails.
    """

    def __init__(self, arm: RodArm, options: ShootingOptions | None = None) -> None:
        self.arm = arm
        self.options = options or ShootingOptions()
        self.equations = ArmEquations(arm)
        n = self.options.steps_per_segment
        w, P = ca.MX.sym("w", 6), ca.MX.sym("P", self.equations.n_loads)
        x = self.equations.base_state(w)
        columns, s_nodes = [x], [0.0]
        bounds = arm.boundaries
        for k in range(len(arm.segments)):
            h = (bounds[k + 1] - bounds[k]) / n
            s_row = bounds[k] + h * np.arange(n)
            step = self.equations.rk4_step(k, h).mapaccum(n)
            X = step(x, ca.DM(s_row).T, ca.repmat(P, 1, n))
            x = X[:, -1]
            if k < len(arm.segments) - 1:
                x = self.equations.junction_function(k)(x, P)
                X = ca.horzcat(X[:, :-1], x)
            columns.append(X)
            s_nodes += list(bounds[k] + h * np.arange(1, n + 1))
        states = ca.horzcat(*columns)
        residual = self.equations.tip_residual_function(x, P)
        self.s = np.array(s_nodes)
        self.n_loads = self.equations.n_loads
        self.shape = ca.Function("cosserat_shape", [w, P], [states, residual], ["w", "P"], ["states", "residual"])
        self.residual = ca.Function("cosserat_residual", [w, P], [residual], ["w", "P"], ["residual"])
        self.rootfinder = ca.rootfinder(
            "cosserat_newton",
            "newton",
            self.residual,
            {
                "abstol": self.options.tolerance / 10,
                "abstolStep": 1e-14,
                "max_iter": self.options.max_iterations,
                "error_on_fail": False,
                "show_eval_warnings": False,  # a trial step can integrate to NaN: Newton rejects it, no print
            },
        )
        self._compiled_newton: CompiledFunction | None = None
        self._jacobian: np.ndarray | None = None  # the last Jacobian, reused while Newton contracts
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # the last compiled evaluation (z, out)
        self._compiled_shape: CompiledFunction | None = None
        if self.options.compiled:
            with_jacobian = self._residual_and_jacobian()
            z = ca.MX.sym("z", 6 + self.n_loads)
            wz, Pz = z[:6], z[6:]
            r, J = with_jacobian(wz, Pz)
            newton = ca.Function("cosserat_newton_step", [z], [ca.vertcat(r, ca.vec(J))])
            st, rr = self.shape(wz, Pz)
            shape = ca.Function("cosserat_shape_packed", [z], [ca.vertcat(ca.vec(st), rr)])
            self._compiled_newton = CompiledFunction(newton, self.options.flags)
            self._compiled_shape = CompiledFunction(shape, self.options.flags)

    def _residual_and_jacobian(self) -> ca.Function:
        """``(w, P) -> (residual, d residual / d w)``, the sensitivities carried along each RK4 step.

        Forward sensitivities ``S = dx/dw`` (13 x 6) are propagated with the state by
        an SX step ``(x, S) -> (x+, dx+/dx S)``, so the Jacobian costs about six
        residuals instead of CasADi's AD through the ``mapaccum``.
        """
        eq, n, bounds = self.equations, self.options.steps_per_segment, self.arm.boundaries
        xs, S, s, Ps = (
            ca.SX.sym("x", STATE_SIZE),
            ca.SX.sym("S", STATE_SIZE, 6),
            ca.SX.sym("s"),
            ca.SX.sym("P", self.n_loads),
        )

        def carried(name: str, f: ca.Function, *extra: ca.SX) -> ca.Function:
            out = f(xs, *extra, Ps)
            return ca.Function(name, [xs, S, *extra, Ps], [out, ca.jtimes(out, xs, S)])

        w, P = ca.MX.sym("w", 6), ca.MX.sym("P", self.n_loads)
        x = eq.base_state(w)
        sens = ca.MX(ca.vertcat(ca.DM.zeros(7, 6), ca.DM.eye(6)))
        for k in range(len(self.arm.segments)):
            h = (bounds[k + 1] - bounds[k]) / n
            step = carried(f"cosserat_rk4_sens{k}", eq.rk4_step(k, h), s).mapaccum(f"cosserat_sweep{k}", n, 2)
            X, SS = step(x, sens, ca.DM(bounds[k] + h * np.arange(n)).T, ca.repmat(P, 1, n))
            x, sens = X[:, -1], SS[:, -6:]
            if k < len(self.arm.segments) - 1:
                x, sens = carried(f"cosserat_disk_sens{k}", eq.junction_function(k))(x, sens, P)
        r, dr = carried("cosserat_tip_sens", eq.tip_residual_function)(x, sens, P)
        return ca.Function("cosserat_residual_jac", [w, P], [r, dr])

    # ----------------------------------------------------------------- one Newton solve

    def _newton(self, w0: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, int, bool]:
        """Newton from ``w0``: ``(w, iterations, converged)``."""
        tol = self.options.tolerance
        if self._compiled_newton is None:
            w = np.asarray(self.rootfinder(w0, P)).ravel()
            stats = self.rootfinder.stats()
            r = float(np.linalg.norm(np.asarray(self.residual(w, P)).ravel()))
            return w, int(stats.get("iter_count", 0)), bool(np.isfinite(r) and r <= tol)
        assert self._compiled_shape is not None
        w = np.array(w0, dtype=float)
        z = np.concatenate([w, P])[None, :]
        K = self.s.size
        previous, last_good, fresh = np.inf, None, False
        for it in range(self.options.max_iterations + 1):
            z[0, :6] = w
            out = self._compiled_shape.raw(z)[0]
            r = out[STATE_SIZE * K :]
            norm = float(np.linalg.norm(r))
            if not np.isfinite(norm):
                if last_good is None or fresh:
                    return w, it, False
                # A step with a Jacobian kept from other loads overshot: step again from the last
                # finite point with the Jacobian of that point.
                w, r, norm = last_good
                z[0, :6] = w
                self._jacobian = None
            else:
                self._last = (z[0].copy(), out)
                if norm <= tol / 10:
                    return w, it, True
            if it == self.options.max_iterations:
                break
            fresh = self._jacobian is None or norm > 0.1 * previous
            if fresh or self._jacobian is None:
                self._jacobian = self._compiled_newton.raw(z)[0, 6:].reshape(6, 6, order="F")
            jacobian = self._jacobian
            previous, last_good = norm, (w.copy(), r.copy(), norm)
            try:
                w = w - np.linalg.solve(jacobian, r)
            except np.linalg.LinAlgError:
                return w, it, False
        return w, self.options.max_iterations, False

    def _evaluate(self, w: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(states 13 x K, residual 6)`` at ``w``."""
        if self._compiled_shape is None:
            states, r = self.shape(w, P)
            return np.asarray(states), np.asarray(r).ravel()
        z = np.concatenate([w, P])
        if self._last is not None and np.array_equal(self._last[0], z):
            out = self._last[1]
        else:
            out = self._compiled_shape.raw(z[None, :])[0]
        K = self.s.size
        return out[: STATE_SIZE * K].reshape(STATE_SIZE, K, order="F"), out[STATE_SIZE * K :]

    def _ramp(self, P: np.ndarray) -> tuple[np.ndarray, int, bool]:
        """Continuation from zero load to ``P`` in 1, 2, 4, ... equal steps."""
        steps, total = 1, 0
        while steps <= self.options.max_ramp_steps:
            w = np.zeros(6)
            self._jacobian = None  # the kept Jacobian belongs to other loads
            ok = True
            for t in np.arange(1, steps + 1) / steps:
                w, it, ok = self._newton(w, t * P)
                total += it
                if not ok:
                    break
            if ok:
                return w, total, True
            steps *= 2
        return w, total, False

    # ----------------------------------------------------------------- public API

    def load_vector(self, loads: Loads | np.ndarray) -> np.ndarray:
        """``P`` of ``loads`` (a :class:`~optikin.physics.model.Loads` or already a vector ``(n_P,)``)."""
        if isinstance(loads, Loads):
            return load_vector(self.arm, loads)
        P = np.asarray(loads, dtype=float).ravel()
        if P.shape != (self.n_loads,):
            raise ValueError(f"expected a load vector of {self.n_loads} entries, got {P.size}")
        return P

    def residual_at(self, w: np.ndarray, P: np.ndarray) -> np.ndarray:
        """The tip residual ``(N(L) - F_tip, M(L) - C_tip)`` (6) from base wrench ``w`` (6) under loads ``P``.

        One integration (compiled when the solver is), for callers that iterate on ``w``
        themselves, e.g. a continuation corrector.
        """
        if self._compiled_shape is None:
            return np.asarray(self.residual(w, P)).ravel()
        return self._compiled_shape.raw(np.concatenate([w, P])[None, :])[0, STATE_SIZE * self.s.size :]

    def solve(self, loads: Loads | np.ndarray, guess: np.ndarray | None = None) -> RodSolution:
        """One equilibrium.

        Parameters
        ----------
        loads : Loads or numpy.ndarray
            The loads, or their vector ``P`` (:attr:`~optikin.physics.model.RodArm.load_names`).
        guess : numpy.ndarray, optional
            ``(6,)`` start for the base wrench; without one (or when Newton fails from
            it) the loads are ramped from zero.

        Returns
        -------
        RodSolution
            ``status == "failed"`` (with the residual) when Newton did not converge.
        """
        P = self.load_vector(loads)
        iterations = 0
        ok = False
        if guess is not None:
            w, iterations, ok = self._newton(np.asarray(guess, dtype=float), P)
        if not ok:
            w, more, ok = self._ramp(P)
            iterations += more
        states, r = self._evaluate(w, P)
        message = "" if ok else "Newton did not converge, even ramping the loads from zero"
        return RodSolution.from_states(
            self.s, states, float(np.linalg.norm(r)), self.options.tolerance, iterations, message
        )

    def solve_at(
        self,
        base_position: Sequence[float] | np.ndarray,
        base_orientation: Sequence[float] | np.ndarray,
        loads: Loads | np.ndarray,
        guess: np.ndarray | None = None,
    ) -> RodSolution:
        """One equilibrium of the same arm clamped at another base pose, without building another solver.

        The static rod is frame-invariant: turned by ``T = R(q_b) R(q_a)^T`` from the arm's own base
        orientation ``q_a`` to ``q_b`` (and moved to ``p_b``), its equilibrium under loads ``L`` is the
        equilibrium at the arm's own pose under ``T^T L``, turned by ``T``. So the loads given in the
        global frame (gravity, the distributed force, a spatial tip force or couple) are turned into the
        arm's frame, the compiled solver solves there, and the shape is turned back; follower loads and
        actuation are material and stay. One compile serves every base frame.

        Parameters
        ----------
        base_position : array_like
            ``(3,)`` clamp position [m], global frame.
        base_orientation : array_like
            ``(4,)`` unit quaternion ``(w, x, y, z)`` of the clamped cross-section.
        loads : Loads or numpy.ndarray
            As for :meth:`solve`, in the global frame.
        guess : numpy.ndarray, optional
            ``(6,)`` base wrench ``(n(0), m(0))`` in the global frame.

        Returns
        -------
        RodSolution
            The shape at the given base, every vector in the global frame.
        """
        q_b = np.asarray(base_orientation, dtype=float)
        q_b = q_b / np.linalg.norm(q_b)
        q_a = np.asarray(self.arm.base_orientation, dtype=float)
        turn = quat_multiply(q_b, quat_conjugate(q_a))
        T = np.asarray(matrix_from_quat(turn, check=False), dtype=float)
        P = self.load_vector(loads).copy()
        spatial = [slice(6, 9), slice(9, 12)]
        spatial += [slice(0, 3)] if self.arm.tip_force_frame == "spatial" else []
        spatial += [slice(3, 6)] if self.arm.tip_couple_frame == "spatial" else []
        for part in spatial:
            P[part] = T.T @ P[part]
        start = None if guess is None else np.concatenate([T.T @ guess[0:3], T.T @ guess[3:6]])
        local = self.solve(P, start)
        p_a = np.asarray(self.arm.base_position, dtype=float)
        positions = np.asarray(base_position, dtype=float) + (local.positions - p_a) @ T.T
        orientations = quat_multiply(np.broadcast_to(turn, local.orientations.shape), local.orientations)
        n, m = local.n @ T.T, local.m @ T.T
        return RodSolution(
            s=local.s,
            positions=positions,
            orientations=orientations,
            n=n,
            m=m,
            base_wrench=np.concatenate([n[0], m[0]]),
            residual_norm=local.residual_norm,
            status=local.status,
            iterations=local.iterations,
            message=local.message,
        )

    def solve_sequence(self, loads: Sequence[Loads | np.ndarray], guess: np.ndarray | None = None) -> list[RodSolution]:
        """Equilibria along a sequence of loads, each warm-started from the ones before.

        The start is the previous base wrench extrapolated linearly from the two
        before it (the previous one alone for the second), or ``guess`` for the first.

        Parameters
        ----------
        loads : sequence of Loads or numpy.ndarray
            The loads in order (slowly varying for the warm start to pay).
        guess : numpy.ndarray, optional
            ``(6,)`` start of the first solve.

        Returns
        -------
        list of RodSolution
        """
        out: list[RodSolution] = []
        for item in loads:
            start = guess
            if len(out) >= 1 and out[-1].ok:
                start = out[-1].base_wrench
                if len(out) >= 2 and out[-2].ok:
                    start = 2 * out[-1].base_wrench - out[-2].base_wrench
            out.append(self.solve(item, start))
        return out

    @cached_property
    def _sensitivity(self) -> ca.Function:
        guess, P = ca.MX.sym("w0", 6), ca.MX.sym("P", self.n_loads)
        w = self.rootfinder(guess, P)
        states, _ = self.shape(w, P)
        K = self.s.size
        return ca.Function(
            "cosserat_load_sensitivity",
            [guess, P],
            [
                ca.jacobian(ca.reshape(states[0:3, :], 3 * K, 1), P),
                ca.jacobian(ca.reshape(states[3:7, :], 4 * K, 1), P),
                ca.jacobian(w, P),
            ],
        )

    def jacobian_wrt_loads(self, loads: Loads | np.ndarray, guess: np.ndarray | None = None) -> LoadSensitivity:
        """Derivatives of the equilibrium with respect to every load, by the implicit function theorem.

        ``dw/dP = -(dr/dw)^-1 dr/dP`` at the root ``r(w, P) = 0``, then the chain rule through
        the integration (CasADi differentiates its rootfinder this way).

        Parameters
        ----------
        loads : Loads or numpy.ndarray
            The loads.
        guess : numpy.ndarray, optional
            ``(6,)`` start of the solve.

        Returns
        -------
        LoadSensitivity

        Raises
        ------
        optikin.errors.SolverError
            When the equilibrium itself cannot be found.
        """
        P = self.load_vector(loads)
        solution = self.solve(P, guess)
        if not solution.ok:
            raise SolverError(f"no equilibrium to differentiate: {solution.message}")
        dp, dq, dw = (np.asarray(a) for a in self._sensitivity(solution.base_wrench, P))
        K = self.s.size
        return LoadSensitivity(
            names=self.arm.load_names,
            positions=dp.reshape(K, 3, self.n_loads),
            orientations=dq.reshape(K, 4, self.n_loads),
            base_wrench=dw,
            solution=solution,
        )
