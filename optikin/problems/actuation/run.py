"""Solve an ``actuation`` problem: each method trained on nested shares of each training fold, scored held out.

:func:`solve` reads the recording (the markers of the three end disks and the six motor channels), assigns
every posture to one of ``options.folds`` shuffled folds (:func:`optikin.calibration.calibrate.folds_of`),
draws in each training fold one seeded order of its postures whose first ``fraction`` share is the training
set of every method at that share (the same postures for all, nested), and predicts the held-out fold's
markers from its motor inputs with the physics model (:mod:`optikin.calibration.actuation`, every fit
started from the nominal parameters of ``options``) and with each listed regressor (:data:`REGRESSORS`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from optikin.calibration import actuation as physics
from optikin.calibration.calibrate import folds_of
from optikin.errors import InputDataError
from optikin.problems import Baseline, ProblemContext
from optikin.problems.actuation.options import ActuationOptions

PHYSICS = "physics"
"""The kind's own method: the tendon-driven Kirchhoff rod with its lab parameters fitted."""
MIN_TRAINING = 5
"""Postures in a training share at least."""

Regressor = Callable[[int, int], Any]
"""``make(n_training, seed) -> estimator``: a scikit-learn regressor of scaled inputs to scaled outputs."""


def knn(n: int, seed: int) -> Any:
    """k nearest neighbours (k = 5, or fewer postures), weighted by inverse distance."""
    from sklearn.neighbors import KNeighborsRegressor

    return KNeighborsRegressor(n_neighbors=min(5, n), weights="distance")


def mlp(n: int, seed: int) -> Any:
    """A multilayer perceptron of two hidden layers of 64 tanh units, L-BFGS, weight decay 1e-3."""
    from sklearn.neural_network import MLPRegressor

    return MLPRegressor(
        hidden_layer_sizes=(64, 64), activation="tanh", solver="lbfgs", alpha=1e-3, max_iter=1000, random_state=seed
    )


def gp(n: int, seed: int) -> Any:
    """A Gaussian process: a constant times an RBF with one length scale per input, plus white noise."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    kernel = ConstantKernel(1.0, (1e-2, 1e2)) * RBF(np.ones(6), (1e-2, 1e2)) + WhiteKernel(1e-2, (1e-6, 1.0))
    return GaussianProcessRegressor(kernel=kernel, random_state=seed)


REGRESSORS: dict[str, tuple[str, Regressor]] = {
    "knn": ("k-NN (5, distance)", knn),
    "mlp": ("MLP (64, 64)", mlp),
    "gp": ("Gaussian process (ARD RBF)", gp),
}
"""The kind's baselines: name -> (title, maker)."""


def regressor_of(ctx: ProblemContext, setup: Any) -> Regressor:
    """The maker of a baseline's regressor (its :class:`~optikin.problems.Baseline` build)."""
    return REGRESSORS[setup][1]


def baselines() -> list[Baseline[Any, Any]]:
    """The kind's baselines, one per regressor."""
    return [Baseline(name, title, build=regressor_of) for name, (title, _) in REGRESSORS.items()]


@dataclass
class ActuationOutcome:
    """What :func:`solve` found.

    Attributes
    ----------
    methods, titles:
        Method names (``physics`` first, then the listed baselines) and their row titles.
    fractions:
        ``(F,)`` the shares of each training fold.
    fold:
        ``(N,)`` the test fold of every posture.
    errors:
        Per method ``(F, N)`` each posture's largest held-out marker error [m] (``inf``: no prediction).
    predicted:
        Per method ``(N, 3, 3)`` held-out markers at the full share [m].
    training:
        ``(folds, F)`` postures in each training share.
    fit_time:
        Per method, seconds of training and prediction over every fold and share.
    physics_fits:
        ``(folds, F)`` the physics fits.
    measured, inputs:
        ``(N, 3, 3)`` [m] and ``(N, 6)`` [N].
    indices:
        ``(N,)`` the recording's posture of each posture used.
    truth_errors:
        ``(N,)`` for a recording with truth: each posture's largest error of the noise-free markers [m].
    notes:
        What the run noticed.
    """

    methods: list[str]
    titles: list[str]
    fractions: np.ndarray
    fold: np.ndarray
    errors: dict[str, np.ndarray]
    predicted: dict[str, np.ndarray]
    training: np.ndarray
    fit_time: dict[str, float]
    physics_fits: list[list[physics.Fit]]
    measured: np.ndarray
    inputs: np.ndarray
    indices: np.ndarray
    truth_errors: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)


def largest_error(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """``(N,)`` each posture's largest marker error [m] over its seen markers (``inf`` where no prediction,
    NaN where no marker was seen)."""
    distance = np.linalg.norm(predicted - measured, axis=2)
    seen = ~np.isnan(measured).any(axis=2)
    missing = np.isnan(predicted).any(axis=(1, 2)) & seen.any(axis=1)
    out = np.max(np.where(seen, np.nan_to_num(distance, nan=np.inf), -np.inf), axis=1)
    out[~seen.any(axis=1)] = np.nan
    out[missing] = np.inf
    return out


def read(ctx: ProblemContext, options: ActuationOptions) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """Inputs ``(N, 6)`` [N], markers ``(N, 3, 3)`` [m], the recording's posture indices and the recording."""
    recording = ctx.load_data()
    missing = [name for name in options.motors if name not in recording.actuators]
    if missing:
        raise ctx.error(
            "options.motors", f"channels {missing} not in the recording (it has {sorted(recording.actuators)})"
        )
    try:
        measured = recording.marker_array(options.markers)
    except Exception as err:
        raise ctx.error("options.markers", str(err)) from err
    inputs = np.stack([np.asarray(recording.actuators[name], dtype=float) for name in options.motors], axis=1)
    if not np.isfinite(inputs).all() or (inputs < 0).any():
        k = int(np.flatnonzero(~np.isfinite(inputs).all(axis=1) | (inputs < 0).any(axis=1))[0])
        raise InputDataError(f"{ctx.path.name}: motor inputs must be finite and >= 0 [N]", sample=k)
    indices = np.arange(len(inputs))
    if options.postures is not None and options.postures < len(indices):
        indices = np.sort(ctx.rng(1).choice(len(indices), size=options.postures, replace=False))
    return inputs[indices], measured[indices], indices, recording


def fit_regressor(make: Regressor, X: np.ndarray, Y: np.ndarray, X_test: np.ndarray, seed: int) -> np.ndarray:
    """Predicted markers ``(n_test, 3, 3)`` of a regressor trained on the postures of ``X (n, 6)`` whose markers
    ``Y (n, 3, 3)`` are all seen, inputs and outputs standardised on the training set."""
    from sklearn.compose import TransformedTargetRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    complete = ~np.isnan(Y).any(axis=(1, 2))
    X, Y = X[complete], Y[complete].reshape(-1, 9)
    model = TransformedTargetRegressor(
        regressor=make_pipeline(StandardScaler(), make(len(X), seed)), transformer=StandardScaler()
    )
    model.fit(X, Y)
    return np.asarray(model.predict(X_test)).reshape(-1, 3, 3)


def solve(ctx: ProblemContext) -> ActuationOutcome:
    """Every method at every share of every training fold, scored on the held-out fold (module docstring)."""
    options: ActuationOptions = ctx.options
    inputs, measured, indices, recording = read(ctx, options)
    N = len(inputs)
    if N < 2 * options.folds:
        raise ctx.error("options.folds", f"{options.folds} folds need at least {2 * options.folds} postures, got {N}")
    fold = folds_of(N, "kfold", options.folds, 0.0, ctx.rng(2))
    names = [b.name for b in ctx.baselines]
    methods = [PHYSICS, *names]
    titles = ["physics (Kirchhoff rod, fitted)", *(b.title for b in ctx.baselines)]
    makers = {b.name: b.method(ctx, b.name) for b in ctx.baselines}
    fractions = np.asarray(options.fractions, dtype=float)
    F = len(fractions)
    errors = {m: np.full((F, N), np.nan) for m in methods}
    predicted = {m: np.full((N, 3, 3), np.nan) for m in methods}
    fit_time = dict.fromkeys(methods, 0.0)
    training = np.zeros((options.folds, F), dtype=int)
    fits: list[list[physics.Fit]] = []
    nominal = physics.start_params(
        np.asarray(options.section_lengths, dtype=float),
        options.stiffness,
        options.payload,
        options.tendon_offset,
        options.linear_density,
    )
    with ctx.progress.task(f"actuation: {options.folds} folds x {F} shares", total=options.folds * F) as advance:
        for f in range(options.folds):
            test = np.flatnonzero(fold == f)
            order = ctx.rng(10 + f).permutation(np.flatnonzero(fold != f))
            row = []
            for i, share in enumerate(fractions):
                train = order[: max(MIN_TRAINING, int(round(share * len(order))))]
                training[f, i] = len(train)
                t0 = time.perf_counter()
                result = physics.fit(
                    inputs[train],
                    measured[train],
                    nominal,
                    (float(options.length_range[0]), float(options.length_range[1])),
                    options.steps,
                    options.max_evaluations,
                    options.loss_scale,
                )
                guess = physics.predict(
                    result.params, inputs[test], options.steps, (result.inputs, result.base_moments)
                )
                fit_time[PHYSICS] += time.perf_counter() - t0
                row.append(result)
                errors[PHYSICS][i, test] = largest_error(guess, measured[test])
                if i == F - 1:
                    predicted[PHYSICS][test] = guess
                for name in names:
                    t0 = time.perf_counter()
                    guess = fit_regressor(
                        makers[name], inputs[train], measured[train], inputs[test], ctx.spec.data.seed
                    )
                    fit_time[name] += time.perf_counter() - t0
                    errors[name][i, test] = largest_error(guess, measured[test])
                    if i == F - 1:
                        predicted[name][test] = guess
                advance()
            fits.append(row)
    truth = getattr(recording, "truth", None)
    truth_errors = None if truth is None else largest_error(truth.clean_markers[indices], measured)
    notes = []
    unreached = int(np.isinf(errors[PHYSICS][-1]).sum())
    if unreached:
        notes.append(f"physics: {unreached} held-out postures without a converged equilibrium (inf)")
    return ActuationOutcome(
        methods,
        titles,
        fractions,
        fold,
        errors,
        predicted,
        training,
        fit_time,
        fits,
        measured,
        inputs,
        indices,
        truth_errors,
        notes,
    )
