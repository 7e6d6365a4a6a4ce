"""Multilayer perceptrons of the hybrid approach (seed 004 sections IV-V), trained with scikit-learn.

Forward models (section IV-A, Table II): one network per section, the section's
24 leg lengths ``q_{m,k}`` in, its 24 platform variables ``(Z_k, theta_k, psi_k)``
out (eq. 10). The hybrid forward kinematics (Fig. 9) then chains the predicted
platforms with the exact transforms of eq. (5).

Inverse models (section V, Table III): ``NN1`` maps the tip position to the end
of section 1; ``NN2``, ``NN3`` and ``NN4`` map (tip, end of section 1) to the
``Z_k``, the ``theta_k`` and the ``psi_k`` of all 16 platforms. The seed only says
"the last three models ... provide Z_k, theta_k and psi_k as outputs"; one model
per variable fits Table III, where NN2 has the smallest error (``Z`` varies by
millimetres, the angles by tenths of a radian). The hybrid inverse kinematics
(Fig. 10) turns the predicted platforms into leg lengths by the exact
equations (7)-(9).

Training follows section IV-A: two hidden layers of equal width, the width
searched over 2..20 in steps of 2 on the validation MSE; each candidate trained
epoch by epoch on the training split and stopped early once the validation
criterion has not improved for ``patience`` epochs, keeping the weights of its
best epoch. Settings (:data:`SETTINGS`):

``seed``       back-propagation (stochastic gradient descent) with a momentum term, as the
               seed describes it, with the pre-processing MATLAB's Neural Network Toolbox applies
               by default (``mapminmax``: every input and output mapped affinely from its range on
               the training split to ``[-1, 1]``); the seed states no pre-processing, and its tool
               does this unless told otherwise;
``seed-raw``   as ``seed`` on the raw SI values (metres, radians), no pre-processing: leg lengths
               of about 10 mm and ``Z_k`` of a few millimetres give gradients too small for the
               seed's learning rate;
``adam``       Adam on standardised inputs and outputs (zero mean, unit variance on the
               training split), same width search;
``adam-wide``  as ``adam`` with wider layers (32 and 64 neurons), to separate what the
               optimiser and what the width limit of 20 neurons cost.

Eq. (11) adds ``lambda/2 ||X||^2`` to the squared error of an inverse network's
prediction ``X``. Per sample, ``1/2 ||X_d - X||^2 + lambda/2 ||X||^2 =
(1 + lambda)/2 ||X - X_d/(1 + lambda)||^2 + const``, so the penalised network is
the plain one trained on the shrunk targets ``X_d / (1 + lambda)`` (the constant
factor only rescales the step size): :func:`train_model` does exactly that, and
monitors the penalised criterion on the validation split. It pulls every
prediction towards the origin; among redundant solutions a least-squares fit
already returns their conditional mean, which the penalty only shrinks.

Training uses scikit-learn's ``MLPRegressor``; a :class:`TrainedModel` keeps only its
weights (:class:`Network`), evaluated by :func:`forward_pass`, so that a stored model does not
depend on the scikit-learn version (:mod:`optikin.baselines.nn_store`).

Every score reported here comes from the split it names: :func:`split_mse` reads
only the rows of that split.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Callable, Literal

import numpy as np
from scipy.special import expit
from threadpoolctl import threadpool_limits

from optikin.baselines.nn_database import LearningDatabase
from optikin.interrupt import check_interrupted
from optikin.data.cosserat_nn import CosseratDatabase

if TYPE_CHECKING:
    from sklearn.neural_network import MLPRegressor

Database = LearningDatabase | CosseratDatabase
"""Where a :class:`Task` reads its rows and its train / validation / test split."""

VARIABLES = ("Z", "theta", "psi")
ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "tanh": np.tanh,
    "logistic": expit,
    "relu": lambda a: np.maximum(a, 0.0),
    "identity": lambda a: a,
}
"""Hidden-layer activations of scikit-learn's MLPRegressor, for :meth:`TrainedModel.predict`."""

SEED_TABLE_II = {"fkm_section1": (18, 6.4612e-5), "fkm_section2": (18, 8.2425e-5)}
"""Seed 004 Table II: (neurons, test MSE) of the forward model of each section."""
SEED_TABLE_III = {
    "ikm_nn1": (18, 4.9840e-4),
    "ikm_nn2": (12, 1.2363e-5),
    "ikm_nn3": (16, 4.0503e-5),
    "ikm_nn4": (16, 3.4651e-5),
}
"""Seed 004 Table III: (neurons, test MSE) of the inverse models NN1-NN4."""


# ---------------------------------------------------------------------------------------- tasks
@dataclass(frozen=True)
class Task:
    """What one network maps: columns of one database table to columns of another.

    Tables (:func:`table`): ``legs`` (48 leg lengths), ``configurations`` (48 platform
    variables), ``ends`` (tip x, y, z, then end of section 1 x, y, z), ``tubes`` (the six
    tube lengths, section 1's three then section 2's), and, of a
    :class:`~optikin.data.cosserat_nn.CosseratDatabase`, ``pressures`` (its six tube pressures).
    """

    key: str
    title: str
    inputs: tuple[str, tuple[int, ...]]
    outputs: tuple[str, tuple[int, ...]]
    penalised: bool = False

    def arrays(self, db: Database, rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(X, Y)`` of the given rows (all when ``None``)."""
        X = table(db, self.inputs[0])[:, list(self.inputs[1])]
        Y = table(db, self.outputs[0])[:, list(self.outputs[1])]
        return (X, Y) if rows is None else (X[rows], Y[rows])

    @property
    def seed_reference(self) -> tuple[int, float] | None:
        """(neurons, test MSE) printed in seed 004 Tables II / III."""
        return {**SEED_TABLE_II, **SEED_TABLE_III}.get(self.key)


def table(db: Database, name: str) -> np.ndarray:
    """One of the database tables a :class:`Task` reads."""
    if name == "tubes":
        return db.tube_lengths.reshape(len(db), -1)
    if name == "ends":
        return np.concatenate([db.tip, db.section_ends[:, 0]], axis=1)
    if isinstance(db, CosseratDatabase):
        if name == "pressures":
            return db.pressures.reshape(len(db), -1)
    elif name == "legs":
        return db.leg_lengths
    elif name == "configurations":
        return db.configurations
    raise KeyError(f"unknown table {name!r}")


def direct_tasks() -> list[Task]:
    """Seed 004 Table IV's qualitative models (Melingui et al.): one MLP from the six tube lengths to the
    tip (``direct_fkm``), one back (``direct_ikm``), and the length-pressure controller of section VI
    (``controller``: six tube lengths -> six pressures; a :class:`~optikin.data.cosserat_nn.CosseratDatabase`)."""
    six, three = tuple(range(6)), (0, 1, 2)
    return [
        Task("direct_fkm", "direct FKM: six tube lengths -> tip", ("tubes", six), ("ends", three)),
        Task("direct_ikm", "direct IKM: tip -> six tube lengths", ("ends", three), ("tubes", six)),
        Task(
            "controller",
            "length-pressure controller: six tube lengths -> six pressures",
            ("tubes", six),
            ("pressures", six),
        ),
    ]


def forward_tasks(db: LearningDatabase) -> list[Task]:
    """One forward model per section: its leg lengths -> its platform variables (Table II)."""
    tasks = []
    for s in range(1, len(db.geometry.platforms_per_section) + 1):
        cols = tuple(range(db.section_columns(s).start, db.section_columns(s).stop))
        tasks.append(Task(f"fkm_section{s}", f"FKM section {s}", ("legs", cols), ("configurations", cols)))
    return tasks


def inverse_tasks(db: LearningDatabase) -> list[Task]:
    """NN1 (tip -> end of section 1) and NN2-NN4 ((tip, end 1) -> every Z_k, theta_k, psi_k) (Table III)."""
    if len(db.geometry.platforms_per_section) != 2:
        raise ValueError("the inverse models of seed 004 section V are defined for two sections")
    n = 3 * db.geometry.n_platforms
    tasks = [Task("ikm_nn1", "IKM NN1: tip -> end of section 1", ("ends", (0, 1, 2)), ("ends", (3, 4, 5)), True)]
    for i, variable in enumerate(VARIABLES):
        tasks.append(
            Task(
                f"ikm_nn{i + 2}",
                f"IKM NN{i + 2}: tip, end 1 -> {variable}_k",
                ("ends", tuple(range(6))),
                ("configurations", tuple(range(i, n, 3))),
                True,
            )
        )
    return tasks


# ---------------------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class TrainingSetting:
    """How a network is trained and which widths are searched.

    ``solver`` is ``sgd`` (with classical momentum) or ``adam``; ``scaling`` maps every input and
    output column of the training split before training: ``True`` to zero mean and unit variance,
    ``"minmax"`` from its range to ``[-1, 1]`` (MATLAB's ``mapminmax``), ``False`` not at all;
    ``batch_size`` samples per update; an epoch is one pass over the training split; training stops after ``patience``
    epochs without a better validation criterion, or at ``max_epochs``.
    """

    name: str
    solver: str
    scaling: bool | Literal["minmax"]
    neurons: tuple[int, ...] = tuple(range(2, 21, 2))
    learning_rate: float = 0.01
    momentum: float = 0.9
    batch_size: int = 128
    max_epochs: int = 400
    patience: int = 30
    activation: str = "tanh"

    def __post_init__(self):
        object.__setattr__(self, "neurons", tuple(int(n) for n in self.neurons))
        if self.solver not in ("sgd", "adam"):
            raise ValueError(f"solver must be 'sgd' or 'adam', got {self.solver!r}")
        if not self.neurons or min(self.neurons) < 1:
            raise ValueError(f"neurons must be positive widths, got {self.neurons}")
        for name in ("batch_size", "max_epochs", "patience"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        if not self.learning_rate > 0 or not 0 <= self.momentum < 1:
            raise ValueError("learning_rate must be positive and momentum within [0, 1)")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {', '.join(ACTIVATIONS)}, got {self.activation!r}")
        if self.scaling not in (True, False, "minmax"):
            raise ValueError(f"scaling must be true, false or 'minmax', got {self.scaling!r}")

    @property
    def description(self) -> str:
        opt = f"SGD + momentum {self.momentum:g}" if self.solver == "sgd" else "Adam"
        scaled = {True: "standardised", False: "raw SI units", "minmax": "mapminmax to [-1, 1]"}[self.scaling]
        return f"{opt}, lr {self.learning_rate:g}, {scaled}, widths {list(self.neurons)}"

    def small(self) -> "TrainingSetting":
        """A quick version for tests and notebooks: two widths, at most 15 epochs."""
        if self.name == "direct":
            return replace(self, max_epochs=60, patience=10)
        return replace(
            self, neurons=self.neurons[-2:] if self.name == "adam-wide" else (4, 8), max_epochs=15, patience=4
        )


DIRECT_SETTING = TrainingSetting(
    "direct", "adam", scaling=True, learning_rate=0.01, batch_size=32, max_epochs=200, patience=30, neurons=(16,)
)
"""Training of the direct models (:func:`direct_tasks`): a few hundred postures, so small batches and a
larger step than :data:`SETTINGS` ``adam``."""

SETTINGS = {
    "seed": TrainingSetting("seed", "sgd", scaling="minmax", learning_rate=0.01, momentum=0.9),
    "seed-raw": TrainingSetting("seed-raw", "sgd", scaling=False, learning_rate=0.01, momentum=0.9),
    "adam": TrainingSetting("adam", "adam", scaling=True, learning_rate=0.001),
    "adam-wide": TrainingSetting("adam-wide", "adam", scaling=True, learning_rate=0.001, neurons=(32, 64)),
}


# ---------------------------------------------------------------------------------------- models
@dataclass(frozen=True, eq=False)
class Network:
    """The weights of a trained multilayer perceptron, independent of scikit-learn.

    Layer ``i`` maps ``A`` to ``A @ coefs[i] + intercepts[i]``, followed by ``activation``
    on every hidden layer and the identity on the output layer, as scikit-learn's
    ``MLPRegressor`` does. The arrays are read-only copies.
    """

    coefs: tuple[np.ndarray, ...]
    intercepts: tuple[np.ndarray, ...]
    activation: str

    def __post_init__(self):
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {', '.join(ACTIVATIONS)}, got {self.activation!r}")
        coefs = tuple(_frozen(W) for W in self.coefs)
        intercepts = tuple(_frozen(b) for b in self.intercepts)
        if not coefs or len(coefs) != len(intercepts):
            raise ValueError(f"{len(coefs)} weight matrices and {len(intercepts)} bias vectors")
        for i, (W, b) in enumerate(zip(coefs, intercepts)):
            if W.ndim != 2 or b.shape != (W.shape[1],) or (i and W.shape[0] != coefs[i - 1].shape[1]):
                raise ValueError(f"layer {i}: weights {W.shape} and bias {b.shape} do not chain")
        object.__setattr__(self, "coefs", coefs)
        object.__setattr__(self, "intercepts", intercepts)

    @classmethod
    def from_sklearn(cls, network: MLPRegressor) -> "Network":
        """The weights of a fitted ``MLPRegressor`` (identity output layer)."""
        if network.out_activation_ != "identity":
            raise ValueError(f"output activation {network.out_activation_!r}, expected 'identity'")
        return cls(tuple(network.coefs_), tuple(network.intercepts_), network.activation)

    @property
    def hidden_layer_sizes(self) -> tuple[int, ...]:
        return tuple(W.shape[1] for W in self.coefs[:-1])


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


@dataclass
class TrainedModel:
    """A trained network with its affine input / output maps and how it was chosen.

    ``predict(X) = network((X - x_offset) / x_scale) * y_scale + y_offset``, in SI units. The
    network's forward pass is evaluated here from its weights (:func:`forward_pass`):
    ``MLPRegressor.predict`` validates its input on every call, which costs more than the
    arithmetic of these small networks when they are called one sample at a time; and the
    weights alone can be stored independently of the scikit-learn version
    (:mod:`optikin.baselines.nn_store`).
    """

    task: Task
    setting: TrainingSetting
    penalty: float
    neurons: int
    network: Network
    x_offset: np.ndarray
    x_scale: np.ndarray
    y_offset: np.ndarray
    y_scale: np.ndarray
    search: dict[int, float] = field(default_factory=dict)
    epochs: dict[int, int] = field(default_factory=dict)
    training_time: float = 0.0

    def predict(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return forward_pass(self.network, (X - self.x_offset) / self.x_scale) * self.y_scale + self.y_offset


def forward_pass(network: Network, A: np.ndarray) -> np.ndarray:
    """``MLPRegressor.predict(A)`` as ``(n, outputs)``, from the weights: hidden activations, identity output."""
    act = ACTIVATIONS[network.activation]
    for W, b in zip(network.coefs[:-1], network.intercepts[:-1]):
        A = act(A @ W + b)
    return A @ network.coefs[-1] + network.intercepts[-1]


def split_mse(model: TrainedModel, db: Database, split: str = "test") -> float:
    """Mean squared error over the outputs and the rows of ``split`` only (SI units, no penalty)."""
    X, Y = model.task.arrays(db, db.rows(split))
    return float(np.mean((model.predict(X) - Y) ** 2))


def split_rmse_by_variable(model: TrainedModel, db: Database, split: str = "test") -> dict[str, float]:
    """RMSE of ``Z`` [mm] and of the angles [deg] (or of positions, tube lengths [mm], pressures [kPa])
    over the rows of ``split``."""
    X, Y = model.task.arrays(db, db.rows(split))
    err = model.predict(X) - Y
    single = {"ends": ("position [mm]", 1e3), "tubes": ("tube length [mm]", 1e3), "pressures": ("pressure [kPa]", 1e-3)}
    if model.task.outputs[0] in single:
        label, scale = single[model.task.outputs[0]]
        return {label: float(scale * np.sqrt(np.mean(err**2)))}
    cols = np.array(model.task.outputs[1]) % 3
    out = {}
    for v, variable in enumerate(VARIABLES):
        if np.any(cols == v):
            scale, unit = (1e3, "mm") if variable == "Z" else (180 / np.pi, "deg")
            out[f"{variable} [{unit}]"] = float(scale * np.sqrt(np.mean(err[:, cols == v] ** 2)))
    return out


def _random_state(db: Database, task: Task, neurons: int) -> int:
    key = [db.seed, *task.key.encode(), neurons]
    return int(np.random.SeedSequence(key).generate_state(1)[0] % (2**31))


def affine_map(A: np.ndarray, scaling: bool | str) -> tuple[np.ndarray, np.ndarray]:
    """``(offset, scale)`` with which ``(A - offset) / scale`` is the network's view of the columns of ``A``.

    Parameters
    ----------
    A:
        ``(n, columns)`` training inputs or outputs, SI units.
    scaling:
        ``True``: mean and standard deviation; ``"minmax"``: the mid-range and the half range, so
        that the training columns span ``[-1, 1]`` (MATLAB's ``mapminmax``); ``False``: ``(0, 1)``.
        A constant column keeps the scale 1.

    Returns
    -------
    tuple of numpy.ndarray
        ``(columns,)`` each.
    """
    if scaling is False:
        return np.zeros(A.shape[1]), np.ones(A.shape[1])
    if scaling == "minmax":
        lo, hi = A.min(axis=0), A.max(axis=0)
        half = (hi - lo) / 2
        return (hi + lo) / 2, np.where(half > 0, half, 1.0)
    scale = A.std(axis=0)
    return A.mean(axis=0), np.where(scale > 0, scale, 1.0)


def _fit_width(
    network: MLPRegressor, Xs: np.ndarray, Ys: np.ndarray, criterion: Callable[[], float], setting: TrainingSetting
) -> tuple[float, int]:
    """Epochs of ``partial_fit`` until the validation criterion stalls; restores the best weights."""
    best, best_epoch, best_weights = np.inf, 0, None
    for epoch in range(1, setting.max_epochs + 1):
        check_interrupted()
        network.partial_fit(Xs, Ys)
        value = criterion()
        if value < best:
            best, best_epoch = value, epoch
            best_weights = (copy.deepcopy(network.coefs_), copy.deepcopy(network.intercepts_))
        elif epoch - best_epoch >= setting.patience:
            break
    if best_weights is not None:
        network.coefs_, network.intercepts_ = best_weights
    return float(best), best_epoch


def train_model(
    task: Task,
    db: Database,
    setting: TrainingSetting,
    penalty: float = 0.0,
    on_width: Callable[[int, float], None] | None = None,
) -> TrainedModel:
    """Train ``task`` for every width of ``setting`` and keep the best on the validation split.

    ``penalty`` is ``lambda`` of eq. (11) (inverse models only). The validation criterion is
    ``mean((Y - P)^2 + lambda P^2)`` in SI units, i.e. the MSE when ``lambda = 0``.
    """
    if penalty < 0:
        raise ValueError(f"penalty must be non-negative, got {penalty}")
    if penalty and not task.penalised:
        raise ValueError(f"{task.key}: the penalty of eq. (11) applies to the inverse models only")
    X_train, Y_train = task.arrays(db, db.train)
    X_val, Y_val = task.arrays(db, db.validation)
    target = Y_train / (1.0 + penalty)
    x_off, x_sc = affine_map(X_train, setting.scaling)
    y_off, y_sc = affine_map(target, setting.scaling)
    Xs, Ys = (X_train - x_off) / x_sc, (target - y_off) / y_sc
    Xv = (X_val - x_off) / x_sc
    from sklearn.neural_network import MLPRegressor  # here: two seconds of import a trained model does not need

    results: dict[int, tuple[float, int, MLPRegressor]] = {}
    start = time.perf_counter()
    with threadpool_limits(1):  # tiny matrices: BLAS threads only add overhead
        for n in setting.neurons:
            network = MLPRegressor(
                hidden_layer_sizes=(n, n),
                activation=setting.activation,
                solver=setting.solver,
                alpha=0.0,
                batch_size=min(setting.batch_size, len(Xs)),
                learning_rate_init=setting.learning_rate,
                momentum=setting.momentum,
                nesterovs_momentum=False,
                shuffle=True,
                random_state=_random_state(db, task, n),
            )

            def criterion() -> float:
                P = forward_pass(Network.from_sklearn(network), Xv) * y_sc + y_off
                return float(np.mean((Y_val - P) ** 2 + penalty * P**2))

            value, epochs = _fit_width(network, Xs, Ys, criterion, setting)
            results[n] = (value, epochs, network)
            if on_width is not None:
                on_width(n, value)
    elapsed = time.perf_counter() - start
    best = min(results, key=lambda n: (results[n][0], n))
    return TrainedModel(
        task=task,
        setting=setting,
        penalty=float(penalty),
        neurons=best,
        network=Network.from_sklearn(results[best][2]),
        x_offset=x_off,
        x_scale=x_sc,
        y_offset=y_off,
        y_scale=y_sc,
        search={n: r[0] for n, r in results.items()},
        epochs={n: r[1] for n, r in results.items()},
        training_time=elapsed,
    )


# ---------------------------------------------------------------------------------------- hybrid models
def hybrid_forward_configurations(models: list[TrainedModel], legs: np.ndarray) -> np.ndarray:
    """Fig. 9: every section's platform variables from its leg lengths, ``(n, 48)`` from ``(n, 48)``."""
    legs = np.atleast_2d(np.asarray(legs, dtype=float))
    if sorted(c for m in models for c in m.task.outputs[1]) != list(range(legs.shape[1])):
        raise ValueError("the forward models do not cover every platform exactly once")
    Q = np.empty(legs.shape)
    for model in models:
        Q[:, list(model.task.outputs[1])] = model.predict(legs[:, list(model.task.inputs[1])])
    return Q


def hybrid_inverse_configurations(
    models: list[TrainedModel], tip: np.ndarray, section1_end: np.ndarray | None = None
) -> np.ndarray:
    """Fig. 10: NN1 gives the end of section 1, NN2-NN4 every ``(Z_k, theta_k, psi_k)``; ``(n, 48)``.

    ``section1_end`` ``(n, 3)``, when given (e.g. measured), replaces NN1's prediction, which
    is then not needed.
    """
    by_key = {m.task.key: m for m in models}
    needed = {"ikm_nn2", "ikm_nn3", "ikm_nn4"} | ({"ikm_nn1"} if section1_end is None else set())
    missing = needed - set(by_key)
    if missing:
        raise ValueError(f"missing inverse models: {', '.join(sorted(missing))}")
    tip = np.atleast_2d(np.asarray(tip, dtype=float))
    end1 = by_key["ikm_nn1"].predict(tip) if section1_end is None else np.atleast_2d(np.asarray(section1_end, float))
    if end1.shape != tip.shape:
        raise ValueError(f"section1_end has shape {end1.shape}, the tips {tip.shape}")
    ends = np.concatenate([tip, end1], axis=1)
    n_config = 3 * len(by_key["ikm_nn2"].task.outputs[1])
    Q = np.empty((len(tip), n_config))
    for i in range(3):
        Q[:, i::3] = by_key[f"ikm_nn{i + 2}"].predict(ends)
    return Q


# ---------------------------------------------------------------------------------------- goal babbling
@dataclass
class GoalBabbling:
    """An inverse model learned by goal babbling (Rolf, Steil & Gienger 2010), seed 004 Table IV's BHA row.

    ``g(x) = home + W^T phi(x)``, with ``phi`` Gaussian features of the position about ``centers``
    (width ``width``), the offset from ``center_mean`` and a constant. Learning (:func:`goal_babbling`)
    fits ``W`` by weighted ridge regression on the samples the arm produced while trying to reach goals.

    Attributes
    ----------
    home:
        ``(m,)`` the command of the home posture.
    centers, width, center_mean:
        ``(c, d)`` feature centres, their width and ``(d,)`` mean [units of the positions].
    weights:
        ``(c + d + 1, m)``.
    samples:
        Commands executed while learning.
    """

    home: np.ndarray
    centers: np.ndarray
    width: float
    center_mean: np.ndarray
    weights: np.ndarray
    samples: int = 0

    def features(self, X: np.ndarray) -> np.ndarray:
        """``(n, c + d + 1)`` features of positions ``(n, d)``."""
        X = np.atleast_2d(X)
        d2 = ((X[:, None, :] - self.centers[None]) ** 2).sum(-1)
        return np.concatenate(
            [np.exp(-0.5 * d2 / self.width**2), (X - self.center_mean) / self.width, np.ones((len(X), 1))], 1
        )

    def predict(self, X: np.ndarray) -> np.ndarray:
        """``(n, m)`` commands for positions ``(n, d)``."""
        return self.home + self.features(X) @ self.weights


def goal_babbling(
    execute: Callable[[np.ndarray], np.ndarray],
    home: np.ndarray,
    goals: np.ndarray,
    rng: np.random.Generator,
    steps: int = 2000,
    path_steps: int = 25,
    noise: float = 0.1,
    centers: int = 40,
    ridge: float = 1e-6,
    refit: int = 50,
) -> GoalBabbling:
    """Learn an inverse model by goal babbling (Rolf, Steil & Gienger, "Goal babbling permits direct
    learning of inverse kinematics", IEEE TAMD 2010).

    Goals move along straight paths between targets drawn from ``goals`` (``path_steps`` each, back
    home after every tenth path on average); each step executes the current inverse estimate plus a
    slowly varying exploratory perturbation (standard deviation ``noise``, relative to the spread of
    the commands the arm's ``home`` and range suggest), observes where the arm went, and keeps the
    sample with the weight ``w_dir w_eff`` of the paper: ``w_dir = (1 + cos angle(goal step,
    observed step)) / 2``, ``w_eff = |observed step| / |command step|`` (normalised by its maximum).
    Every ``refit`` steps the model is refitted on all samples by weighted ridge regression.

    Parameters
    ----------
    execute:
        ``command (m,) -> position (d,)``: one posture of the arm.
    home:
        ``(m,)`` the home command.
    goals:
        ``(g, d)`` the positions to learn to reach.
    rng:
        Draws the targets and the perturbations.
    steps, path_steps, noise, centers, ridge, refit:
        The budget of executed commands, the steps per path, the exploration, the number of feature
        centres (drawn from ``goals``), the ridge term and the refit period.

    Returns
    -------
    GoalBabbling
    """
    home = np.asarray(home, dtype=float)
    goals = np.asarray(goals, dtype=float)
    x_home = execute(home)
    spread = goals.std(axis=0).mean()
    model = GoalBabbling(
        home=home,
        centers=goals[rng.choice(len(goals), size=min(centers, len(goals)), replace=False)],
        width=float(spread),
        center_mean=goals.mean(axis=0),
        weights=np.zeros((min(centers, len(goals)) + goals.shape[1] + 1, len(home))),
    )
    scale = noise * np.maximum(np.abs(home), 1e-12)
    X, Q, W = [x_home], [home], [1.0]  # positions, commands, weights
    start, target = x_home, goals[rng.integers(len(goals))]
    e = np.zeros_like(home)
    x_prev, q_prev, g_prev = x_home, home, x_home
    for t in range(1, steps + 1):
        step = (t - 1) % path_steps + 1
        goal = start + (target - start) * step / path_steps
        e = 0.9 * e + np.sqrt(1 - 0.81) * scale * rng.standard_normal(len(home))
        q = model.predict(goal[None])[0] + e
        x = execute(q)
        dg, dx, dq = goal - g_prev, x - x_prev, q - q_prev
        w_dir = 0.5 * (1.0 + float(dg @ dx) / max(float(np.linalg.norm(dg) * np.linalg.norm(dx)), 1e-300))
        w_eff = float(np.linalg.norm(dx)) / max(float(np.linalg.norm(dq / scale)), 1e-300)
        X.append(x)
        Q.append(q)
        W.append(w_dir * w_eff)
        x_prev, q_prev, g_prev = x, q, goal
        if step == path_steps:
            start = target
            target = x_home if rng.random() < 0.1 else goals[rng.integers(len(goals))]
        if t % refit == 0 or t == steps:
            w = np.asarray(W) / np.max(W)
            F = model.features(np.asarray(X)) * np.sqrt(w)[:, None]
            R = (np.asarray(Q) - home) * np.sqrt(w)[:, None]
            model.weights = np.linalg.solve(F.T @ F + ridge * len(F) * np.eye(F.shape[1]), F.T @ R)
    model.samples = steps
    return model
