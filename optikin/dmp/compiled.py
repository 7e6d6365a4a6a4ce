"""The DMP roll-out as generated C: the step of :func:`optikin.dmp.rollout.step_function` in a C loop.

:func:`optikin.dmp.rollout.rollout_function` runs the ``mapaccum`` of the step in
CasADi's virtual machine; here CasADi's code generator writes the same SX step as
C, and a loop appended to it (``optikin_dmp_loop``) applies it ``steps`` times in
one call through ``ctypes``, writing the state trajectory straight into a numpy
array. The integration scheme is the step's, operation for operation; built with
``-O3`` alone (no ``-ffast-math``, no ``-march=native``, so no FMA contraction), the
arithmetic is the virtual machine's and the tests hold the two within 1e-12.

Without phase stopping (``alpha = 0``) the phase of every step is known before the
roll-out, so its features ``s psi(s) / sum psi(s)`` come from a table computed once
(:func:`optikin.dmp.basis.rollout_features`) and the forcing term of every step is one
matrix product with the weights before the loop (no exponentials and no ``dim x n_basis``
product per step), and the loop takes a shorter step wherever nothing couples, displaces or moves
the goal (:func:`~optikin.dmp.rollout.step_function`'s ``plain``). The same library
computes the demonstration's gaps for the imitation (:meth:`CompiledRollout.prepare`:
the goal gaps lifted from the last sample back and the steps, one C call) and the few
gaps a roll-out starts from (:meth:`CompiledRollout.gap`), from the SX of
:func:`~optikin.dmp.rollout.gap_functions`.

The number of steps is an argument of the loop, so one library serves every roll-out
length of a space and basis size; it is cached per user like
:mod:`optikin.codegen`'s libraries. The CasADi Function stays the reference and
the path for derivatives (:mod:`optikin.dmp.tuning`).
"""

from __future__ import annotations

import ctypes
import threading

import casadi as ca
import numpy as np

from optikin import codegen
from optikin.dmp.rollout import gap_functions, input_size, state_size, step_function
from optikin.dmp.spaces import Space
from optikin.errors import SolverError

FLAGS: tuple[str, ...] = ("-O3",)
"""Compiler flags of the roll-out library (bit-for-bit the scalar arithmetic of the virtual machine)."""
N_ARGS = 12
"""Inputs of the step: ``x, u, W, c, h, amplitude, gains, tau, dt, s_end, goal_stopping, goal_rates``."""

_WORK = r"""
/* ---- optikin: work arrays of one generated function ---- */
#include <stdlib.h>
typedef struct {
  const casadi_real** arg;
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
  int mem;
} optikin_work;

static void optikin_free(optikin_work* s) {
  free(s->arg); free(s->res); free(s->iw); free(s->w);
}

static int optikin_alloc(optikin_work* s, casadi_int na, casadi_int nr, casadi_int ni, casadi_int nw) {
  s->arg = (const casadi_real**) calloc(na > 16 ? na : 16, sizeof(*s->arg));
  s->res = (casadi_real**) calloc(nr > 1 ? nr : 1, sizeof(*s->res));
  s->iw = (casadi_int*) calloc(ni > 1 ? ni : 1, sizeof(*s->iw));
  s->w = (casadi_real*) calloc(nw > 1 ? nw : 1, sizeof(*s->w));
  if (!s->arg || !s->res || !s->iw || !s->w) { optikin_free(s); return -1; }
  return 0;
}
"""

_OPEN = r"""
static int optikin_open_{f}(optikin_work* s) {{
  casadi_int na = 0, nr = 0, ni = 0, nw = 0;
  if ({f}_work(&na, &nr, &ni, &nw) || optikin_alloc(s, na, nr, ni, nw)) return -1;
  {f}_incref();
  s->mem = {f}_checkout();
  return 0;
}}

static void optikin_close_{f}(optikin_work* s) {{
  {f}_release(s->mem);
  {f}_decref();
  optikin_free(s);
}}
"""

_LOOP = r"""
/* ---- optikin: steps of {step} in one call; X holds nx x (steps + 1) states, column-major. With Fk
   (dim x steps, column-major) the tabulated step {tab} takes the forcing term from it, and
   {plain} runs the steps without reference (m = 0), output displacement (o = 0) or goal change (g_new = g) ---- */
static int optikin_plain(const casadi_real* x, const casadi_real* u) {{
  int i;
  if (u[{m}] != 0.0) return 0;
  for (i = 0; i < {size}; ++i) if (x[{g} + i] != u[{g_new} + i]) return 0;
  for (i = 0; i < {dim}; ++i) if (u[{o} + i] != 0.0) return 0;
  return 1;
}}

CASADI_SYMBOL_EXPORT int optikin_dmp_loop(const casadi_real** p, const casadi_real* U, long long steps,
                                          casadi_real* X, const casadi_real* Fk) {{
  optikin_work s, t;
  long long k, j;
  int status = 0, failed;
  if (Fk ? optikin_open_{tab}(&s) : optikin_open_{step}(&s)) return -1;
  if (Fk && optikin_open_{plain}(&t)) {{ optikin_close_{tab}(&s); return -1; }}
  for (j = 2; j < {n_args}; ++j) s.arg[j] = p[j];
  if (Fk) for (j = 2; j < {n_args}; ++j) t.arg[j] = p[j];
  for (k = 0; k < steps; ++k) {{
    s.arg[0] = X + k * {nx};
    s.arg[1] = U + k * {nu};
    s.res[0] = X + (k + 1) * {nx};
    if (!Fk) {{
      failed = {step}(s.arg, s.res, s.iw, s.w, s.mem);
    }} else if (optikin_plain(s.arg[0], s.arg[1])) {{
      t.arg[0] = s.arg[0];
      t.arg[1] = s.arg[1];
      t.arg[{n_args}] = Fk + k * {dim};
      t.res[0] = s.res[0];
      failed = {plain}(t.arg, t.res, t.iw, t.w, t.mem);
    }} else {{
      s.arg[{n_args}] = Fk + k * {dim};
      failed = {tab}(s.arg, s.res, s.iw, s.w, s.mem);
    }}
    if (failed) {{ status = (int) (k + 1); break; }}
  }}
  if (Fk) {{ optikin_close_{tab}(&s); optikin_close_{plain}(&t); }} else optikin_close_{step}(&s);
  return status;
}}

/* ---- optikin: the gaps of a demonstration Y (n x size, row-major): E (n x dim) = gap(goal, y_k) lifted from
   the last sample back (the last on the branch nearest zero), S ((n - 1) x dim) = step_gap(y_k+1, y_k, e_k+1, e_k) */
CASADI_SYMBOL_EXPORT int optikin_dmp_prepare(const casadi_real* goal, const casadi_real* Y, long long n,
                                             casadi_real* E, casadi_real* S) {{
  optikin_work gap, lift, step;
  casadi_real raw[{dim}], previous[{dim}];
  long long k, i;
  int status = 0;
  if (optikin_open_dmp_gap(&gap)) return -1;
  if (optikin_open_dmp_lift(&lift)) {{ optikin_close_dmp_gap(&gap); return -1; }}
  if (optikin_open_dmp_step_gap(&step)) {{ optikin_close_dmp_gap(&gap); optikin_close_dmp_lift(&lift); return -1; }}
  for (i = 0; i < {dim}; ++i) previous[i] = 0.0;
  gap.arg[0] = goal;
  gap.res[0] = raw;
  lift.arg[0] = raw;
  lift.arg[1] = previous;
  for (k = n - 1; k >= 0 && !status; --k) {{
    gap.arg[1] = Y + k * {size};
    lift.res[0] = E + k * {dim};
    if (dmp_gap(gap.arg, gap.res, gap.iw, gap.w, gap.mem) || dmp_lift(lift.arg, lift.res, lift.iw, lift.w, lift.mem))
      status = 1;
    for (i = 0; i < {dim}; ++i) previous[i] = E[k * {dim} + i];
  }}
  for (k = 0; k + 1 < n && !status; ++k) {{
    step.arg[0] = Y + (k + 1) * {size};
    step.arg[1] = Y + k * {size};
    step.arg[2] = E + (k + 1) * {dim};
    step.arg[3] = E + k * {dim};
    step.res[0] = S + k * {dim};
    if (dmp_step_gap(step.arg, step.res, step.iw, step.w, step.mem)) status = 1;
  }}
  optikin_close_dmp_gap(&gap);
  optikin_close_dmp_lift(&lift);
  optikin_close_dmp_step_gap(&step);
  return status;
}}

/* ---- optikin: one gap, gap(target, y), lifted onto the branch nearest previous unless it is NULL ---- */
CASADI_SYMBOL_EXPORT int optikin_dmp_gap(const casadi_real* target, const casadi_real* y,
                                         const casadi_real* previous, casadi_real* e) {{
  optikin_work gap, lift;
  casadi_real raw[{dim}];
  int status;
  if (optikin_open_dmp_gap(&gap)) return -1;
  gap.arg[0] = target;
  gap.arg[1] = y;
  gap.res[0] = previous ? raw : e;
  status = dmp_gap(gap.arg, gap.res, gap.iw, gap.w, gap.mem);
  optikin_close_dmp_gap(&gap);
  if (status || !previous) return status;
  if (optikin_open_dmp_lift(&lift)) return -1;
  lift.arg[0] = raw;
  lift.arg[1] = previous;
  lift.res[0] = e;
  status = dmp_lift(lift.arg, lift.res, lift.iw, lift.w, lift.mem);
  optikin_close_dmp_lift(&lift);
  return status;
}}
"""


def _source(space: Space, n_basis: int) -> str:
    step, tab = step_function(space, n_basis), step_function(space, n_basis, tabulated=True)
    plain = step_function(space, n_basis, tabulated=True, plain=True)
    functions = [step, tab, plain, *gap_functions(space)]
    generator = ca.CodeGenerator("dmp_rollout.c", {"with_header": False})
    for function in functions:
        generator.add(function)
    opens = "".join(_OPEN.format(f=function.name()) for function in functions)
    loop = _LOOP.format(
        step=step.name(),
        tab=tab.name(),
        plain=plain.name(),
        n_args=N_ARGS,
        nx=state_size(space),
        nu=input_size(space),
        dim=space.dim,
        size=space.size,
        m=space.dim + space.size,
        g=space.size + space.dim + 1,
        g_new=space.dim + space.size + 1,
        o=space.dim + 2 * space.size + 1,
    )
    return generator.dump() + _WORK + opens + loop


class CompiledRollout:
    """The roll-out of ``space`` with ``n_basis`` basis functions as one C call.

    Parameters
    ----------
    space:
        The DMP's space (:mod:`optikin.dmp.spaces`).
    n_basis:
        Basis functions per gap component.
    build:
        Compile the library unless a valid one is in the per-user cache (else refuse).

    Raises
    ------
    SolverError
        No C compiler, compiling failed, or (``build`` false) the library is not built yet.
    OSError
        The library could not be loaded.
    """

    def __init__(self, space: Space, n_basis: int, build: bool = True):
        self.space, self.n_basis = space, int(n_basis)
        self.nx, self.nu = state_size(space), input_size(space)
        library = codegen.source_library(
            f"optikin_dmp_{self.n_basis}", _source(space, self.n_basis), FLAGS, build=build
        )
        handle = ctypes.CDLL(str(library))
        pointer, int64 = ctypes.c_void_p, ctypes.c_longlong
        loop = handle.optikin_dmp_loop
        loop.argtypes = (ctypes.POINTER(pointer), pointer, int64, pointer, pointer)
        prepare = handle.optikin_dmp_prepare
        prepare.argtypes = (pointer, pointer, int64, pointer, pointer)
        gap = handle.optikin_dmp_gap
        gap.argtypes = (pointer, pointer, pointer, pointer)
        for function in (loop, prepare, gap):
            function.restype = ctypes.c_int
        self._loop, self._prepare, self._gap = loop, prepare, gap

    def prepare(self, goal: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gaps of a demonstration: :func:`~optikin.dmp.spaces.lifted_gaps` and
        :meth:`~optikin.dmp.spaces.Space.step_gaps` in one C call.

        Parameters
        ----------
        goal:
            ``(size,)`` the demonstration's last sample.
        Y:
            ``(N, size)`` samples (quaternion blocks sign-continuous).

        Returns
        -------
        tuple
            Goal gaps ``(N, dim)``, continuous from the last sample back, and steps ``(N - 1, dim)``.
        """
        goal = np.ascontiguousarray(goal, dtype=np.float64).reshape(self.space.size)
        Y = np.ascontiguousarray(Y, dtype=np.float64)
        if Y.ndim != 2 or Y.shape[1] != self.space.size or Y.shape[0] < 1:
            raise ValueError(f"samples: expected shape (N, {self.space.size}), got {Y.shape}")
        E = np.empty((Y.shape[0], self.space.dim))
        S = np.empty((Y.shape[0] - 1, self.space.dim))
        if self._prepare(goal.ctypes.data, Y.ctypes.data, Y.shape[0], E.ctypes.data, S.ctypes.data):
            raise SolverError("compiled DMP gaps failed")
        return E, S

    def gap(self, target: np.ndarray, y: np.ndarray, previous: np.ndarray | None = None) -> np.ndarray:
        """``gap(target, y)`` ``(dim,)`` of two ``(size,)`` elements, lifted onto the branch nearest ``previous``
        ``(dim,)`` when given (:meth:`~optikin.dmp.spaces.Space.lift`)."""
        size = self.space.size
        target = np.ascontiguousarray(target, dtype=np.float64).reshape(size)
        y = np.ascontiguousarray(y, dtype=np.float64).reshape(size)
        before = None if previous is None else np.ascontiguousarray(previous, dtype=np.float64).reshape(-1)
        e = np.empty(self.space.dim)
        if self._gap(target.ctypes.data, y.ctypes.data, None if before is None else before.ctypes.data, e.ctypes.data):
            raise SolverError("compiled DMP gap failed")
        return e

    def __call__(
        self,
        x0: np.ndarray,
        inputs: np.ndarray,
        W: np.ndarray,
        centres: np.ndarray,
        widths: np.ndarray,
        amplitude: np.ndarray,
        gains: np.ndarray,
        tau: float,
        dt: float,
        s_end: float,
        goal_stopping: float,
        goal_rates: np.ndarray,
        forcing: np.ndarray | None = None,
    ) -> np.ndarray:
        """The states of the roll-out, the arguments of :func:`~optikin.dmp.rollout.rollout_function` in numpy.

        Parameters
        ----------
        x0:
            ``(nx,)`` initial state ``(y, eta, s, g, e_prev)``.
        inputs:
            ``(steps, nu)`` per-step inputs (one row per step).
        W:
            ``(dim, n_basis)`` weights.
        centres, widths:
            ``(n_basis,)`` basis in phase.
        amplitude:
            ``(dim,)`` forcing-term scaling.
        gains:
            ``(6,)`` gains in the order of :data:`~optikin.dmp.gains.GAIN_NAMES`.
        tau, dt, s_end, goal_stopping:
            Time constant and step [s], end phase of the forcing term, weight of the goal gap in phase stopping.
        goal_rates:
            ``(dim,)`` goal-filter rates (eq. 24).
        forcing:
            ``(steps, dim)`` the forcing term of every step, ``amplitude * (features @ W.T)`` with the features of
            :func:`optikin.dmp.basis.rollout_features`: valid only where the phase does not depend on the state
            (``alpha = 0``); ``None``: computed in each step.

        Returns
        -------
        numpy.ndarray
            ``(steps + 1, nx)`` states, ``x0`` first.
        """
        U = np.ascontiguousarray(inputs, dtype=np.float64)
        steps = U.shape[0]
        if U.ndim != 2 or U.shape[1] != self.nu:
            raise ValueError(f"inputs: expected shape (steps, {self.nu}), got {U.shape}")
        dim = self.space.dim
        if np.shape(W) != (dim, self.n_basis):
            raise ValueError(f"weights: expected shape ({dim}, {self.n_basis}), got {np.shape(W)}")
        parts = [
            np.ascontiguousarray(x0, dtype=np.float64).reshape(self.nx),
            U,
            np.asfortranarray(W, dtype=np.float64),
            np.ascontiguousarray(centres, dtype=np.float64).reshape(self.n_basis),
            np.ascontiguousarray(widths, dtype=np.float64).reshape(self.n_basis),
            np.ascontiguousarray(amplitude, dtype=np.float64).reshape(dim),
            np.ascontiguousarray(gains, dtype=np.float64).reshape(6),
            np.array([tau, dt, s_end, goal_stopping], dtype=np.float64),
            np.ascontiguousarray(goal_rates, dtype=np.float64).reshape(dim),
        ]
        scalars = parts[7].ctypes.data
        pointers = [p.ctypes.data for p in parts[:7]] + [scalars + 8 * i for i in range(4)] + [parts[8].ctypes.data]
        args = (ctypes.c_void_p * N_ARGS)(*pointers)
        table = None
        if forcing is not None:
            table = np.ascontiguousarray(forcing, dtype=np.float64)
            if table.shape != (steps, dim):
                raise ValueError(f"forcing: expected shape ({steps}, {dim}), got {table.shape}")
        X = np.empty((steps + 1, self.nx))
        X[0] = parts[0]
        status = self._loop(args, U.ctypes.data, steps, X.ctypes.data, None if table is None else table.ctypes.data)
        if status < 0:
            raise SolverError("compiled DMP roll-out: could not allocate its work arrays")
        if status > 0:
            raise SolverError(f"compiled DMP roll-out failed at step {status - 1}")
        return X


ENGINES = ("auto", "compiled", "casadi")
"""Roll-out engines of :meth:`optikin.dmp.DMP.rollout`."""
AUTO_BUILD_AFTER = 20
"""Roll-outs of one space and basis size in a process after which ``engine="auto"`` compiles the
library (compiling costs as much as many roll-outs in CasADi's virtual machine)."""

_ROLLOUTS: dict[tuple[Space, int], CompiledRollout | None] = {}
_UNBUILT: dict[tuple[Space, int], int] = {}
_LOCK = threading.Lock()


def compiled_rollout(space: Space, n_basis: int, build: bool = True) -> CompiledRollout | None:
    """The (cached) :class:`CompiledRollout` of ``space`` and ``n_basis``, or ``None``.

    Parameters
    ----------
    space, n_basis:
        As :class:`CompiledRollout`.
    build:
        Compile the library if needed; if false, load one already in the per-user cache (looked
        for on the first call), or compile once asked :data:`AUTO_BUILD_AFTER` times in this process.

    Returns
    -------
    CompiledRollout or None
        ``None`` when it cannot be built (no compiler) or, with ``build`` false, is not built yet.
    """
    key = (space, int(n_basis))
    with _LOCK:
        if key in _ROLLOUTS:
            return _ROLLOUTS[key]
        asked = _UNBUILT[key] = _UNBUILT.get(key, 0) + 1
        build = build or asked >= AUTO_BUILD_AFTER
        if not build and asked > 1:
            return None  # looked in the per-user cache on the first call already
        try:
            runner = CompiledRollout(space, n_basis, build=build)
        except (SolverError, OSError):
            if not build:
                return None
            runner = None
        _ROLLOUTS[key] = runner
        return runner
