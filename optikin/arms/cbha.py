"""The Compact Bionic Handling Assistant (CBHA) as 17 vertebrae and 16 3UPS-1UP platforms (seed 004).

Seed 004 (Lakhal, Melingui & Merzouki, IEEE/ASME T-Mech 2016), section III,
models the trunk as ``N = 17`` vertebrae; vertebrae ``k`` and ``k + 1`` form a
parallel platform ``k`` whose central UP leg leaves three degrees of freedom,
``(Z_k, theta_k, psi_k)``, and whose three UPS legs of lengths ``q_{m,k}`` are
the tube segments. The pose of vertebra ``k + 1`` in the frame of vertebra
``k`` is eq. (5): ``T = [Ry(theta_k) Rx(psi_k), (0, 0, Z_k)]``. ``theta_k`` is
the pitch (about ``y_k``) and ``psi_k`` the roll (about ``x_k``); section IV
calls ``psi_k`` "yaw", but the assumptions of section III exclude rotation
about ``z_k``. Vertebra ``n`` carries the legs' attachment points on a circle of
radius ``r_n`` (eq. 3), tapering from ``r_max`` at the base to ``r_min`` at the
apex (eq. 2).

Leg lengths are derived again from eqs. (3), (4) and (6): with the unit vectors
``u_m`` of eq. (3), ``Q_{m,k} = T (r_{k+1} u_m) - r_k u_m`` and
``q_{m,k} = |Q_{m,k}|``. Expanding ``|Q|^2`` gives

    q_{m,k}^2 = Z^2 + r_k^2 + r_{k+1}^2 + 2 Z r_{k+1} (R u_m)_z - 2 r_k r_{k+1} u_m . R u_m,

which is what eqs. (7)-(9) print (``r_k`` the lower, ``r_{k+1}`` the upper
vertebra); :func:`printed_leg_lengths` transcribes them and the tests compare.

Printed eq. (2), ``r_n = (k/N)(r_min - r_max) + r_max``, gives neither
``r_1 = r_max`` nor, with ``k = n - 1``, ``r_N = r_min``; here
``r_n = r_max + (n - 1)/(N - 1) (r_min - r_max)`` so the base vertebra has
``r_max`` and the apex ``r_min`` as the text says.

A vertebra is a plane in this model: the legs above and below vertebra ``n``
both attach on the plane ``z = 0`` of its frame (eqs. 3-5), so there is no
vertebra thickness; a real one is part of the inter-vertebra lengths of
Table I as the seed measured them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra import (
    dq_from_rotation_translation,
    matrix_from_quat,
    quat_from_axis_angle,
    quat_multiply,
    quat_rotate,
)
from optikin.algebra.backend import Array
from optikin.arms.base import ArmModel
from optikin.checks import ParameterError, check_parameter
from optikin.errors import InputDataError

TABLE_I_LEG_MIN_MM = (8.5, 8.5, 8.5, 7.0, 7.0, 7.0, 8.5, 10.0, 6.5, 8.0, 8.0, 7.5, 7.5, 7.0, 7.0, 6.5)
"""Seed 004 Table I: minimum elongation of inter-vertebra (platform) k = 1..16, millimetres."""
TABLE_I_LEG_MAX_MM = (19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20.0, 22.0, 16.0, 20.5, 20.5, 19.0, 19.0, 18.0, 18.0, 16.0)
"""Seed 004 Table I: maximum elongation of inter-vertebra (platform) k = 1..16, millimetres."""

LEG_DIRECTIONS = np.array([[-1.0, 0.0, 0.0], [0.5, np.sqrt(3.0) / 2.0, 0.0], [0.5, -np.sqrt(3.0) / 2.0, 0.0]])
"""Rows ``u_m``: the attachment points of eq. (3) are ``A_{m,n} = r_n u_m`` in the frame of vertebra ``n``."""

MAX_RADIUS = 1.0
"""Largest accepted vertebra radius and leg length [m] (the CBHA's are tens of millimetres)."""
MAX_TOOL_OFFSET = 10.0
"""Largest accepted ``|tool_offset|`` [m]."""
MAX_VERTEBRAE = 1000
"""Largest accepted number of vertebrae."""

CBHA_FUNCTION_NAMES = ("leg_lengths", "vertebra_positions", "vertebra_frames", "tube_points", "tube_lengths")
"""The CBHA's Functions beyond :data:`optikin.arms.base.FUNCTION_NAMES` (table in :class:`CBHAArm`)."""


@dataclass(frozen=True)
class CBHAGeometry:
    """Every constant of the CBHA model; lengths in metres.

    Parameters
    ----------
    n_vertebrae : int
        ``N = 17`` (seed 004, section III-A).
    r_max, r_min : float
        Circumradius of the leg triangle at the base and at the apex (eq. 2). Seed 004
        gives no value and no published CBHA dimension was found, so both are assumptions.
        ``r_max = 40 mm``: with it, Table I lets each section bend about 90-110 degrees in
        a plane (8 platforms of 11-15 degrees). ``r_min = 29 mm``: the 3 degree taper Festo
        describes for the bellows of its Bionic Handling Assistant ("Servopneumatics lets
        robot mimic nature", Power & Motion) over the trunk's straight length at mid
        elongation, ``sum_k (q_min + q_max)/2 = 210 mm``, i.e. ``0.21 tan 3 deg = 11 mm``.
    leg_min, leg_max : tuple of float
        Limits [m] of the 3 legs of platform ``k = 1..N-1``: seed 004 Table I, mm -> m.
    platforms_per_section : tuple of int
        Platforms 1-8 form section 1, platforms 9-16 section 2 (seed 004 section IV-A).
    tool_offset : float
        Distance [m] of the tool point along the tip vertebra's z axis. Default 0: the seed
        takes vertebra 17 as the tip and does not model the wrist and gripper.

    Raises
    ------
    optikin.checks.ParameterTypeError
        A :class:`TypeError` naming the field for a value that is not a number (``"0.04"``).
    optikin.checks.ParameterError
        A :class:`ValueError` naming the field (``leg_min.3``): a value that is not a finite
        number, fewer than 2 or more than :data:`MAX_VERTEBRAE` vertebrae, radii not
        ``0 < r_min <= r_max <= MAX_RADIUS``, limits not one per platform, above :data:`MAX_RADIUS`
        or not ``|r_k - r_{k+1}| < leg_min <= leg_max``, a tool offset beyond :data:`MAX_TOOL_OFFSET`,
        or sections that do not add up to the platforms.
    """

    n_vertebrae: int = 17
    r_max: float = 0.040
    r_min: float = 0.029
    leg_min: tuple[float, ...] = tuple(v / 1000.0 for v in TABLE_I_LEG_MIN_MM)
    leg_max: tuple[float, ...] = tuple(v / 1000.0 for v in TABLE_I_LEG_MAX_MM)
    platforms_per_section: tuple[int, ...] = (8, 8)
    tool_offset: float = 0.0

    def __post_init__(self) -> None:
        n = self.n_vertebrae
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= MAX_VERTEBRAE:
            raise ParameterError("n_vertebrae", f"must be an integer in [2, {MAX_VERTEBRAE}], got {n!r}")
        n_platforms = n - 1
        for name in ("r_max", "r_min"):
            value = check_parameter(getattr(self, name), name, positive=True, maximum=MAX_RADIUS, unit="m", scalar=True)
            object.__setattr__(self, name, float(value))
        for name in ("leg_min", "leg_max"):
            values = check_parameter(getattr(self, name), name, positive=True, maximum=MAX_RADIUS, unit="m")
            if values.shape != (n_platforms,):
                raise ParameterError(name, f"leg_min and leg_max need one value per platform ({n_platforms})")
            object.__setattr__(self, name, tuple(float(v) for v in values))
        offset = check_parameter(self.tool_offset, "tool_offset", maximum=MAX_TOOL_OFFSET, unit="m", scalar=True)
        object.__setattr__(self, "tool_offset", float(offset))
        sections = self.platforms_per_section
        if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in sections):
            raise ParameterError("platforms_per_section", f"expected integers, got {sections!r}")
        object.__setattr__(self, "platforms_per_section", tuple(int(v) for v in sections))
        if sum(self.platforms_per_section) != n_platforms or min(self.platforms_per_section) < 1:
            raise ParameterError(
                "platforms_per_section",
                f"{list(self.platforms_per_section)} must be positive and add up to {n_platforms}",
            )
        if not self.r_min <= self.r_max:
            raise ParameterError(
                "r_min", f"radii must satisfy 0 < r_min <= r_max, got r_min={self.r_min}, r_max={self.r_max}"
            )
        step = abs(self.r_max - self.r_min) / n_platforms
        for k, (lo, hi) in enumerate(zip(self.leg_min, self.leg_max)):
            if not step < lo <= hi:
                raise ParameterError(
                    f"leg_min.{k}",
                    f"platform {k + 1}: leg limits must satisfy |r_k - r_k+1| = {step:.4g} < "
                    f"leg_min <= leg_max, got [{lo}, {hi}]",
                )

    @property
    def n_platforms(self) -> int:
        """Number of platforms (inter-vertebrae), ``N - 1``."""
        return self.n_vertebrae - 1

    def vertebra_radius(self, n: int | np.ndarray) -> float | np.ndarray:
        """Leg-circle radius of vertebra ``n``: ``r_n = r_max + (n - 1)/(N - 1) (r_min - r_max)`` (seed 004 eq. 2).

        Re-indexed: the printed ``k/N`` would leave the base vertebra below ``r_max``; this form
        puts ``r_max`` at vertebra 1 and ``r_min`` at vertebra ``N``, as the text defines them.

        Parameters
        ----------
        n : int or numpy.ndarray
            Vertebra index (or indices) in ``1..N``.

        Returns
        -------
        float or numpy.ndarray
            ``r_n`` [m], of the shape of ``n``.

        Raises
        ------
        ValueError
            For an index that is not an integer in ``1..N``.
        """
        n_arr = np.asarray(n)
        if np.any((n_arr < 1) | (n_arr > self.n_vertebrae)) or np.any(n_arr != np.round(n_arr)):
            raise ValueError(f"vertebra index must be an integer in 1..{self.n_vertebrae}, got {n}")
        r = self.r_max + (n_arr - 1) / (self.n_vertebrae - 1) * (self.r_min - self.r_max)
        return float(r) if r.ndim == 0 else r

    @property
    def radii(self) -> np.ndarray:
        """Radii ``r_1 .. r_N`` [m] of every vertebra (eq. 2), shape ``(N,)``."""
        return np.asarray(self.vertebra_radius(np.arange(1, self.n_vertebrae + 1)))


# ---------------------------------------------------------------------------------------- one platform
def _transform_entries(Z: Array, theta: Array, psi: Array) -> list[list[Array]]:
    ct, st, cp, sp = B.cos(theta), B.sin(theta), B.cos(psi), B.sin(psi)
    return [[ct, st * sp, st * cp, 0.0], [0.0, cp, -sp, 0.0], [-st, sp * ct, ct * cp, Z], [0.0, 0.0, 0.0, 1.0]]


def platform_transform(Z: Array, theta: Array, psi: Array) -> Array:
    """Pose of vertebra ``k + 1`` in the frame of vertebra ``k`` (seed 004 eq. 5).

    ``[Ry(theta) Rx(psi), (0, 0, Z); 0 0 0 1]``.

    Parameters
    ----------
    Z : Array
        Height of vertebra ``k + 1`` along ``z_k`` [m].
    theta : Array
        Pitch about ``y_k`` [rad].
    psi : Array
        Roll about ``x_k`` [rad].

    Returns
    -------
    Array
        A CasADi ``4 x 4`` for CasADi scalars; for numpy inputs (broadcast together)
        ``(..., 4, 4)``.
    """
    rows = _transform_entries(Z, theta, psi)
    if B.any_casadi(Z, theta, psi):
        return ca.vertcat(*[ca.horzcat(*row) for row in rows])
    entries = np.broadcast_arrays(*[e for row in rows for e in row])
    return np.stack(entries, axis=-1).reshape(entries[0].shape + (4, 4))


def platform_quaternion(theta: Array, psi: Array) -> Array:
    """Unit quaternion of the platform rotation ``Ry(theta) Rx(psi)`` (seed 004 eq. 5).

    Composed from the two axis rotations, so smooth in both angles, with no
    matrix-to-quaternion branching.

    Parameters
    ----------
    theta : Array
        Pitch about ``y_k`` [rad]: numpy array or CasADi scalar/row.
    psi : Array
        Roll about ``x_k`` [rad], broadcast against ``theta``.

    Returns
    -------
    Array
        ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    """
    return quat_multiply(
        quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), theta, check=False),
        quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), psi, check=False),
    )


def platform_leg_vectors(Z: Array, theta: Array, psi: Array, r_lower: Array, r_upper: Array) -> list[Array]:
    """Leg vectors of one platform, ``Q_m = T (r_{k+1} u_m, 1) - (r_k u_m, 1)`` (seed 004 eq. 4).

    The product with the matrix ``T`` of eq. (5) is written out row by row (the attachment
    points ``A = r u_m`` of eq. 3 have no z component).

    Parameters
    ----------
    Z, theta, psi : Array
        Platform variables (m, rad, rad): CasADi scalars or numpy arrays (broadcast together).
    r_lower : Array
        ``r_k``, the radius of the lower vertebra ``k`` [m].
    r_upper : Array
        ``r_{k+1}``, the radius of the upper vertebra ``k + 1`` [m].

    Returns
    -------
    list of Array
        ``[Q_1, Q_2, Q_3]`` [m] in the frame of vertebra ``k``, each a CasADi ``3 x 1`` or a
        numpy ``(..., 3)``.
    """
    T = _transform_entries(Z, theta, psi)
    return [
        B.stack(
            [
                T[i][0] * r_upper * ux + T[i][1] * r_upper * uy + T[i][3] - r_lower * a
                for i, a in enumerate((ux, uy, 0.0))
            ]
        )
        for ux, uy, _ in LEG_DIRECTIONS
    ]


def _platform_leg_lengths_function() -> ca.Function:
    """The CasADi Function of :data:`PLATFORM_LEG_LENGTHS`."""
    args = [ca.SX.sym(s) for s in ("Z", "theta", "psi", "r_k", "r_k1")]
    lengths = ca.vertcat(*[ca.norm_2(Q) for Q in platform_leg_vectors(*args)])
    return ca.Function("cbha_platform_leg_lengths", args, [lengths], ["Z", "theta", "psi", "r_k", "r_k1"], ["q"])


PLATFORM_LEG_LENGTHS = _platform_leg_lengths_function()
"""``(Z_k, theta_k, psi_k, r_k, r_{k+1}) -> (q_1, q_2, q_3)``: ``q_m = |Q_{m,k}|``, eqs. (3)-(6)."""


def printed_leg_lengths(Z: Array, theta: Array, psi: Array, r_k: Array, r_k1: Array) -> tuple[Array, Array, Array]:
    """Leg lengths of one platform by seed 004 eqs. (7)-(9) as printed ("sqrt" split by the extraction).

    For cross-checks: the model itself uses :data:`PLATFORM_LEG_LENGTHS`, derived from
    eqs. (3)-(6); the tests show both agree.

    Parameters
    ----------
    Z, theta, psi : Array
        Platform variables (m, rad, rad): numpy arrays (broadcast together) or CasADi scalars.
    r_k, r_k1 : Array
        Radii ``r_k`` and ``r_{k+1}`` of the lower and upper vertebra [m].

    Returns
    -------
    tuple of Array
        ``(q_1, q_2, q_3)`` [m], each of the broadcast shape (numpy) or a CasADi scalar.
    """
    ct, st, cp, sp = B.cos(theta), B.sin(theta), B.cos(psi), B.sin(psi)
    s3 = np.sqrt(3.0)
    common = Z * Z + r_k1 * r_k1 + r_k * r_k
    q1 = common + 2 * Z * r_k1 * st - 2 * r_k1 * r_k * ct
    q2 = common + Z * r_k1 * (s3 * ct * sp - st) - r_k1 * r_k * (s3 / 2 * st * sp + 1.5 * cp + 0.5 * ct)
    q3 = common - Z * r_k1 * (s3 * ct * sp + st) + r_k1 * r_k * (s3 / 2 * st * sp - 1.5 * cp - 0.5 * ct)
    return B.sqrt(q1), B.sqrt(q2), B.sqrt(q3)


def platform_bounds(geometry: CBHAGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds on ``(Z_k, theta_k, psi_k)`` of every platform implied by Table I of seed 004.

    With ``d = r_k - r_{k+1}``, summing eq. (6) over the legs gives the identity

        (q_1^2 + q_2^2 + q_3^2)/3 = Z^2 + d^2 + r_k r_{k+1} (2 - cos theta - cos psi).

    * ``Z_k <= sqrt(q_max^2 - d^2)``: from the identity; reached by the straight pose at ``q_max``.
    * ``Z_k >= sqrt(q_min^2 - d^2)``, the straight pose at ``q_min``. The legs alone do not
      bound ``Z`` from below (``Z -> -Z`` at ``theta = psi = 0`` keeps every length); the bound
      assumes every upper attachment point lies above the lower vertebra's plane
      (``Q_{m,z} >= 0``). Then the lowest attachment point sits ``r_{k+1} |w|`` below the
      centre, ``w = (R u_m)_z``, while its leg's horizontal offset grows only with ``w^2``, so
      tilting raises ``Z``. That argument is exact for a tilt about a horizontal axis; for
      ``Ry Rx`` the tests confirm it by constrained minimisation of ``Z`` on every platform.
    * ``|theta_k|, |psi_k| <= arcsin(2 q_max / (3 r_{k+1}))``: the heights ``Q_{m,z}`` lie in
      ``[0, q_max]`` and have mean ``Z``, so their spread ``sum_m (Q_{m,z} - Z)^2 = 1.5 r_{k+1}^2
      sin^2(alpha)`` is at most ``2 q_max^2 / 3``, where ``cos(alpha) = cos(theta) cos(psi)`` is
      the tilt. ``alpha >= |theta|, |psi|`` holds when both cosines are positive, which the
      identity guarantees if ``q_max^2 - d^2 < r_k r_{k+1}``; otherwise the bound
      ``arccos(1 - (q_max^2 - d^2) / (r_k r_{k+1}))`` from the identity alone is used.

    Parameters
    ----------
    geometry : CBHAGeometry
        Radii and leg limits.

    Returns
    -------
    tuple of numpy.ndarray
        ``(lower, upper)``, each ``(N - 1, 3)``: row ``k - 1`` bounds ``(Z_k [m], theta_k [rad],
        psi_k [rad])``.
    """
    r = geometry.radii
    r_k, r_k1 = r[:-1], r[1:]
    q_min, q_max = np.asarray(geometry.leg_min), np.asarray(geometry.leg_max)
    d2 = (r_k - r_k1) ** 2
    from_identity = np.arccos(np.clip(1.0 - (q_max**2 - d2) / (r_k * r_k1), -1.0, 1.0))
    from_heights = np.arcsin(np.minimum(1.0, 2.0 * q_max / (3.0 * r_k1)))
    tilt = np.where(from_identity < np.pi / 2, np.minimum(from_identity, from_heights), from_identity)
    lower = np.column_stack([np.sqrt(q_min**2 - d2), -tilt, -tilt])
    upper = np.column_stack([np.sqrt(q_max**2 - d2), tilt, tilt])
    return lower, upper


# ---------------------------------------------------------------------------------------- the arm
class CBHAArm(ArmModel):
    """The CBHA as a chain of 16 platforms, ``q = (Z_1, theta_1, psi_1, ..., Z_16, theta_16, psi_16)``.

    Vertebra 1 is the base frame; vertebra ``k + 1`` is reached by the transforms of eq. (5)
    of platforms ``1..k``. Section 1 ends at vertebra 9, section 2 (the tip) at vertebra 17,
    plus :attr:`CBHAGeometry.tool_offset` along the tip's z axis. Bounds come from
    :func:`platform_bounds`.

    Besides the functions of :class:`ArmModel` (the CBHA's own are in :data:`CBHA_FUNCTION_NAMES`):

    ======================  ==============================================================
    ``leg_lengths``         q -> ``(q_{1,1}, q_{2,1}, q_{3,1}, q_{1,2}, ...)``, 3 (N-1)
    ``vertebra_positions``  q -> centres of vertebrae 1..N in the base frame, 3 x N
    ``vertebra_frames``     q -> poses of vertebrae 1..N as dual quaternions, 8 x N
    ``tube_points``         q -> ``A_{m,n}`` in the base frame, 3 x 3N: tube 1's N points,
                            then tube 2's, then tube 3's
    ``tube_lengths``        q -> ``sum_k q_{m,k}`` over each section's platforms,
                            (section, tube), 2 x 3
    ======================  ==============================================================

    ``Z_k`` is in metres, ``theta_k`` (pitch about ``y_k``) and ``psi_k`` (roll about ``x_k``)
    in radians; the base frame is vertebra 1, its z axis along the unbent trunk.

    Parameters
    ----------
    geometry : CBHAGeometry or Mapping, optional
        A :class:`CBHAGeometry`, or a mapping of its fields (e.g. from a problem file).
        Default: ``CBHAGeometry()``.
    name : str
        Identifier in problem files, Function names and reports.
    backbone_points_per_section : int
        Points per section in :attr:`backbone`; the default, one per platform, gives the
        vertebra centres exactly.

    Raises
    ------
    optikin.checks.ParameterError
        For a geometry field the :class:`CBHAGeometry` rejects, named ``geometry.<field>`` when
        ``geometry`` is a mapping.
    """

    extra_function_names = CBHA_FUNCTION_NAMES

    def __init__(
        self,
        geometry: CBHAGeometry | Mapping[str, Any] | None = None,
        name: str = "cbha",
        backbone_points_per_section: int = 8,
    ) -> None:
        if geometry is None:
            geometry = CBHAGeometry()
        elif isinstance(geometry, Mapping):
            try:
                geometry = CBHAGeometry(**geometry)
            except ParameterError as exc:
                raise ParameterError(f"geometry.{exc.field}", exc.message) from None
        elif not isinstance(geometry, CBHAGeometry):
            raise ParameterError("geometry", f"expected a mapping of CBHAGeometry fields, got {geometry!r:.40}")
        self.geometry = geometry
        names = tuple(f"{v}{k}" for k in range(1, geometry.n_platforms + 1) for v in ("Z", "theta", "psi"))
        self.leg_names = tuple(f"q{m}_{k}" for k in range(1, geometry.n_platforms + 1) for m in (1, 2, 3))
        lower, upper = platform_bounds(geometry)
        positive = tuple(v == "Z" for _ in range(geometry.n_platforms) for v in ("Z", "theta", "psi"))
        super().__init__(name, names, lower.ravel(), upper.ravel(), backbone_points_per_section, positive=positive)

    @property
    def n_sections(self) -> int:
        """Number of sections (2 by default)."""
        return len(self.geometry.platforms_per_section)

    @property
    def section_end_vertebrae(self) -> tuple[int, ...]:
        """0-based index of the vertebra that ends each section (8 and 16 by default)."""
        return tuple(int(i) for i in np.cumsum(self.geometry.platforms_per_section))

    # ------------------------------------------------------------------ kinematics
    def vertebra_chain(self, q: Array) -> list[tuple[Array, Array]]:
        """Poses of vertebrae 1..N in the base frame, by the chain of seed 004 eq. (5).

        ``p_{k+1} = p_k + R_k (0, 0, Z_k)``, ``R_{k+1} = R_k Ry(theta_k) Rx(psi_k)``.

        Parameters
        ----------
        q : Array
            A CasADi column ``3(N-1) x 1`` or a numpy batch ``(..., 3(N-1))``.

        Returns
        -------
        list of (Array, Array)
            ``N`` pairs ``(quaternion, position [m])``, vertebra 1 (the identity) first: CasADi
            ``4 x 1`` and ``3 x 1``, or numpy ``(..., 4)`` and ``(..., 3)``.

        Raises
        ------
        TypeError
            For a numeric ``q`` that is not numbers.
        ValueError
            For a numeric ``q`` that is not finite, plausible configurations (:meth:`ArmModel.checked_numeric`).
        """
        return self._vertebra_chain(self.checked_numeric(q))

    def _vertebra_chain(self, q: Array) -> list[tuple[Array, Array]]:
        """:meth:`vertebra_chain` without the check."""
        v = B.components(q, self.n_config, "q")
        zero = 0.0 * v[0]
        quat, pos = B.stack([zero + 1.0, zero, zero, zero]), B.stack([zero, zero, zero])
        frames = [(quat, pos)]
        for k in range(self.geometry.n_platforms):
            Z, theta, psi = v[3 * k : 3 * k + 3]
            pos = pos + quat_rotate(quat, B.stack([zero, zero, Z]), check=False)
            quat = quat_multiply(quat, platform_quaternion(theta, psi))
            frames.append((quat, pos))
        return frames

    def section_frames(self, q: Array) -> list[tuple[Array, Array]]:
        """End poses of the sections: vertebrae 9 and 17 by default, the last moved by the tool offset.

        Parameters
        ----------
        q : Array
            A CasADi column ``3(N-1) x 1`` or a numpy batch ``(..., 3(N-1))``.

        Returns
        -------
        list of (Array, Array)
            One ``(quaternion, position [m])`` per section, as :meth:`vertebra_chain`.

        Raises
        ------
        TypeError
            For a numeric ``q`` that is not numbers.
        ValueError
            For a numeric ``q`` that is not finite, plausible configurations (:meth:`ArmModel.checked_numeric`).
        """
        chain = self._chain_of(self.checked_numeric(q))
        frames = [chain[i] for i in self.section_end_vertebrae]
        quat, pos = frames[-1]
        if self.geometry.tool_offset != 0.0:
            pos = pos + quat_rotate(quat, np.array([0.0, 0.0, self.geometry.tool_offset]), check=False)
        return frames[:-1] + [(quat, pos)]

    def backbone_points(self, q: ca.SX, points_per_section: int) -> ca.SX:
        """The polyline through the vertebra centres, ``points_per_section`` points per section.

        Point ``j`` of a section of ``P`` platforms lies at platform parameter ``j P / points``
        along it, linearly interpolated between vertebra centres; a multiple of ``P`` gives
        every centre. The tool offset is not part of the backbone.

        Parameters
        ----------
        q : casadi.SX
            Configuration ``3(N-1) x 1``.
        points_per_section : int
            Points per section after the base point.

        Returns
        -------
        casadi.SX
            ``3 x (1 + sections points_per_section)`` [m] in the base frame.
        """
        centres = [pos for _, pos in self._chain_of(q)]
        points, start = [centres[0]], 0
        for P in self.geometry.platforms_per_section:
            for j in range(1, points_per_section + 1):
                i, rest = divmod(j * P, points_per_section)
                if rest == 0:
                    points.append(centres[start + i])
                else:
                    f = rest / points_per_section
                    points.append((1.0 - f) * centres[start + i] + f * centres[start + i + 1])
            start += P
        return ca.horzcat(*points)

    def leg_length_expressions(self, q: ca.SX) -> ca.SX:
        """Leg lengths ``q_{m,k} = |Q_{m,k}|`` of every platform (seed 004 eq. 6).

        Parameters
        ----------
        q : casadi.SX
            Configuration ``3(N-1) x 1``.

        Returns
        -------
        casadi.SX
            ``3(N-1) x 1`` [m], ordered ``(q_{1,1}, q_{2,1}, q_{3,1}, q_{1,2}, ...)`` as :attr:`leg_names`.
        """
        r = self.geometry.radii
        return ca.vertcat(
            *[
                PLATFORM_LEG_LENGTHS(q[3 * k], q[3 * k + 1], q[3 * k + 2], r[k], r[k + 1])
                for k in range(self.geometry.n_platforms)
            ]
        )

    # ------------------------------------------------------------------ extra Functions
    @cached_property
    def _chain_expr(self) -> list[tuple[ca.SX, ca.SX]]:
        return self._vertebra_chain(self._q)

    def _chain_of(self, q: Array) -> list[tuple[Array, Array]]:
        """The chain of ``q``, built once for the arm's own symbol."""
        return self._chain_expr if q is self._q else self._vertebra_chain(q)

    @cached_property
    def leg_lengths(self) -> ca.Function:
        """``q -> lengths (3(N-1) x 1)``: every leg [m] (:meth:`leg_length_expressions`).

        A numeric ``q`` need only be finite: solvers evaluate this constraint at infeasible configurations.
        """
        return self._function("leg_lengths", self.leg_length_expressions(self._q), "lengths", within="finite")

    @cached_property
    def vertebra_positions(self) -> ca.Function:
        """``q -> positions (3 x N)``: centres of vertebrae 1..N [m] in the base frame."""
        return self._function("vertebra_positions", ca.horzcat(*[p for _, p in self._chain_expr]), "positions")

    @cached_property
    def vertebra_frames(self) -> ca.Function:
        """``q -> dq (8 x N)``: poses of vertebrae 1..N as unit dual quaternions."""
        dqs = [dq_from_rotation_translation(quat, p, check=False) for quat, p in self._chain_expr]
        return self._function("vertebra_frames", ca.horzcat(*dqs), "dq")

    @cached_property
    def tube_points(self) -> ca.Function:
        """``q -> points (3 x 3N)``: attachment points ``A_{m,n}`` [m]; tube 1's N points, then tube 2's, tube 3's."""
        r = self.geometry.radii
        chain = self._chain_expr
        offsets = [
            ca.mtimes(matrix_from_quat(quat, check=False), r[n] * LEG_DIRECTIONS.T) for n, (quat, _) in enumerate(chain)
        ]
        points = [p + offsets[n][:, m] for m in range(3) for n, (_, p) in enumerate(chain)]
        return self._function("tube_points", ca.horzcat(*points), "points")

    @cached_property
    def tube_lengths(self) -> ca.Function:
        """``q -> lengths (sections x 3)``: ``sum_k q_{m,k}`` [m] over each section's platforms, per tube.

        A numeric ``q`` need only be finite, as for :attr:`leg_lengths`.
        """
        legs = ca.reshape(self.leg_length_expressions(self._q), 3, self.geometry.n_platforms)  # tube x platform
        bounds = (0,) + self.section_end_vertebrae
        rows = [ca.sum2(legs[:, a:b]).T for a, b in zip(bounds[:-1], bounds[1:])]
        return self._function("tube_lengths", ca.vertcat(*rows), "lengths", within="finite")

    # ------------------------------------------------------------------ legs and limits
    def leg_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Table I limits of every leg.

        Returns
        -------
        tuple of numpy.ndarray
            ``(min, max)`` [m], each ``(3(N-1),)`` in the order of :attr:`leg_lengths`.
        """
        return np.repeat(self.geometry.leg_min, 3), np.repeat(self.geometry.leg_max, 3)

    def check_leg_lengths(
        self, lengths: np.ndarray, source: str = "leg lengths", tolerance: float = 1e-9
    ) -> np.ndarray:
        """Check leg lengths against Table I of seed 004; raise naming the sample and the leg.

        Rejects a wrong shape, non-finite values and lengths outside Table I by more than
        ``tolerance``.

        Parameters
        ----------
        lengths : numpy.ndarray
            ``(N, 3(N_v - 1))`` [m] in the order of :attr:`leg_names`, or one row.
        source : str
            Where the data came from, for the error message.
        tolerance : float
            Slack on the limits [m].

        Returns
        -------
        numpy.ndarray
            The lengths as floats, ``(N, 3(N_v - 1))`` [m].

        Raises
        ------
        optikin.errors.InputDataError
            Naming ``source``, the sample and the leg (``q{m}_{k}``).
        """
        L = np.asarray(lengths, dtype=float)
        L = L[None, :] if L.ndim == 1 else L
        n_legs = len(self.leg_names)
        if L.ndim != 2 or L.shape[1] != n_legs:
            raise InputDataError(
                f"expected shape (N, {n_legs}) of leg lengths in metres, got {np.shape(lengths)}", source=source
            )
        bad = ~np.isfinite(L)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise InputDataError(
                f"{L[i, j]} is not a finite number", source=source, sample=int(i), field=self.leg_names[j]
            )
        lo, hi = self.leg_limits()
        outside = (L < lo - tolerance) | (L > hi + tolerance)
        if outside.any():
            i, j = np.argwhere(outside)[0]
            raise InputDataError(
                f"{1000 * L[i, j]:.3f} mm outside the Table I limits [{1000 * lo[j]:.1f}, {1000 * hi[j]:.1f}] mm "
                f"of platform {j // 3 + 1}, tube {j % 3 + 1}",
                source=source,
                sample=int(i),
                field=self.leg_names[j],
            )
        return L

    def validate(
        self,
        configurations: np.ndarray,
        source: str = "configurations",
        check_bounds: bool = True,
        tolerance: float = 1e-12,
    ) -> np.ndarray:
        """As :meth:`ArmModel.validate`; with ``check_bounds`` also every leg within Table I.

        Parameters
        ----------
        configurations : numpy.ndarray
            ``(N, 3(N_v - 1))`` or one configuration.
        source : str
            Where the data came from, for the error message.
        check_bounds : bool
            Whether to check the box bounds and the leg limits.
        tolerance : float
            Slack on the box bounds.

        Returns
        -------
        numpy.ndarray
            ``(N, 3(N_v - 1))``.

        Raises
        ------
        optikin.errors.InputDataError
            Naming ``source``, the sample and the variable or leg.
        """
        Q = super().validate(configurations, source, check_bounds, tolerance)
        if check_bounds:
            self.check_leg_lengths(self.evaluate("leg_lengths", Q).reshape(len(Q), -1), source)
        return Q

    def straight_configuration(self, fraction: float = 0.5) -> np.ndarray:
        """The straight pose with every leg at ``q_min + fraction (q_max - q_min)`` (Table I).

        ``theta_k = psi_k = 0`` and ``Z_k = sqrt(q_k^2 - (r_k - r_{k+1})^2)``.

        Parameters
        ----------
        fraction : float
            Where in ``[0, 1]`` each leg lies between its limits.

        Returns
        -------
        numpy.ndarray
            ``(3(N_v - 1),)``; the tip lies on the base z axis.

        Raises
        ------
        ValueError
            For a fraction outside ``[0, 1]``.
        """
        if not 0.0 <= fraction <= 1.0:
            raise ValueError(f"fraction must be within [0, 1], got {fraction}")
        g = self.geometry
        legs = np.asarray(g.leg_min) + fraction * (np.asarray(g.leg_max) - np.asarray(g.leg_min))
        Z = np.sqrt(legs**2 - np.diff(g.radii) ** 2)
        return np.column_stack([Z, np.zeros_like(Z), np.zeros_like(Z)]).ravel()

    def sample_configurations(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` configurations uniform over the feasible poses, platform by platform.

        Each platform is drawn uniformly inside its bounds and redrawn until its three legs
        are within Table I and their upper ends above the lower vertebra (the assumption of
        :func:`platform_bounds`): the database generation of seed 004, Fig. 7.

        Parameters
        ----------
        n : int
            Number of configurations.
        rng : numpy.random.Generator
            Source of the draws.

        Returns
        -------
        numpy.ndarray
            ``(n, 3(N_v - 1))``.
        """
        g, r = self.geometry, self.geometry.radii
        lower, upper = self.lower.reshape(-1, 3), self.upper.reshape(-1, 3)
        out = np.empty((n, g.n_platforms, 3))
        for k in range(g.n_platforms):
            kept = np.empty((0, 3))
            while len(kept) < n:
                draw = rng.uniform(lower[k], upper[k], size=(max(4 * n, 64), 3))
                Z, theta, psi = draw.T
                Q = np.stack(platform_leg_vectors(Z, theta, psi, r[k], r[k + 1]), axis=1)  # (draw, leg, xyz)
                legs = np.linalg.norm(Q, axis=-1)
                ok = np.all((legs >= g.leg_min[k]) & (legs <= g.leg_max[k]) & (Q[..., 2] >= 0.0), axis=1)
                kept = np.vstack([kept, draw[ok]])
            out[:, k] = kept[:n]
        return out.reshape(n, -1)

    def describe(self) -> dict[str, Any]:
        """:meth:`ArmModel.describe` plus ``kind`` and the ``geometry`` fields.

        Returns
        -------
        dict
            JSON-serialisable geometry and bounds (lengths in metres, angles in radians).
        """
        return super().describe() | {"kind": "cbha", "geometry": asdict(self.geometry)}
