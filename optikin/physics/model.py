"""An arm of rod segments joined at rigid disks, its loads, and its equations as CasADi Functions.

An arm (:class:`RodArm`) is a chain of :class:`Segment` s, each a
:class:`~optikin.physics.rod.Rod` with its own tendons
(:mod:`~optikin.physics.tendons`, running from the base to the segment's end
disk) and pneumatic chambers (:mod:`~optikin.physics.pneumatic`, inside the
segment). The base of the first segment is clamped at a given pose; each disk is
rigid, massless and of zero thickness, so position and orientation are continuous
there, and the rod's wrench ``n, m`` jumps by the point loads of the actuators that
end (or, for chambers, start) at the disk.

The loads are one vector ``P`` (:data:`LOAD_NAMES`, then one entry per actuator in
the order of :attr:`RodArm.actuator_names`): tip force and couple, a uniform
distributed force [N/m], gravity [m/s^2] and the actuation (tendon tensions [N],
chamber pressures [Pa]). Gravity is a load, not a constant, so continuation can
scale it and derivatives with respect to it are available.

:class:`ArmEquations` writes the equations once as ``SX``: the right-hand side of
the state ``x = (p, q, n, m)`` (13), an RK4 step, the jump at a disk and the tip
residual ``N(L) - F_tip, M(L) - C_tip``. Both solvers
(:mod:`~optikin.physics.shooting`, :mod:`~optikin.physics.collocation`) build on them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, Literal

import casadi as ca
import numpy as np
from pydantic import Field, model_validator

from optikin.algebra import matrix_from_quat, quat_from_pure, quat_multiply
from optikin.checks import check_quaternion
from optikin.errors import InputDataError
from optikin.options import Options
from optikin.physics.pneumatic import Chamber, chamber_offset
from optikin.physics.rod import E3, Rod, Vector3
from optikin.physics.tendons import Tendon, routing, tangent

STATE_SIZE = 13
"""``x = (p (3), q (4), n (3), m (3))``."""
LOAD_NAMES = (
    "tip_force_x",
    "tip_force_y",
    "tip_force_z",
    "tip_couple_x",
    "tip_couple_y",
    "tip_couple_z",
    "distributed_force_x",
    "distributed_force_y",
    "distributed_force_z",
    "gravity_x",
    "gravity_y",
    "gravity_z",
)
"""The first entries of the load vector ``P``; the actuation follows."""


class Segment(Options):
    """One segment of an arm: a rod, the tendons that end at its end disk, the chambers inside it."""

    rod: Rod
    tendons: tuple[Tendon, ...] = Field((), description="tendons from the base to this segment's end disk")
    chambers: tuple[Chamber, ...] = Field((), description="pressurised chambers along this segment")

    @model_validator(mode="after")
    def _chambers_inside(self) -> Segment:
        for i, c in enumerate(self.chambers):
            if c.offset >= self.rod.section_radius:
                raise ValueError(
                    f"chambers.{i}.offset: {c.offset} m is not inside the section radius {self.rod.section_radius} m"
                )
        return self


class RodArm(Options):
    """Segments in series, clamped at the base; tip loads spatially fixed or following the tip frame.

    Raises
    ------
    pydantic.ValidationError
        When a tendon is not strictly inside the section of every segment it runs
        through (naming ``segments.k.tendons.i.offset``), segments have different
        gravity, or the base orientation is not a unit quaternion.
    """

    segments: tuple[Segment, ...] = Field(min_length=1, description="the segments, base first")
    base_position: Vector3 = Field((0.0, 0.0, 0.0), description="clamped base position [m]")
    base_orientation: tuple[float, float, float, float] = Field(
        (1.0, 0.0, 0.0, 0.0), description="clamped base orientation, unit quaternion (w, x, y, z)"
    )
    tip_force_frame: Literal["spatial", "follower"] = Field(
        "spatial", description="tip force fixed in space, or given in the tip frame (follower)"
    )
    tip_couple_frame: Literal["spatial", "follower"] = Field(
        "spatial", description="tip couple fixed in space, or given in the tip frame (follower)"
    )

    @model_validator(mode="after")
    def _consistent(self) -> RodArm:
        check_quaternion(self.base_orientation, name="base_orientation")
        if any(s.rod.gravity != self.segments[0].rod.gravity for s in self.segments):
            raise ValueError("segments: every segment's rod must have the same gravity")
        for k, seg in enumerate(self.segments):
            for i, t in enumerate(seg.tendons):
                for j in range(k + 1):
                    radius = self.segments[j].rod.section_radius
                    if t.offset >= radius:
                        raise ValueError(
                            f"segments.{k}.tendons.{i}.offset: {t.offset} m is not inside the section radius "
                            f"{radius} m of segment {j}"
                        )
        return self

    @classmethod
    def single(cls, rod: Rod, **kwargs) -> RodArm:
        """An arm of one segment: ``RodArm.single(rod, tendons=..., chambers=..., tip_force_frame=...)``."""
        seg = {k: kwargs.pop(k) for k in ("tendons", "chambers") if k in kwargs}
        return cls(segments=(Segment(rod=rod, **seg),), **kwargs)

    @property
    def length(self) -> float:
        """Total length [m]."""
        return float(sum(s.rod.length for s in self.segments))

    @property
    def boundaries(self) -> np.ndarray:
        """Arc length of the base, every disk and the tip [m], ``(n_segments + 1,)``."""
        return np.concatenate([[0.0], np.cumsum([s.rod.length for s in self.segments])])

    @property
    def actuator_names(self) -> tuple[str, ...]:
        """``segments.k.tendons.i`` then ``segments.k.chambers.i`` per segment: the order of the actuation."""
        names: list[str] = []
        for k, seg in enumerate(self.segments):
            names += [f"segments.{k}.tendons.{i}" for i in range(len(seg.tendons))]
            names += [f"segments.{k}.chambers.{i}" for i in range(len(seg.chambers))]
        return tuple(names)

    @property
    def load_names(self) -> tuple[str, ...]:
        """Every entry of the load vector ``P``."""
        return LOAD_NAMES + tuple(f"{n}.{'tension' if '.tendons.' in n else 'pressure'}" for n in self.actuator_names)


class Loads(Options):
    """The loads of one equilibrium.

    ``actuation`` has one entry per actuator of the arm (:attr:`RodArm.actuator_names`):
    tendon tensions [N] (``>= 0``) and chamber gauge pressures [Pa]. ``gravity``
    defaults to the rods'.
    """

    tip_force: Vector3 = Field((0.0, 0.0, 0.0), description="tip force [N]")
    tip_couple: Vector3 = Field((0.0, 0.0, 0.0), description="tip couple [N m]")
    distributed_force: Vector3 = Field((0.0, 0.0, 0.0), description="uniform distributed force [N/m], global frame")
    gravity: Vector3 | None = Field(None, description="gravity [m/s^2]; None: the rods' gravity")
    actuation: tuple[float, ...] = Field((), description="tendon tensions [N] and chamber pressures [Pa]")


def load_vector(arm: RodArm, loads: Loads) -> np.ndarray:
    """The load vector ``P`` of ``loads`` on ``arm`` (:attr:`RodArm.load_names`).

    Raises
    ------
    optikin.errors.InputDataError
        When the actuation does not have one entry per actuator, or a tension is negative (naming it).
    """
    names = arm.actuator_names
    act = np.asarray(loads.actuation, dtype=float)
    if act.shape != (len(names),):
        raise InputDataError(
            f"expected {len(names)} entries ({', '.join(names) or 'no actuators'}), got {act.size}", field="actuation"
        )
    for i, name in enumerate(names):
        if ".tendons." in name and act[i] < 0:
            raise InputDataError(
                f"{name}: tension {act[i]} N is negative (a tendon cannot push)", field=f"actuation.{i}"
            )
    gravity = arm.segments[0].rod.gravity if loads.gravity is None else loads.gravity
    return np.concatenate([loads.tip_force, loads.tip_couple, loads.distributed_force, gravity, act])


@dataclass(frozen=True)
class _Actuator:
    """An actuator as the equations see it: signed tension, its offset, and whether it follows its own path."""

    index: int  # into the actuation part of P
    sign: float  # tension = sign * value * scale: +1 for a tendon, -area for a chamber
    tendon: Tendon | None  # None: a chamber (tangent d3, fixed offset)
    offset: ca.DM | None  # chambers only

    def tension(self, P: ca.SX) -> ca.SX:
        return self.sign * P[len(LOAD_NAMES) + self.index]

    def offset_and_tangent(self, v: ca.SX, u: ca.SX, s: ca.SX) -> tuple[ca.SX, ca.SX]:
        if self.tendon is None:
            assert self.offset is not None
            return ca.SX(self.offset), ca.SX(E3)
        return routing(self.tendon, s)[0], tangent(self.tendon, v, u, s)


def _strains(rod: Rod, R: ca.SX, n: ca.SX, m: ca.SX) -> tuple[ca.SX, ca.SX]:
    """``v, u`` from the constitutive law (``v = v*`` for a Kirchhoff rod)."""
    u = ca.DM(rod.intrinsic_curvature) + (R.T @ m) / ca.DM(rod.K_bt)
    v = ca.SX(E3) if rod.model == "kirchhoff" else ca.DM(E3) + (R.T @ n) / ca.DM(rod.K_se)
    return v, u


class ArmEquations:
    """The equations of a :class:`RodArm` as ``SX`` expressions and CasADi Functions.

    Parameters
    ----------
    arm : RodArm
        The arm.
    """

    def __init__(self, arm: RodArm) -> None:
        self.arm = arm
        self.n_loads = len(arm.load_names)
        self.actuators: list[list[_Actuator]] = []  # active inside segment k
        self.ending: list[list[_Actuator]] = []  # whose point load acts at the end disk of segment k
        self.starting: list[list[_Actuator]] = []  # chambers starting at the base disk of segment k
        index = 0
        tendons_of: list[list[_Actuator]] = []
        chambers_of: list[list[_Actuator]] = []
        for seg in arm.segments:
            tendons_of.append([_Actuator(index + i, 1.0, t, None) for i, t in enumerate(seg.tendons)])
            index += len(seg.tendons)
            chambers_of.append(
                [_Actuator(index + i, -c.area, None, chamber_offset(c)) for i, c in enumerate(seg.chambers)]
            )
            index += len(seg.chambers)
        for k in range(len(arm.segments)):
            passing = [a for j in range(k, len(arm.segments)) for a in tendons_of[j]]
            self.actuators.append(passing + chambers_of[k])
            self.ending.append(tendons_of[k] + chambers_of[k])
            self.starting.append(chambers_of[k])

    # ----------------------------------------------------------------- pieces

    def rhs(self, k: int, s: ca.SX, x: ca.SX, P: ca.SX) -> ca.SX:
        """``dx/ds`` in segment ``k`` (13 x 1).

        Without actuators, ``n' = -f`` and ``m' = -p' x n``. With them, ``u'`` and ``v'``
        solve ``N' + f = 0``, ``M' + p' x N = 0`` (:mod:`~optikin.physics.tendons`):
        the linear system of Rucker & Webster (2011) eqs. 13-16, assembled here by
        differentiating the section wrench in the material frame.
        """
        rod = self.arm.segments[k].rod
        q, n, m = x[3:7], x[7:10], x[10:13]
        R = matrix_from_quat(q, check=False)
        v, u = _strains(rod, R, n, m)
        f = rod.density * rod.A * P[9:12] + P[6:9]
        dp = R @ v
        dq = 0.5 * quat_multiply(q, quat_from_pure(u))
        acts = self.actuators[k]
        if not acts:
            return ca.vertcat(dp, dq, -f, -ca.cross(dp, n))
        kse, kbt = ca.DM(rod.K_se), ca.DM(rod.K_bt)
        vs, us, ss = ca.SX.sym("v", 3), ca.SX.sym("u", 3), ca.SX.sym("s")
        T = ca.SX.zeros(3)  # sum tau t, material frame
        C = ca.SX.zeros(3)  # sum r x tau t
        for a in acts:
            r, t = a.offset_and_tangent(vs, us, ss)
            T += a.tension(P) * t
            C += a.tension(P) * ca.cross(r, t)
        terms = ca.Function(
            "tendon_terms",
            [vs, us, ss, P],
            [
                T,
                C,
                ca.jacobian(T, vs),
                ca.jacobian(T, us),
                ca.jacobian(T, ss),
                ca.jacobian(C, vs),
                ca.jacobian(C, us),
                ca.jacobian(C, ss),
            ],
        )
        T, C, Tv, Tu, Ts, Cv, Cu, Cs = terms(v, u, s, P)
        nb, mb = R.T @ n, R.T @ m
        Nb, Mb = nb + T, mb + C
        rhs_m = -ca.cross(u, Mb) - ca.cross(v, Nb) - Cs
        if rod.model == "kirchhoff":
            du = ca.solve(ca.diag(kbt) + Cu, rhs_m)
            dn = -f - R @ (ca.cross(u, T) + Tu @ du + Ts)
        else:
            rhs_n = -ca.cross(u, Nb) - R.T @ f - Ts
            J = ca.vertcat(ca.horzcat(ca.diag(kse) + Tv, Tu), ca.horzcat(Cv, ca.diag(kbt) + Cu))
            dvu = ca.solve(J, ca.vertcat(rhs_n, rhs_m))
            du = dvu[3:6]
            dn = R @ (ca.cross(u, nb) + kse * dvu[0:3])
        dm = R @ (ca.cross(u, mb) + kbt * du)
        return ca.vertcat(dp, dq, dn, dm)

    def _point_loads(self, acts: list[_Actuator], k: int, s: ca.SX, x: ca.SX, P: ca.SX) -> tuple[ca.SX, ca.SX]:
        """``sum tau R t`` and ``sum (R r) x tau R t`` of ``acts`` at the state ``x`` in segment ``k``."""
        rod = self.arm.segments[k].rod
        R = matrix_from_quat(x[3:7], check=False)
        v, u = _strains(rod, R, x[7:10], x[10:13])
        force, moment = ca.SX.zeros(3), ca.SX.zeros(3)
        for a in acts:
            r, t = a.offset_and_tangent(v, u, s)
            force += a.tension(P) * (R @ t)
            moment += a.tension(P) * (R @ ca.cross(r, t))
        return force, moment

    def junction(self, k: int, x: ca.SX, P: ca.SX) -> ca.SX:
        """The state just after the disk between segments ``k`` and ``k + 1``, from the state just before it.

        The section wrench ``N, M`` is continuous; the actuators ending there stop, the
        chambers of segment ``k + 1`` start (their axis is ``d3`` on both sides).
        """
        s = ca.SX(float(self.arm.boundaries[k + 1]))
        f_end, m_end = self._point_loads(self.ending[k], k, s, x, P)
        f_start, m_start = self._point_loads(self.starting[k + 1], k + 1, s, x, P)
        return ca.vertcat(x[0:7], x[7:10] + f_end - f_start, x[10:13] + m_end - m_start)

    def tip_residual(self, x: ca.SX, P: ca.SX) -> ca.SX:
        """``N(L) - F_tip`` and ``M(L) - C_tip`` (6 x 1, global frame) at the tip state ``x``."""
        k = len(self.arm.segments) - 1
        s = ca.SX(float(self.arm.boundaries[-1]))
        f_end, m_end = self._point_loads(self.ending[k], k, s, x, P)
        R = matrix_from_quat(x[3:7], check=False)
        force = R @ P[0:3] if self.arm.tip_force_frame == "follower" else P[0:3]
        couple = R @ P[3:6] if self.arm.tip_couple_frame == "follower" else P[3:6]
        return ca.vertcat(x[7:10] + f_end - force, x[10:13] + m_end - couple)

    def base_state(self, wrench: Any) -> Any:
        """``x(0)`` from the unknown base wrench ``(n(0), m(0))`` (6), the clamped pose given."""
        pose = ca.DM(list(self.arm.base_position) + list(self.arm.base_orientation))
        return ca.vertcat(pose, wrench)

    # ----------------------------------------------------------------- Functions

    def rhs_function(self, k: int) -> ca.Function:
        """``(s, x, P) -> dx/ds`` in segment ``k``."""
        s, x, P = ca.SX.sym("s"), ca.SX.sym("x", STATE_SIZE), ca.SX.sym("P", self.n_loads)
        return ca.Function(f"cosserat_rhs{k}", [s, x, P], [self.rhs(k, s, x, P)], ["s", "x", "P"], ["dx"])

    def rk4_step(self, k: int, h: float) -> ca.Function:
        """``(x, s, P) -> x(s + h)``: one classical RK4 step in segment ``k``, the quaternion renormalised."""
        s, x, P = ca.SX.sym("s"), ca.SX.sym("x", STATE_SIZE), ca.SX.sym("P", self.n_loads)
        k1 = self.rhs(k, s, x, P)
        k2 = self.rhs(k, s + h / 2, x + h / 2 * k1, P)
        k3 = self.rhs(k, s + h / 2, x + h / 2 * k2, P)
        k4 = self.rhs(k, s + h, x + h * k3, P)
        xn = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        q = xn[3:7] / ca.norm_2(xn[3:7])
        xn = ca.vertcat(xn[0:3], q, xn[7:13])
        return ca.Function(f"cosserat_rk4_{k}", [x, s, P], [xn], ["x", "s", "P"], ["x_next"])

    def junction_function(self, k: int) -> ca.Function:
        """``(x, P) -> x`` across the disk after segment ``k``."""
        x, P = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("P", self.n_loads)
        return ca.Function(f"cosserat_disk{k}", [x, P], [self.junction(k, x, P)], ["x", "P"], ["x_after"])

    @cached_property
    def tip_residual_function(self) -> ca.Function:
        """``(x_tip, P) -> residual`` (6)."""
        x, P = ca.SX.sym("x", STATE_SIZE), ca.SX.sym("P", self.n_loads)
        return ca.Function("cosserat_tip", [x, P], [self.tip_residual(x, P)], ["x", "P"], ["residual"])
