"""The static BVP of a rod arm by direct collocation, solved by IPOPT: the second method.

Each segment is cut into ``intervals_per_segment`` equal intervals; on each, the
state is a polynomial of degree ``degree`` through its value at the interval start
and at the Gauss-Legendre points (``casadi.collocation_points``), and the ODE holds
at those points. The unknowns are all these states, the base wrench included; the
constraints are the collocation equations, continuity across intervals, the disk
jumps (:meth:`~optikin.physics.model.ArmEquations.junction`) and the tip boundary
condition. The objective is zero: IPOPT (``nlpsol``) solves the square system.
Gauss-Legendre collocation is of order ``2 degree`` at the interval ends and keeps
quadratic invariants, here the unit norm of the quaternion, exactly.

It shares only the right-hand side of the equations with
:mod:`~optikin.physics.shooting`, so the two agree to their discretisation errors.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from pydantic import Field

from optikin.algebra import quat_rotate
from optikin.options import Options
from optikin.physics.model import STATE_SIZE, ArmEquations, Loads, RodArm, load_vector
from optikin.physics.solution import RodSolution


class CollocationOptions(Options):
    """Settings of :class:`CollocationSolver`."""

    intervals_per_segment: int = Field(25, ge=1, description="collocation intervals per segment")
    degree: int = Field(3, ge=1, le=9, description="Gauss-Legendre points per interval")
    tolerance: float = Field(1e-10, gt=0, description="largest accepted norm of the tip residual [N, N m]")
    max_iterations: int = Field(200, ge=1, description="IPOPT iterations")


class CollocationSolver:
    """Equilibria of a :class:`~optikin.physics.model.RodArm` by Gauss-Legendre collocation and IPOPT.

    Parameters
    ----------
    arm : RodArm
        The arm.
    options : CollocationOptions
        Grid and IPOPT settings.

    Attributes
    ----------
    s : numpy.ndarray
        ``(K,)`` arc length of the interval ends, ``K = n_segments * intervals_per_segment + 1``.
    """

    def __init__(self, arm: RodArm, options: CollocationOptions | None = None) -> None:
        self.arm = arm
        self.options = options or CollocationOptions()
        eq = ArmEquations(arm)
        self.n_loads = eq.n_loads
        n, d = self.options.intervals_per_segment, self.options.degree
        tau = np.array(ca.collocation_points(d, "legendre"))
        nodes = np.concatenate([[0.0], tau])
        C, D = np.zeros((d + 1, d + 1)), np.zeros(d + 1)  # derivative and end-value coefficients
        for j in range(d + 1):
            basis = np.poly1d([1.0])
            for r in range(d + 1):
                if r != j:
                    basis *= np.poly1d([1.0, -nodes[r]]) / (nodes[j] - nodes[r])
            D[j] = basis(1.0)
            C[j] = np.polyder(basis)(nodes)
        P = ca.SX.sym("P", self.n_loads)
        w = ca.SX.sym("w", 6)
        x = eq.base_state(w)
        unknowns, constraints, ends = [w], [], [x]
        self._layout: list[tuple[str, int]] = []  # ("end", index into ends) per unknown block after w
        bounds = arm.boundaries
        for k in range(len(arm.segments)):
            h = (bounds[k + 1] - bounds[k]) / n
            rhs = eq.rhs_function(k)
            for i in range(n):
                Xc = ca.SX.sym(f"X{k}_{i}", STATE_SIZE, d)
                unknowns.append(ca.vec(Xc))
                points = ca.horzcat(x, Xc)
                for j in range(1, d + 1):
                    slope = sum(C[r, j] * points[:, r] for r in range(d + 1))
                    s_j = bounds[k] + h * (i + tau[j - 1])
                    constraints.append(slope - h * rhs(s_j, points[:, j], P))
                x_end = sum(D[r] * points[:, r] for r in range(d + 1))
                if i == n - 1 and k < len(arm.segments) - 1:
                    x_end = eq.junction_function(k)(x_end, P)
                if i < n - 1 or k < len(arm.segments) - 1:
                    x = ca.SX.sym(f"x{k}_{i + 1}", STATE_SIZE)
                    unknowns.append(x)
                    constraints.append(x - x_end)
                else:
                    x = x_end
                ends.append(x)
        residual = eq.tip_residual_function(x, P)
        constraints.append(residual)
        z = ca.vertcat(*unknowns)
        self._z_size = z.numel()
        self.nlp = ca.nlpsol(
            "cosserat_collocation",
            "ipopt",
            {"x": z, "p": P, "f": 0, "g": ca.vertcat(*constraints)},
            {
                "ipopt.print_level": 0,
                "print_time": False,
                "ipopt.tol": 1e-14,
                "ipopt.constr_viol_tol": self.options.tolerance / 10,
                "ipopt.max_iter": self.options.max_iterations,
                "ipopt.sb": "yes",
            },
        )
        self._n_g = int(ca.vertcat(*constraints).numel())
        self._states = ca.Function("cosserat_collocation_states", [z, P], [ca.horzcat(*ends), residual])
        self._unknowns = unknowns
        self.s = np.concatenate(
            [[0.0]]
            + [bounds[k] + (bounds[k + 1] - bounds[k]) / n * np.arange(1, n + 1) for k in range(len(arm.segments))]
        )

    def _straight_guess(self) -> np.ndarray:
        """The unknowns of the straight, unloaded rod (every state at the clamp pose, moved along ``d3``)."""
        q0 = np.asarray(self.arm.base_orientation)
        tangent = quat_rotate(q0, np.array([0.0, 0.0, 1.0]), check=False)
        n, d = self.options.intervals_per_segment, self.options.degree
        tau = np.array(ca.collocation_points(d, "legendre"))
        bounds = self.arm.boundaries
        parts = [np.zeros(6)]

        def state(s: float) -> np.ndarray:
            return np.concatenate([np.asarray(self.arm.base_position) + s * tangent, q0, np.zeros(6)])

        for k in range(len(self.arm.segments)):
            h = (bounds[k + 1] - bounds[k]) / n
            for i in range(n):
                s0 = bounds[k] + h * i
                parts.append(np.concatenate([state(s0 + h * t) for t in tau]))
                if i < n - 1 or k < len(self.arm.segments) - 1:
                    parts.append(state(s0 + h))
        return np.concatenate(parts)

    def solve(self, loads: Loads | np.ndarray, guess: np.ndarray | None = None) -> RodSolution:
        """One equilibrium by IPOPT.

        Parameters
        ----------
        loads : Loads or numpy.ndarray
            The loads, or their vector ``P``.
        guess : numpy.ndarray, optional
            All unknowns (as returned in the previous solve's ``unknowns``); default the straight rod.

        Returns
        -------
        RodSolution
            ``status == "failed"`` when IPOPT did not converge or the tip residual is above the tolerance.
        """
        P = load_vector(self.arm, loads) if isinstance(loads, Loads) else np.asarray(loads, dtype=float).ravel()
        z0 = self._straight_guess() if guess is None else np.asarray(guess, dtype=float)
        out = self.nlp(x0=z0, p=P, lbg=0, ubg=0)
        stats = self.nlp.stats()
        z = np.asarray(out["x"]).ravel()
        self.unknowns = z
        states, r = self._states(z, P)
        message = "" if stats["success"] else f"IPOPT: {stats['return_status']}"
        norm = float(np.linalg.norm(np.asarray(r).ravel()))
        tolerance = self.options.tolerance if stats["success"] else -1.0
        return RodSolution.from_states(
            self.s, np.asarray(states), norm, tolerance, int(stats.get("iter_count", 0)), message
        )
