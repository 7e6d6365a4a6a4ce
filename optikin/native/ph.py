"""The minimum-energy PH fast path (``ph_newton``) of a trajectory in the exported C, one call per batch.

:func:`solve` is :meth:`NewtonAdapter.solve <optikin.solvers.ph_backends.PHAdapter.solve>` (the warm-start loop
of :meth:`~optikin.curves.min_energy.ShapeEnergyModel.solve_newton`) with the samples run by the C of
``optikin export --what ph-shape`` (:func:`optikin.export.ph_shape.ph_library`: modified Newton on the
CasADi-generated derivatives, coarse-grid restart, basin check, angles wrapped), compiled once per model
and adapter settings into the per-user cache (:mod:`optikin.native`). The C agrees with the Python path to
rounding: statuses, Newton steps and notes equal, angles, energies and lengths within 1e-12
(``tests/test_ph_fast_c.py``).

Where the Python path would fall back to IPOPT (Newton failed, ``fallback`` on) or the C refuses a sample
(a non-finite entry, an end speed <= 0), that sample is solved by the adapter's own ``solve_one`` from the
same warm start, and the C continues after it from its answer. The answers come back as a
:class:`ShapeBatch`: arrays, and a :class:`~optikin.curves.min_energy.ShapeSolution` made for a sample when it
is asked for.

Covered: a :class:`~optikin.solvers.ph_backends.NewtonAdapter` on a model with given end speeds; anything
else (free speeds, another backend, ``OPTIKIN_NATIVE=0``, no ``gcc``) runs the adapter's own :meth:`solve`.
"""

from __future__ import annotations

import ctypes
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np

from optikin.curves.min_energy import ShapeSolution
from optikin.interrupt import check_interrupted
from optikin.native import CHUNK, compiler_found, load_library, native_enabled, pointer, report_fallback
from optikin.status import Status

STEM = "optikin_native_ph"

OK, NOT_CONVERGED = 0, 2
"""The C status codes of a solved and an unconverged sample (``enum optikin_native_ph_status``)."""

NOTES = (
    (1, "warm start failed; coarse grid restart"),
    (2, "basin check: the coarse-grid start found a lower minimum"),
)
"""The C's note bits and the notes of :meth:`~optikin.curves.min_energy.ShapeEnergyModel.solve_newton`."""

_DRIVER = r"""
/* ---- optikin.native.ph: a trajectory in one call, stopping where the Python path takes over ---- */
#include <stdlib.h>
/* Samples k = 0..n-1 (rows of P), the first from x_first (NULL: the coarse grid), each next one from the
   previous solution when that is OK and warm is set. Stops after the first sample that is not OK when stop is
   set. Returns the number of samples done, or -1 when the work structure cannot be allocated. */
long long optikin_native_ph_many(const double* P, long long n, const double* x_first, int stop, double tolerance,
                                 int max_iterations, int warm, int restart, int basin_check, double* X,
                                 double* energy_length, int* iterations, int* status, int* notes) {
  long long k;
  const double* previous = x_first;
  optikin_native_ph_work* w = (optikin_native_ph_work*) malloc(sizeof(optikin_native_ph_work));
  if (!w) return -1;
  optikin_native_ph_init(w);
  w->tolerance = tolerance;
  w->max_iterations = max_iterations;
  w->warm_start = warm;
  w->restart = restart;
  w->basin_check = basin_check;
  for (k = 0; k < n; ++k) {
    status[k] = solve_noted(w, P + k * OPTIKIN_NATIVE_PH_NP, previous, X + 2 * k, energy_length + 2 * k,
                            iterations + k, notes + k);
    previous = warm && status[k] == OPTIKIN_NATIVE_PH_OK ? X + 2 * k : 0;
    if (stop && status[k] != OPTIKIN_NATIVE_PH_OK) {
      free(w);
      return k + 1;
    }
  }
  free(w);
  return n;
}
"""


@dataclass
class NativePH:
    """The compiled C of one model and adapter settings: ``many(...)`` is ``optikin_native_ph_many``."""

    many: Any


def not_covered(adapter, model) -> str | None:
    """Why the C path does not solve ``model``'s samples for ``adapter`` (None when it does)."""
    from optikin.solvers.ph_backends import NewtonAdapter

    if not native_enabled():
        return "turned off"
    if not isinstance(adapter, NewtonAdapter):
        return f"backend {type(adapter).__name__} is not ph_newton"
    if model.free_speeds:
        return "free end speeds (the C covers given speeds)"
    return None


def native_ph(adapter, model) -> NativePH | None:
    """The compiled C of ``model`` for ``adapter``, built once per model and settings that shape the code (kept
    on the model); None when no compiler is there. Limits and options are arguments of each call."""
    from optikin.export.ph_shape import ph_library

    cache = model.native
    key = (model.settings, model.coarse_grid)
    if key in cache:
        return cache[key]
    loaded = None
    if compiler_found(STEM):
        loaded = load_library(STEM, ph_library("native", model, adapter, STEM).translation_unit() + _DRIVER)
    native = None
    if loaded is not None:
        many = loaded.optikin_native_ph_many
        many.argtypes = (
            ctypes.c_void_p,
            ctypes.c_longlong,
            ctypes.c_void_p,
            ctypes.c_int,
            ctypes.c_double,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
        ) + (ctypes.c_void_p,) * 5
        many.restype = ctypes.c_longlong
        native = NativePH(many)
    cache[key] = native
    return native


class ShapeBatch(Sequence):
    """The solutions of a trajectory as arrays; ``batch[k]`` is sample ``k``'s
    :class:`~optikin.curves.min_energy.ShapeSolution`, made when first asked for and kept.

    Attributes
    ----------
    x:
        ``(N, 2)`` angles ``(phi0, phi2)`` [rad].
    status:
        ``ok`` or ``not_converged`` (or what the Python path decided for a sample it solved).
    iterations, energy, arc_length, seconds:
        ``(N,)`` Newton steps, energies, lengths [m], seconds per sample (the batch's time shared out).
    notes:
        ``(N,)`` note bits of the C (:data:`NOTES`).
    """

    def __init__(self, x, status, iterations, energy, arc_length, seconds, notes, solved: dict[int, ShapeSolution]):
        self.x, self.status, self.iterations = x, status, iterations
        self.energy, self.arc_length, self.seconds, self.notes = energy, arc_length, seconds, notes
        self._made = dict(solved)

    def __len__(self) -> int:
        return len(self.status)

    @overload
    def __getitem__(self, k: int) -> ShapeSolution: ...

    @overload
    def __getitem__(self, k: slice) -> list[ShapeSolution]: ...

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        k = range(len(self))[k]
        made = self._made.get(k)
        if made is None:
            bits = int(self.notes[k])
            made = self._made[k] = ShapeSolution(
                self.x[k].copy(),
                self.status[k],
                int(self.iterations[k]),
                seconds=float(self.seconds[k]),
                method="newton",
                energy=float(self.energy[k]),
                arc_length=float(self.arc_length[k]),
                multiplier=math.nan,
                notes=[text for bit, text in NOTES if bits & bit],
            )
        return made


def native_solve(adapter, model, samples: Sequence) -> ShapeBatch | None:
    """``adapter.solve(model, samples)`` in C, or None where the C path does not apply (module docstring).

    Parameters
    ----------
    adapter:
        A :class:`~optikin.solvers.ph_backends.NewtonAdapter`.
    model:
        Its :class:`~optikin.curves.min_energy.ShapeEnergyModel` (given end speeds).
    samples:
        The :class:`~optikin.curves.min_energy.ShapeData` of the trajectory, in order.

    Raises
    ------
    InputDataError
        A sample lacks what the model needs (as the Python path raises).
    """
    reason = not_covered(adapter, model)
    if reason is not None:
        if reason != "turned off":
            report_fallback("ph_newton", reason)
        return None
    native = native_ph(adapter, model)
    if native is None:
        return None
    started = time.perf_counter()
    P = np.ascontiguousarray(model.parameters_of(samples))
    N = len(P)
    X, EL = np.empty((N, 2)), np.empty((N, 2))
    iterations, status, notes = (np.zeros(N, dtype=np.intc) for _ in range(3))
    options, limits = adapter.options, adapter.preset.limits
    fallback, warm = bool(options.fallback), bool(options.warm_start)
    solved: dict[int, ShapeSolution] = {}
    previous: np.ndarray | None = None
    k = 0
    while k < N:
        end = min(k + CHUNK, N)
        done = native.many(
            pointer(P[k:]),
            end - k,
            None if previous is None else pointer(previous),
            1,
            float(limits.tolerance),
            int(limits.max_iterations),
            int(warm),
            int(fallback),
            int(options.basin_check),
            pointer(X[k:]),
            pointer(EL[k:]),
            pointer(iterations[k:]),
            pointer(status[k:]),
            pointer(notes[k:]),
        )
        if done < 0:
            report_fallback("ph_newton", "the C could not allocate its work structure")
            return None
        check_interrupted()
        last = k + int(done) - 1
        if status[last] != OK and (fallback or status[last] != NOT_CONVERGED):
            # the Python path's answer: IPOPT after Newton, or its verdict on a sample the C refuses
            if last > k:
                previous = X[last - 1].copy() if warm and status[last - 1] == OK else None
            solution = adapter.solve_one(model, samples[last], previous)
            solved[last] = solution
            X[last] = np.asarray(solution.x)[:2]
            EL[last] = solution.energy, solution.arc_length
            iterations[last] = solution.iterations
            status[last] = OK if solution.status == Status.OK else NOT_CONVERGED
        previous = X[last].copy() if warm and status[last] == OK else None
        k = last + 1
    elapsed = time.perf_counter() - started
    names = np.where(status == OK, Status.OK, Status.NOT_CONVERGED).tolist()
    for i, solution in solved.items():
        names[i] = solution.status
    return ShapeBatch(X, names, iterations, EL[:, 0], EL[:, 1], np.full(N, elapsed / max(N, 1)), notes, solved)


def solve(adapter, model, samples: Sequence) -> Sequence[ShapeSolution]:
    """``adapter.solve(model, samples)``, in C where :func:`native_solve` applies."""
    batch = native_solve(adapter, model, samples)
    return batch if batch is not None else adapter.solve(model, samples)
