"""Batched constant-curvature forward kinematics as a vectorised C loop (structure of arrays).

For an ``m``-section :class:`~optikin.arms.constant_curvature.ConstantCurvatureArm` the
tip pose (seed 000 eqs. 1, 5, 9-10) is written here once more, straight into C, so that
the compiler can run the loop over the samples in SIMD lanes:

* every section needs ``sin`` and ``cos`` of ``theta/2`` and of ``phi`` only (four calls,
  shared by the rotation and the position): with ``h = theta/2`` and
  ``c = sin(h)/h``, ``(1 - cos theta)/theta = sin(h) c`` and ``sin(theta)/theta = cos(h) c``;
* ``theta = 0`` is handled without a branch: the divisor is selected (``h``, or 1 inside the
  series band of :data:`optikin.algebra.backend.SERIES_BAND`) and so is the result (the
  quotient, or the series ``1 - h^2/6 + h^4/120``), both blends in the vector code;
* the samples are stored variable by variable (``q[j * ld + i]``), so every load and store in
  the loop is unit-stride; the row-major batches of :meth:`~optikin.arms.base.ArmModel.evaluate`
  are transposed through a small block on the stack inside the same C call;
* ``sin`` and ``cos`` are declared with GCC's ``simd`` attribute, so the vectoriser calls
  glibc's vector maths library (``libmvec``, at most 4 ulp) in place of the scalar functions.

Flags (:data:`VECTOR_FLAGS`): ``-O3 -fno-math-errno -fno-trapping-math -march=native
-fopenmp-simd -fno-builtin-sin -fno-builtin-cos`` (the last two stop GCC from fusing the
pair into ``sincos``, which has no vector clone). ``-march=native`` lets the compiler
contract into FMA and libmvec is not correctly rounded, so the results differ from the
CasADi Function in the last bits: the tests hold them within 1e-14 of it (theta = 0,
1e-8, pi and arbitrary phi included). Where that build fails (no glibc ``libmvec``, no
GCC), the same source is built with ``-O3`` alone; where no compiler is found,
:func:`soa_evaluate` returns ``None`` and the caller keeps the CasADi path, which stays
the reference. The library is cached like :mod:`optikin.codegen`'s, its source carrying
the CPU's identity so a cache shared between machines never loads code built for another.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import platform
import threading
from pathlib import Path
from typing import Any

import numpy as np

from optikin import codegen
from optikin.algebra.backend import SERIES_BAND
from optikin.errors import SolverError
from optikin.interrupt import check_interrupted

VECTOR_FLAGS: tuple[str, ...] = (
    "-O3",
    "-fno-math-errno",
    "-fno-trapping-math",
    "-march=native",
    "-fopenmp-simd",
    "-fno-builtin-sin",
    "-fno-builtin-cos",
)
"""Flags of the vectorised build (see the module docstring)."""
PORTABLE_FLAGS: tuple[str, ...] = ("-O3",)
"""Flags of the fallback build: scalar loop, results bit-identical to scalar libm arithmetic."""
BLOCK = 256
"""Samples per block of the row-major entry points (transposed through the stack)."""
LANES = 16
"""The loop only ever runs over a multiple of this many samples (a tail is padded with straight
sections), so every sample takes the same vector code whatever its place in the batch."""
CHUNK = 1 << 18
"""Samples per C call: a stop request waits at most for one chunk."""
OUTPUTS = {"fk_dq": 8, "fk_position": 3}
"""Functions this module evaluates and their output size per sample."""

_HEADER = """/* optikin: constant-curvature tip pose, {m} section(s), structure of arrays; cpu {cpu} */
#if defined(__GNUC__) && defined(__x86_64__) && defined(__linux__) && !defined(OPTIKIN_SCALAR)
double sin(double) __attribute__((simd("notinbranch"), const, nothrow));
double cos(double) __attribute__((simd("notinbranch"), const, nothrow));
#else
#include <math.h>
#endif
#define OPTIKIN_BAND2 {band2!r}
"""


def _section(s: int, load) -> list[str]:
    """C statements of section ``s``: its relative rotation ``(rw, rx, ry, 0)`` and tip position ``v``."""
    return [
        f"    const double S{s} = {load(3 * s)}, t{s} = {load(3 * s + 1)}, f{s} = {load(3 * s + 2)};",
        f"    const double h{s} = 0.5 * t{s}, sh{s} = sin(h{s}), ch{s} = cos(h{s});",
        f"    const double sp{s} = sin(f{s}), cp{s} = cos(f{s});",
        f"    const double x2{s} = t{s} * t{s};",
        f"    const int sm{s} = x2{s} < OPTIKIN_BAND2;",
        f"    const double dn{s} = sm{s} ? 1.0 : h{s};",
        f"    const double ra{s} = sh{s} / dn{s};",
        f"    const double sc{s} = sm{s} ? 1.0 - x2{s} / 24.0 + x2{s} * x2{s} / 1920.0 : ra{s};",
        f"    const double rad{s} = S{s} * sh{s} * sc{s};",
        f"    const double vx{s} = rad{s} * cp{s}, vy{s} = rad{s} * sp{s}, vz{s} = S{s} * ch{s} * sc{s};",
        f"    const double rw{s} = ch{s}, rx{s} = -sh{s} * sp{s}, ry{s} = sh{s} * cp{s};",
    ]


def _chain(s: int) -> list[str]:
    """C statements appending section ``s`` to the frame ``(q, p)``: ``p += q v q*``, ``q <- q r``."""
    if s == 0:
        return ["    double px = vx0, py = vy0, pz = vz0;", "    double qw = rw0, qx = rx0, qy = ry0, qz = 0.0;"]
    return [
        f"    {{ const double tx = 2.0 * (qy * vz{s} - qz * vy{s}), ty = 2.0 * (qz * vx{s} - qx * vz{s}),"
        f" tz = 2.0 * (qx * vy{s} - qy * vx{s});",
        f"      px += vx{s} + qw * tx + (qy * tz - qz * ty);",
        f"      py += vy{s} + qw * ty + (qz * tx - qx * tz);",
        f"      pz += vz{s} + qw * tz + (qx * ty - qy * tx); }}",
        f"    {{ const double aw = qw * rw{s} - qx * rx{s} - qy * ry{s};",
        f"      const double ax = qw * rx{s} + qx * rw{s} - qz * ry{s};",
        f"      const double ay = qw * ry{s} + qy * rw{s} + qz * rx{s};",
        f"      const double az = qz * rw{s} + qx * ry{s} - qy * rx{s};",
        "      qw = aw; qx = ax; qy = ay; qz = az; }",
    ]


def _outputs(name: str, store) -> list[str]:
    """C statements storing the tip pose: ``(Q_r, 0.5 (0, p) Q_r)`` (``fk_dq``) or ``p`` (``fk_position``)."""
    if name == "fk_position":
        return [f"    {store(0)} = px; {store(1)} = py; {store(2)} = pz;"]
    return [
        f"    {store(0)} = qw; {store(1)} = qx; {store(2)} = qy; {store(3)} = qz;",
        f"    {store(4)} = -0.5 * (px * qx + py * qy + pz * qz);",
        f"    {store(5)} = 0.5 * (px * qw + py * qz - pz * qy);",
        f"    {store(6)} = 0.5 * (py * qw + pz * qx - px * qz);",
        f"    {store(7)} = 0.5 * (pz * qw + px * qy - py * qx);",
    ]


def _kernels(m: int, name: str) -> str:
    """C of ``name``: the SIMD loop ``core``, the SoA entry ``optikin_<name>_soa`` and the row-major ``_aos``."""
    n_in, n_out = 3 * m, OUTPUTS[name]
    body = [s for i in range(m) for s in _section(i, lambda j: f"q[{j} * ldq + i]") + _chain(i)]
    lanes = LANES
    core = [
        f"static void optikin_{name}_core(long long n, long long ldq, const double* restrict q,"
        " long long ldo, double* restrict out) {",
        "  long long i;",
        "  #pragma omp simd",
        "  for (i = 0; i < n; ++i) {",
        *body,
        *_outputs(name, lambda k: f"out[{k} * ldo + i]"),
        "  }",
        "}",
    ]
    soa = [
        f"void optikin_{name}_soa(long long n, long long ldq, const double* restrict q,"
        " long long ldo, double* restrict out) {",
        f"  double qb[{n_in * lanes}] = {{0}}, ob[{n_out * lanes}];",
        f"  long long i, j, body = n - n % {lanes};",
        f"  optikin_{name}_core(body, ldq, q, ldo, out);",
        "  if (body == n) return;",
        f"  for (j = 0; j < {n_in}; ++j) for (i = body; i < n; ++i) qb[j * {lanes} + i - body] = q[j * ldq + i];",
        f"  optikin_{name}_core({lanes}, {lanes}, qb, {lanes}, ob);",
        f"  for (j = 0; j < {n_out}; ++j) for (i = body; i < n; ++i) out[j * ldo + i] = ob[j * {lanes} + i - body];",
        "}",
    ]
    aos = [
        f"void optikin_{name}_aos(long long n, const double* restrict q, double* restrict out) {{",
        f"  double qb[{n_in * BLOCK}] = {{0}}, ob[{n_out * BLOCK}];",
        "  long long start, i, j, b;",
        f"  for (start = 0; start < n; start += {BLOCK}) {{",
        f"    b = n - start < {BLOCK} ? n - start : {BLOCK};",
        f"    for (i = 0; i < b; ++i) for (j = 0; j < {n_in}; ++j)",
        f"      qb[j * {BLOCK} + i] = q[(start + i) * {n_in} + j];",
        f"    optikin_{name}_core((b + {lanes - 1}) / {lanes} * {lanes}, {BLOCK}, qb, {BLOCK}, ob);",
        f"    for (i = 0; i < b; ++i) for (j = 0; j < {n_out}; ++j)",
        f"      out[(start + i) * {n_out} + j] = ob[j * {BLOCK} + i];",
        "  }",
        "}",
    ]
    return "\n".join(core + soa + aos) + "\n"


@functools.lru_cache(maxsize=1)
def _cpu() -> str:
    """A short hash of the CPU's model and feature flags (part of the source, hence of the cache key)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
        lines = [line for line in text.splitlines() if line.startswith(("model name", "flags"))][:2]
    except OSError:
        lines = []
    identity = "\n".join(lines) or platform.processor() or platform.machine()
    return hashlib.sha256(identity.encode()).hexdigest()[:16]


def source(m: int, scalar: bool = False) -> str:
    """The C source of the kernels for ``m`` sections (``scalar``: without the vector maths declarations)."""
    header = _HEADER.format(m=m, cpu=_cpu(), band2=SERIES_BAND**2)
    if scalar:
        header = "#define OPTIKIN_SCALAR 1\n" + header
    return header + "".join(_kernels(m, name) for name in OUTPUTS)


def _library(m: int, flags: tuple[str, ...], scalar: bool, compiler: str = "gcc") -> Path:
    """The cached shared library of :func:`source` built with ``flags`` (compiled unless valid)."""
    return codegen.source_library(f"optikin_fk_soa_{m}", source(m, scalar), flags, compiler)


class SoAKernel:
    """The compiled tip-pose kernels of an ``m``-section constant-curvature arm.

    Parameters
    ----------
    m:
        Number of sections; the configuration is ``(S_1, theta_1, phi_1, ..., S_m, theta_m, phi_m)``.

    Attributes
    ----------
    flags:
        The flags the loaded library was built with (:data:`VECTOR_FLAGS` or :data:`PORTABLE_FLAGS`).

    Raises
    ------
    SolverError
        No C compiler, or neither build succeeded.
    OSError
        The portable library could not be loaded.
    """

    def __init__(self, m: int):
        self.m = int(m)
        try:
            self.flags, lib = VECTOR_FLAGS, ctypes.CDLL(str(_library(self.m, VECTOR_FLAGS, scalar=False)))
        except (SolverError, OSError):
            self.flags, lib = PORTABLE_FLAGS, ctypes.CDLL(str(_library(self.m, PORTABLE_FLAGS, scalar=True)))
        self._aos, self._soa = {}, {}
        for name in OUTPUTS:
            aos = getattr(lib, f"optikin_{name}_aos")
            aos.argtypes = (ctypes.c_longlong, ctypes.c_void_p, ctypes.c_void_p)
            aos.restype = None
            soa = getattr(lib, f"optikin_{name}_soa")
            soa.argtypes = (ctypes.c_longlong, ctypes.c_longlong, ctypes.c_void_p, ctypes.c_longlong, ctypes.c_void_p)
            soa.restype = None
            self._aos[name], self._soa[name] = aos, soa

    def __call__(self, name: str, Q: np.ndarray) -> np.ndarray:
        """``name`` (``fk_dq`` or ``fk_position``) on row-major configurations.

        Parameters
        ----------
        name:
            A key of :data:`OUTPUTS`.
        Q:
            ``(N, 3m)`` configurations [m, rad].

        Returns
        -------
        numpy.ndarray
            ``(N, 8)`` unit dual quaternions or ``(N, 3)`` positions [m], base frame.
        """
        Q = np.ascontiguousarray(Q, dtype=np.float64)
        if Q.ndim != 2 or Q.shape[1] != 3 * self.m:
            raise ValueError(f"expected configurations of shape (N, {3 * self.m}), got {Q.shape}")
        n = Q.shape[0]
        out = np.empty((n, OUTPUTS[name]))
        run = self._aos[name]
        if n <= CHUNK:
            run(n, Q.ctypes.data, out.ctypes.data)
            return out
        for start in range(0, n, CHUNK):
            run(min(CHUNK, n - start), Q[start:].ctypes.data, out[start:].ctypes.data)
            check_interrupted()
        return out

    def soa(self, name: str, Q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``name`` on configurations stored variable by variable, without any copy.

        Parameters
        ----------
        name:
            A key of :data:`OUTPUTS`.
        Q:
            ``(3m, N)`` C-contiguous float64: row ``j`` holds variable ``j`` of every sample.
        out:
            Optional ``(n_out, N)`` C-contiguous float64 array to write into.

        Returns
        -------
        numpy.ndarray
            ``(8, N)`` or ``(3, N)``: row ``k`` holds output ``k`` of every sample.
        """
        if Q.dtype != np.float64 or not Q.flags.c_contiguous or Q.ndim != 2 or Q.shape[0] != 3 * self.m:
            raise ValueError(f"expected a C-contiguous float64 array of shape ({3 * self.m}, N), got {Q.shape}")
        n = Q.shape[1]
        if out is None:
            out = np.empty((OUTPUTS[name], n))
        elif out.dtype != np.float64 or not out.flags.c_contiguous or out.shape != (OUTPUTS[name], n):
            raise ValueError(f"out: expected a C-contiguous float64 array of shape ({OUTPUTS[name]}, {n})")
        self._soa[name](n, n, Q.ctypes.data, n, out.ctypes.data)
        return out


_KERNELS: dict[int, SoAKernel | None] = {}
_COVERED: dict[type, bool] = {}
_LOCK = threading.Lock()


def kernel(m: int) -> SoAKernel | None:
    """The (cached) :class:`SoAKernel` for ``m`` sections, or ``None`` when it cannot be built."""
    with _LOCK:
        if m not in _KERNELS:
            try:
                _KERNELS[m] = SoAKernel(m)
            except (SolverError, OSError):
                _KERNELS[m] = None
        return _KERNELS[m]


def applies(arm: Any, name: str) -> bool:
    """Whether ``arm.evaluate(name, ...)`` may use the SoA kernel: a constant-curvature arm with the
    kinematics of :class:`~optikin.arms.constant_curvature.ConstantCurvatureArm` and ``name`` in
    :data:`OUTPUTS`."""
    cls = type(arm)
    covered = _COVERED.get(cls)
    if covered is None:
        from optikin.arms.base import ArmModel
        from optikin.arms.constant_curvature import ConstantCurvatureArm

        covered = _COVERED[cls] = (
            issubclass(cls, ConstantCurvatureArm)
            and cls.section_frames is ConstantCurvatureArm.section_frames
            and cls._chain is ConstantCurvatureArm._chain
            and all(getattr(cls, output) is getattr(ArmModel, output) for output in OUTPUTS)
        )
    return covered and name in OUTPUTS


def soa_evaluate(arm: Any, name: str, Q: np.ndarray) -> np.ndarray | None:
    """``arm``'s ``name`` on ``Q (N, 3m)`` through the SoA kernel, or ``None`` where it does not apply.

    Parameters
    ----------
    arm:
        An arm model; only those :func:`applies` accepts are evaluated.
    name:
        ``fk_dq`` or ``fk_position``.
    Q:
        ``(N, n_config)`` configurations.

    Returns
    -------
    numpy.ndarray or None
        ``(N, 8)`` or ``(N, 3)``, within 1e-14 of the CasADi Function; ``None`` when the
        arm or output is not covered or no kernel could be built.
    """
    if not applies(arm, name):
        return None
    runner = kernel(arm.n_sections)
    return None if runner is None else runner(name, Q)
