"""Seed 004's kinematic models scored on a Cosserat-rod CBHA: a truth none of the compared methods shares.

The source ``fig7`` of the family ``nn_database`` (:mod:`optikin.baselines.nn_database`)
draws its rows from the CBHA vertebra model (seed 004), which is also the model of the
exact solvers the networks are compared with, so its test split cannot tell the model's
own error. The source ``cosserat`` of the same family draws instead the postures of the
static Cosserat CBHA of :mod:`optikin.data.cosserat_markers` (two pneumatic sections of
the real arm's size, three tubes each, gravity; :func:`~optikin.data.cosserat_markers.cosserat_cbha_arm`):

* **commands**: each of the six tube pressures uniform on ``pressure_range``, independently
  per posture (seeded ``[seed, 1]``), as the arm is driven;
* **equilibria**: the compiled :class:`~optikin.physics.ShootingSolver`, each posture ramped
  from zero load when the previous one's wrench does not start it; a posture whose
  equilibrium is not found is an :class:`~optikin.errors.InputDataError` naming it;
* **sensors**: the tip position and orientation (material frame at ``s = L``), the end of
  section 1 (the backbone at ``s = L_1``), and the length of each tube's offset curve over
  each section (the six potentiometers of seed 004 section II: section 1's, and the whole
  tube's minus it), noise-free; arc lengths extrapolated to zero node spacing
  (:func:`~optikin.data.cosserat_markers.richardson_lengths`);
* **split**: one random 70 / 15 / 15 partition of the postures (``[seed, 2]``), for the
  methods that learn from the arm itself (seed 004 Table IV, "qualitative" rows).

The hybrid networks are trained, as in the seed, on a database of the vertebra model
(``params.model``: a :class:`~optikin.baselines.nn_database.Fig7Params`, ``model_samples``
draws) for the problem's ``arm``; they and the exact solvers then meet the Cosserat
postures only through the sensors. A vertebra model whose Table I cannot hold the
recorded tube lengths extrapolates; the problem files scale Table I to the recorded arm.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import Field

from optikin.algebra import quat_normalize, quat_rotate
from optikin.arms.base import ArmModel
from optikin.arms.cbha import LEG_DIRECTIONS, CBHAArm
from optikin.baselines.nn_database import SPLITS, Fig7Params, LearningDatabase, build_database, split_rows
from optikin.data.cosserat_markers import CosseratMarkerParams, actuation, cosserat_cbha_arm, richardson_lengths
from optikin.data.sources import register_source
from optikin.errors import InputDataError, SpecError
from optikin.options import Options
from optikin.physics import Loads, ShootingOptions, ShootingSolver
from optikin.spec import DataSpec

STREAM_COMMANDS, STREAM_SPLIT = 1, 2


class CosseratNNParams(Options):
    """``data.params`` of the source ``cosserat`` (family ``nn_database``)."""

    rod: CosseratMarkerParams = Field(
        default_factory=CosseratMarkerParams,
        description="the Cosserat CBHA (optikin.data.cosserat_markers.CosseratMarkerParams); its arm fields, "
        "pressure_range and payload are used, its motion and recorder fields are not",
    )
    model: Fig7Params = Field(
        default_factory=Fig7Params, description="the vertebra-model database the hybrid networks are trained on"
    )
    model_samples: int = Field(40_000, ge=1, description="data.samples of the vertebra-model database")
    split: tuple[float, float, float] = Field(
        (0.70, 0.15, 0.15), description="fractions of the Cosserat postures for training, validation and test"
    )


@dataclass
class CosseratDatabase:
    """Cosserat postures with their sensors, and the vertebra-model database of the hybrid networks.

    Attributes
    ----------
    model:
        The vertebra-model :class:`~optikin.baselines.nn_database.LearningDatabase`.
    params:
        The source's params.
    pressures:
        ``(n, sections, 3)`` tube pressures [Pa].
    tube_lengths:
        ``(n, sections, 3)`` length of each tube over each section [m].
    tip, tip_orientation:
        ``(n, 3)`` [m] and ``(n, 4)`` unit quaternions (base frame; the clamp is the origin).
    section_ends:
        ``(n, sections, 3)`` backbone at the end of each section [m].
    train, validation, test:
        Posture indices of the split.
    seed:
        The ``data.seed`` of every draw.
    """

    model: LearningDatabase
    params: CosseratNNParams
    pressures: np.ndarray
    tube_lengths: np.ndarray
    tip: np.ndarray
    tip_orientation: np.ndarray
    section_ends: np.ndarray
    train: np.ndarray
    validation: np.ndarray
    test: np.ndarray
    seed: int

    def __len__(self) -> int:
        return len(self.tip)

    def rows(self, split: str) -> np.ndarray:
        """Posture indices of ``split`` (``train``, ``validation`` or ``test``)."""
        if split not in SPLITS:
            raise KeyError(f"unknown split {split!r}; known: {', '.join(SPLITS)}")
        return getattr(self, split)

    def summary(self) -> dict:
        """Counts and ranges for reports."""
        L = self.tube_lengths * 1e3
        return {
            "Cosserat postures": len(self),
            "Cosserat train / validation / test": [len(self.train), len(self.validation), len(self.test)],
            "tube length per section, min [mm]": np.round(L.min(axis=(0, 2)), 2).tolist(),
            "tube length per section, max [mm]": np.round(L.max(axis=(0, 2)), 2).tolist(),
            "vertebra-model database": self.model.summary(),
        }


class CosseratSensors:
    """The Cosserat CBHA of ``params`` and its sensors: pressures in, equilibria's sensor readings out.

    One compiled :class:`~optikin.physics.ShootingSolver` serves every call (``compiled``: Newton on
    C-compiled functions, compiled once per arm and cached on disk; else CasADi's virtual machine).
    """

    def __init__(self, params: CosseratMarkerParams, compiled: bool = True) -> None:
        self.params = params
        options = ShootingOptions(steps_per_segment=params.steps_per_segment, compiled=compiled)
        self.solver = ShootingSolver(cosserat_cbha_arm(params), options)
        self.tip_force = tuple(float(v) for v in params.payload * np.asarray(params.gravity, dtype=float))

    def __call__(self, pressures: np.ndarray, source: str = "cosserat postures") -> dict[str, np.ndarray]:
        """Equilibria and sensors under ``pressures`` ``(n, sections, 3)`` [Pa], warm-started along them.

        Returns
        -------
        dict
            ``tube_lengths`` ``(n, sections, 3)`` [m], ``tip`` ``(n, 3)`` [m], ``tip_orientation``
            ``(n, 4)``, ``section_ends`` ``(n, sections, 3)`` [m] (module docstring).

        Raises
        ------
        optikin.errors.InputDataError
            Naming the first posture without an equilibrium.
        """
        params = self.params
        loads = [Loads(tip_force=self.tip_force, actuation=tuple(a)) for a in actuation(params, pressures)]
        solutions = self.solver.solve_sequence(loads)
        for i, sol in enumerate(solutions):
            if not sol.ok:
                raise InputDataError(f"no equilibrium of the Cosserat arm: {sol.message}", source=source, sample=i)
        s = self.solver.s
        backbone = np.stack([sol.positions for sol in solutions])  # (n, K, 3)
        frames = quat_normalize(np.stack([sol.orientations for sol in solutions]), check=False)
        per_section = params.segments_per_section * params.steps_per_segment
        ends = [per_section * (j + 1) for j in range(len(params.section_lengths))]
        directions = quat_rotate(frames[:, :, None, :], LEG_DIRECTIONS[None, None, :, :], check=False)
        offsets = params.tube_offset(s)[None, :, None, None] * directions
        tubes = (backbone[:, :, None, :] + offsets).transpose(0, 2, 1, 3)
        cumulative = richardson_lengths(tubes, ends)  # (n, tube, section): from the base to each section's end
        zero = np.zeros(cumulative.shape[:2] + (1,))
        per_section_lengths = np.diff(np.concatenate([zero, cumulative], -1), axis=-1)
        return {
            "tube_lengths": per_section_lengths.transpose(0, 2, 1),
            "tip": backbone[:, -1],
            "tip_orientation": frames[:, -1],
            "section_ends": backbone[:, ends],
        }


def cosserat_postures(
    params: CosseratMarkerParams, pressures: np.ndarray, source: str = "cosserat postures", compiled: bool = True
) -> dict[str, np.ndarray]:
    """Equilibria and sensors of the Cosserat CBHA of ``params`` under ``pressures`` ``(n, sections, 3)`` [Pa]
    (:class:`CosseratSensors`)."""
    return CosseratSensors(params, compiled)(pressures, source)


def build_cosserat_database(
    arm: CBHAArm, params: CosseratNNParams, samples: int, seed: int, source: str = "cosserat"
) -> CosseratDatabase:
    """``samples`` Cosserat postures (module docstring) and the vertebra-model database of ``arm``."""
    model_data = DataSpec(source="fig7", seed=seed, samples=params.model_samples)
    model = build_database(arm.geometry, params.model.database_spec(model_data))
    low, high = params.rod.pressure_range
    pressures = np.random.default_rng([seed, STREAM_COMMANDS]).uniform(
        low, high, (samples, len(params.rod.section_lengths), 3)
    )
    sensors = cosserat_postures(params.rod, pressures, source)
    train, validation, test = split_rows(samples, params.split, np.random.default_rng([seed, STREAM_SPLIT]))
    return CosseratDatabase(
        model=model,
        params=params,
        pressures=pressures,
        train=train,
        validation=validation,
        test=test,
        seed=seed,
        **sensors,
    )


@register_source(
    "nn_database",
    "cosserat",
    "postures of a two-section pneumatic Cosserat-rod CBHA (real size, gravity) under random tube pressures: "
    "tip pose, section ends, six tube lengths; with the vertebra-model database of the hybrid networks",
    params=CosseratNNParams,
)
def load_cosserat(arm: ArmModel, data: DataSpec, params: CosseratNNParams, path: Path) -> CosseratDatabase:
    """:func:`build_cosserat_database` of ``data.samples`` postures seeded by ``data.seed``.

    Raises
    ------
    SpecError
        On ``arm.type`` for an arm other than the CBHA, on ``data`` when the vertebra-model
        database cannot be drawn or the split leaves a part empty.
    """
    if not isinstance(arm, CBHAArm):
        raise SpecError(path, "arm.type", f"the nn kinds model the CBHA of seed 004, not {arm.name!r}")
    if min(round(f * data.samples) for f in params.split) < 1:
        raise SpecError(path, "data.samples", f"{data.samples} postures leave a part of the split empty")
    try:
        return build_cosserat_database(arm, params, data.samples, data.seed, f"{Path(path).name}: cosserat")
    except ValueError as exc:
        raise SpecError(path, "data.params", str(exc)) from None
