"""The DMP roll-out as generated C: the step of :func:`optikin.dmp.rollout.step_function` in a C loop.

:func:`optikin.dmp.rollout.rollout_function` runs the ``mapaccum`` of the step in
CasADi's virtual machine; here CasADi's code generator writes the same SX step as
C, and a loop appended to it (``optikin_dmp_loop``) applies it ``steps`` times in
one call through ``ctypes``, writing the state trajectory straight into a numpy
array. The integration scheme is the step's, operation for operation; built with
``-O3`` alone (no ``-ffast-math``, no ``-march=native``, so no FMA contraction), the
arithmetic is the virtual machine's and the tests hold the two within 1e-12. The
number of steps is an argument of the loop, so one library serves every roll-out
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
from optikin.dmp.rollout import input_size, state_size, step_function
from optikin.dmp.spaces import Space
from optikin.errors import SolverError

FLAGS: tuple[str, ...] = ("-O3",)
"""Compiler flags of the roll-out library (bit-for-bit the scalar arithmetic of the virtual machine)."""
N_ARGS = 12
"""Inputs of the step: ``x, u, W, c, h, amplitude, gains, tau, dt, s_end, goal_stopping, goal_rates``."""

_LOOP = r"""
/* ---- optikin: steps of {name} in one call; X holds nx x (steps + 1) states, column-major ---- */
#include <stdlib.h>
CASADI_SYMBOL_EXPORT int optikin_dmp_loop(const casadi_real** p, const casadi_real* U, long long steps,
                                          casadi_real* X) {{
  casadi_int sz_arg = 0, sz_res = 0, sz_iw = 0, sz_w = 0;
  long long k, j;
  int mem, status = 0;
  const casadi_real** arg;
  casadi_real** res;
  casadi_int* iw;
  casadi_real* w;
  if ({name}_work(&sz_arg, &sz_res, &sz_iw, &sz_w)) return -1;
  arg = (const casadi_real**) calloc(sz_arg > {n_args} ? sz_arg : {n_args}, sizeof(*arg));
  res = (casadi_real**) calloc(sz_res > 1 ? sz_res : 1, sizeof(*res));
  iw = (casadi_int*) calloc(sz_iw > 1 ? sz_iw : 1, sizeof(*iw));
  w = (casadi_real*) calloc(sz_w > 1 ? sz_w : 1, sizeof(*w));
  if (!arg || !res || !iw || !w) {{ free(arg); free(res); free(iw); free(w); return -1; }}
  for (j = 2; j < {n_args}; ++j) arg[j] = p[j];
  {name}_incref();
  mem = {name}_checkout();
  for (k = 0; k < steps; ++k) {{
    arg[0] = X + k * {nx};
    arg[1] = U + k * {nu};
    res[0] = X + (k + 1) * {nx};
    if ({name}(arg, res, iw, w, mem)) {{ status = (int) (k + 1); break; }}
  }}
  {name}_release(mem);
  {name}_decref();
  free(arg); free(res); free(iw); free(w);
  return status;
}}
"""


def _source(step: ca.Function, nx: int, nu: int) -> str:
    generator = ca.CodeGenerator(f"{step.name()}.c", {"with_header": False})
    generator.add(step)
    return generator.dump() + _LOOP.format(name=step.name(), n_args=N_ARGS, nx=nx, nu=nu)


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
        step = step_function(space, n_basis)
        self.space, self.n_basis = space, int(n_basis)
        self.nx, self.nu = state_size(space), input_size(space)
        text = _source(step, self.nx, self.nu)
        path = codegen.find_compiler("gcc")
        record = codegen._record(text, path, FLAGS)
        key = str(record["hash"])
        stem = f"optikin_{step.name()}_{key[:16]}"
        cache = codegen.cache_dir()
        library, sidecar = cache / f"{stem}.so", cache / f"{stem}.json"
        if not codegen._is_valid(library, sidecar, key):
            if not build:
                raise SolverError(f"{stem} is not built yet")
            codegen._build(stem, text, path, FLAGS, record, library, sidecar)
        loop = ctypes.CDLL(str(library)).optikin_dmp_loop
        loop.argtypes = (ctypes.POINTER(ctypes.c_void_p), ctypes.c_void_p, ctypes.c_longlong, ctypes.c_void_p)
        loop.restype = ctypes.c_int
        self._loop = loop

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
        X = np.empty((steps + 1, self.nx))
        X[0] = parts[0]
        status = self._loop(args, U.ctypes.data, steps, X.ctypes.data)
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
