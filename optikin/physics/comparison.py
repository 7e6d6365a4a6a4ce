"""Backbone reconstruction from end poses compared on one relaxed rod: PH quintics, a circular arc, the physics.

Every method gets the same inputs, those of the PH method (Singh et al. 2018,
section II.A): the base pose (the clamp), the tip pose and the known reference
length ``L`` of the rod; the physics fit also gets the rod's stiffness. Each
reconstructs the backbone, and it is measured against the rod's nodes at matched
arc lengths:

* ``ph-speeds``: the minimum-energy PH quintic of the end points and tangents with
  both end speeds set to ``L`` (:class:`~optikin.curves.ShapeEnergyModel`,
  ``free_speeds=False``, the seed's setting);
* ``ph-length``: the same with the end speeds free and the arc length held to ``L``
  (``free_speeds=True``);
* ``cc-arc``: the circular arc tangent to the base direction through the tip point
  (closed form, :func:`cc_arc_points`; it uses neither the tip direction nor ``L``:
  the constant-curvature arm's inverse kinematics of the tip position);
* ``physics``: the tip force and couple whose static Cosserat equilibrium reaches
  the tip pose (:class:`~optikin.physics.reconstruction.ShapeReconstructor`, 6
  unknowns), the rod's weight not modelled, as for a measured rod whose loads are
  unknown;
* ``physics-distributed``: the same with a uniform distributed force as 3 more
  unknowns (9 unknowns, 6 residuals: the fit stops at one of a 3-parameter family
  of exact solutions, the one Levenberg-Marquardt reaches from the start; a rule
  preferring the smallest distributed force would pick ``f = 0``, the 6-unknown fit,
  whenever the tip wrench alone reaches the tip pose, so end poses alone cannot
  reveal a distributed load);
* ``physics-weight``: the 6-unknown fit with the rod's weight ``rho A g`` modelled
  (known density and gravity), the fit for a rod whose only unknown load is at the tip.

The weightless fits start from the clamp wrench of the circular arc of the end
tangents (the couple ``E I theta / L`` about ``t0 x t1``), as the ``cosserat-wrench``
baseline of ``ph_shape`` does; the fit with the weight continues from the weightless
fit as the weight is raised (:func:`physics_fit`). The fit has other exact solutions
(other equilibria of a rod bent far, reaching the same tip pose, under large tip
forces), so the start matters.

Matched arc lengths: the rod's node ``k`` at reference arc length ``s_k`` is compared
with the reconstruction's point at ``s_k`` (the physics fits, on the same reference
grid) or, for the curves, at the fraction ``s_k / L`` of their own arc length ``S``
(arc length ``s_k S / L``: the PH curve of given speeds and the arc are not of length
``L`` in general). The distance is reported as its largest and its root-mean-square
value over the nodes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from optikin.algebra import quat_from_matrix
from optikin.curves import PHQuintic, ShapeData, ShapeEnergyModel
from optikin.physics.model import RodArm
from optikin.physics.reconstruction import Reconstruction, ReconstructionOptions, ShapeReconstructor
from optikin.physics.rod import Rod
from optikin.status import Status

METHODS = ("ph-speeds", "ph-length", "cc-arc", "physics", "physics-distributed", "physics-weight")
"""The compared methods (module docstring), in table order."""


@dataclass(frozen=True)
class RelaxedRod:
    """A clamped rod in static equilibrium, as a simulator gives it, with what its reconstruction may use.

    Attributes
    ----------
    name : str
        Case name.
    s : numpy.ndarray
        ``(K,)`` reference arc length of the nodes [m], ``s[0] = 0``, ``s[-1] = length``.
    positions : numpy.ndarray
        ``(K, 3)`` nodes [m], global frame.
    base_rotation, tip_rotation : numpy.ndarray
        ``(3, 3)`` material frames at the clamp and at the tip (columns ``d1, d2, d3``, body to world).
    length : float
        Reference length [m].
    shear_stiffness, axial_stiffness : float
        ``S = diag(GA_s, GA_s, EA)`` [N] (``GA_s`` includes the section's shear factor).
    bending_stiffness, torsional_stiffness : float
        ``B = diag(EI, EI, GJ)`` [N m^2].
    weight_per_length : numpy.ndarray
        ``(3,)`` ``rho A g`` [N/m], global frame (the distributed load of the rod's own weight).
    """

    name: str
    s: np.ndarray
    positions: np.ndarray
    base_rotation: np.ndarray
    tip_rotation: np.ndarray
    length: float
    shear_stiffness: float
    axial_stiffness: float
    bending_stiffness: float
    torsional_stiffness: float
    weight_per_length: np.ndarray

    @property
    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """``(position (3,) [m], quaternion (4,))`` of the clamp."""
        return self.positions[0], quat_from_matrix(self.base_rotation)

    @property
    def tip_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """``(position (3,) [m], quaternion (4,))`` of the tip."""
        return self.positions[-1], quat_from_matrix(self.tip_rotation)

    @property
    def loaded_by_weight(self) -> bool:
        """Whether the rod carries a distributed load (its weight)."""
        return bool(np.any(self.weight_per_length != 0.0))

    def arm(self, weight: float) -> RodArm:
        """The rod as a one-segment :class:`~optikin.physics.model.RodArm` with these stiffnesses.

        ``Rod`` has ``S = diag(GA, GA, EA)`` and ``B = diag(EI, EI, GJ)`` from one shear
        modulus; a shear factor is carried by setting ``G = GA_s / A`` and ``J = GJ / G``.

        Parameters
        ----------
        weight : float
            The fraction of its weight the rod carries (0: weightless, 1: its weight).
        """
        modulus = 1.0e6  # only the products E A, E I, G A, G J enter the equilibrium
        area = self.axial_stiffness / modulus
        shear = self.shear_stiffness / area
        density = 1000.0
        gravity = weight * self.weight_per_length / (density * area)
        rod = Rod(
            length=self.length,
            area=area,
            second_moment=self.bending_stiffness / modulus,
            polar_moment=self.torsional_stiffness / shear,
            outer_radius=float(np.sqrt(area / np.pi)),
            youngs_modulus=modulus,
            shear_modulus=shear,
            density=density,
            gravity=tuple(float(g) for g in gravity),
        )
        return RodArm.single(rod)


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation nearest to ``M`` (3, 3) in the Frobenius norm (polar factor by SVD)."""
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    return R


def pyelastica_rod(files: Mapping[int, Mapping[str, np.ndarray]], elements: int | None = None) -> RelaxedRod:
    """A :class:`RelaxedRod` from shipped PyElastica equilibria (``tests/data/pyelastica/README.md``).

    Parameters
    ----------
    files : mapping
        Element count ``N`` to the fields of that ``.npz`` (``positions`` ``(N+1, 3)``,
        ``directors`` ``(N, 3, 3)`` with rows ``d1, d2, d3``, the rod data).
    elements : int, optional
        Use the raw shape of this ``N`` (its tip frame is the last element's, at
        ``s = L - L/(2N)``). None: the Richardson extrapolation ``2 x_2N - x_N`` of the two
        finest grids (PyElastica converges at first order in ``1/N``) for the nodes and the
        tip frame (then projected on the rotations), at the coarser grid's nodes.

    Returns
    -------
    RelaxedRod
    """
    if elements is None:
        coarse, fine = sorted(files)[-2:]
        if fine != 2 * coarse:
            raise ValueError(f"extrapolation needs grids N and 2N, got {coarse} and {fine}")
        a, b = files[coarse], files[fine]
        positions = 2.0 * b["positions"][::2] - a["positions"]
        tip = _nearest_rotation(2.0 * b["directors"][-1].T - a["directors"][-1].T)
        d, n = a, coarse
    else:
        d, n = files[elements], elements
        positions, tip = np.asarray(d["positions"], dtype=float), np.asarray(d["directors"][-1].T, dtype=float)
    length, radius = float(d["length"]), float(d["radius"])
    E, G = float(d["youngs_modulus"]), float(d["shear_modulus"])
    area, second = np.pi * radius**2, np.pi * radius**4 / 4.0
    shear_factor = 27.0 / 28.0  # PyElastica's built-in Timoshenko factor for a solid circle
    return RelaxedRod(
        name=str(d["case"]),
        s=length * np.arange(n + 1) / n,
        positions=positions,
        base_rotation=np.asarray(d["directors"][0].T, dtype=float),
        tip_rotation=tip,
        length=length,
        shear_stiffness=shear_factor * G * area,
        axial_stiffness=E * area,
        bending_stiffness=E * second,
        torsional_stiffness=G * 2.0 * second,
        weight_per_length=float(d["density"]) * area * np.asarray(d["gravity"], dtype=float),
    )


# ----------------------------------------------------------------------------- the methods


def cc_arc_points(p0: np.ndarray, t0: np.ndarray, p1: np.ndarray, fractions: np.ndarray) -> tuple[np.ndarray, float]:
    """The circular arc from ``p0`` tangent to ``t0`` through ``p1``, at fractions of its arc length.

    In the plane of ``t0`` and the chord ``c = p1 - p0``, with ``alpha`` the angle between
    them, the arc has curvature ``kappa = 2 sin(alpha) / |c|``, turns by ``2 alpha`` and is
    ``S = alpha |c| / sin(alpha)`` long; its point at arc length ``sigma`` is
    ``p0 + sin(kappa sigma) / kappa t0 + 2 sin(kappa sigma / 2)^2 / kappa n`` with ``n`` the unit
    part of ``c`` normal to ``t0`` (the constant-curvature arc: Webster & Jones,
    Int. J. Robot. Res. 29(13), pp. 1661-1683, 2010).

    Parameters
    ----------
    p0, t0, p1 : numpy.ndarray
        ``(3,)`` base point [m], unit base tangent, tip point [m].
    fractions : numpy.ndarray
        ``(K,)`` in ``[0, 1]``.

    Returns
    -------
    points : numpy.ndarray
        ``(K, 3)`` [m].
    arc_length : float
        ``S`` [m].
    """
    chord = p1 - p0
    c = float(np.linalg.norm(chord))
    along = float(chord @ t0)
    normal = chord - along * t0
    h = float(np.linalg.norm(normal))
    alpha = float(np.arctan2(h, along))
    if h <= 1e-15 * c:
        return p0 + np.outer(fractions * c, t0), c
    n = normal / h
    S = alpha * c / np.sin(alpha)
    kappa = 2.0 * np.sin(alpha) / c
    sigma = fractions * S
    bend = np.sin(0.5 * kappa * sigma)  # 1 - cos(x) = 2 sin(x/2)^2, without cancellation on nearly straight arcs
    points = p0 + np.outer(np.sin(kappa * sigma) / kappa, t0) + np.outer(2.0 * bend**2 / kappa, n)
    return points, float(S)


def ph_points_at_fractions(curve: PHQuintic, fractions: np.ndarray, iterations: int = 30) -> np.ndarray:
    """Points of a PH quintic at fractions of its arc length: ``(K, 3)`` [m].

    The arc length ``s(t)`` of a PH curve is a polynomial (:meth:`PHQuintic.arc_length_at`)
    with derivative the parametric speed ``sigma(t) > 0``; ``s(t) = f S`` is solved for ``t``
    by Newton's method from ``t = f``, safeguarded by bisection (a step onto a bracket end is kept,
    so the fractions 0 and 1 give the end points exactly).
    """
    target = fractions * float(curve.arc_length())
    t, lo, hi = np.array(fractions, dtype=float), np.zeros_like(fractions), np.ones_like(fractions)
    for _ in range(iterations):
        r = np.asarray(curve.arc_length_at(t)) - target
        lo, hi = np.where(r < 0, t, lo), np.where(r > 0, t, hi)
        step = t - r / np.maximum(np.asarray(curve.parametric_speed(t)), 1e-300)
        t = np.where((step >= lo) & (step <= hi), step, 0.5 * (lo + hi))
    return np.asarray(curve.point(t))


def _arc_start(rod: RelaxedRod, distributed: bool) -> np.ndarray:
    """Clamp wrench of the weightless circular arc of the end tangents (module docstring), then a zero force."""
    t0, t1 = rod.base_rotation[:, 2], rod.tip_rotation[:, 2]
    axis = np.cross(t0, t1)
    sine = float(np.linalg.norm(axis))
    theta = float(np.arctan2(sine, float(t0 @ t1)))
    couple = rod.bending_stiffness * theta / rod.length * axis / sine if sine > 1e-12 else np.zeros(3)
    return np.concatenate([np.zeros(3), couple] + ([np.zeros(3)] if distributed else []))


def physics_fit(
    rod: RelaxedRod,
    *,
    distributed: bool = False,
    weight: bool = False,
    guess: np.ndarray | None = None,
    weight_steps: int = 4,
) -> Reconstruction:
    """The tip-wrench fit of ``rod`` from its end poses and length, on its node grid (module docstring).

    With the weight, the weightless fit comes first and the weight is then raised to
    its value in ``weight_steps`` equal steps, each fit started from the previous one's
    clamp wrench: a continuation along the branch of the weightless fit (started
    directly, the fit can end on another equilibrium through the same tip pose).

    Parameters
    ----------
    rod : RelaxedRod
        The rod (its nodes must be equally spaced in reference arc length).
    distributed : bool
        Also fit a uniform distributed force (9 unknowns).
    weight : bool
        Model the rod's weight.
    guess : numpy.ndarray, optional
        Start, the clamp wrench ``(6,)`` (then the distributed force); default the arc's clamp couple.
    weight_steps : int
        Continuation steps in the weight.

    Returns
    -------
    Reconstruction
        The fit (``seconds`` and ``iterations`` summed over the continuation); its
        ``solution.positions`` lie at ``rod.s``.
    """
    options = ReconstructionOptions(steps_per_segment=rod.s.size - 1, distributed_force=distributed)
    start = _arc_start(rod, distributed) if guess is None else guess
    scales = [0.0] + (list(np.arange(1, weight_steps + 1) / weight_steps) if weight and rod.loaded_by_weight else [])
    seconds, iterations = 0.0, 0
    for scale in scales:
        reconstructor = ShapeReconstructor(rod.arm(float(scale)), options)
        result, start = reconstructor.reconstruct(rod.base_pose, rod.tip_pose, None, start)
        seconds, iterations = seconds + result.seconds, iterations + result.iterations
    return replace(result, seconds=seconds, iterations=iterations)


@dataclass
class MethodResult:
    """One method's reconstruction of one rod.

    Attributes
    ----------
    points : numpy.ndarray
        ``(K, 3)`` reconstructed backbone at the rod's matched arc lengths [m].
    max_error, rms_error : float
        Largest and root-mean-square distance to the rod's nodes [m].
    arc_length : float
        Length of the reconstructed backbone [m] (the reference length for the physics fits).
    status : str
        ``"ok"``, or the solver's status.
    seconds : float
        Wall time of the reconstruction (model building excluded) [s].
    wrench : numpy.ndarray
        The fitted loads of a physics fit (:attr:`Reconstruction.wrench`), else empty.
    """

    points: np.ndarray
    max_error: float
    rms_error: float
    arc_length: float
    status: str
    seconds: float
    wrench: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass
class Comparison:
    """Every method on one rod: ``results[method]`` (:data:`METHODS`)."""

    rod: RelaxedRod
    results: dict[str, MethodResult]

    def row(self) -> list[str]:
        """Table cells ``case | method: max / RMS [mm] ...``."""
        cells = [self.rod.name]
        for name in METHODS:
            r = self.results[name]
            mark = "" if r.status == Status.OK else f" ({r.status})"
            cells.append(f"{1e3 * r.max_error:.3g} / {1e3 * r.rms_error:.3g}{mark}")
        return cells


class Comparator:
    """Builds the PH models once and compares every method on rods (module docstring)."""

    def __init__(self) -> None:
        self.ph_models = {
            "ph-speeds": ShapeEnergyModel(free_speeds=False),
            "ph-length": ShapeEnergyModel(free_speeds=True),
        }

    def _measured(self, rod: RelaxedRod, points: np.ndarray, **kwargs) -> MethodResult:
        e = np.linalg.norm(points - rod.positions, axis=1)
        return MethodResult(points, float(e.max()), float(np.sqrt(np.mean(e**2))), **kwargs)

    def compare(self, rod: RelaxedRod) -> Comparison:
        """Reconstruct ``rod`` by every method and measure each against its nodes."""
        p0, p1 = rod.positions[0], rod.positions[-1]
        t0, t1 = rod.base_rotation[:, 2], rod.tip_rotation[:, 2]
        fractions = rod.s / rod.length
        results: dict[str, MethodResult] = {}
        for name, model in self.ph_models.items():
            tic = time.perf_counter()
            data = ShapeData.checked(p0, t0, p1, t1, length=rod.length)
            solution = model.solve_newton(data)
            curve = model.curve(solution, data)
            points = ph_points_at_fractions(curve, fractions)
            results[name] = self._measured(
                rod,
                points,
                arc_length=float(curve.arc_length()),
                status=solution.status,
                seconds=time.perf_counter() - tic,
            )
        tic = time.perf_counter()
        points, S = cc_arc_points(p0, t0, p1, fractions)
        results["cc-arc"] = self._measured(
            rod, points, arc_length=S, status=Status.OK, seconds=time.perf_counter() - tic
        )
        weightless = physics_fit(rod)
        fits = {
            "physics": weightless,
            "physics-distributed": physics_fit(rod, distributed=True),
            "physics-weight": physics_fit(rod, weight=True),
        }
        for name, result in fits.items():
            results[name] = self._measured(
                rod,
                result.solution.positions,
                arc_length=rod.length,
                status=result.status,
                seconds=result.seconds,
                wrench=result.wrench,
            )
        return Comparison(rod, results)


def markdown_table(comparisons: list[Comparison]) -> str:
    """The comparisons as a Markdown table: one row per rod, ``max / RMS`` distance [mm] per method."""
    header = ["case"] + [f"{m} max / RMS [mm]" for m in METHODS]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(c.row()) + " |" for c in comparisons]
    return "\n".join(lines)


__all__ = [
    "METHODS",
    "Comparator",
    "Comparison",
    "MethodResult",
    "RelaxedRod",
    "cc_arc_points",
    "markdown_table",
    "ph_points_at_fractions",
    "physics_fit",
    "pyelastica_rod",
]
