"""What every compared method is given: the fairness manifest of a comparison.

The rule, stated once: **every method gets what it would have in a lab.** The arm's
geometry as the lab would know it (measured, or calibrated from the same training data
the networks see; never the generator's own nor a different arm's without saying so),
the same measurements, the same limits and the same evaluation budget; a network tested
outside its training range is labelled, with the distance of each test input to the
nearest training input.

Each comparison (kinds ``ph_ik``, ``ph_shape``, ``nn_fkm``, ``nn_ikm``) builds a
:class:`Manifest`: one :class:`Given` per method, saying

``geometry``
    where its model of the arm comes from: one of :data:`GEOMETRY_SOURCES`;
``arm``
    the dimensions it is given (:class:`ArmSize`: tube offsets, the tube lengths its
    model can take), checked against the recorded arm's (:func:`mismatch`);
``training``, ``budget``, ``limits``, ``information``
    its training set, evaluation budget, the limits it knows and any information the
    others do not get (an extra marker, the truth's stiffness);
``label``
    why a method given another arm, the generator's own model or inputs outside its
    training range is still in the table; required for those (:meth:`Manifest.violations`);
``coverage``
    for a learned method, how far the test inputs lie from its training inputs
    (:func:`coverage`).

The manifest goes into every comparison row (``given.*`` columns of ``result.json`` and
``comparison.csv``), into the metrics (``fairness.*``) and into one printed note per
method; ``tests/test_fairness_manifest.py`` fails when a shipped comparison problem gives
its methods different arms without a label.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any, Sequence

import numpy as np
from scipy.spatial import cKDTree

from optikin.results import MethodRow

GEOMETRY_SOURCES = ("measured", "calibrated", "generator's own", "another arm", "none")
"""Where a method's model of the arm comes from. ``measured``: dimensions a lab measures (tube
offsets, lengths); ``calibrated``: fitted to the training data every method sees; ``generator's
own``: the model that made the data (a synthetic recording's own arm, or the truth's stiffness);
``another arm``: a model of a different arm (e.g. networks trained on a smaller one); ``none``:
no model of the arm (a learned map, a shape from the end poses alone)."""
NEEDS_LABEL = ("generator's own", "another arm")
"""Geometry sources that a comparison on a truth the methods do not share must label."""
RADIUS_TOLERANCE = 5e-4
"""Tube offsets [m] closer than this to the recorded arm's count as the same."""
MM = 1e3


@dataclass(frozen=True)
class ArmSize:
    """The dimensions of an arm that decide whether a model of it can hold the recorded arm.

    Attributes
    ----------
    name:
        What the dimensions are of (e.g. ``"cbha vertebra model, Table I x 1.8"``).
    tube_radii:
        ``(base, tip)`` offset of the tubes from the backbone [m], or None when not given.
    tube_range:
        ``(shortest, longest)`` whole tube length the model can take [m], or None.
    rest_length:
        The recorded arm's unpressurised length [m] (the truth's only), or None.
    """

    name: str
    tube_radii: tuple[float, float] | None = None
    tube_range: tuple[float, float] | None = None
    rest_length: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, in mm."""
        out: dict[str, Any] = {"name": self.name}
        if self.tube_radii is not None:
            out["tube radii [mm]"] = [round(r * MM, 3) for r in self.tube_radii]
        if self.tube_range is not None:
            out["tube lengths [mm]"] = [round(r * MM, 3) for r in self.tube_range]
        if self.rest_length is not None:
            out["rest length [mm]"] = round(self.rest_length * MM, 3)
        return out


def mismatch(given: ArmSize, truth: ArmSize, tube_lengths: np.ndarray | None = None) -> str:
    """Why ``given`` cannot be the recorded arm ``truth`` (``""`` when it can).

    The tube offsets must agree within :data:`RADIUS_TOLERANCE`; the model's tube-length range
    must hold the truth's unpressurised length and, when given, every recorded tube length
    ``tube_lengths`` [m] (any shape).
    """
    reasons = []
    if given.tube_radii is not None and truth.tube_radii is not None:
        if np.max(np.abs(np.subtract(given.tube_radii, truth.tube_radii))) > RADIUS_TOLERANCE:
            reasons.append(f"tube offsets {_mm(given.tube_radii)} mm, the recorded arm's {_mm(truth.tube_radii)} mm")
    if given.tube_range is not None:
        low, high = given.tube_range
        if truth.rest_length is not None and not low <= truth.rest_length <= high:
            reasons.append(
                f"tube lengths {_mm(given.tube_range)} mm cannot hold the recorded arm's unpressurised "
                f"{truth.rest_length * MM:.0f} mm"
            )
        if tube_lengths is not None:
            L = np.asarray(tube_lengths, dtype=float)
            L = L[np.isfinite(L)]
            outside = int(np.sum((L < low) | (L > high)))
            if outside:
                reasons.append(
                    f"{outside} of {L.size} recorded tube lengths ({_mm((L.min(), L.max()))} mm) outside its "
                    f"{_mm(given.tube_range)} mm"
                )
    return "; ".join(reasons)


def _mm(values: Sequence[float]) -> str:
    return "-".join(f"{v * MM:.0f}" for v in values)


def coverage(train: np.ndarray, test: np.ndarray, unit: str = "mm", scale: float = MM) -> dict[str, Any]:
    """How far each test input lies from the nearest training input, against the training set's own spacing.

    Parameters
    ----------
    train, test:
        ``(m, d)`` and ``(n, d)`` inputs (any shape whose last axis is the input's; flattened per row).
    unit, scale:
        The unit of the reported distances and the factor from the inputs' (default: m -> mm).

    Returns
    -------
    dict
        The median and largest distance of a test input to its nearest training input, the 95th
        percentile of the training inputs' distance to their nearest other one (the spacing), and
        the share of test inputs farther than that spacing; ``outside training range`` when the
        median test distance exceeds the spacing.
    """
    A = np.asarray(train, dtype=float).reshape(len(train), -1)
    B = np.asarray(test, dtype=float).reshape(len(test), -1)
    tree = cKDTree(A)
    d = tree.query(B)[0] * scale
    spacing = float(np.percentile(tree.query(A, k=2)[0][:, 1] * scale, 95)) if len(A) > 1 else 0.0
    return {
        f"test input to nearest training input, median [{unit}]": float(np.median(d)),
        f"test input to nearest training input, max [{unit}]": float(np.max(d)),
        f"training inputs' own spacing, 95th percentile [{unit}]": spacing,
        "test inputs beyond that spacing": float(np.mean(d > spacing)),
        "outside training range": bool(np.median(d) > spacing),
    }


@dataclass(frozen=True)
class Given:
    """What one method of a comparison was given (module docstring)."""

    method: str
    geometry: str
    arm: ArmSize | None = None
    training: str = "none"
    budget: str = ""
    limits: str = "none"
    information: str = ""
    label: str = ""
    coverage: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.geometry not in GEOMETRY_SOURCES:
            raise ValueError(f"{self.method}: geometry {self.geometry!r} is not one of {GEOMETRY_SOURCES}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: every field, the arm's in mm."""
        out = {k: v for k, v in asdict(self).items() if k not in ("method", "arm", "coverage")}
        out["arm"] = "" if self.arm is None else self.arm.name
        if self.arm is not None:
            out |= {k: v for k, v in self.arm.as_dict().items() if k != "name"}
        if self.coverage is not None:
            out |= self.coverage
        return out


@dataclass(frozen=True)
class Manifest:
    """The :class:`Given` of every method of a comparison and the recorded arm they are scored on.

    Attributes
    ----------
    truth:
        The recorded arm's dimensions.
    shared:
        Whether the methods' models share the truth (a synthetic recording of the problem's own
        arm): then ``generator's own`` needs no label.
    given:
        One per method, in the order of the comparison.
    tube_lengths:
        The recorded tube lengths [m] (checked against each model's range), or None.
    """

    truth: ArmSize
    shared: bool
    given: tuple[Given, ...] = field(default_factory=tuple)
    tube_lengths: np.ndarray | None = None

    def of(self, method: str) -> Given | None:
        """The entry of ``method`` (None when it has none)."""
        return next((g for g in self.given if g.method == method), None)

    def with_coverage(self, method: str, found: dict[str, Any], label: str = "") -> Manifest:
        """The manifest with ``method``'s coverage set; labelled ``label`` (or a default) when outside its range."""
        entries = []
        for g in self.given:
            if g.method == method:
                text = g.label
                if found.get("outside training range") and not text:
                    text = label or "tested outside its training range (coverage columns)"
                g = replace(g, coverage=found, label=text)
            entries.append(g)
        return replace(self, given=tuple(entries))

    def problems(self, g: Given) -> list[str]:
        """Why ``g`` needs a label (empty when it does not)."""
        why = []
        if g.arm is not None:
            text = mismatch(g.arm, self.truth, self.tube_lengths)
            if text:
                why.append(f"given another arm ({text})")
        if g.geometry == "another arm" and not why:
            why.append("given another arm")
        if g.geometry == "generator's own" and not self.shared:
            why.append("given the generator's own model of a truth the others do not share")
        if g.coverage is not None and g.coverage.get("outside training range"):
            why.append("tested outside its training range")
        return why

    def violations(self) -> list[str]:
        """One line per method given another arm, the generator's own model or untrained inputs without a label."""
        return [
            f"{g.method}: {'; '.join(why)}, without a label"
            for g in self.given
            if (why := self.problems(g)) and not g.label
        ]

    def notes(self) -> list[str]:
        """One printed line per method: what it was given, and its label."""
        lines = []
        for g in self.given:
            parts = [f"geometry {g.geometry}" + (f" ({g.arm.name})" if g.arm is not None else "")]
            parts += [f"{k} {v}" for k, v in (("training", g.training), ("budget", g.budget), ("limits", g.limits))]
            if g.information:
                parts.append(f"information: {g.information}")
            why = "; ".join(self.problems(g))
            if why:
                label = g.label or "UNLABELLED"
                parts.append(label if label.startswith(why) else f"{why}: {label}")
            lines.append(f"given to {g.method}: " + ", ".join(parts))
        return lines

    def metrics(self) -> dict[str, Any]:
        """``fairness``: the truth's dimensions and the unlabelled entries."""
        return {
            "fairness": {
                "recorded arm": self.truth.as_dict(),
                "methods sharing the truth's model": self.shared,
                "unlabelled": self.violations(),
            }
        }

    def annotate(self, rows: list[MethodRow]) -> list[MethodRow]:
        """``rows`` with a ``given`` column group on every row whose method has an entry (matched by name, or by
        the longest entry name the row's method starts with: ``ph-newton, euler_rodrigues frame``)."""
        names = sorted((g.method for g in self.given), key=len, reverse=True)
        out = []
        for row in rows:
            match = next((n for n in names if row.method == n or row.method.startswith(n)), None)
            if match is not None:
                entry = self.of(match)
                assert entry is not None
                row = MethodRow(row.method, row.role, {**row.metrics, "given": entry.as_dict()})
            out.append(row)
        return out


def cbha_size(geometry: Any, name: str) -> ArmSize:
    """The dimensions of a CBHA vertebra model (:class:`~optikin.arms.cbha.CBHAGeometry`): its radii and the
    whole tube lengths its Table I allows (the legs of every platform summed)."""
    return ArmSize(
        name,
        (float(geometry.r_max), float(geometry.r_min)),
        (float(np.sum(geometry.leg_min)), float(np.sum(geometry.leg_max))),
    )


def table_i_scale(geometry: Any) -> float:
    """The factor of a CBHA geometry's Table I over seed 004's (1 for the seed's own)."""
    from optikin.arms.cbha import CBHAGeometry

    return float(np.sum(geometry.leg_max) / np.sum(CBHAGeometry().leg_max))


def cbha_name(geometry: Any) -> str:
    """``cbha vertebra model, Table I`` with its scale when not the seed's."""
    scale = table_i_scale(geometry)
    return "cbha vertebra model, Table I" + ("" if abs(scale - 1) < 1e-6 else f" x {scale:.2f}")


def recorded_arm(source: str, params: Any, arm: Any) -> tuple[ArmSize, bool]:
    """The recorded arm of a problem's data and whether the problem's own arm model shares it.

    Parameters
    ----------
    source:
        ``data.source``.
    params:
        The validated ``data.params`` (a ``cosserat`` source's, or one holding them as ``rod``).
    arm:
        The problem's arm (a CBHA gives the dimensions of a recording it generates).
    """
    from optikin.data.cosserat_markers import CosseratMarkerParams

    rod = getattr(params, "rod", params)
    if isinstance(rod, CosseratMarkerParams):
        radii = (float(rod.tube_radius[0]), float(rod.tube_radius[1]))
        return ArmSize("Cosserat-rod CBHA (source cosserat)", radii, None, rod.length), False
    if source == "csv":
        return ArmSize("the recorded arm (csv)"), False
    geometry = getattr(arm, "geometry", None)
    if geometry is None:
        return ArmSize(f"the problem's arm (source {source})"), True
    return cbha_size(geometry, f"the problem's arm, {cbha_name(geometry)} (source {source})"), True


__all__ = [
    "ArmSize",
    "GEOMETRY_SOURCES",
    "Given",
    "Manifest",
    "cbha_name",
    "cbha_size",
    "coverage",
    "mismatch",
    "recorded_arm",
    "table_i_scale",
]
