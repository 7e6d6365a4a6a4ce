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

Each evaluation at a new actuation is a predictor-corrector continuation from the
stored equilibrium nearest to it, ``(a_k, w_k)``: the IFT gives the predictor
``w = w_k + dw/da (a - a_k)``, ``dw/da = -(dr/dw)^-1 dr/dP_a`` (Allgower & Georg
1990, ch. 2), and a simplified Newton iteration on the residual alone, with the
``(dr/dw)^-1`` of ``a_k`` (Deuflhard 2011, ch. 2), corrects it; the derivative
Function is then evaluated once, at the corrected root, which gives ``y``, ``dy/da``
and the ``dr/dw`` the next predictor uses. When the corrector does not contract
the robust path takes over (:meth:`optikin.physics.ShootingSolver.solve`: Newton
with fresh Jacobians, else the loads ramped from zero). The Callbacks pass numpy
buffers (``eval_buffer``), so no ``DM`` is built per call, and the last
:data:`RECENT` evaluations are kept, so a backend returning to a point (a rejected
step, the previous target's answer) solves nothing.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np

from optikin.codegen import CompiledFunction, CompilerFlag
from optikin.physics import ShootingSolver
from optikin.physics.model import STATE_SIZE

POSE_SIZE = 7
"""``y = (p_tip (3) [m], q_tip (4))``."""
MEMORY = 256
"""Equilibria kept as warm starts (the nearest actuation's is used)."""
RECENT = 8
"""Evaluations ``(y, dy/da)`` kept by actuation, returned again without solving."""
CORRECTOR_ITERATIONS = 8
"""Most simplified Newton iterations of the corrector before the robust path takes over."""
CONTRACTION = 0.5
"""A corrector iteration that keeps more than this fraction of ``||r||`` hands over to the robust path."""


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

    Attributes
    ----------
    equilibria : int
        Equilibria solved so far (evaluations at an actuation not among the :data:`RECENT` last).

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
        # The stored equilibria, a ring of MEMORY: actuation, base wrench, dw/da and (dr/dw)^-1.
        self._actuations = np.empty((MEMORY, self.n_act))
        self._wrenches = np.empty((MEMORY, 6))
        self._slopes = np.empty((MEMORY, 6, self.n_act))
        self._inverses = np.empty((MEMORY, 6, 6))
        self._stored = 0
        self._recent: OrderedDict[bytes, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self.equilibria = 0

    def _tip_and_sensitivities(self) -> ca.Function:
        """``z = (w, P) -> (r (6), y (7), vec d(r, y)/d(w, a) (13 x (6 + n_act)))``, packed in one column.

        Forward sensitivities ``S = dx/d(w, a)`` (13 x (6 + n_act)) are carried with the state
        through every RK4 step and disk, as :class:`~optikin.physics.ShootingSolver` carries
        ``dx/dw``: one forward sweep of ``6 + n_act`` directions through ``(x, P_a)`` per step.
        """
        solver, eq = self.solver, self.solver.equations
        arm, n = solver.arm, solver.options.steps_per_segment
        n_P, n_dir = solver.n_loads, 6 + self.n_act
        seed = np.zeros((self.n_act, n_dir))
        seed[:, 6:] = np.eye(self.n_act)  # dP_a/d(w, a)
        xs, S, s = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("S", STATE_SIZE, n_dir), ca.SX.sym("s")
        P_fixed, P_act = ca.SX.sym("P_fixed", n_P - self.n_act), ca.SX.sym("P_act", self.n_act)
        Ps = ca.vertcat(P_fixed, P_act)

        def carried(name: str, f: ca.Function, *extra: ca.SX) -> ca.Function:
            out = f(xs, *extra, Ps)
            return ca.Function(
                name, [xs, S, *extra, Ps], [out, ca.jtimes(out, ca.vertcat(xs, P_act), ca.vertcat(S, ca.DM(seed)))]
            )

        z = ca.MX.sym("z", 6 + n_P)
        w, P = z[:6], z[6:]
        x = eq.base_state(w)
        sens = ca.MX(
            ca.horzcat(
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
        self._stored = 0
        self._recent.clear()

    def loads(self, a: np.ndarray) -> np.ndarray:
        """The load vector ``P`` of actuation ``a``."""
        return np.concatenate([self.fixed_loads, np.asarray(a, dtype=float).ravel()])

    def _nearest(self, a: np.ndarray) -> int | None:
        """Index of the stored equilibrium whose actuation is nearest ``a`` (None before any)."""
        count = min(self._stored, MEMORY)
        if count == 0:
            return None
        return int(np.argmin(np.sum((self._actuations[:count] - a) ** 2, axis=1)))

    def _correct(self, w: np.ndarray, P: np.ndarray, inverse: np.ndarray) -> np.ndarray | None:
        """Simplified Newton ``w <- w - (dr/dw)^-1 r(w)`` with a fixed inverse; None unless it converges.

        Converged at the solver's own test (``||r|| <= tolerance / 10``, as its Newton); given up
        after :data:`CORRECTOR_ITERATIONS` or when an iteration keeps more than
        :data:`CONTRACTION` of the residual.
        """
        tol = self.solver.options.tolerance / 10
        previous = np.inf
        for _ in range(CORRECTOR_ITERATIONS):
            r = self.solver.residual_at(w, P)
            norm = float(np.sqrt(r @ r))
            if not np.isfinite(norm) or norm > CONTRACTION * previous:
                return None
            if norm <= tol:
                return w
            previous = norm
            w = w - inverse @ r
        return None

    def _solve(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``y(a)``, ``dy/da`` by continuation from the nearest stored equilibrium (module docstring)."""
        P = self.loads(a)
        self.equilibria += 1
        j = self._nearest(a)
        w: np.ndarray | None = None
        predicted = None
        if j is not None:
            predicted = self._wrenches[j] + self._slopes[j] @ (a - self._actuations[j])
            w = self._correct(predicted, P, self._inverses[j])
        if w is None:
            solution = self.solver.solve(P, predicted)
            if not solution.ok:
                return np.full(POSE_SIZE, np.nan), np.full((POSE_SIZE, self.n_act), np.nan)
            w = solution.base_wrench
        out = self._derivatives.raw(np.concatenate([w, P])[None, :])[0]
        m = 6 + POSE_SIZE
        J = out[m:].reshape(m, 6 + self.n_act, order="F")
        try:
            inverse = np.linalg.inv(J[:6, :6])
        except np.linalg.LinAlgError:
            return np.full(POSE_SIZE, np.nan), np.full((POSE_SIZE, self.n_act), np.nan)
        slope = -inverse @ J[:6, 6:]  # dw/da
        k = self._stored % MEMORY
        self._actuations[k], self._wrenches[k], self._slopes[k], self._inverses[k] = a, w, slope, inverse
        self._stored += 1
        return out[6:m].copy(), J[6:, 6:] + J[6:, :6] @ slope

    def evaluate(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``y(a)`` (7) and ``dy/da`` (7 x n_act); NaN when the equilibrium does not converge.

        The last :data:`RECENT` evaluations are kept, so the Jacobian asked for right after the
        value, or a point met again, costs nothing more.
        """
        a = np.array(a, dtype=float).ravel()
        key = a.tobytes()
        kept = self._recent.get(key)
        if kept is not None:
            self._recent.move_to_end(key)
            return kept
        kept = self._solve(a)
        self._recent[key] = kept
        if len(self._recent) > RECENT:
            self._recent.popitem(last=False)
        return kept


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

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: Sequence[memoryview], res: Sequence[memoryview]) -> int:
        dy = self.equilibrium.evaluate(np.frombuffer(arg[0], dtype=float))[1]
        np.frombuffer(res[0], dtype=float)[:] = dy.ravel(order="F")  # column-major, as CasADi stores it
        return 0


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

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg: Sequence[memoryview], res: Sequence[memoryview]) -> int:
        np.frombuffer(res[0], dtype=float)[:] = self.equilibrium.evaluate(np.frombuffer(arg[0], dtype=float))[0]
        return 0

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
