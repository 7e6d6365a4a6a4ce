"""Calibration of a constant-curvature arm from measured marker positions: start, robust fit, outliers, refit,
identifiability, held-out test.

:func:`calibrate` runs the steps:

1. **start** (:func:`initial_base`, :func:`chord_configurations`): the base axis is
   the mean direction of the chords between consecutive disks, the base position lies
   on that axis behind the first disk, at the distance that makes the first disks lie
   on average one section length from it; each posture's bending vectors follow in
   closed form from its chords: a CC section of length ``S`` and bend ``theta`` has
   its chord at ``theta/2`` from its start tangent, of length ``S sinc(theta/2)``, in
   the bending plane (seed 000 eq. 1). The reference base orientation ``R_ref`` has
   its z axis on the base axis and its x axis on the measurement frame's x (or y)
   projected across it;
2. **configurations**: every posture fitted with the shared parameters held;
3. **robust fit** of everything (:func:`optikin.calibration.solver.solve`), to screen for outliers;
4. **outliers**: a posture is rejected when one of its marker errors exceeds
   ``outlier_threshold`` times the median marker error; the reason names the marker
   and, when exchanging two markers' labels explains the posture, the swap;
5. **refit** without the rejected postures (robust loss still on), to convergence, screened
   again the same way (a posture the first screen missed is rejected and the fit repeated, up
   to :data:`SCREENING_ROUNDS` times);
6. **least squares**: every posture, rejected ones included, fitted by least squares with the
   final geometry held: the errors reported (the robust loss only estimates the geometry);
7. **identifiability** (:mod:`optikin.calibration.identifiability`) at the start and at the
   solution: a geometry weakly determined or on a bound makes the verdict ``not_identifiable``.

The base is estimated, started from the data or a given pose, or held in part: components by
``fix``, in a mount plane (``plane``: one coordinate held) and along an exit direction
(``direction``: the base axis held). Section lengths may be bounded (``length_bounds``, fractions
of the nominal). :func:`held_out` repeats steps 3-5 in each training fold and scores the test
postures by least squares, over every posture.

Without measured orientations, the rotation of the base about its own axis (yaw) is
not observable: a torsion-free CC arm turned about its base axis reaches the same
points with every bending plane turned back. It stays at ``R_ref`` unless an
orientation prior fixes it (``estimate_yaw`` with ``orientation_sigma``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import lru_cache
from itertools import combinations
from typing import Sequence

import numpy as np

from optikin.algebra import matrix_from_rotation_vector
from optikin.calibration.identifiability import MAX_STD, Identifiability, analyse
from optikin.calibration.model import Layout, MarkerModel
from optikin.calibration.solver import Fit, Loss, Problem, solve
from optikin.status import Status

SCREENING_ITERATIONS = 10
"""Steps of the robust fit on every posture that screens for outliers (it need not converge to the last digit:
postures far from the model, nearly weightless, converge slowly; the final fit without them does)."""
SCREENING_TOLERANCE = 1e-6
"""Relative decrease of the cost that ends the screening fit."""
FOLD_ITERATIONS = 20
"""Steps of each training fold's fits at most: they start from the calibration's solution on every posture,
next to their own minimum (a start that did not converge on every posture is not made to converge per fold)."""
SCREENING_ROUNDS = 3
"""Fits without the rejected postures, each screened again, at most."""

MIN_OUTLIER_ERROR = 1e-6
"""A marker error below this [m] never makes an outlier (noise-free recordings: the median is rounding)."""

BASE_FIELDS = ("x", "y", "z", "tilt", "yaw")
"""Components of the base pose that ``fix`` may hold at their starting value."""


@dataclass(eq=False)
class Outlier:
    """A rejected posture: its index among the postures given, and why."""

    posture: int
    reason: str


@dataclass(eq=False)
class Calibration:
    """What :func:`calibrate` found.

    Attributes
    ----------
    fit : Fit
        The final fit, on the postures kept.
    robust : Fit
        The robust fit on every posture, from which the outliers were found.
    problem : Problem
        The problem on the postures kept.
    kept : numpy.ndarray
        Indices of the postures kept (the rows of ``fit.X``).
    outliers : list of Outlier
        The rejected postures.
    names : list of str
        Names of the shared parameters.
    seconds : float
        Wall time of the whole calibration.
    start : numpy.ndarray
        The shared parameters the fit started from.
    actuators, actuator_reference : numpy.ndarray or None
        With an actuator map: every posture's readings minus the reference ``(N, n_a)``, and the
        reference (their mean) ``(n_a,)``.
    full : Problem
        The problem on every posture (the rows of ``measured``).
    least_squares : Fit
        Every posture fitted by least squares (loss ``linear``) with the final geometry held: the errors
        reported in sample.
    identifiability, identifiability_start : Identifiability
        The identifiability reports at the solution and at the start
        (:mod:`optikin.calibration.identifiability`).
    outlier_threshold, max_iterations, tolerance : float, int, float
        The settings of the fit, which the held-out test repeats in each training fold.
    """

    fit: Fit
    robust: Fit
    problem: Problem
    kept: np.ndarray
    outliers: list[Outlier]
    names: list[str]
    marker_names: list[str]
    seconds: float
    start: np.ndarray = field(default_factory=lambda: np.zeros(0))
    actuators: np.ndarray | None = None
    actuator_reference: np.ndarray | None = None
    full: Problem | None = None
    least_squares: Fit | None = None
    identifiability: Identifiability | None = None
    identifiability_start: Identifiability | None = None
    outlier_threshold: float = 6.0
    max_iterations: int = 100
    tolerance: float = 1e-10

    @property
    def verdict(self) -> str:
        """``ok``, or ``not_identifiable`` when the identifiability report at the solution finds a reason."""
        return Status.OK if self.identifiability is None else self.identifiability.verdict

    @property
    def X_all(self) -> np.ndarray:
        """``(N, n_x)`` every posture's configuration: the final fit's, the screening fit's for rejected ones."""
        X = self.robust.X.copy()
        X[self.kept] = self.fit.X
        return X

    @property
    def layout(self) -> Layout:
        return self.problem.model.layout

    @property
    def lengths(self) -> np.ndarray:
        """Section lengths [m]: shared, or for an extensible arm the median over the postures."""
        lay = self.layout
        if lay.extensible:
            return np.median(self.fit.X[:, -lay.n_sections :], axis=0)
        return self.fit.beta[lay.lengths]

    @property
    def length_ranges(self) -> np.ndarray:
        """``(m, 2)`` smallest and largest length of each section over the postures [m]."""
        lay = self.layout
        if not lay.extensible:
            return np.repeat(self.lengths[:, None], 2, axis=1)
        S = self.fit.X[:, -lay.n_sections :]
        return np.stack([S.min(axis=0), S.max(axis=0)], axis=1)

    @property
    def base_position(self) -> np.ndarray:
        return self.fit.beta[self.layout.position]

    @property
    def base_rotation(self) -> np.ndarray:
        """``(3, 3)`` base orientation in the measurement frame."""
        return self.problem.ref @ matrix_from_rotation_vector(self.fit.beta[self.layout.rotation])

    @property
    def offsets(self) -> np.ndarray:
        """``(M, 3)`` marker offsets in their disk's frame [m]."""
        return self.fit.beta[self.layout.offsets].reshape(-1, 3)

    @property
    def actuator_map(self) -> tuple[np.ndarray, np.ndarray]:
        """``K (2 m, n_a)`` and ``k0 (2 m,)``: bending vectors ``K (a - a_ref) + k0`` [rad, rad per reading unit]."""
        lay = self.layout
        coefficients = self.fit.beta[lay.actuator_map]
        rows = 2 * lay.n_sections
        return coefficients[: rows * lay.n_actuators].reshape(rows, lay.n_actuators), coefficients[
            rows * lay.n_actuators :
        ]

    def configurations(self, X: np.ndarray | None = None) -> np.ndarray:
        """``(N, 3 m)`` ``(S, theta, phi)`` per section of the kept postures (or of the per-posture variables ``X``
        of the kept or of all postures), in the arm's convention (:mod:`optikin.arms.constant_curvature`)."""
        X = self.fit.X if X is None else X
        lay = self.layout
        m = lay.n_sections
        if lay.actuated:
            a = self.problem.actuators if len(X) == len(self.kept) else self.actuators
            assert a is not None
            K, k0 = self.actuator_map
            bending, lengths = a @ K.T + k0, X
        else:
            bending, lengths = X[:, : 2 * m], X[:, 2 * m :]
        u, v = bending[:, 0::2], bending[:, 1::2]
        S = lengths if lay.extensible else np.broadcast_to(self.lengths, u.shape)
        return np.stack([S, np.hypot(u, v), np.arctan2(v, u)], axis=-1).reshape(len(X), 3 * m)

    def std(self, name: str) -> float:
        return float(self.fit.std[self.names.index(name)])


@lru_cache(maxsize=16)
def marker_model(layout: Layout) -> MarkerModel:
    """The :class:`MarkerModel` of ``layout``, built once (its CasADi functions are cached on it)."""
    return MarkerModel(layout)


def initial_base(
    measured: np.ndarray, marker_sections: Sequence[int], first_length: float, axis: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A starting base pose from the data alone (module docstring, step 1), or on a given base axis.

    Parameters
    ----------
    measured : numpy.ndarray
        ``(N, M, 3)`` marker positions [m], NaN where missing.
    marker_sections : sequence of int
        Section end (1-based) of each marker.
    first_length : float
        Nominal length of the first section [m].
    axis : numpy.ndarray, optional
        ``(3,)`` the base axis (the direction the backbone leaves the base) instead of the mean chord.

    Returns
    -------
    tuple of numpy.ndarray
        The base position ``(3,)`` [m] and the reference orientation ``R_ref (3, 3)``.
    """
    order = np.argsort(marker_sections, kind="stable")
    P = measured[:, order]
    if axis is None:
        chords = np.diff(P, axis=1).reshape(-1, 3)
        chords = chords[np.all(np.isfinite(chords), axis=1)]
        chords = chords[np.linalg.norm(chords, axis=1) > 0]
        if len(chords) == 0:
            raise ValueError("no posture shows two consecutive disks: cannot find the base axis")
        axis = np.sum(chords / np.linalg.norm(chords, axis=1, keepdims=True), axis=0)
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    first = P[:, 0]
    first = first[np.all(np.isfinite(first), axis=1)]
    centre = np.mean(first, axis=0)
    # p0 = centre - t axis with the mean distance of the first disks to p0 equal to the first length
    ts = np.linspace(0.0, 2.0 * first_length, 401)
    spread = [np.mean(np.linalg.norm(first - (centre - t * axis), axis=1)) - first_length for t in ts]
    t = ts[int(np.argmin(np.abs(spread)))]
    return centre - t * axis, reference_orientation(axis)


def reference_orientation(axis: np.ndarray) -> np.ndarray:
    """``R_ref``: z along ``axis``, x along the measurement x (or y, if x is near the axis) across it."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def chord_configurations(
    measured: np.ndarray, layout: Layout, lengths: np.ndarray, base: np.ndarray, R0: np.ndarray
) -> np.ndarray:
    """Each posture's bending vectors (and lengths, when extensible) from its chords (module docstring):
    ``(N, 2 m)``, or ``(N, 3 m)`` for an extensible arm (:func:`per_posture` takes a layout's unknowns).

    A section whose end disk was not measured starts straight, and the chain continues from its
    predicted end.
    """
    N, m = len(measured), layout.n_sections
    disk = {s: j for j, s in enumerate(layout.marker_sections)}
    X = np.zeros((N, (3 if layout.extensible else 2) * m))
    R = np.broadcast_to(R0, (N, 3, 3)).copy()
    p = np.broadcast_to(base, (N, 3)).copy()
    for i in range(m):
        j = disk.get(i + 1)
        S = np.full(N, float(lengths[i]))
        theta, phi = np.zeros(N), np.zeros(N)
        if j is not None:
            target = measured[:, j]
            seen = np.all(np.isfinite(target), axis=1)
            c = np.einsum("nji,nj->ni", R, np.where(seen[:, None], target - p, 0.0))
            theta = np.where(seen, 2.0 * np.arctan2(np.hypot(c[:, 0], c[:, 1]), c[:, 2]), 0.0)
            phi = np.where(seen, np.arctan2(c[:, 1], c[:, 0]), 0.0)
            if layout.extensible:
                chord = np.sinc(theta / (2.0 * np.pi))  # sin(theta/2) / (theta/2)
                S = np.where(seen, np.linalg.norm(c, axis=1) / chord, S)
        if layout.extensible:
            X[:, 2 * m + i] = S
        u, v = theta * np.cos(phi), theta * np.sin(phi)
        X[:, 2 * i], X[:, 2 * i + 1] = u, v
        half = 0.5 * np.sinc(theta / (2.0 * np.pi)) ** 2  # (1 - cos theta) / theta^2
        local = S[:, None] * np.stack([u * half, v * half, np.sinc(theta / np.pi)], axis=1)
        p = p + np.einsum("nij,nj->ni", R, local)
        R = R @ matrix_from_rotation_vector(np.stack([-v, u, np.zeros(N)], axis=1))
    return X


def per_posture(layout: Layout, X: np.ndarray) -> np.ndarray:
    """The per-posture unknowns of ``layout`` from bending vectors (and lengths) ``X (N, 2 m [+ m])``: all of
    them, or with an actuator map only the lengths of an extensible arm."""
    return X[:, 2 * layout.n_sections :] if layout.actuated else X


def calibrate(
    measured: np.ndarray,
    lengths: Sequence[float],
    marker_sections: Sequence[int],
    marker_names: Sequence[str] | None = None,
    *,
    base_position: Sequence[float] | None = None,
    base_rotation: np.ndarray | None = None,
    position_sigma: float | None = None,
    orientation_sigma: float | None = None,
    fix: Sequence[str] = (),
    plane: tuple[int, float] | None = None,
    direction: Sequence[float] | None = None,
    estimate_yaw: bool = False,
    fix_lengths: bool = False,
    length_bounds: tuple[float, float] | None = None,
    offsets: bool = False,
    offset_sigma: float | None = None,
    initial_offsets: np.ndarray | None = None,
    extensible: bool = False,
    actuators: np.ndarray | None = None,
    loss: Loss = "soft_l1",
    loss_scale: float = 1e-3,
    marker_noise: float = 3e-4,
    outlier_threshold: float = 6.0,
    max_iterations: int = 100,
    tolerance: float = 1e-10,
    max_std: float = MAX_STD,
) -> Calibration:
    """Estimate section lengths, base pose and (optionally) marker offsets from ``N`` measured postures.

    Parameters
    ----------
    measured : numpy.ndarray
        ``(N, M, 3)`` marker positions [m] in the measurement frame, NaN where missing.
    lengths : sequence of float
        Nominal section lengths [m] (the start; held with ``fix_lengths``).
    marker_sections : sequence of int
        For each marker, the 1-based section whose end disk carries it.
    marker_names : sequence of str, optional
        For the reasons of rejected postures (default ``marker1``, ...).
    base_position : sequence of float, optional
        Starting base position [m] (default: from the data).
    base_rotation : numpy.ndarray, optional
        ``(3, 3)`` starting base orientation, which becomes ``R_ref`` (default: from the data).
    position_sigma, orientation_sigma : float, optional
        Standard deviations [m, rad] of Gaussian priors at the starting base pose (default: none).
    fix : sequence of str
        Base components held at their start: among ``x``, ``y``, ``z``, ``tilt``, ``yaw``.
    plane : tuple of (int, float), optional
        The mount plane ``p0[axis] = value`` [m] of the measurement frame: the base position starts on it
        (its other coordinates from the data or ``base_position``) and stays there.
    direction : sequence of float, optional
        ``(3,)`` the direction the backbone leaves the base: the base axis, held (``R_ref`` has its z on it).
    estimate_yaw : bool
        Estimate the rotation about the base axis too (only meaningful with a prior or
        orientation measurements; module docstring).
    fix_lengths : bool
        Hold the section lengths at ``lengths``.
    length_bounds : tuple of float, optional
        ``(low, high)`` fractions of the nominal lengths that bound the estimated ones (default: none).
    offsets : bool
        Estimate one offset per marker in its disk's frame.
    offset_sigma : float, optional
        Standard deviation [m] of a zero-mean prior on the offsets.
    initial_offsets : numpy.ndarray, optional
        ``(M, 3)`` starting (or, without ``offsets``, fixed) offsets [m].
    extensible : bool
        Per-posture section lengths instead of shared ones.
    actuators : numpy.ndarray, optional
        ``(N, n_a)`` actuator readings (finite): the bending vectors become a linear map of them
        (:mod:`optikin.calibration.model`), estimated with the geometry, started from a linear fit
        to the postures' own bending vectors.
    loss, loss_scale : str, float
        Robust loss and its scale [m] (:mod:`optikin.calibration.solver`), used where the geometry is
        estimated; every reported error is a least-squares one (:attr:`Calibration.least_squares`).
    marker_noise : float
        Expected marker noise per coordinate [m], which weighs the priors against the data and is the
        floor of the noise level of the identifiability report.
    outlier_threshold : float
        A posture with a marker error above this many median marker errors is rejected.
    max_iterations, tolerance : int, float
        Of each Levenberg-Marquardt solve.
    max_std : float
        The standard deviation [m] above which the geometry is weakly determined
        (:mod:`optikin.calibration.identifiability`).

    Returns
    -------
    Calibration
        The estimates, their covariance, the rejected postures, the identifiability reports.
    """
    started = time.perf_counter()
    measured = np.asarray(measured, dtype=float)
    N, M, _ = measured.shape
    marker_sections = tuple(int(s) for s in marker_sections)
    lengths0 = np.asarray(lengths, dtype=float)
    readings, reference = None, None
    if actuators is not None:
        readings = np.asarray(actuators, dtype=float)
        if readings.ndim != 2 or len(readings) != N or not np.all(np.isfinite(readings)):
            raise ValueError(f"actuators: expected finite readings of shape ({N}, n_a), got {readings.shape}")
        reference = readings.mean(axis=0)
        readings = readings - reference
    layout = Layout(len(lengths0), marker_sections, extensible, 0 if readings is None else readings.shape[1])
    names = layout.beta_names()
    model = marker_model(layout)
    unknown = set(fix) - set(BASE_FIELDS)
    if unknown:
        raise ValueError(f"fix: unknown base components {sorted(unknown)}; known: {', '.join(BASE_FIELDS)}")
    if len(marker_sections) != M:
        raise ValueError(f"{M} markers measured, {len(marker_sections)} marker sections given")
    fix = list(fix)
    axis = None
    if direction is not None:
        axis = np.asarray(direction, dtype=float)
        if axis.shape != (3,) or not np.linalg.norm(axis) > 0:
            raise ValueError(f"direction: expected a non-zero 3-vector, got {direction}")
        fix.append("tilt")
    guess_p, guess_R = initial_base(measured, marker_sections, float(lengths0[0]), axis)
    p0 = guess_p if base_position is None else np.asarray(base_position, dtype=float)
    ref = guess_R if base_rotation is None or axis is not None else np.asarray(base_rotation, dtype=float)
    if plane is not None:
        p0 = p0.copy()
        p0[plane[0]] = plane[1]
        fix.append("xyz"[plane[0]])

    beta0 = np.zeros(layout.n_beta)
    beta0[layout.lengths] = lengths0[layout.lengths]
    beta0[layout.position] = p0
    if initial_offsets is not None:
        beta0[layout.offsets] = np.asarray(initial_offsets, dtype=float).ravel()
    free = np.zeros(layout.n_beta, dtype=bool)
    free[layout.lengths] = not fix_lengths
    position_free = np.array([a not in fix for a in "xyz"])
    free[layout.position] = position_free
    rotation_free = np.array(["tilt" not in fix, "tilt" not in fix, estimate_yaw and "yaw" not in fix])
    free[layout.rotation] = rotation_free
    free[layout.offsets] = offsets
    free[layout.actuator_map] = True
    lower = upper = None
    if length_bounds is not None and not layout.extensible:
        lower, upper = np.full(layout.n_beta, -np.inf), np.full(layout.n_beta, np.inf)
        lower[layout.lengths] = length_bounds[0] * lengths0
        upper[layout.lengths] = length_bounds[1] * lengths0
    prior_mean = beta0.copy()
    prior_sigma = np.full(layout.n_beta, np.inf)
    if position_sigma is not None:
        prior_sigma[layout.position] = position_sigma
    if orientation_sigma is not None:
        prior_sigma[layout.rotation] = orientation_sigma
    if offset_sigma is not None:
        prior_sigma[layout.offsets] = offset_sigma
    X0 = chord_configurations(measured, layout, lengths0, p0, ref)
    free_layout = Layout(layout.n_sections, marker_sections, extensible)
    held = Problem(
        marker_model(free_layout),
        measured,
        ref,
        np.zeros(free_layout.n_beta, dtype=bool),
        prior_mean[: free_layout.n_beta],
        prior_sigma[: free_layout.n_beta],
        "linear",
        loss_scale,
        marker_noise,
    )
    X0 = solve(
        held, X0, beta0[: free_layout.n_beta], min(max_iterations, SCREENING_ITERATIONS), SCREENING_TOLERANCE, 1e-8
    ).X
    if readings is not None:
        design = np.column_stack([readings, np.ones(N)])
        W = np.linalg.lstsq(design, X0[:, : 2 * layout.n_sections], rcond=None)[0]  # (n_a + 1, 2 m)
        beta0[layout.actuator_map] = np.concatenate([W[:-1].T.ravel(), W[-1]])
        prior_mean = beta0.copy()
    X0 = per_posture(layout, X0)
    problem = Problem(
        model, measured, ref, free, prior_mean, prior_sigma, loss, loss_scale, marker_noise, readings, lower, upper
    )
    names_of_markers = list(marker_names) if marker_names is not None else [f"marker{j + 1}" for j in range(M)]
    start_report = analyse(problem, X0, beta0, names, marker_noise, max_std)
    screened = screened_fit(problem, X0, beta0, outlier_threshold, names_of_markers, max_iterations, tolerance)
    X_all = screened.robust.X.copy()
    X_all[screened.kept] = screened.fit.X
    least_squares = least_squares_fit(problem, screened.fit.beta, X_all, screened.kept)
    sigma = screened.fit.sigma if np.isfinite(screened.fit.sigma) else 0.0
    report = analyse(screened.problem, screened.fit.X, screened.fit.beta, names, max(sigma, marker_noise), max_std)
    return Calibration(
        screened.fit,
        screened.robust,
        screened.problem,
        screened.kept,
        screened.outliers,
        names,
        names_of_markers,
        time.perf_counter() - started,
        beta0,
        readings,
        reference,
        full=problem,
        least_squares=least_squares,
        identifiability=report,
        identifiability_start=start_report,
        outlier_threshold=outlier_threshold,
        max_iterations=max_iterations,
        tolerance=tolerance,
    )


def least_squares_fit(problem: Problem, beta: np.ndarray, X0: np.ndarray, kept: np.ndarray) -> Fit:
    """Every posture fitted by least squares with ``beta`` held (step 6), the kept and the rejected postures in
    two batches (a rejected posture, far from the model, converges slowly: it does not hold the others back;
    each posture's solve is its own, with its own damping and stop, so the batches change the time and not the
    answers, but where a batch ends at the iteration limit).

    Returns
    -------
    Fit
        Rows in the order of ``problem``'s postures; ``sigma`` and ``converged`` of the kept postures' batch.
    """
    N = len(problem.measured)
    rejected = np.setdiff1d(np.arange(N), kept)
    fit = fit_postures(problem.subset(kept), beta, X0[kept], loss="linear")
    if len(rejected) == 0:
        return fit
    other = fit_postures(problem.subset(rejected), beta, X0[rejected], loss="linear")
    X, errors, weights = np.empty_like(X0), np.empty((N, fit.errors.shape[1])), np.empty((N, fit.errors.shape[1]))
    for rows, part in ((kept, fit), (rejected, other)):
        X[rows], errors[rows], weights[rows] = part.X, part.errors, part.weights
    return Fit(
        X,
        fit.beta,
        errors,
        weights,
        fit.covariance,
        fit.sigma,
        fit.cost + other.cost,
        max(fit.iterations, other.iterations),
        fit.converged,
        fit.seconds + other.seconds,
    )


@dataclass(eq=False)
class Screened:
    """The outcome of :func:`screened_fit`: the screening fit, the final fit, the postures kept and rejected."""

    robust: Fit
    fit: Fit
    kept: np.ndarray
    outliers: list[Outlier]
    problem: Problem
    limit: float


def screened_fit(
    problem: Problem,
    X0: np.ndarray,
    beta0: np.ndarray,
    threshold: float,
    marker_names: Sequence[str],
    max_iterations: int = 100,
    tolerance: float = 1e-10,
) -> Screened:
    """Steps 3-5 of the module docstring on ``problem``: the screening fit, the outliers by the rule
    (:func:`find_outliers`), the fit without them, screened again up to :data:`SCREENING_ROUNDS` times.

    Returns
    -------
    Screened
        Indices are the postures of ``problem``; ``limit`` [m] is the rule's last marker-error limit
        (``threshold`` times the final fit's median marker error, at least :data:`MIN_OUTLIER_ERROR`).
    """
    N = len(problem.measured)
    robust = solve(problem, X0, beta0, min(max_iterations, SCREENING_ITERATIONS), SCREENING_TOLERANCE, 1e-8)
    outliers = find_outliers(problem, robust, threshold, marker_names)
    X_all, beta = robust.X.copy(), robust.beta
    for _ in range(SCREENING_ROUNDS):
        kept = np.setdiff1d(np.arange(N), [o.posture for o in outliers])
        final_problem = problem.subset(kept)
        fit = solve(final_problem, X_all[kept], beta, max_iterations, tolerance)
        X_all[kept], beta = fit.X, fit.beta
        more = find_outliers(final_problem, fit, threshold, marker_names)
        if not more:
            break
        outliers += [Outlier(int(kept[o.posture]), o.reason) for o in more]
    else:
        kept = np.setdiff1d(np.arange(N), [o.posture for o in outliers])
        final_problem = problem.subset(kept)
        fit = solve(final_problem, X_all[kept], beta, max_iterations, tolerance)
    outliers.sort(key=lambda o: o.posture)
    limit = max(threshold * float(np.nanmedian(fit.errors)), MIN_OUTLIER_ERROR)
    return Screened(robust, fit, kept, outliers, final_problem, limit)


def find_outliers(problem: Problem, fit: Fit, threshold: float, marker_names: Sequence[str]) -> list[Outlier]:
    """The postures with a marker error above ``threshold`` median marker errors (and above
    :data:`MIN_OUTLIER_ERROR`), each with its reason.

    The reason names the worst marker and its error; when refitting the posture with two
    markers' labels exchanged brings every error under the limit, it says so.
    """
    errors = fit.errors
    median = float(np.nanmedian(errors))
    limit = max(threshold * median, MIN_OUTLIER_ERROR)
    bad = np.flatnonzero(np.nanmax(np.where(np.isfinite(errors), errors, 0.0), axis=1) > limit)
    swaps = explaining_swaps(problem, fit, bad, limit)
    outliers = []
    for k, swap in zip(bad, swaps):
        j = int(np.nanargmax(errors[k]))
        reason = (
            f"{marker_names[j]} is {errors[k, j] * 1e3:.2f} mm from the fit, "
            f"{errors[k, j] / median:.0f} x the median marker error ({median * 1e3:.3f} mm)"
        )
        if swap is not None:
            a, b, worst = swap
            reason += f"; labels {marker_names[a]} and {marker_names[b]} exchanged (fits within {worst * 1e3:.2f} mm)"
        outliers.append(Outlier(int(k), reason))
    return outliers


def explaining_swaps(
    problem: Problem, fit: Fit, postures: np.ndarray, limit: float
) -> list[tuple[int, int, float] | None]:
    """For each of ``postures``, the pair of markers whose exchange makes it fit within ``limit`` (the best such
    pair), or None; every exchanged posture is refitted with the shared parameters held, in one batch."""
    M = problem.measured.shape[1]
    pairs = list(combinations(range(M), 2))
    if not pairs or len(postures) == 0:
        return [None] * len(postures)
    trials = np.repeat(problem.measured[postures], len(pairs), axis=0)  # posture-major, then pair
    for n, (a, b) in enumerate(pairs):
        rows = trials[n :: len(pairs)]
        rows[:, [a, b]] = rows[:, [b, a]]
    held = Problem(
        problem.model,
        trials,
        problem.ref,
        np.zeros_like(problem.free),
        problem.prior_mean,
        problem.prior_sigma,
        "linear",
        problem.loss_scale,
        problem.noise,
        None if problem.actuators is None else np.repeat(problem.actuators[postures], len(pairs), axis=0),
    )
    lay = problem.model.layout
    R0 = problem.ref @ matrix_from_rotation_vector(fit.beta[lay.rotation])
    lengths = fit.beta[lay.lengths] if not lay.extensible else np.median(fit.X[:, -lay.n_sections :], axis=0)
    X0 = per_posture(lay, chord_configurations(trials, lay, lengths, fit.beta[lay.position], R0))
    worst = np.nanmax(solve(held, X0, fit.beta, 50, 1e-12).errors, axis=1).reshape(len(postures), len(pairs))
    found: list[tuple[int, int, float] | None] = []
    for row in worst:
        best = int(np.argmin(row))
        found.append((pairs[best][0], pairs[best][1], float(row[best])) if row[best] <= limit else None)
    return found


def fit_postures(problem: Problem, beta: np.ndarray, X0: np.ndarray | None = None, loss: Loss | None = None) -> Fit:
    """Every posture's configuration with the shared parameters ``beta`` held (the inverse kinematics of the markers).

    The start is :func:`chord_configurations` unless ``X0`` is given; ``loss`` replaces the problem's (``linear``:
    the least-squares fit every reported error comes from).
    """
    lay = problem.model.layout
    held = problem.held(loss)
    if X0 is None:
        if lay.extensible:
            raise ValueError("fit_postures on an extensible arm needs starting configurations")
        R0 = problem.ref @ matrix_from_rotation_vector(beta[lay.rotation])
        X0 = per_posture(lay, chord_configurations(problem.measured, lay, beta[lay.lengths], beta[lay.position], R0))
    return solve(held, X0, beta)


@dataclass(eq=False)
class HeldOut:
    """Errors on postures left out of the fit that estimated the shared parameters, over every posture.

    Attributes
    ----------
    errors : numpy.ndarray
        ``(N, M)`` least-squares marker errors [m] of every posture, fitted with the shared parameters of the
        fold that left it out (NaN where not seen, and for postures never tested by ``split``).
    fold : numpy.ndarray
        ``(N,)`` the test fold of each posture (``-1``: never tested).
    betas : numpy.ndarray
        ``(folds, n_beta)`` the shared parameters of each fold.
    method : str
        ``kfold`` or ``split``.
    screened : numpy.ndarray
        ``(N,)`` bool: tested postures beyond their training fold's outlier limit.
    limits : numpy.ndarray
        ``(folds,)`` each training fold's limit [m]: ``threshold`` times its median marker error.
    training_outliers : list of list of int
        Per fold, the postures its screening rejected from training.
    threshold : float
        The rule's multiple of the median marker error.
    loss : str
        The loss of the training fits (the test fits are least squares).
    """

    errors: np.ndarray
    fold: np.ndarray
    betas: np.ndarray
    method: str
    screened: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    limits: np.ndarray = field(default_factory=lambda: np.zeros(0))
    training_outliers: list[list[int]] = field(default_factory=list)
    threshold: float = 6.0
    loss: str = "linear"

    @property
    def tested(self) -> np.ndarray:
        return self.fold >= 0

    @property
    def posture_errors(self) -> np.ndarray:
        """``(N,)`` each posture's largest held-out marker error [m] (NaN where not tested or nothing seen)."""
        finite = np.isfinite(self.errors)
        largest = np.max(np.where(finite, self.errors, -np.inf), axis=1)
        return np.where(finite.any(axis=1), largest, np.nan)

    @property
    def posture_rms(self) -> np.ndarray:
        """``(N,)`` each posture's RMS held-out marker error [m] (NaN where not tested or nothing seen)."""
        finite = np.isfinite(self.errors)
        squares = np.sum(np.where(finite, self.errors**2, 0.0), axis=1)
        count = finite.sum(axis=1)
        return np.where(count > 0, np.sqrt(squares / np.maximum(count, 1)), np.nan)

    def headline(self, screened: bool | None = None) -> dict[str, float]:
        """Median, p95 and max [m] of :attr:`posture_errors` over every tested posture (``screened``: only the
        screened ones, or only the others)."""
        e = self.posture_errors
        keep = self.tested & np.isfinite(e)
        if screened is not None:
            keep &= self.screened == screened
        e = e[keep]
        if len(e) == 0:
            return {"median": float("nan"), "p95": float("nan"), "max": float("nan")}
        return {"median": float(np.median(e)), "p95": float(np.percentile(e, 95)), "max": float(np.max(e))}

    @property
    def rms(self) -> float:
        """Root-mean-square held-out marker error [m]."""
        return float(np.sqrt(np.nanmean(self.errors[self.tested] ** 2)))


def folds_of(n: int, method: str, folds: int, test_fraction: float, rng: np.random.Generator) -> np.ndarray:
    """``(n,)`` the test fold of each posture: ``folds`` shuffled folds, or for ``split`` fold 0 for the test
    share ``test_fraction`` and -1 (never tested) for the rest."""
    order = rng.permutation(n)
    fold = np.empty(n, dtype=int)
    if method == "kfold":
        fold[order] = np.arange(n) % folds
        return fold
    n_test = max(1, int(round(test_fraction * n)))
    fold[order] = -1
    fold[order[:n_test]] = 0
    return fold


def held_out(
    calibration: Calibration,
    method: str = "kfold",
    folds: int = 5,
    test_fraction: float = 0.2,
    rng: np.random.Generator | None = None,
    fold: np.ndarray | None = None,
) -> HeldOut:
    """The held-out error of a calibration over all its postures, by ``k``-fold cross-validation or one split.

    For each fold the calibration is repeated on the other postures (:func:`screened_fit`: the robust loss,
    the outlier rule applied to the training postures alone), from the calibration's solution (the same
    minimum, reached faster; at most :data:`FOLD_ITERATIONS` steps); then every posture of the fold is fitted
    by least squares with that geometry held
    (its configuration is its own; only the shared parameters are learnt elsewhere), and its marker errors are
    the held-out errors. A test posture whose largest error exceeds its training fold's outlier limit is
    *screened*: flagged, reported apart, and still counted in every headline figure.

    Parameters
    ----------
    calibration : Calibration
        The calibration on all postures.
    method : str
        ``kfold`` or ``split``.
    folds : int
        Folds of ``kfold``.
    test_fraction : float
        Share of postures tested by ``split``.
    rng : numpy.random.Generator, optional
        Shuffles the postures (default seeded 0).
    fold : numpy.ndarray, optional
        ``(N,)`` a given fold assignment (``-1``: never tested), instead of drawing one.

    Returns
    -------
    HeldOut
        Per-posture held-out errors, the fold assignment, the shared parameters of every fold, the screening.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    problem = calibration.full
    assert problem is not None
    N = len(problem.measured)
    if fold is None:
        fold = folds_of(N, method, folds, test_fraction, rng)
    fold = np.asarray(fold, dtype=int)
    if fold.shape != (N,):
        raise ValueError(f"fold: expected one fold per posture ({N}), got shape {fold.shape}")
    X_all = calibration.X_all
    errors = np.full((N, problem.measured.shape[1]), np.nan)
    screened = np.zeros(N, dtype=bool)
    betas, limits, rejected = [], [], []
    for f in np.unique(fold[fold >= 0]):
        test, train = np.flatnonzero(fold == f), np.flatnonzero(fold != f)
        trained = screened_fit(
            problem.subset(train),
            X_all[train],
            calibration.fit.beta,
            calibration.outlier_threshold,
            calibration.marker_names,
            min(calibration.max_iterations, FOLD_ITERATIONS),
            calibration.tolerance,
        )
        betas.append(trained.fit.beta)
        limits.append(trained.limit)
        rejected.append([int(train[o.posture]) for o in trained.outliers])
        kept = np.isin(test, calibration.kept)
        errors[test] = least_squares_fit(
            problem.subset(test), trained.fit.beta, X_all[test], np.flatnonzero(kept)
        ).errors
        largest = np.nanmax(np.where(np.isfinite(errors[test]), errors[test], 0.0), axis=1)
        screened[test] = largest > trained.limit
    return HeldOut(
        errors,
        fold,
        np.array(betas),
        method,
        screened,
        np.array(limits),
        rejected,
        calibration.outlier_threshold,
        problem.loss,
    )
