"""Multi-section constant-curvature (CC) arm, Seleem et al. 2020 (seed 000) section II.

Each section ``i`` has configuration ``(S_i, theta_i, phi_i)``: arc length,
bending angle (``theta = kappa S``) and bending-plane angle. The section's
rotation relative to its base is ``R = Rz(phi) Ry(theta) Rz(-phi)`` (the
convention of Webster & Jones 2010) and its tip lies at

    p = S [cos(phi) (1 - cos theta)/theta,  sin(phi) (1 - cos theta)/theta,  sin(theta)/theta].

Seed 000 eq. (1) is garbled by extraction, and its eq. (2) (a 5th-order Taylor
form to dodge the theta -> 0 singularity) bends the other way: it equals this
convention with ``phi`` replaced by ``phi + pi`` (tested). Here the ratios are
written as ``(1 - cos theta)/theta = theta (1 - cos theta)/theta^2`` and
``sin(theta)/theta = sinc(theta)``, each switched to its series inside a tiny
band, so values *and* derivatives are exact and finite for a straight section.

The rotation is composed as a quaternion, ``q = (cos(theta/2), -sin(theta/2) sin(phi),
sin(theta/2) cos(phi), 0)``, which is smooth everywhere: no matrix-to-quaternion
branching in the symbolic graph.

Section angles from an IMU quaternion (seed 000 eqs. 6-8, derived again): the
section's tip z axis is ``R e_z = (sin theta cos phi, sin theta sin phi, cos theta)``,
so ``theta = atan2(sqrt(R13^2 + R23^2), R33)`` and ``phi = atan2(R23, R13)``;
a twist about the tip axis (which a CC section cannot make) is discarded.
"""

from __future__ import annotations

from typing import Any, Sequence, cast

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra import check_unit_quaternions, quat_conjugate, quat_multiply, quat_rotate
from optikin.algebra.backend import Array
from optikin.arms.base import ArmModel
from optikin.checks import ParameterError, check_numbers, check_parameter, check_quaternion

DEFAULT_SECTION_LENGTH = 0.18
"""Seed 000 section VII: two rods of 18 cm each."""
DEFAULT_LENGTH_RANGE = (0.9, 1.1)
"""Section length bounds as fractions of the nominal length (an assumption: Table 1 of seed 000 is lost)."""
DEFAULT_THETA_MAX = 2.0 * np.pi / 3.0
"""|theta| <= 120 degrees per section (an assumption, typical of cable-driven sections)."""
MAX_SECTION_LENGTH = 10.0
"""Largest accepted nominal section length [m]: above the longest continuum sections built (about 2 m), far
below a length in millimetres (180 for 18 cm)."""
MAX_LENGTH_FACTOR = 10.0
"""Largest accepted ``length_range`` factor: a section stretching to 10 times its nominal length."""


def section_quaternion(theta: Array, phi: Array) -> Array:
    """Rotation ``Rz(phi) Ry(theta) Rz(-phi)`` of one CC section relative to its base, as a unit quaternion.

    ``(cos(theta/2), -sin(theta/2) sin(phi), sin(theta/2) cos(phi), 0)``: the rotation by
    ``theta`` about the axis ``(-sin phi, cos phi, 0)``; seed 000 eq. (1), derived again.

    Parameters
    ----------
    theta : Array
        Bending angle [rad]: numpy array or CasADi scalar/row.
    phi : Array
        Bending-plane angle [rad], broadcast against ``theta``.

    Returns
    -------
    Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    """
    h = 0.5 * theta
    s = B.sin(h)
    return B.stack([B.cos(h), -s * B.sin(phi), s * B.cos(phi), 0.0 * theta])


def section_position(length: Array, theta: Array, phi: Array) -> Array:
    """Tip position of one CC section relative to its base (seed 000 eq. 1, derived again).

    ``S [cos(phi) (1 - cos theta)/theta, sin(phi) (1 - cos theta)/theta, sin(theta)/theta]``,
    with both ratios exact and smooth at ``theta = 0`` (instead of the Taylor form of eq. 2).

    Parameters
    ----------
    length : Array
        Arc length ``S`` [m]: numpy array or CasADi scalar/row.
    theta : Array
        Bending angle [rad], broadcast against ``length``.
    phi : Array
        Bending-plane angle [rad], broadcast against ``length``.

    Returns
    -------
    Array
        Positions [m] in the section's base frame: numpy ``(..., 3)`` or CasADi ``3 x N``.
    """
    radial = length * theta * B.one_minus_cos_over_square(theta)
    return B.stack([radial * B.cos(phi), radial * B.sin(phi), length * B.sinc(theta)])


def section_angles_from_quaternion(q: Array, check: bool = True) -> tuple[Array, Array]:
    """Section angles from the orientation of a CC section relative to its base (seed 000 eq. 8, derived again).

    The tip z axis is ``R e_z = (sin theta cos phi, sin theta sin phi, cos theta)``, so
    ``theta = atan2(sqrt(R13^2 + R23^2), R33)`` and ``phi = atan2(R23, R13)``; a twist about
    the tip axis is discarded.

    Parameters
    ----------
    q : Array
        Unit quaternions ``(w, x, y, z)``: numpy ``(..., 4)`` or CasADi ``4 x N``.
    check : bool
        Refuse a numpy ``q`` that is not a finite unit quaternion (:func:`optikin.checks.check_quaternion`);
        False in inner loops.

    Returns
    -------
    tuple of Array
        ``(theta, phi)`` [rad], each numpy ``(...)`` or CasADi ``1 x N``; ``theta`` in
        ``[0, pi]``, ``phi`` in ``(-pi, pi]`` (0 when the section is straight).

    Raises
    ------
    ValueError
        With ``check``, for a non-finite, zero or non-unit numpy quaternion, naming ``q``.
    """
    if check and not B.is_casadi(q):
        q = check_quaternion(q, unit=True, name="q")
    w, x, y, z = B.components(q, 4, "q")
    r13 = 2 * (x * z + w * y)
    r23 = 2 * (y * z - w * x)
    r33 = 1 - 2 * (x * x + y * y)
    theta = B.atan2(B.sqrt(r13 * r13 + r23 * r23), r33)
    phi = B.atan2(r23, r13)
    return theta, phi


def relative_section_quaternions(imu_quaternions: np.ndarray, source: str = "IMU quaternions") -> np.ndarray:
    """Each section's orientation relative to the previous section's tip (seed 000 eq. 7).

    ``Q_rel,i = Q_{i-1}^-1 Q_i`` with ``Q_0`` the identity.

    Parameters
    ----------
    imu_quaternions : numpy.ndarray
        ``(..., m, 4)``: the reading ``(w, x, y, z)`` of the IMU at the tip of each of the ``m``
        sections, in the base frame; the first axis is the sample.
    source : str
        Where the readings came from, for the error message.

    Returns
    -------
    numpy.ndarray
        ``(..., m, 4)`` relative orientations, the input of :func:`section_angles_from_quaternion`.

    Raises
    ------
    optikin.errors.InputDataError
        When a reading is not a unit quaternion, naming the sample.
    """
    Q = check_unit_quaternions(imu_quaternions, source)
    previous = np.concatenate([np.broadcast_to([1.0, 0, 0, 0], Q[..., :1, :].shape), Q[..., :-1, :]], axis=-2)
    return quat_multiply(quat_conjugate(previous), Q)


class ConstantCurvatureArm(ArmModel):
    """An ``m``-section constant-curvature arm, ``q = (S_1, theta_1, phi_1, ..., S_m, theta_m, phi_m)``.

    The base frame has its z axis along the unbent backbone; section ``i`` starts at the
    end frame of section ``i - 1``. ``phi_i`` is periodic (solvers wrap it).

    Parameters
    ----------
    section_lengths : tuple of float
        Nominal length of each section [m], in ``(0, MAX_SECTION_LENGTH]`` (default: two 18 cm
        sections, seed 000 section VII).
    length_range : tuple of float
        Bounds ``(low, high)`` of ``S_i`` as fractions of the nominal length,
        ``0 < low <= high <= MAX_LENGTH_FACTOR``.
    theta_max : float
        Bound on ``|theta_i|`` [rad], in ``(0, pi]``.
    name : str
        Identifier in problem files, Function names and reports.
    backbone_points_per_section : int
        Points per section in :attr:`backbone`.

    Raises
    ------
    optikin.checks.ParameterTypeError
        A :class:`TypeError` naming the parameter for a value that is not a number (``"1"``, ``None``).
    optikin.checks.ParameterError
        A :class:`ValueError` naming the parameter (``section_lengths.0``) for a value that is not
        a finite number, not positive or outside the ranges above.
    """

    def __init__(
        self,
        section_lengths: tuple[float, ...] = (DEFAULT_SECTION_LENGTH, DEFAULT_SECTION_LENGTH),
        length_range: tuple[float, float] = DEFAULT_LENGTH_RANGE,
        theta_max: float = DEFAULT_THETA_MAX,
        name: str = "cc",
        backbone_points_per_section: int = 20,
    ) -> None:
        lengths = check_parameter(
            section_lengths, "section_lengths", positive=True, maximum=MAX_SECTION_LENGTH, unit="m"
        )
        if lengths.ndim != 1 or len(lengths) == 0:
            raise ParameterError("section_lengths", f"expected a list of section lengths, got {section_lengths!r}")
        range_ = check_parameter(length_range, "length_range", positive=True, size=2, maximum=MAX_LENGTH_FACTOR)
        lo, hi = (float(v) for v in range_)
        if not lo <= hi:
            raise ParameterError("length_range", f"must satisfy 0 < low <= high, got {list(length_range)}")
        theta_max = float(
            check_parameter(theta_max, "theta_max", positive=True, maximum=np.pi, unit="rad", scalar=True)
        )
        self.section_lengths = lengths
        self.length_range = (float(lo), float(hi))
        self.theta_max = float(theta_max)
        m = len(lengths)
        names = tuple(f"{v}{i + 1}" for i in range(m) for v in ("S", "theta", "phi"))
        lower = np.ravel([[lo * L, -theta_max, -np.pi] for L in lengths])
        upper = np.ravel([[hi * L, theta_max, np.pi] for L in lengths])
        periodic = tuple(v == "phi" for _ in range(m) for v in ("S", "theta", "phi"))
        positive = tuple(v == "S" for _ in range(m) for v in ("S", "theta", "phi"))
        super().__init__(name, names, lower, upper, backbone_points_per_section, periodic, positive)

    @property
    def n_sections(self) -> int:
        """Number of sections ``m``."""
        return len(self.section_lengths)

    def section_frames(self, q: Array) -> list[tuple[Array, Array]]:
        """End pose of every section in the base frame, by chaining the sections (seed 000 eq. 5).

        ``p_i = p_{i-1} + R_{i-1} p_rel,i`` and ``q_i = q_{i-1} q_rel,i`` with ``p_rel`` from
        :func:`section_position` and ``q_rel`` from :func:`section_quaternion`.

        Parameters
        ----------
        q : Array
            A CasADi column ``3m x 1`` or a numpy batch ``(..., 3m)`` of
            ``(S_1, theta_1, phi_1, ..., S_m, theta_m, phi_m)``.

        Returns
        -------
        list of (Array, Array)
            ``m`` pairs ``(quaternion, position [m])``: CasADi ``4 x 1`` and ``3 x 1``, or numpy
            ``(..., 4)`` and ``(..., 3)``.

        Raises
        ------
        TypeError
            For a numeric ``q`` that is not numbers.
        ValueError
            For a numeric ``q`` that is not finite, plausible configurations (:meth:`ArmModel.checked_numeric`).
        """
        return self._chain(self.checked_numeric(q), fractions=())[0]

    def frame_at(self, q: Array, section: int, fraction: float = 1.0) -> tuple[Array, Array]:
        """Pose of the backbone frame at ``fraction`` of section ``section``'s arc (from 0), base frame.

        A part ``f S`` of a constant-curvature section bends by ``f theta`` in the same plane
        ``phi``: the frame is the end frame of section ``section - 1`` composed with
        :func:`section_quaternion` ``(f theta, phi)`` at :func:`section_position` ``(f S, f theta, phi)``.

        Parameters
        ----------
        q : Array
            Configuration ``3m`` (CasADi column or numpy batch ``(..., 3m)``).
        section : int
            Section index from 0.
        fraction : float
            Fraction of the section's arc length, in ``(0, 1]``.

        Returns
        -------
        (Array, Array)
            ``(quaternion, position [m])`` in the base frame.

        Raises
        ------
        TypeError
            A ``section`` that is not an integer, a ``fraction`` or numeric ``q`` that is not numbers.
        ValueError
            ``section`` out of range, ``fraction`` outside ``(0, 1]``, or a numeric ``q`` that is not finite,
            plausible configurations.
        """
        if isinstance(section, bool) or not isinstance(section, (int, np.integer)):
            raise TypeError(f"section: expected an integer index from 0, got {type(section).__name__} {section!r}")
        fraction = float(check_numbers(fraction, "fraction"))
        if not 0 <= section < self.n_sections:
            raise ValueError(f"section {section + 1} out of range: {self.name} has {self.n_sections} sections")
        if not 0.0 < fraction <= 1.0:
            raise ValueError(f"fraction must lie in (0, 1], got {fraction:g}")
        q = self.checked_numeric(q)
        S, theta, phi = B.components(q, self.n_config, "q")[3 * section : 3 * section + 3]
        quat = section_quaternion(fraction * theta, phi)
        position = section_position(fraction * S, fraction * theta, phi)
        if section == 0:
            return quat, position
        base_quat, base_position = self._chain(q, fractions=())[0][section - 1]
        return quat_multiply(base_quat, quat), base_position + quat_rotate(base_quat, position, check=False)

    def backbone_points(self, q: ca.SX, points_per_section: int) -> ca.SX:
        """Points at equal arc-length fractions along every section, base point first.

        Parameters
        ----------
        q : casadi.SX
            Configuration ``3m x 1``.
        points_per_section : int
            Points per section; the last of each is the section's end.

        Returns
        -------
        casadi.SX
            ``3 x (1 + m points_per_section)`` [m] in the base frame.
        """
        fractions = np.linspace(0.0, 1.0, points_per_section + 1)[1:]
        return cast(ca.SX, ca.horzcat(ca.DM.zeros(3), *self._chain(q, fractions)[1]))

    def _chain(
        self, q: Array, fractions: Sequence[float] | np.ndarray
    ) -> tuple[list[tuple[Array, Array]], list[Array]]:
        """Section end frames and the points at ``fractions`` of every section."""
        variables = B.components(q, self.n_config)
        quat, pos = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
        frames, points = [], []
        for i in range(self.n_sections):
            S, theta, phi = variables[3 * i : 3 * i + 3]
            points += [pos + quat_rotate(quat, section_position(f * S, f * theta, phi), check=False) for f in fractions]
            pos = pos + quat_rotate(quat, section_position(S, theta, phi), check=False)
            quat = quat_multiply(quat, section_quaternion(theta, phi))
            frames.append((quat, pos))
        return frames, points

    def straight_configuration(self) -> np.ndarray:
        """All sections straight at their nominal lengths: ``(L_1, 0, 0, ..., L_m, 0, 0)``.

        Returns
        -------
        numpy.ndarray
            ``(3m,)``; the tip lies at ``(0, 0, sum L_i)``.
        """
        return np.ravel([[L, 0.0, 0.0] for L in self.section_lengths])

    def describe(self) -> dict[str, Any]:
        """:meth:`ArmModel.describe` plus ``kind``, ``section_lengths``, ``length_range`` and ``theta_max``.

        Returns
        -------
        dict
            JSON-serialisable geometry and bounds (lengths in metres, angles in radians).
        """
        return super().describe() | {
            "kind": "constant_curvature",
            "section_lengths": self.section_lengths.tolist(),
            "length_range": list(self.length_range),
            "theta_max": self.theta_max,
        }
