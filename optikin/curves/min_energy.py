"""Minimum-energy choice of a PH quintic backbone among its Hermite interpolants, posed as an NLP.

Seed 002 (section II.A) reconstructs a backbone from its two end poses: the PH
quintic Hermite interpolants of ``(p0, t0, p1, t1)`` form a two-parameter family
(:mod:`optikin.curves.ph_quintic`; angles ``phi0, phi2`` with ``phi1 = 0``), and
the member of least energy (:mod:`optikin.curves.energy`) is taken. The seed gives
the end *directions* only; the end speeds ``|r'(0)|, |r'(1)|`` are either

* **given** (``free_speeds=False``): the seed's setting. The default is the backbone
  length for both, the speed of a curve parametrised proportionally to arc length;
  variables ``x = (phi0, phi2)``; or
* **free** (``free_speeds=True``): ``x = (phi0, phi2, s0, s1)`` with the arc length
  held to the known backbone length ``L`` (equality constraint ``S(x) = L``) and
  ``s`` in ``[SPEED_BOUNDS[0] L, SPEED_BOUNDS[1] L]``. Bending energy alone
  decreases as a curve grows longer, so free speeds need the length.

Three solvers, one model (:class:`ShapeEnergyModel`):

* :meth:`ShapeEnergyModel.solve_nlp` - CasADi ``nlpsol('ipopt')``, the reference,
  started from the best points of a coarse grid;
* :meth:`ShapeEnergyModel.solve_newton` - the fast path: Newton on the compiled
  CasADi gradient and Hessian (:mod:`optikin.curves.newton`: modified Newton with
  an Armijo line search for given speeds; null-space SQP with a second-order
  correction for free speeds), warm-started from the previous sample along a
  trajectory, with the coarse grid and IPOPT as fallbacks;
* :meth:`ShapeEnergyModel.solve_grid` - the baseline: a dense grid over the free
  parameters (for free speeds, over ``phi0, phi2, log(s0/s1)`` with the common
  speed scale solved to meet the length).

One solve is one sample; the ``ph`` backends (:mod:`optikin.solvers.ph_backends`)
solve a trajectory of samples, warm-starting each from the previous solution. The
model builds the curve of a solution (:meth:`ShapeEnergyModel.curve`, or
:meth:`ShapeEnergyModel.curves` for a batch) from the same parameter layout
(:class:`ShapeParameters`) its CasADi expressions use.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, NamedTuple, Sequence

import casadi as ca
import numpy as np

from optikin.algebra.angles import wrap_periodic
from optikin.fastcall import BufferedFunction
from optikin.curves.energy import DEFAULT_CURVATURE_FLOOR, DEFAULT_NODES, shape_energy
from optikin.curves.newton import kkt_newton, kkt_newton_function, modified_newton, modified_newton_function
from optikin.curves.ph_quintic import PHQuintic, hermite_family
from optikin.errors import InputDataError
from optikin.solvers.base import Solution
from optikin.status import Status

SPEED_BOUNDS = (0.2, 5.0)
"""Bounds of free end speeds, as multiples of the backbone length."""

GRID_SECANT_STEPS = 12
"""Secant steps of the free-speed grid; points whose length is still off are left out."""


class ShapeParameters(NamedTuple):
    """The parameter vector ``P`` of :class:`ShapeEnergyModel`, by name.

    ``P`` is ``p0 (3), t0 (3), p1 (3), t1 (3), s0, s1, length``: the end points, unit
    end tangents, given end speeds ``|r'(0)|, |r'(1)|`` [m] and backbone length [m].
    The one place that knows where each lies in ``P``; the fields are numpy views or
    CasADi expressions, whichever ``P`` is.
    """

    p0: Any
    t0: Any
    p1: Any
    t1: Any
    s0: Any
    s1: Any
    length: Any

    @classmethod
    def of(cls, P: Any) -> "ShapeParameters":
        """The fields of a parameter vector ``P`` (numpy ``(N_PARAMETERS,)`` or CasADi ``N_PARAMETERS x 1``)."""
        fields, start = [], 0
        for size in PARAMETER_SIZES:
            fields.append(P[start : start + size] if size > 1 else P[start])
            start += size
        return cls(*fields)

    def vector(self) -> np.ndarray:
        """The numpy parameter vector of numpy fields."""
        return np.concatenate([self.p0, self.t0, self.p1, self.t1, [self.s0, self.s1, self.length]])


PARAMETER_SIZES = (3, 3, 3, 3, 1, 1, 1)
"""Sizes of the fields of :class:`ShapeParameters`, in the order they lie in ``P``."""
N_PARAMETERS = sum(PARAMETER_SIZES)


@dataclass(frozen=True)
class EnergySettings:
    """What is minimised: ``int kappa^2 ds + twist_weight int tau^2 ds`` with ``nodes`` Gauss-Legendre points."""

    twist_weight: float = 0.0
    nodes: int = DEFAULT_NODES
    curvature_floor: float = DEFAULT_CURVATURE_FLOOR


@dataclass(frozen=True)
class ShapeData:
    """End poses of one backbone: points ``p0, p1``, unit tangents ``t0, t1``, speeds or length.

    ``speeds`` are ``(|r'(0)|, |r'(1)|)`` when given; ``length`` is the known
    backbone length (the default speed, and the constraint when speeds are free).
    """

    p0: np.ndarray
    t0: np.ndarray
    p1: np.ndarray
    t1: np.ndarray
    speeds: tuple[float, float] | None = None
    length: float | None = None

    @classmethod
    def checked(cls, p0, t0, p1, t1, speeds=None, length=None, *, source: str = "", sample: int | None = None):
        """Validated, with unit tangents; raises :class:`InputDataError` naming the field."""
        vectors = {}
        for name, v in (("p0", p0), ("t0", t0), ("p1", p1), ("t1", t1)):
            v = np.asarray(v, dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise InputDataError(f"expected a finite 3-vector, got {v!r}", source=source, sample=sample, field=name)
            vectors[name] = v
        for name in ("t0", "t1"):
            n = np.linalg.norm(vectors[name])
            if not n > 0:
                raise InputDataError("end direction has zero length", source=source, sample=sample, field=name)
            vectors[name] = vectors[name] / n
        if speeds is not None:
            speeds = tuple(float(s) for s in speeds)
            if len(speeds) != 2 or not all(math.isfinite(s) and s > 0 for s in speeds):
                raise InputDataError(
                    f"end speeds must be two positive numbers, got {speeds}",
                    source=source,
                    sample=sample,
                    field="speeds",
                )
        if length is not None:
            length = float(length)
            if not (math.isfinite(length) and length > 0):
                raise InputDataError(
                    f"backbone length must be positive, got {length}", source=source, sample=sample, field="length"
                )
            chord = float(np.linalg.norm(vectors["p1"] - vectors["p0"]))
            if chord >= length * (1 + 1e-12):
                raise InputDataError(
                    f"end points are {chord:.6g} apart, more than the backbone length {length:.6g}",
                    source=source,
                    sample=sample,
                    field="length",
                )
        return cls(vectors["p0"], vectors["t0"], vectors["p1"], vectors["t1"], speeds, length)

    @cached_property
    def _parameters(self) -> np.ndarray:
        s0, s1 = self.speeds if self.speeds is not None else (self.length or 0.0, self.length or 0.0)
        P = ShapeParameters(self.p0, self.t0, self.p1, self.t1, s0, s1, self.length or 0.0).vector()
        P.setflags(write=False)
        return P

    def parameters(self) -> np.ndarray:
        """The parameter vector :class:`ShapeParameters` (speeds default to the length; an absent length is 0)."""
        return self._parameters


def arc_length_estimate(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Backbone length from the end poses alone: the circular arc through them, ``c (D/2) / sin(D/2)``.

    ``c`` is the chord ``|p1 - p0|`` and ``D`` the sum of the angles of the unit
    tangents ``t0``, ``t1`` with it. Exact for a planar circular arc (where both
    angles are half the bend); a lower bound on the length of any other curve of
    these end poses is the chord.

    Parameters
    ----------
    p0, t0, p1, t1:
        End points [m] and unit end tangents, shapes ``(..., 3)`` that broadcast.

    Returns
    -------
    numpy.ndarray
        The lengths [m], shape ``(...)``.
    """
    chord = p1 - p0
    c = np.linalg.norm(chord, axis=-1)
    u = chord / np.maximum(c, 1e-300)[..., None]
    D = np.arccos(np.clip(np.sum(t0 * u, axis=-1), -1.0, 1.0)) + np.arccos(np.clip(np.sum(t1 * u, axis=-1), -1.0, 1.0))
    half = 0.5 * D
    return c * np.where(half > 1e-8, half / np.maximum(np.sin(half), 1e-300), 1.0 + half**2 / 6.0)


@dataclass
class ShapeSolution(Solution):
    """One minimum-energy backbone: a :class:`~optikin.solvers.base.Solution` with the PH fields.

    ``x`` holds the free parameters ``(phi0, phi2)`` or, with free end speeds,
    ``(phi0, phi2, s0, s1)``; the curve is :meth:`ShapeEnergyModel.curve`.
    ``residual`` is the energy (the family's measure of the answer); ``message``
    joins the notes of a solve that is not ``ok``.

    Attributes
    ----------
    method:
        ``newton``, ``ipopt`` or ``grid``.
    energy, arc_length:
        Energy of the curve (units of the energy functional: 1/m for bending) and its length [m].
    evaluations:
        Energy evaluations of a grid solve.
    multiplier:
        The length constraint's Lagrange multiplier (free speeds), NaN otherwise.
    quadrature_error:
        ``|E(2 nodes) - E(nodes)|`` of an IPOPT solution.
    notes:
        What happened on the way (warm start failed, fallbacks, IPOPT return statuses).
    """

    method: str = ""
    energy: float = math.nan
    arc_length: float = math.nan
    evaluations: int = 0
    multiplier: float = math.nan
    quadrature_error: float = math.nan
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.residual = self.energy
        if self.status != Status.OK and not self.message:
            self.message = "; ".join(self.notes)

    @property
    def angles(self) -> np.ndarray:
        """The free angles ``(phi0, phi2)`` [rad]."""
        return self.x[:2]


class ShapeEnergyModel:
    """The minimum-energy backbone problem, built once as CasADi expressions and reused for every sample.

    ``compile=True`` turns the Functions the fast path calls into C (a few seconds,
    once, cached on disk); otherwise they run in CasADi's virtual machine.
    """

    def __init__(
        self,
        settings: EnergySettings = EnergySettings(),
        *,
        free_speeds: bool = False,
        compile: bool = False,
        coarse_grid: int = 12,
    ):
        self.settings = settings
        self.free_speeds = free_speeds
        self.compile = compile
        self.coarse_grid = coarse_grid
        self.n_x = 4 if free_speeds else 2
        P = ca.SX.sym("P", N_PARAMETERS)
        x = ca.SX.sym("x", self.n_x)
        self._parameters = ShapeParameters.of(P)
        curve = self._member(x, self._parameters)
        energy = shape_energy(curve, settings.twist_weight, settings.nodes, settings.curvature_floor)
        self._x, self._P, self._curve, self._energy, self._length = x, P, curve, energy, curve.arc_length()
        self.energy_function = ca.Function("ph_energy", [x, P], [energy, self._length], ["x", "P"], ["E", "S"])
        self._maps: dict[int, BufferedFunction] = {}
        self.native: dict[Any, Any] = {}
        """The compiled C of this model's fast path (:mod:`optikin.native.ph`), by what shapes its code."""

    # -- curves -------------------------------------------------------------------
    def _member(self, x: Any, P: ShapeParameters) -> PHQuintic:
        """The family member at free parameters ``x`` of the data ``P`` (numpy or CasADi)."""
        s0, s1 = (x[2], x[3]) if self.free_speeds else (P.s0, P.s1)
        return hermite_family(P.p0, s0 * P.t0, P.p1, s1 * P.t1).member(x[0], x[1], 0.0)

    def symbols(self) -> tuple[ca.SX, ca.SX, PHQuintic]:
        """``(x, P, curve)``: the CasADi free parameters, parameter vector and the curve built from them.

        For Functions of the model's curve (e.g. tube lengths) that take the same
        ``x`` and ``P`` as the energy.
        """
        return self._x, self._P, self._curve

    def curve(self, solution: Solution | np.ndarray, data: ShapeData) -> PHQuintic:
        """The numpy curve of a solution (or of free parameters ``x``) for the end data ``data``."""
        x = solution.x if isinstance(solution, Solution) else np.asarray(solution, dtype=float)
        return self._member(x, ShapeParameters.of(data.parameters()))

    def curves(self, solutions: Sequence[Solution], samples: Sequence[ShapeData]) -> PHQuintic:
        """The curves of ``solutions`` as one numpy batch ``(N, ...)``; samples without a point get NaN coefficients."""
        batch = []
        for sol, data in zip(solutions, samples):
            if np.all(np.isfinite(sol.x)):
                batch.append(self.curve(sol, data))
            else:
                nan = np.full(4, np.nan)
                batch.append(PHQuintic(data.p0, nan, nan, nan))
        return PHQuintic(*(np.stack([getattr(c, k) for c in batch]) for k in ("p0", "A0", "A1", "A2")))

    # -- data checks --------------------------------------------------------------
    def _check(self, data: ShapeData, source: str = "", sample: int | None = None) -> np.ndarray:
        if self.free_speeds and data.length is None:
            raise InputDataError(
                "free end speeds need the backbone length (the arc-length constraint)",
                source=source,
                sample=sample,
                field="length",
            )
        if not self.free_speeds and data.speeds is None and data.length is None:
            raise InputDataError(
                "give the end speeds or the backbone length", source=source, sample=sample, field="speeds"
            )
        return data.parameters()

    def parameters_of(self, samples: Sequence[ShapeData]) -> np.ndarray:
        """``(N, N_PARAMETERS)`` parameter vectors of ``samples``, each checked as :meth:`solve_newton` checks it.

        Raises
        ------
        InputDataError
            A sample lacks what the model needs (the backbone length for free speeds; speeds or length).
        """
        if not samples:
            return np.empty((0, N_PARAMETERS))
        return np.array([self._check(data) for data in samples])

    def _bounds(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if not self.free_speeds:
            return np.full(2, -np.inf), np.full(2, np.inf)
        L = ShapeParameters.of(P).length
        lo, hi = SPEED_BOUNDS
        return np.array([-np.inf, -np.inf, lo * L, lo * L]), np.array([np.inf, np.inf, hi * L, hi * L])

    # -- coarse start -------------------------------------------------------------
    def _angle_grid(self, n: int) -> np.ndarray:
        a = -np.pi + 2 * np.pi * np.arange(n) / n
        A0, A2 = np.meshgrid(a, a, indexing="ij")
        return np.stack([A0.ravel(), A2.ravel()])

    def _evaluate_many(self, X: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Energy and arc length at the columns of ``X`` (one mapped call; compiled with the model)."""
        n = X.shape[1]
        if n not in self._maps:
            mapped = self.energy_function.map(f"ph_energy_map{n}", "serial", n, [1], [])  # P shared
            self._maps[n] = BufferedFunction(mapped, compiled=self.compile)
        E, S = self._maps[n](X, P)
        return E.copy(), S.copy()

    def coarse_starts(self, P: np.ndarray, count: int = 1) -> np.ndarray:
        """The ``count`` best points of the ``coarse_grid`` x ``coarse_grid`` angle grid (speeds at ``L``).

        Returns ``n_x x count`` starts, best first.
        """
        X = self._angle_grid(self.coarse_grid)
        if self.free_speeds:
            X = np.vstack([X, np.full((2, X.shape[1]), ShapeParameters.of(P).length)])
        E, _ = self._evaluate_many(X, P)
        E = np.where(np.isfinite(E), E, np.inf)
        return X[:, np.argsort(E)[:count]]

    # -- reference: IPOPT -----------------------------------------------------------
    @cached_property
    def _nlp(self) -> ca.Function:
        problem = {"x": self._x, "p": self._P, "f": self._energy}
        if self.free_speeds:
            problem["g"] = self._length - self._parameters.length
        options: dict[str, Any] = {
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.tol": 1e-12,
            "ipopt.max_iter": 200,
        }
        return ca.nlpsol("ph_min_energy", "ipopt", problem, options)

    def solve_nlp(self, data: ShapeData, x0: np.ndarray | None = None, starts: int = 3) -> ShapeSolution:
        """IPOPT from ``x0``, or from the ``starts`` best coarse-grid points (the best result is kept)."""
        P = self._check(data)
        tic = time.perf_counter()
        X0 = np.asarray(x0, dtype=float).reshape(self.n_x, 1) if x0 is not None else self.coarse_starts(P, starts)
        lbx, ubx = self._bounds(P)
        best, iterations, statuses = None, 0, []
        for j in range(X0.shape[1]):
            args: dict[str, Any] = dict(x0=X0[:, j], p=P, lbx=lbx, ubx=ubx)
            if self.free_speeds:
                args.update(lbg=0.0, ubg=0.0)
            sol = self._nlp(**args)
            stats = self._nlp.stats()
            iterations += int(stats.get("iter_count", 0))
            statuses.append(stats["return_status"])
            energy = float(sol["f"])
            if stats["success"] and (best is None or energy < best[0]):
                multiplier = -float(sol["lam_g"]) if self.free_speeds else math.nan
                best = (energy, np.asarray(sol["x"]).ravel(), multiplier)
        seconds = time.perf_counter() - tic
        if best is None:
            return ShapeSolution(X0[:, 0], Status.FAILED, iterations, seconds=seconds, method="ipopt", notes=statuses)
        x = best[1].copy()
        x[:2] = wrap_periodic(x[:2])
        E, S = self.energy_function(x, P)
        E_fine, _ = self._fine_energy_function(x, P)
        return ShapeSolution(
            x,
            Status.OK,
            iterations,
            seconds=seconds,
            method="ipopt",
            energy=float(E),
            arc_length=float(S),
            multiplier=best[2],
            quadrature_error=abs(float(E_fine) - float(E)),
            notes=statuses,
        )

    @cached_property
    def _fine_energy_function(self) -> ca.Function:
        """The energy with twice the quadrature nodes, to estimate the quadrature error of a solution."""
        fine = ShapeEnergyModel(
            EnergySettings(self.settings.twist_weight, 2 * self.settings.nodes, self.settings.curvature_floor),
            free_speeds=self.free_speeds,
        )
        return fine.energy_function

    # -- baseline: dense grid -------------------------------------------------------
    def solve_grid(self, data: ShapeData, n: int = 64, n_ratio: int = 9) -> ShapeSolution:
        """Best point of an ``n x n`` angle grid (free speeds: times ``n_ratio`` speed ratios in [1/3, 3]).

        With free speeds, each grid point's common speed scale ``k`` (``s0 = k r``,
        ``s1 = k / r``) is found by the secant method so that the arc length is ``L``.
        """
        P = self._check(data)
        tic = time.perf_counter()
        X = self._angle_grid(n)
        if self.free_speeds:
            ratios = np.exp(np.linspace(-np.log(3.0), np.log(3.0), n_ratio))
            X = np.repeat(X, n_ratio, axis=1)
            r = np.tile(ratios, n * n)
            X, E, S = self._grid_on_length(X, r, P)
        else:
            E, S = self._evaluate_many(X, P)
        E = np.where(np.isfinite(E), E, np.inf)
        k = int(np.argmin(E))
        seconds = time.perf_counter() - tic
        status = Status.OK if np.isfinite(E[k]) else Status.FAILED
        return ShapeSolution(
            X[:, k].copy(),
            status,
            0,
            seconds=seconds,
            method="grid",
            energy=float(E[k]),
            arc_length=float(S[k]),
            evaluations=X.shape[1],
        )

    def _grid_on_length(self, X2: np.ndarray, r: np.ndarray, P: np.ndarray):
        L = ShapeParameters.of(P).length
        lo, hi = SPEED_BOUNDS

        def length_at(k):
            X = np.vstack([X2, k * r, k / r])
            return self._evaluate_many(X, P)

        k_a, k_b = np.full(r.shape, 0.8 * L), np.full(r.shape, 1.2 * L)
        (_, S_a), (E, S_b) = length_at(k_a), length_at(k_b)
        for _ in range(GRID_SECANT_STEPS):
            moving = np.abs(S_b - L) >= 1e-12 * L
            if not np.any(moving):
                break
            denom = np.where(np.abs(S_b - S_a) > 1e-300, S_b - S_a, 1e-300)
            k_c = np.where(moving, np.clip(k_b - (S_b - L) * (k_b - k_a) / denom, lo * L / 3, hi * L * 3), k_b)
            k_a, S_a = k_b, S_b
            k_b = k_c
            E, S_b = length_at(k_b)
        X = np.vstack([X2, k_b * r, k_b / r])
        ok = (np.abs(S_b - L) < 1e-9 * L) & (X[2] >= lo * L) & (X[2] <= hi * L) & (X[3] >= lo * L) & (X[3] <= hi * L)
        return X, np.where(ok, E, np.inf), S_b

    # -- fast path: Newton ----------------------------------------------------------
    @cached_property
    def _newton_function(self) -> BufferedFunction:
        if self.free_speeds:
            f = kkt_newton_function(
                self._energy, self._length - self._parameters.length, self._length, self._x, self._P
            )
        else:
            f = modified_newton_function(self._energy, self._length, self._x, self._P)
        return BufferedFunction(f, compiled=self.compile)

    def solve_newton(
        self,
        data: ShapeData,
        x0: np.ndarray | None = None,
        *,
        tolerance: float = 1e-10,
        max_iterations: int = 50,
        fallback: bool = True,
        basin_check: bool = False,
    ) -> ShapeSolution:
        """Fast path: Newton from ``x0`` (or the best coarse-grid point).

        Converged means ``|grad L| <= tolerance (1 + |E|)`` (and ``|S - L| <= tolerance L``
        with free speeds) at a point where the (reduced) Hessian is positive definite.
        Otherwise, with ``fallback``, it restarts from the coarse grid, then calls IPOPT.

        ``basin_check``: a warm start stays in the basin of the previous sample's minimum,
        which need not be the lowest (with free speeds the energy has several minima along a
        trajectory). Newton is then also run from the best coarse-grid point, and the lower of
        the two converged minima kept: about three times the time per sample.
        """
        tic = time.perf_counter()
        P = self._check(data)
        notes: list[str] = []
        start = x0 if x0 is not None else self.coarse_starts(P)[:, 0]
        x, lam, E, S, iterations, ok = self._newton(start, P, tolerance, max_iterations)
        if not ok and fallback and x0 is not None:
            notes.append("warm start failed; coarse grid restart")
            x, lam, E, S, more, ok = self._newton(self.coarse_starts(P)[:, 0], P, tolerance, max_iterations)
            iterations += more
        if ok and basin_check and x0 is not None:
            x2, lam2, E2, S2, more, ok2 = self._newton(self.coarse_starts(P)[:, 0], P, tolerance, max_iterations)
            iterations += more
            if ok2 and E2 < E - 1e-9 * abs(E):
                notes.append("basin check: the coarse-grid start found a lower minimum")
                x, lam, E, S = x2, lam2, E2, S2
        if not ok and fallback:
            notes.append("Newton failed; IPOPT fallback")
            ref = self.solve_nlp(data, starts=3)
            return replace(ref, method="newton", seconds=time.perf_counter() - tic, notes=notes + ref.notes, message="")
        x[0], x[1] = wrap_periodic(x[0]), wrap_periodic(x[1])
        return ShapeSolution(
            x,
            Status.OK if ok else Status.NOT_CONVERGED,
            iterations,
            seconds=time.perf_counter() - tic,
            method="newton",
            energy=E,
            arc_length=S,
            multiplier=lam,
            notes=notes,
        )

    def _newton(self, x: np.ndarray, P: np.ndarray, tol: float, max_iterations: int):
        """``(x, multiplier, E, S, iterations, converged)``; the multiplier is NaN without the length constraint."""
        fn = self._newton_function
        fn.inputs[-1][:] = P
        if not self.free_speeds:
            x, E, S, iterations, ok = modified_newton(fn, x, tol, max_iterations)
            return x, math.nan, E, S, iterations, ok
        L = ShapeParameters.of(P).length
        bounds = (SPEED_BOUNDS[0] * L, SPEED_BOUNDS[1] * L)
        return kkt_newton(fn, x, tol, L, {2: bounds, 3: bounds}, max_iterations)
