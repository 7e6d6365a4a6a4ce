"""Backend ``qp_daqp``: DAQP's dual active-set method on the controller's own buffers, warm-started every step.

The tracking QPs are small and dense (``n`` rates, ``H`` full, the box plus a few rows):
once the active set is found the answer is exact up to rounding, and consecutive steps rarely
change it, so a step warm-started from the previous active set often takes one iteration and one
dense Cholesky factorisation of ``H``. :func:`optikin.control.qp.default_step_solver` chooses this
backend by structure when no preset names one.

Two ways into daqp run the same C code on the same arrays and give the same bits:

* :class:`DirectDaqp`: daqp's own C functions (``setup_daqp``, ``daqp_update_ldp``,
  ``daqp_solve``, exported by its extension module) called through ``ctypes`` on a problem, a
  result and a workspace held here, which point at the controller's arrays; daqp writes the answer
  into the step solver's array. No Python object is made per step. It needs the C structures'
  layout, that of the daqp versions in :data:`DIRECT_VERSIONS` (the tests check it against
  ``daqp.Model`` bit for bit), and arrays daqp can read as they are (C-contiguous ``float64``).
* ``daqp.Model`` (:class:`ModelDaqp`), daqp's Python class, otherwise: each ``solve`` copies the
  answer and the multipliers into new arrays and builds a dict.

Preset::

    name: qp-active-set
    backend: qp_daqp
    options: {}
"""

from __future__ import annotations

import ctypes
import functools
import logging
import time
import weakref
from importlib import metadata
from typing import Any, Callable

import numpy as np

from optikin.options import Options
from optikin.solvers import register_backend
from optikin.solvers.base import Solution
from optikin.solvers.qp.common import QPData, StepSolverFactory
from optikin.spec import SolverSpec
from optikin.status import Status

_DAQP_INFINITY = 1e30
"""daqp's ``DAQP_INF``: a bound at or beyond it is no bound."""
DIRECT_VERSIONS = frozenset({"0.11.0"})
"""daqp versions whose ``DAQPProblem``, ``DAQPResult`` and exported functions :class:`DirectDaqp` is written for."""
_UPDATE_BOX = 1 | 4 | 8
"""daqp's ``DAQP_UPDATE_Rinv | DAQP_UPDATE_v | DAQP_UPDATE_d``: new ``H``, ``f`` and bounds
(``daqp.Model.update``'s mask when these are named)."""
_UPDATE_ROWS = 2
"""daqp's ``DAQP_UPDATE_M``: new ``A``."""
_WORKSPACE_BYTES = 4096
"""Room for daqp's ``DAQPWorkspace`` (about 400 bytes), zeroed as ``calloc`` would."""

logger = logging.getLogger(__name__)

_doubles = ctypes.POINTER(ctypes.c_double)
_ints = ctypes.POINTER(ctypes.c_int)


class DaqpOptions(Options):
    """Options of backend ``qp_daqp`` (none yet: daqp's own tolerances)."""


class _Problem(ctypes.Structure):
    """daqp's ``DAQPProblem``: ``n`` variables, ``m`` constraints of which the first ``ms`` simple bounds."""

    _fields_ = [
        ("n", ctypes.c_int),
        ("m", ctypes.c_int),
        ("ms", ctypes.c_int),
        ("H", _doubles),
        ("f", _doubles),
        ("A", _doubles),
        ("bupper", _doubles),
        ("blower", _doubles),
        ("sense", _ints),
        ("break_points", _ints),
        ("nh", ctypes.c_int),
        ("problem_type", ctypes.c_int),
    ]


class _Result(ctypes.Structure):
    """daqp's ``DAQPResult``: where ``daqp_solve`` writes the answer, the exit flag and the iterations."""

    _fields_ = [
        ("x", _doubles),
        ("lam", _doubles),
        ("fval", ctypes.c_double),
        ("soft_slack", ctypes.c_double),
        ("exitflag", ctypes.c_int),
        ("iter", ctypes.c_int),
        ("nodes", ctypes.c_int),
        ("solve_time", ctypes.c_double),
        ("setup_time", ctypes.c_double),
    ]


@functools.cache
def _library() -> Any:
    """daqp's extension module as a C library (calls keep the GIL), or None where :class:`DirectDaqp` cannot run."""
    import daqp

    try:
        version = metadata.version("daqp")
        if version not in DIRECT_VERSIONS:
            logger.info(
                "daqp %s: DirectDaqp was written for %s; the QP step runs through daqp.Model (same answers, slower)",
                version,
                " or ".join(sorted(DIRECT_VERSIONS)),
            )
            return None
        library = ctypes.PyDLL(daqp.__file__)
        for name in ("setup_daqp", "daqp_update_ldp", "daqp_solve", "free_daqp_workspace", "free_daqp_ldp"):
            getattr(library, name).restype = None if name.startswith(("free", "daqp_solve")) else ctypes.c_int
    except (metadata.PackageNotFoundError, OSError, AttributeError, TypeError):
        return None
    return library


def _release(library: Any, workspace: ctypes.Array) -> None:
    """Free what daqp allocated in ``workspace`` (nothing if zeroed) and zero it."""
    library.free_daqp_workspace(ctypes.byref(workspace))
    library.free_daqp_ldp(ctypes.byref(workspace))
    ctypes.memset(workspace, 0, ctypes.sizeof(workspace))


class DirectDaqp:
    """daqp's C functions through ``ctypes`` on a problem, result and workspace of this object (module docstring).

    :meth:`setup` points the problem at the arrays (kept here, read in place, never copied) and runs
    ``setup_daqp`` on a zeroed workspace, as ``daqp.Model.setup`` does; :attr:`refresh` runs
    ``daqp_update_ldp`` with the mask ``daqp.Model.update`` sets when ``H``, ``f``, the bounds (and
    ``A``, with rows) are named, so daqp redoes the same work on the arrays' new contents; :meth:`solve`
    runs ``daqp_solve``, which writes the answer into ``x``. The memory daqp allocates is freed at the
    next :meth:`setup` and when this object is collected.
    """

    @staticmethod
    def available() -> bool:
        """Whether the installed daqp is one of :data:`DIRECT_VERSIONS` with its C functions exported."""
        return _library() is not None

    def __init__(self) -> None:
        self._library = library = _library()
        if library is None:
            raise RuntimeError(f"DirectDaqp needs daqp {' or '.join(sorted(DIRECT_VERSIONS))}")
        self._problem, self._result = _Problem(), _Result()
        self._workspace = ctypes.create_string_buffer(_WORKSPACE_BYTES)
        self._setup_time = ctypes.c_double()
        self._arrays: tuple[np.ndarray, ...] = ()
        self._workspace_at, self._problem_at = ctypes.byref(self._workspace), ctypes.byref(self._problem)
        self.refresh: Callable[[], int] = _not_set_up
        self._run = functools.partial(library.daqp_solve, ctypes.byref(self._result), self._workspace_at)
        weakref.finalize(self, _release, library, self._workspace)

    def setup(
        self,
        H: np.ndarray,
        f: np.ndarray,
        A: np.ndarray,
        upper: np.ndarray,
        lower: np.ndarray,
        sense: np.ndarray,
        x: np.ndarray,
    ) -> int:
        """Set daqp up on these arrays (the rows of ``A`` after the ``n`` simple bounds); its exit flag."""
        _release(self._library, self._workspace)
        self._arrays = (H, f, A, upper, lower, sense, x)  # daqp keeps pointers to them
        problem = self._problem
        problem.n, problem.m, problem.ms = H.shape[0], upper.shape[0], upper.shape[0] - A.shape[0]
        problem.H, problem.f = H.ctypes.data_as(_doubles), f.ctypes.data_as(_doubles)
        problem.A = A.ctypes.data_as(_doubles) if A.shape[0] else None
        problem.bupper, problem.blower = upper.ctypes.data_as(_doubles), lower.ctypes.data_as(_doubles)
        problem.sense = sense.ctypes.data_as(_ints)
        problem.break_points, problem.nh, problem.problem_type = None, 0, 0
        self._result.x, self._result.lam = x.ctypes.data_as(_doubles), None  # no multipliers wanted
        mask = _UPDATE_BOX | (_UPDATE_ROWS if A.shape[0] else 0)
        self.refresh = functools.partial(self._library.daqp_update_ldp, mask, self._workspace_at, self._problem_at)
        return int(self._library.setup_daqp(self._problem_at, self._workspace_at, ctypes.byref(self._setup_time)))

    def solve(self) -> tuple[int, int]:
        """``daqp_solve`` from the active set left by the previous solve: its exit flag and iterations."""
        self._run()
        result = self._result
        return result.exitflag, result.iter


class ModelDaqp:
    """The same calls through ``daqp.Model``, which copies its answer into a new array every solve.

    :attr:`refresh` is ``daqp.Model.update`` naming ``H``, ``f``, the bounds and ``A`` (with rows).
    """

    def __init__(self) -> None:
        import daqp

        self._model = daqp.Model()
        self._x = np.zeros(0)
        self.refresh: Callable[[], int] = _not_set_up

    def setup(
        self,
        H: np.ndarray,
        f: np.ndarray,
        A: np.ndarray,
        upper: np.ndarray,
        lower: np.ndarray,
        sense: np.ndarray,
        x: np.ndarray,
    ) -> int:
        """As :meth:`DirectDaqp.setup`."""
        self._x = x
        self.refresh = functools.partial(self._model.update, H, f, A if A.shape[0] else None, upper, lower)
        flag, _ = self._model.setup(H, f, A, upper, lower, sense)
        return int(flag)

    def solve(self) -> tuple[int, int]:
        """As :meth:`DirectDaqp.solve`."""
        x, _, flag, info = self._model.solve()
        if flag == 1:
            self._x[...] = x
        return flag, info["iterations"]


def _not_set_up() -> Any:
    raise RuntimeError("daqp is not set up yet")


def _kept_as_is(array: np.ndarray) -> bool:
    """Whether daqp reads ``array`` itself (C-contiguous ``float64``) rather than a copy of it."""
    return array.dtype == np.float64 and array.flags.c_contiguous


class ActiveSetStepSolver:
    """The per-step QP by DAQP's dual active-set method on the controller's own buffers, warm-started.

    DAQP (Arnstrom, Bemporad and Axehill 2022, "A dual active-set solver for embedded
    quadratic programming using recursive LDL' updates", IEEE TAC 67(8), doi:10.1109/TAC.2022.3176430)
    solves ``min 1/2 x'Hx + g'x`` s.t. ``lb <= x <= ub`` (simple bounds) and ``b <= A x``.
    daqp is set up at the first :meth:`solve` on the arrays of that
    :class:`~optikin.solvers.qp.common.QPData`: ``H`` (its transpose, the same symmetric
    matrix, C-ordered), ``g``, ``lb``, ``ub`` and ``A`` are handed over without a copy, so daqp
    reads the buffers the task Function writes. Each step then refreshes daqp's transformation of
    the QP (the Cholesky factor of the new ``H``, the new ``g``, bounds and ``A``) and solves from
    the previous step's active set. With rows, the bounds go through two
    buffers ``[lb; b]``, ``[ub; inf]`` filled in place (``b`` clipped at daqp's infinity). After a
    failed solve the next one starts from the empty active set. The calls go through
    :class:`DirectDaqp` when it can run (module docstring), else through :class:`ModelDaqp`.

    The answer (:meth:`solve`) is one :class:`~optikin.solvers.base.Solution` updated in place
    every step: ``x`` a preallocated array, overwritten by the next call (copy what you keep);
    ``status`` ``"ok"`` or ``"failed"`` (``message`` daqp's exit flag, e.g. ``-1`` infeasible).

    Parameters
    ----------
    n:
        Number of rates.
    m:
        Number of task rows (unused; the signature of a ``qp`` step-solver factory).
    options:
        The preset's options (none: daqp's defaults).
    rows:
        Number of rows ``A qdot >= b``.
    direct:
        Whether to call daqp's C functions directly when they can be (:class:`DirectDaqp`); False: always
        through ``daqp.Model``.
    """

    name = "daqp-active-set"

    def __init__(self, n: int, m: int = 0, options: DaqpOptions | None = None, rows: int = 0, *, direct: bool = True):
        import daqp  # noqa: F401 - fails here, not at the first step, when daqp is missing

        self.n, self.rows = n, rows
        self._direct = direct and DirectDaqp.available()
        self.daqp: DirectDaqp | ModelDaqp | None = None
        self._refresh: Callable[[], int] = _not_set_up
        self._run: Callable[[], tuple[int, int]] = _not_set_up
        self._data: QPData | None = None
        self._sense = np.zeros(n + rows, dtype=np.intc)
        self._x = np.full(n, np.nan)
        self.solution = Solution(self._x, Status.OK)
        if rows:
            self._lower, self._upper = np.empty(n + rows), np.full(n + rows, _DAQP_INFINITY)
            self._lower_box, self._lower_rows, self._upper_box = self._lower[:n], self._lower[n:], self._upper[:n]

    def _setup(self, data: QPData) -> int:
        """Set daqp up on ``data``'s arrays; its exit flag (negative on failure)."""
        if data.H.shape != (self.n, self.n) or data.A.shape[0] != self.rows:
            raise ValueError(
                f"{self.name}: QP of {data.n} rates and {data.A.shape[0]} rows, set up for {self.n}, {self.rows}"
            )
        H = data.H.T  # H is symmetric and column-major: its transpose is the same matrix, C-ordered, no copy
        A = data.A if self.rows else np.zeros((0, self.n))
        if self.rows:
            self._fill_bounds(data)
            upper, lower = self._upper, self._lower
        else:
            upper, lower = data.ub, data.lb
        direct = self._direct and all(_kept_as_is(a) for a in (H, data.g, A, upper, lower))
        if self.daqp is None or isinstance(self.daqp, DirectDaqp) != direct:
            self.daqp = DirectDaqp() if direct else ModelDaqp()
        self._data = data
        self._sense.fill(0)  # no constraint assumed active
        flag = self.daqp.setup(H, data.g, A, upper, lower, self._sense, self._x)
        self._refresh, self._run = self.daqp.refresh, self.daqp.solve
        return flag

    def _fill_bounds(self, data: QPData) -> None:
        self._lower_box[...] = data.lb
        self._upper_box[...] = data.ub
        np.maximum(data.b, -_DAQP_INFINITY, out=self._lower_rows)

    def solve(self, data: QPData) -> Solution:
        """One warm-started solve of this step's QP (``data`` the same object every step, written in place)."""
        start = time.perf_counter()
        solution = self.solution
        if data is not self._data:
            flag = self._setup(data)
        else:
            if self.rows:
                self._fill_bounds(data)
            flag = self._refresh()
        iterations = -1
        if flag >= 0:  # set up or refreshed (the factorisation of H succeeded)
            flag, iterations = self._run()
        if flag == 1:
            if solution.status != Status.OK:
                solution.status, solution.message = Status.OK, ""
        else:
            self._x.fill(np.nan)
            solution.status, solution.message = Status.FAILED, f"daqp exit flag {flag}"
            self._data = None  # the next step sets daqp up afresh: empty active set, new factorisation
        solution.iterations, solution.seconds = iterations, time.perf_counter() - start
        return solution


@register_backend(
    "qp_daqp", "qp", "DAQP's dual active set on the controller's buffers, warm-started every step", options=DaqpOptions
)
def build(preset: SolverSpec, options: DaqpOptions) -> StepSolverFactory[DaqpOptions]:
    """The factory of DAQP active-set step solvers."""
    return StepSolverFactory(ActiveSetStepSolver, options)
