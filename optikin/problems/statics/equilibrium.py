"""The equilibrium tip pose as a CasADi Function of the actuation, for inverse statics by any ``nonlinear`` backend.

For an arm with fixed external loads (gravity, payload, tip wrench) the tip pose
``y(a) = (p_tip, q_tip)`` (7) is a function of the actuation ``a`` through the
equilibrium: ``w(a)`` solves the shooting residual ``r(w, P(a)) = 0``
(:mod:`optikin.physics.shooting`) and ``y = Y(w, P(a))`` is read off the
integrated states. Its derivative follows from the implicit function theorem,

    dy/da = dY/dP_a - dY/dw (dr/dw)^-1 dr/dP_a,

with ``P_a`` the actuation entries of the load vector.

:class:`TipEquilibrium` evaluates both with the compiled shooting path: the
equilibrium by :meth:`optikin.physics.ShootingSolver.solve`, started from the
stored equilibrium of the nearest actuation met so far (so a trajectory of
targets, and the iterations of one solve, are warm-started), and ``r``, ``dr/dz``,
``Y`` and ``dY/dz`` (``z = (w, P)``) by one C-compiled Function. CasADi's own
``rootfinder`` embeds the same equilibrium in a Function with the same derivatives,
but its VM Newton iteration costs tens of milliseconds per equilibrium; here a
:class:`casadi.Callback` (:func:`tip_function`) carries the compiled evaluation
into CasADi expressions, its Jacobian another Callback (and second derivatives,
for backends that want them, CasADi's finite differences of that Jacobian). A
sample whose equilibrium does not converge, even ramping the loads from zero,
gives NaN, which every backend reports ``failed``.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np

from optikin.codegen import CompiledFunction, CompilerFlag
from optikin.physics import RodSolution, ShootingSolver
from optikin.physics.model import STATE_SIZE

POSE_SIZE = 7
"""``y = (p_tip (3) [m], q_tip (4))``."""
MEMORY = 256
"""Equilibria kept as warm starts (the nearest actuation's is used)."""


class TipEquilibrium:
    """Tip pose ``y(a)`` of the equilibrium under actuation ``a`` and fixed loads, with ``dy/da``.

    Parameters
    ----------
    solver : optikin.physics.ShootingSolver
        The shooting solver of the arm (compiled for speed; the VM path works too).
    fixed_loads : numpy.ndarray
        ``(12,)`` the entries of the load vector before the actuation
        (:data:`optikin.physics.LOAD_NAMES`).
    flags : tuple of str
        Compiler flags of the derivative Function.

    Raises
    ------
    optikin.errors.SolverError
        When compiling fails.
    """

    def __init__(self, solver: ShootingSolver, fixed_loads: np.ndarray, flags: tuple[CompilerFlag, ...] = ("-O3",)):
        self.solver = solver
        self.fixed_loads = np.asarray(fixed_loads, dtype=float)
        self.n_act = solver.n_loads - self.fixed_loads.size
        self._derivatives = CompiledFunction(self._tip_and_sensitivities(), flags)
        self._memory: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=MEMORY)
        self._last: tuple[bytes, np.ndarray, np.ndarray] | None = None
        self.equilibria = 0

    def _tip_and_sensitivities(self) -> ca.Function:
        """``z = (w, P) -> (r (6), y (7), vec d(r, y)/d(w, a) (13 x (6 + n_act)))``, packed in one column.

        Forward sensitivities ``S = dx/d(w, a)`` (13 x (6 + n_act)) are carried with the state
        through every RK4 step and disk, as :class:`~optikin.physics.ShootingSolver` carries
        ``dx/dw``: about ``6 + n_act`` times the cost of one integration.
        """
        solver, eq = self.solver, self.solver.equations
        arm, n = solver.arm, solver.options.steps_per_segment
        n_P, n_dir = solver.n_loads, 6 + self.n_act
        seed = np.zeros((n_P, n_dir))
        seed[n_P - self.n_act :, 6:] = np.eye(self.n_act)  # dP/d(w, a): the actuation entries
        xs, S, s, Ps = (
            ca.SX.sym("x", STATE_SIZE),
            ca.SX.sym("S", STATE_SIZE, n_dir),
            ca.SX.sym("s"),
            ca.SX.sym("P", n_P),
        )

        def carried(name: str, f: ca.Function, *extra: ca.SX) -> ca.Function:
            out = f(xs, *extra, Ps)
            return ca.Function(
                name, [xs, S, *extra, Ps], [out, ca.jtimes(out, xs, S) + ca.jtimes(out, Ps, ca.DM(seed))]
            )

        z = ca.MX.sym("z", 6 + n_P)
        w, P = z[:6], z[6:]
        x = eq.base_state(w)
        sens = ca.MX(
            ca.horzcat(
                ca.DM.zeros(STATE_SIZE, 0),
                ca.vertcat(ca.DM.zeros(7, 6), ca.DM.eye(6)),
                ca.DM.zeros(STATE_SIZE, self.n_act),
            )
        )
        bounds = arm.boundaries
        for k in range(len(arm.segments)):
            h = (bounds[k + 1] - bounds[k]) / n
            step = carried(f"statics_rk4_sens{k}", eq.rk4_step(k, h), s).mapaccum(f"statics_sweep{k}", n, 2)
            X, SS = step(x, sens, ca.DM(bounds[k] + h * np.arange(n)).T, ca.repmat(P, 1, n))
            x, sens = X[:, -1], SS[:, -n_dir:]
            if k < len(arm.segments) - 1:
                x, sens = carried(f"statics_disk_sens{k}", eq.junction_function(k))(x, sens, P)
        r, dr = carried("statics_tip_sens", eq.tip_residual_function)(x, sens, P)
        out = ca.vertcat(r, x[0:7], ca.vec(ca.vertcat(dr, sens[0:7, :])))
        return ca.Function("statics_tip_derivatives", [z], [out])

    def forget(self) -> None:
        """Drop the stored equilibria (the next solve starts from zero load)."""
        self._memory.clear()
        self._last = None

    def loads(self, a: np.ndarray) -> np.ndarray:
        """The load vector ``P`` of actuation ``a``."""
        return np.concatenate([self.fixed_loads, np.asarray(a, dtype=float).ravel()])

    def guess(self, a: np.ndarray) -> np.ndarray | None:
        """The base wrench of the stored equilibrium whose actuation is nearest ``a`` (None before any)."""
        if not self._memory:
            return None
        actuations = np.array([m[0] for m in self._memory])
        return self._memory[int(np.argmin(np.linalg.norm(actuations - a, axis=1)))][1]

    def equilibrium(self, a: np.ndarray) -> RodSolution:
        """The equilibrium under actuation ``a``, warm-started from the nearest one stored; stored when ``ok``."""
        a = np.asarray(a, dtype=float).ravel()
        solution = self.solver.solve(self.loads(a), self.guess(a))
        self.equilibria += 1
        if solution.ok:
            self._memory.append((a.copy(), solution.base_wrench))
        return solution

    def evaluate(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``y(a)`` (7) and ``dy/da`` (7 x n_act); NaN when the equilibrium does not converge.

        The last evaluation is kept, so the Jacobian asked for right after the value costs nothing more.
        """
        a = np.asarray(a, dtype=float).ravel()
        key = a.tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1], self._last[2]
        solution = self.equilibrium(a)
        if not solution.ok:
            y, dy = np.full(POSE_SIZE, np.nan), np.full((POSE_SIZE, self.n_act), np.nan)
        else:
            z = np.concatenate([solution.base_wrench, self.loads(a)])
            out = self._derivatives.raw(z[None, :])[0]
            m = 6 + POSE_SIZE
            y = out[6:m]
            J = out[m:].reshape(m, 6 + self.n_act, order="F")
            dr_dw, dr_da = J[:6, :6], J[:6, 6:]
            dy_dw, dy_da = J[6:, :6], J[6:, 6:]
            dy = dy_da - dy_dw @ np.linalg.solve(dr_dw, dr_da)
        self._last = (key, y, dy)
        return y, dy


class _TipJacobian(ca.Callback):
    """``(a, y) -> dy/da``: the Jacobian Function of :class:`_Tip` (second derivatives by finite differences)."""

    def __init__(self, name: str, equilibrium: TipEquilibrium, opts: Mapping[str, Any]) -> None:
        ca.Callback.__init__(self)
        self.equilibrium = equilibrium
        self.construct(name, {**opts, "enable_fd": True})

    def get_n_in(self) -> int:
        return 2

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.equilibrium.n_act if i == 0 else POSE_SIZE, 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(POSE_SIZE, self.equilibrium.n_act)

    def eval(self, arg: Sequence[ca.DM]) -> list[ca.DM]:
        return [ca.DM(self.equilibrium.evaluate(np.asarray(arg[0]).ravel())[1])]


class _Tip(ca.Callback):
    """``a -> y``: the equilibrium tip pose (:class:`TipEquilibrium`) as a CasADi Function with a Jacobian."""

    def __init__(self, name: str, equilibrium: TipEquilibrium) -> None:
        ca.Callback.__init__(self)
        self.equilibrium = equilibrium
        self._jacobian: _TipJacobian | None = None
        self.construct(name, {})

    def get_n_in(self) -> int:
        return 1

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.equilibrium.n_act, 1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(POSE_SIZE, 1)

    def eval(self, arg: Sequence[ca.DM]) -> list[ca.DM]:
        return [ca.DM(self.equilibrium.evaluate(np.asarray(arg[0]).ravel())[0])]

    def has_jacobian(self) -> bool:
        return True

    def get_jacobian(
        self, name: str, inames: Sequence[str], onames: Sequence[str], opts: Mapping[str, Any]
    ) -> ca.Function:
        self._jacobian = _TipJacobian(name, self.equilibrium, opts)  # a Callback must outlive its uses
        return self._jacobian


def tip_function(equilibrium: TipEquilibrium, name: str = "statics_tip") -> ca.Function:
    """``a (n_act) -> y (7)``, the equilibrium tip pose as a CasADi Function with its IFT Jacobian.

    Parameters
    ----------
    equilibrium : TipEquilibrium
        What evaluates it.
    name : str
        The Function's name.

    Returns
    -------
    casadi.Function
        Callable on SX and MX symbols (a call node), differentiable once exactly and
        twice by finite differences; the returned object keeps its Callback alive.
    """
    return _Tip(name, equilibrium)
