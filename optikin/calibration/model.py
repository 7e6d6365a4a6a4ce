"""The measurement model of a calibration: marker positions of a constant-curvature arm as CasADi functions.

A section of a constant-curvature (CC) arm (:mod:`optikin.arms.constant_curvature`,
Seleem et al. 2020 section II, the convention of Webster & Jones 2010) with arc
length ``S``, bending angle ``theta`` and bending-plane angle ``phi`` rotates by
``R = Rz(phi) Ry(theta) Rz(-phi)`` and ends at
``S [cos(phi) (1 - cos theta)/theta, sin(phi) (1 - cos theta)/theta, sin(theta)/theta]``.

A calibration fits every posture's configuration, so it writes a section in its
*bending vector* ``(u, v) = theta (cos phi, sin phi)`` instead: with
``theta^2 = u^2 + v^2``

    R = exp([w]x),  w = (-v, u, 0)          (Rodrigues: I + sinc(theta) [w]x + (1 - cos theta)/theta^2 [w]x^2)
    p = S [u c(theta^2), v c(theta^2), sinc(theta)],   c = (1 - cos theta)/theta^2 = sinc(theta/2)^2 / 2,

which are the same pose (tested against the arm) and, unlike ``(theta, phi)``, smooth
and well conditioned through the straight section, where ``phi`` is undefined.

The arm sits in the measurement frame (the motion-capture frame) at a base pose
``(p0, R0)``, ``R0 = R_ref exp([omega]x)``: ``omega`` is a rotation vector in the
base frame about the reference orientation ``R_ref`` fixed at the start of the fit,
so ``omega_z`` is the rotation about the base axis (*yaw*). A marker on the disk at
the end of section ``s`` sits at ``p_s + R_s d`` with ``d`` its offset in that disk's
frame.

Parameters shared by every posture, in this order (:class:`Layout`): the section
lengths ``L`` (m; none when the arm is extensible, whose lengths are per posture),
``p0`` (3), ``omega`` (3) and the marker offsets (3 per marker). Per posture:
``(u_1, v_1, ..., u_m, v_m)`` and, for an extensible arm, ``(S_1, ..., S_m)``.

Where actuator readings ``a`` (``n_a`` channels, e.g. tendon lengths) come with each
posture, the bending vectors may instead be a linear map of them shared by every posture,
``(u_1, v_1, ..., u_m, v_m) = K (a - a_ref) + k0`` (``K`` row-major and ``k0`` appended to
the shared parameters): there are then no per-posture unknowns and every posture is
predicted from its readings. For a tendon of section ``i`` at radius ``r`` and angle
``alpha`` the length change is exactly linear in the bending vectors of the sections it
runs through, ``-r sum_j (u_j cos alpha + v_j sin alpha)`` (Webster & Jones 2010 eq. 20),
so a linear map is exact for tendons when there are at least ``2 m`` independent ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from optikin.algebra import backend as B
from optikin.algebra.rotation_vector import matrix_from_rotation_vector
from optikin.batch import batch_evaluate


def section_pose(S: ca.SX, u: ca.SX, v: ca.SX) -> tuple[ca.SX, ca.SX]:
    """End pose ``(R (3 x 3), p (3 x 1) [m])`` of one CC section relative to its base, from its bending vector.

    Parameters
    ----------
    S : casadi.SX
        Arc length [m].
    u, v : casadi.SX
        Bending vector ``theta (cos phi, sin phi)`` [rad] (module docstring).

    Returns
    -------
    tuple of casadi.SX
        The rotation ``Rz(phi) Ry(theta) Rz(-phi)`` and the tip position of seed 000 eq. (1).
    """
    t2 = u * u + v * v
    half = B.sinc_of_square(t2 / 4.0)
    c = 0.5 * half * half
    p = S * ca.vertcat(u * c, v * c, B.sinc_of_square(t2))
    return matrix_from_rotation_vector(ca.vertcat(-v, u, 0)), p


@dataclass(frozen=True)
class Layout:
    """Where each quantity sits in the shared vector ``beta`` and the per-posture vector ``x``.

    Attributes
    ----------
    n_sections : int
        Sections ``m``.
    marker_sections : tuple of int
        For each marker, the 1-based section whose end disk carries it.
    extensible : bool
        Per-posture section lengths (no shared ``L``).
    n_actuators : int
        Actuator channels of the linear map to the bending vectors (0: the bending vectors are
        per-posture unknowns).
    """

    n_sections: int
    marker_sections: tuple[int, ...]
    extensible: bool = False
    n_actuators: int = 0

    @property
    def actuated(self) -> bool:
        return self.n_actuators > 0

    @property
    def n_markers(self) -> int:
        return len(self.marker_sections)

    @property
    def n_x(self) -> int:
        """Per-posture variables: ``2 m`` bending components (none with an actuator map), ``+ m`` lengths when
        extensible."""
        return (0 if self.actuated else 2 * self.n_sections) + (self.n_sections if self.extensible else 0)

    @property
    def lengths(self) -> slice:
        return slice(0, 0 if self.extensible else self.n_sections)

    @property
    def position(self) -> slice:
        start = self.lengths.stop
        return slice(start, start + 3)

    @property
    def rotation(self) -> slice:
        start = self.position.stop
        return slice(start, start + 3)

    @property
    def offsets(self) -> slice:
        start = self.rotation.stop
        return slice(start, start + 3 * self.n_markers)

    @property
    def actuator_map(self) -> slice:
        """``K`` (``2 m x n_a``, row-major) then ``k0`` (``2 m``)."""
        start = self.offsets.stop
        return slice(start, start + (2 * self.n_sections * (self.n_actuators + 1) if self.actuated else 0))

    @property
    def n_beta(self) -> int:
        return self.actuator_map.stop

    def beta_names(self) -> list[str]:
        """One name per shared parameter (``L1``, ``base_x``, ``base_rx``, ``m1_dx``, ...)."""
        names = [] if self.extensible else [f"L{i + 1}" for i in range(self.n_sections)]
        names += ["base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz"]
        names += [f"marker{j + 1}_d{a}" for j in range(self.n_markers) for a in "xyz"]
        if self.actuated:
            rows = [f"{c}{i + 1}" for i in range(self.n_sections) for c in ("u", "v")]
            names += [f"map_{row}_a{j + 1}" for row in rows for j in range(self.n_actuators)]
            names += [f"map_{row}_0" for row in rows]
        return names

    def x_names(self) -> list[str]:
        names = [] if self.actuated else [f"{c}{i + 1}" for i in range(self.n_sections) for c in ("u", "v")]
        if self.extensible:
            names += [f"S{i + 1}" for i in range(self.n_sections)]
        return names


class MarkerModel:
    """Marker positions ``(3 M)`` of one posture as a CasADi function of ``(x, beta, R_ref)``, and its Jacobians.

    Parameters
    ----------
    layout : Layout
        The arrangement of sections, markers and parameters.
    """

    def __init__(self, layout: Layout) -> None:
        if any(not 1 <= s <= layout.n_sections for s in layout.marker_sections):
            raise ValueError(f"marker sections must lie in 1..{layout.n_sections}, got {layout.marker_sections}")
        self.layout = layout

    @cached_property
    def _symbols(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX, ca.SX]:
        lay = self.layout
        x = ca.SX.sym("x", lay.n_x)
        beta = ca.SX.sym("beta", lay.n_beta)
        ref = ca.SX.sym("R_ref", 3, 3)
        a = ca.SX.sym("a", lay.n_actuators)
        m = lay.n_sections
        if lay.actuated:
            coefficients = beta[lay.actuator_map]
            K = ca.reshape(coefficients[: 2 * m * lay.n_actuators], lay.n_actuators, 2 * m).T
            bending = K @ a + coefficients[2 * m * lay.n_actuators :]
            lengths = x[0:m] if lay.extensible else beta[lay.lengths]
        else:
            bending = x[0 : 2 * m]
            lengths = x[2 * m : 3 * m] if lay.extensible else beta[lay.lengths]
        R = ref @ matrix_from_rotation_vector(beta[lay.rotation])
        p = beta[lay.position]
        ends = []
        for i in range(m):
            Ri, pi = section_pose(lengths[i], bending[2 * i], bending[2 * i + 1])
            p = p + R @ pi
            R = R @ Ri
            ends.append((R, p))
        offsets = beta[lay.offsets]
        markers = [
            ends[s - 1][1] + ends[s - 1][0] @ offsets[3 * j : 3 * j + 3] for j, s in enumerate(lay.marker_sections)
        ]
        return x, beta, ref, a, ca.vertcat(*markers)

    def _stacked(self, jacobians: bool) -> ca.Function:
        """One input ``z = (x, beta, a, vec R_ref)``, one dense output ``(markers, vec J_x, vec J_beta)``: the
        form :func:`optikin.batch.batch_evaluate` runs over a batch without copies."""
        x, beta, ref, a, out = self._symbols
        z = ca.vertcat(x, beta, a, ca.vec(ref))
        parts = [out]
        if jacobians:
            parts += [ca.vec(ca.densify(ca.jacobian(out, x))), ca.vec(ca.densify(ca.jacobian(out, beta)))]
        name = "calibration_jacobians" if jacobians else "calibration_positions"
        return ca.Function(name, [z], [ca.densify(ca.vertcat(*parts))], ["z"], ["out"], {"cse": True})

    @cached_property
    def stacked_jacobians(self) -> ca.Function:
        """``z -> (markers, vec d markers/dx, vec d markers/d beta)`` (column-major ``vec``)."""
        return self._stacked(True)

    @cached_property
    def stacked_positions(self) -> ca.Function:
        """``z -> markers``."""
        return self._stacked(False)

    def evaluate(
        self,
        X: np.ndarray,
        beta: np.ndarray,
        ref: np.ndarray,
        jacobians: bool = True,
        actuators: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Markers and Jacobians of ``N`` postures in one batched call.

        Parameters
        ----------
        X : numpy.ndarray
            ``(N, n_x)`` per-posture variables.
        beta : numpy.ndarray
            ``(n_beta,)`` shared parameters.
        ref : numpy.ndarray
            ``(3, 3)`` reference base orientation.
        jacobians : bool
            Whether to compute the Jacobians.
        actuators : numpy.ndarray, optional
            ``(N, n_a)`` actuator readings minus their reference, for a layout with an actuator map.

        Returns
        -------
        tuple
            ``markers (N, 3M)``, and ``J_x (N, 3M, n_x)``, ``J_beta (N, 3M, n_beta)`` (None without jacobians).
        """
        N, lay = len(X), self.layout
        na = lay.n_actuators
        Z = np.empty((N, lay.n_x + lay.n_beta + na + 9))
        Z[:, : lay.n_x] = X
        Z[:, lay.n_x : lay.n_x + lay.n_beta] = beta
        if na:
            if actuators is None or np.shape(actuators) != (N, na):
                raise ValueError(f"the actuator map needs readings of shape ({N}, {na})")
            Z[:, lay.n_x + lay.n_beta : lay.n_x + lay.n_beta + na] = actuators
        Z[:, lay.n_x + lay.n_beta + na :] = np.asarray(ref, dtype=float).ravel(order="F")
        f = self.stacked_jacobians if jacobians else self.stacked_positions
        out = batch_evaluate(f, Z)[:, :, 0]
        k = 3 * lay.n_markers
        markers = out[:, :k]
        if not jacobians:
            return markers, None, None
        nx = k * lay.n_x
        Jx = out[:, k : k + nx].reshape(N, lay.n_x, k).transpose(0, 2, 1)
        Jb = out[:, k + nx :].reshape(N, lay.n_beta, k).transpose(0, 2, 1)
        return markers, Jx, Jb
