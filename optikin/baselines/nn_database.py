"""The learning database of the hybrid approach (seed 004, section IV-A, Fig. 7).

Fig. 7: the platform variables ``(Z_k, theta_k, psi_k)`` are drawn on wide
ranges, the leg lengths follow from the inverse kinematic equations (eqs. 3-9,
:func:`optikin.arms.cbha.platform_leg_vectors`), and only the draws whose three
legs lie within the limits of Table I are kept. Here every platform ``k``
draws the same number of candidates, ``candidates``, uniformly on the same
wide box (seeded, one independent stream per platform), and keeps those with
``q_min,k <= q_m,k <= q_max,k`` for ``m = 1, 2, 3``; with ``require_upright``
(default) also every upper attachment point above the lower vertebra's plane
(``Q_{m,k,z} >= 0``), the admissibility of :meth:`CBHAArm.sample_configurations`:
on a wide box Table I alone also admits folded poses whose legs pass below
the lower vertebra, which neither the arm nor eq. (10) (a function of the
lengths) can represent.

How the seed's counts come about is not stated: it reports 11,559 samples for
section 1 and 18,512 for section 2 without the ranges, the number of draws or
whether they were a grid. A count is ``draws x acceptance``; the acceptance,
and hence the ratio of the two sections, depends on the ranges only. Pooled
over the eight platforms of a section, the default box (``Z`` in [0, 25] mm,
``theta``, ``psi`` in [-45, 45] degrees) keeps section 2 about 1.6 times as
often as section 1, the seed's ratio (18,512 / 11,559 = 1.60); see
:meth:`LearningDatabase.kept_per_section`.

A row of the database is one whole arm: row ``i`` takes the ``i``-th kept draw
of every platform, so the platforms are independent and no platform draw is used
twice. There are as many rows as the scarcest platform kept. The forward model
of section ``s`` reads its 24 leg lengths and 24 platform variables from the row;
the inverse models (section V, "the same learning base") its tip and section-1
end, computed by the exact forward kinematics. One random 70 / 15 / 15 split of
the rows serves every model, so every model is scored on the same held-out arms.

``coupling="section"`` draws one ``(Z, theta, psi)`` per section instead and gives
it to all eight platforms of the section, kept when every one of them is
admissible: the section then bends with constant curvature, its legs are nearly
in the fixed proportions of the seed's Fig. 6, and it has 3 degrees of freedom
instead of 24. That is an assumption about the seed's data, not its text; it
gives the networks the easy problem the low MSEs of Tables II and III suggest.

``coupling="tubes"`` is the database a practitioner would build for an arm driven by its
tubes: each row draws the elongation fractions ``f_{s,m}`` of the three tubes of every
section uniformly on ``[0, 1]``, every leg of the section is ``q_min,k + f_{s,m} (q_max,k -
q_min,k)`` (the percentage split of Fig. 6, :func:`split_tube_lengths`), and each platform's
``(Z_k, theta_k, psi_k)`` is solved from its legs (Newton on eqs. 3-6,
:func:`optikin.data.markers.configurations_from_fractions`); a row is kept when every
platform is upright. It samples the postures the arm takes when its six tubes are driven,
with 6 degrees of freedom, and ``candidates`` counts rows drawn, not draws per platform.

The database is the data source ``fig7`` of the family ``nn_database`` (the
``data`` section of the ``nn_fkm`` and ``nn_ikm`` problem files): ``data.seed``
and ``data.samples`` are :attr:`DatabaseSpec.seed` and
:attr:`DatabaseSpec.candidates`, ``data.params`` is :class:`Fig7Params`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from optikin.algebra import dq_translation
from optikin.arms.base import ArmModel
from optikin.arms.cbha import CBHAArm, CBHAGeometry, platform_bounds, platform_leg_vectors
from optikin.data.markers import configurations_from_fractions
from optikin.data.sources import register_source
from optikin.errors import SpecError
from optikin.options import Options
from optikin.spec import DataSpec

WIDE_Z_RANGE = (0.0, 0.025)
"""Default range of ``Z_k`` drawn in Fig. 7 [m]: from 0 to above every Table I maximum."""
WIDE_ANGLE_RANGE = (-np.pi / 4, np.pi / 4)
"""Default range of ``theta_k`` and ``psi_k`` drawn in Fig. 7 [rad]: +-45 degrees."""
SEED_KEPT_PER_SECTION = (11_559, 18_512)
"""Seed 004 section IV-A: samples kept for section 1 and section 2 (30,071 in all)."""
STREAM_CANDIDATES, STREAM_SPLIT = 0, 1
SPLITS = ("train", "validation", "test")
COUPLINGS = ("platform", "section", "tubes")


@dataclass(frozen=True)
class DatabaseSpec:
    """How the learning database is drawn (everything that makes it reproducible).

    Attributes
    ----------
    candidates:
        Draws per platform on the wide box.
    seed:
        Seed of every draw (the candidates of platform ``k`` use the stream ``[seed, 0, k]``,
        the split ``[seed, 1]``).
    z_range, angle_range:
        The wide box of Fig. 7: ``Z_k`` [m], and ``theta_k``, ``psi_k`` [rad]. Must contain the
        feasible box of every platform (:func:`optikin.arms.cbha.platform_bounds`).
    require_upright:
        Also keep only draws whose upper attachment points lie above the lower vertebra.
    split:
        Fractions of the rows for training, validation and test.
    coupling:
        ``platform``: every platform drawn on its own (Fig. 7); ``section``: one draw per
        section shared by its platforms; ``tubes``: six tube elongation fractions per row,
        split over the platforms as in Fig. 6 (module docstring).
    """

    candidates: int = 600_000
    seed: int = 2016
    z_range: tuple[float, float] = WIDE_Z_RANGE
    angle_range: tuple[float, float] = WIDE_ANGLE_RANGE
    require_upright: bool = True
    split: tuple[float, float, float] = (0.70, 0.15, 0.15)
    coupling: str = "platform"

    def __post_init__(self):
        for name in ("z_range", "angle_range", "split"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        if self.candidates < 1:
            raise ValueError(f"candidates must be positive, got {self.candidates}")
        for name in ("z_range", "angle_range"):
            lo, hi = getattr(self, name)
            if len(getattr(self, name)) != 2 or not lo < hi:
                raise ValueError(f"{name} must be [low, high] with low < high, got {getattr(self, name)}")
        if len(self.split) != 3 or min(self.split) <= 0 or abs(sum(self.split) - 1.0) > 1e-9:
            raise ValueError(f"split must be three positive fractions adding up to 1, got {self.split}")
        if self.coupling not in COUPLINGS:
            raise ValueError(f"coupling must be one of {', '.join(COUPLINGS)}, got {self.coupling!r}")

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` of ``(Z, theta, psi)``."""
        (z0, z1), (a0, a1) = self.z_range, self.angle_range
        return np.array([z0, a0, a0]), np.array([z1, a1, a1])

    def as_dict(self) -> dict:
        return asdict(self)


def draw_candidates(spec: DatabaseSpec, unit: int) -> np.ndarray:
    """The ``(candidates, 3)`` draws of ``(Z, theta, psi)`` of one unit (0-based; a platform or a section).

    Stored column by column (the transpose of a C-ordered ``(3, candidates)`` array), so each
    variable is contiguous for the vectorised leg lengths.
    """
    lower, upper = spec.box()
    rng = np.random.default_rng([spec.seed, STREAM_CANDIDATES, unit])
    return rng.uniform(lower[:, None], upper[:, None], size=(3, spec.candidates)).T


def admissible(
    draws: np.ndarray, geometry: CBHAGeometry, platform: int, require_upright: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Masks ``(within Table I, admissible)`` of draws ``(n, 3)`` of platform ``platform`` (0-based).

    Leg lengths by eqs. (3)-(6); "admissible" adds the upright condition when asked for.
    """
    r = geometry.radii
    within = np.ones(len(draws), dtype=bool)
    upright = np.ones(len(draws), dtype=bool)
    Z, theta, psi = draws.T
    for Q in platform_leg_vectors(Z, theta, psi, r[platform], r[platform + 1]):  # one (n, 3) per leg
        length = np.sqrt(np.einsum("ij,ij->i", Q, Q))
        within &= (length >= geometry.leg_min[platform]) & (length <= geometry.leg_max[platform])
        if require_upright:
            upright &= Q[:, 2] >= 0.0
    return within, within & upright


@dataclass
class LearningDatabase:
    """Whole-arm rows of platform variables and leg lengths, with one train / validation / test split.

    Attributes
    ----------
    configurations:
        ``(n, 48)``: ``(Z_1, theta_1, psi_1, ..., psi_16)`` [m, rad].
    leg_lengths:
        ``(n, 48)``: ``(q_{1,1}, q_{2,1}, q_{3,1}, ..., q_{3,16})`` [m] by eqs. (3)-(6).
    section_ends:
        ``(n, sections, 3)``: position of the end of each section (vertebrae 9 and 17) [m], by the
        exact forward kinematics of :class:`CBHAArm`.
    kept:
        Per unit (platform, or section with ``coupling="section"``), the candidates kept.
    kept_table_i:
        Per unit, the candidates within Table I (lengths alone, the seed's criterion).
    train, validation, test:
        Row indices of the split.
    """

    geometry: CBHAGeometry
    spec: DatabaseSpec
    configurations: np.ndarray
    leg_lengths: np.ndarray
    section_ends: np.ndarray
    kept: np.ndarray
    kept_table_i: np.ndarray
    train: np.ndarray
    validation: np.ndarray
    test: np.ndarray

    def __len__(self) -> int:
        return len(self.configurations)

    @cached_property
    def arm(self) -> CBHAArm:
        return CBHAArm(self.geometry)

    def rows(self, split: str) -> np.ndarray:
        """Row indices of ``split`` (``train``, ``validation`` or ``test``)."""
        if split not in SPLITS:
            raise KeyError(f"unknown split {split!r}; known: {', '.join(SPLITS)}")
        return getattr(self, split)

    def section_columns(self, section: int) -> slice:
        """Columns of section ``section`` (1-based) in :attr:`configurations` and :attr:`leg_lengths`."""
        start = 3 * sum(self.geometry.platforms_per_section[: section - 1])
        return slice(start, start + 3 * self.geometry.platforms_per_section[section - 1])

    def kept_per_section(self, table_i_only: bool = False) -> tuple[int, ...]:
        """Candidates kept per section (the seed's 11,559 and 18,512), pooled over its platforms
        when each platform is drawn on its own."""
        kept = self.kept_table_i if table_i_only else self.kept
        if self.spec.coupling == "tubes":
            return tuple(int(kept[0]) for _ in self.geometry.platforms_per_section)
        if self.spec.coupling == "section":
            return tuple(int(k) for k in kept)
        bounds = np.cumsum((0,) + self.geometry.platforms_per_section)
        return tuple(int(kept[a:b].sum()) for a, b in zip(bounds[:-1], bounds[1:]))

    @property
    def tip(self) -> np.ndarray:
        """``(n, 3)`` tip positions [m]."""
        return self.section_ends[:, -1]

    @property
    def seed(self) -> int:
        """The seed of every draw (:attr:`DatabaseSpec.seed`)."""
        return self.spec.seed

    @cached_property
    def tube_lengths(self) -> np.ndarray:
        """``(n, sections, 3)``: each tube's legs summed over each section [m] (the six potentiometers)."""
        return section_tube_lengths(self.geometry, self.leg_lengths)

    def summary(self) -> dict:
        """Counts for reports, beside the seed's."""
        return {
            "coupling": self.spec.coupling,
            f"candidates per {self.spec.coupling}": self.spec.candidates,
            f"kept per {self.spec.coupling}": self.kept.tolist(),
            "kept per section": list(self.kept_per_section()),
            "within Table I per section (lengths only)": list(self.kept_per_section(table_i_only=True)),
            "seed 004 kept per section": list(SEED_KEPT_PER_SECTION),
            "rows (whole arms)": len(self),
            "train / validation / test rows": [len(self.train), len(self.validation), len(self.test)],
        }


def split_rows(n: int, fractions: tuple[float, float, float], rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """A random partition of ``range(n)`` into three sorted index arrays of the given fractions."""
    order = rng.permutation(n)
    n_train = int(round(fractions[0] * n))
    n_val = int(round(fractions[1] * n))
    parts = order[:n_train], order[n_train : n_train + n_val], order[n_train + n_val :]
    return tuple(np.sort(p) for p in parts)


def draw_units(geometry: CBHAGeometry, spec: DatabaseSpec) -> list[range]:
    """The platforms (0-based) sharing each draw: one each, or one section each."""
    if spec.coupling == "platform":
        return [range(k, k + 1) for k in range(geometry.n_platforms)]
    bounds = np.cumsum((0,) + geometry.platforms_per_section)
    return [range(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def section_limits(geometry: CBHAGeometry) -> tuple[np.ndarray, np.ndarray]:
    """``(sum_k q_min,k, sum_k q_max,k)`` over each section's platforms [m], ``(sections,)`` each:
    the range of a tube's length over a section (Table I)."""
    bounds = np.cumsum((0,) + geometry.platforms_per_section)
    lo, hi = np.asarray(geometry.leg_min), np.asarray(geometry.leg_max)
    return (
        np.array([lo[a:b].sum() for a, b in zip(bounds[:-1], bounds[1:])]),
        np.array([hi[a:b].sum() for a, b in zip(bounds[:-1], bounds[1:])]),
    )


def tube_fractions_of_lengths(geometry: CBHAGeometry, tube_lengths: np.ndarray) -> np.ndarray:
    """Elongation fractions ``f_{s,m} = (L_{s,m} - sum q_min) / (sum q_max - sum q_min)`` of tube lengths.

    Parameters
    ----------
    geometry:
        The CBHA (Table I, sections).
    tube_lengths:
        ``(n, sections, 3)``: length of tube ``m`` over section ``s`` [m] (section 1's
        potentiometer, and the whole tube's minus it).

    Returns
    -------
    numpy.ndarray
        ``(n, sections, 3)``; 0 and 1 at the Table I totals, outside ``[0, 1]`` beyond them.
    """
    L = np.asarray(tube_lengths, dtype=float)
    lo, hi = section_limits(geometry)
    if L.ndim != 3 or L.shape[1:] != (len(lo), 3):
        raise ValueError(f"tube lengths must be (n, {len(lo)}, 3), got {L.shape}")
    return (L - lo[None, :, None]) / (hi - lo)[None, :, None]


def split_tube_lengths(geometry: CBHAGeometry, tube_lengths: np.ndarray) -> np.ndarray:
    """Fig. 9: the 48 leg lengths of six tube-length readings, by the percentage split of Fig. 6.

    Every leg ``m`` of section ``s`` takes the same fraction of its Table I range,
    ``q_{m,k} = q_min,k + f_{s,m} (q_max,k - q_min,k)`` (:func:`tube_fractions_of_lengths`),
    so the legs of a tube add up to its length over the section. Seed 004 section IV-A:
    "the elongation of each inter-vertebra at any time represents a percentage of the total
    length of the tube ... obtained by considering the minimum and the maximum elongations".

    Parameters
    ----------
    geometry:
        The CBHA.
    tube_lengths:
        ``(n, sections, 3)`` [m].

    Returns
    -------
    numpy.ndarray
        ``(n, 3 (N - 1))``: ``(q_{1,1}, q_{2,1}, q_{3,1}, ..., q_{3,16})`` [m], the order of
        :attr:`LearningDatabase.leg_lengths`.
    """
    f = tube_fractions_of_lengths(geometry, tube_lengths)
    section_of = np.repeat(np.arange(len(geometry.platforms_per_section)), geometry.platforms_per_section)
    lo, hi = np.asarray(geometry.leg_min), np.asarray(geometry.leg_max)
    legs = lo[None, :, None] + f[:, section_of, :] * (hi - lo)[None, :, None]  # (n, platform, tube)
    return legs.reshape(len(f), -1)


def section_tube_lengths(geometry: CBHAGeometry, leg_lengths: np.ndarray) -> np.ndarray:
    """``(n, sections, 3)``: each tube's legs summed over each section [m], from ``(n, 48)`` leg lengths."""
    legs = np.asarray(leg_lengths, dtype=float).reshape(len(leg_lengths), -1, 3)
    bounds = np.cumsum((0,) + geometry.platforms_per_section)
    return np.stack([legs[:, a:b].sum(axis=1) for a, b in zip(bounds[:-1], bounds[1:])], axis=1)


def _tube_driven_rows(geometry: CBHAGeometry, spec: DatabaseSpec) -> tuple[np.ndarray, int]:
    """Configurations of the upright rows of ``coupling="tubes"`` and the rows drawn (module docstring)."""
    arm = CBHAArm(geometry)
    rng = np.random.default_rng([spec.seed, STREAM_CANDIDATES, 0])
    fractions = rng.uniform(0.0, 1.0, size=(spec.candidates, len(geometry.platforms_per_section), 3))
    configurations = configurations_from_fractions(arm, fractions)
    ok = np.ones(len(configurations), dtype=bool)
    for k in range(geometry.n_platforms):
        if spec.require_upright:
            ok &= admissible(configurations[:, 3 * k : 3 * k + 3], geometry, k, True)[1]
    return configurations[ok], spec.candidates


def build_database(geometry: CBHAGeometry | None = None, spec: DatabaseSpec | None = None) -> LearningDatabase:
    """Draw the learning database of Fig. 7 (see the module docstring). Deterministic given ``spec.seed``."""
    geometry = geometry or CBHAGeometry()
    spec = spec or DatabaseSpec()
    if spec.coupling == "tubes":
        configurations, drawn = _tube_driven_rows(geometry, spec)
        return _database(geometry, spec, configurations, np.array([len(configurations)]), np.array([drawn]))
    lower, upper = platform_bounds(geometry)
    box_lo, box_hi = spec.box()
    if np.any(lower < box_lo) or np.any(upper > box_hi):
        k = int(np.argwhere(np.any((lower < box_lo) | (upper > box_hi), axis=1))[0, 0])
        raise ValueError(
            f"the wide ranges must contain every platform's feasible box; platform {k + 1} needs "
            f"Z in [{lower[k, 0]:.4g}, {upper[k, 0]:.4g}] m, theta and psi within "
            f"+-{upper[k, 1]:.4g} rad"
        )
    units = draw_units(geometry, spec)
    kept_draws, kept, kept_table_i = [], [], []
    for u, platforms in enumerate(units):
        columns = draw_candidates(spec, u).T  # (3, candidates), C-ordered
        alive = np.arange(columns.shape[1])  # within Table I on every platform so far
        upright = np.ones(len(alive), dtype=bool)
        for k in platforms:  # later platforms only test the survivors
            within, ok = admissible(columns[:, alive].T, geometry, k, spec.require_upright)
            alive, upright = alive[within], (upright & ok)[within]
        kept_draws.append(columns[:, alive[upright]].T)
        kept.append(int(upright.sum()))
        kept_table_i.append(len(alive))
    n = min(kept)
    configurations = np.concatenate([np.tile(d[:n], len(platforms)) for d, platforms in zip(kept_draws, units)], axis=1)
    return _database(geometry, spec, configurations, np.array(kept), np.array(kept_table_i))


def _database(
    geometry: CBHAGeometry, spec: DatabaseSpec, configurations: np.ndarray, kept: np.ndarray, kept_table_i: np.ndarray
) -> LearningDatabase:
    """The database of the whole-arm rows ``configurations`` ``(n, 48)``: legs, section ends, split."""
    n = len(configurations)
    if n < 10:
        raise ValueError(f"only {n} whole-arm rows from {spec.candidates} candidates per {spec.coupling}; draw more")
    arm = CBHAArm(geometry)
    leg_lengths = arm.evaluate("leg_lengths", configurations).reshape(n, -1)
    section_ends = dq_translation(arm.evaluate("section_dq", configurations).transpose(0, 2, 1))
    train, validation, test = split_rows(n, spec.split, np.random.default_rng([spec.seed, STREAM_SPLIT]))
    return LearningDatabase(
        geometry=geometry,
        spec=spec,
        configurations=configurations,
        leg_lengths=leg_lengths,
        section_ends=section_ends,
        kept=kept,
        kept_table_i=kept_table_i,
        train=train,
        validation=validation,
        test=test,
    )


# ---------------------------------------------------------------------------------------- data source
class Fig7Params(Options):
    """``data.params`` of the source ``fig7``: the wide box of Fig. 7, admissibility, coupling and split."""

    z_range_mm: tuple[float, float] = Field((0.0, 25.0), description="range of Z_k drawn [mm], [low, high]")
    angle_range_deg: tuple[float, float] = Field(
        (-45.0, 45.0), description="range of theta_k and psi_k drawn [deg], [low, high]"
    )
    require_upright: bool = Field(
        True, description="keep only draws whose upper attachment points lie above the lower vertebra"
    )
    coupling: Literal["platform", "section", "tubes"] = Field(
        "platform",
        description="platform: every platform drawn on its own (Fig. 7); section: one draw per section "
        "shared by its platforms; tubes: six tube elongation fractions per row split over the platforms "
        "as in Fig. 6 (the postures the arm takes when driven by its tubes; samples counts rows)",
    )
    split: tuple[float, float, float] = Field(
        (0.70, 0.15, 0.15), description="fractions of the rows for training, validation and test"
    )

    @field_validator("z_range_mm", "angle_range_deg")
    @classmethod
    def _increasing(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not value[0] < value[1]:
            raise ValueError(f"must be [low, high] with low < high, got {list(value)}")
        return value

    @field_validator("split")
    @classmethod
    def _fractions(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if min(value) <= 0 or abs(sum(value) - 1.0) > 1e-9:
            raise ValueError(f"must be three positive fractions adding up to 1, got {list(value)}")
        return value

    def database_spec(self, data: DataSpec) -> DatabaseSpec:
        """The :class:`DatabaseSpec` of these params with the ``data`` section's seed and draws.

        Parameters
        ----------
        data:
            The problem file's ``data`` section: ``samples`` draws per unit, ``seed``.

        Returns
        -------
        DatabaseSpec
            Ranges in SI units (``Z`` [m], angles [rad]).
        """
        (z0, z1), (a0, a1) = self.z_range_mm, self.angle_range_deg
        return DatabaseSpec(
            candidates=data.samples,
            seed=data.seed,
            z_range=(z0 / 1e3, z1 / 1e3),
            angle_range=(float(np.radians(a0)), float(np.radians(a1))),
            require_upright=self.require_upright,
            split=self.split,
            coupling=self.coupling,
        )


@register_source(
    "nn_database",
    "fig7",
    "seed 004 Fig. 7: platform variables drawn on a wide box, kept within Table I",
    params=Fig7Params,
)
def load_fig7(arm: ArmModel, data: DataSpec, params: Fig7Params, path: Path) -> LearningDatabase:
    """The learning database of ``data`` for the CBHA ``arm`` (:func:`build_database`).

    Raises
    ------
    SpecError
        On ``arm.type`` for an arm other than the CBHA, on ``data`` when the wide box misses a
        platform's feasible box or too few rows are kept.
    """
    if not isinstance(arm, CBHAArm):
        raise SpecError(path, "arm.type", f"the fig7 database is drawn for the CBHA of seed 004, not {arm.name!r}")
    try:
        return build_database(arm.geometry, params.database_spec(data))
    except ValueError as exc:
        raise SpecError(path, "data", str(exc)) from None
