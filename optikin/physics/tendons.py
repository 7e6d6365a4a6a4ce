"""Tendons routed along a rod: tension -> distributed and point loads on the backbone.

Follows Rucker & Webster, "Statics and Dynamics of Continuum Robots With General
Tendon Routing and External Loading", IEEE T-RO 27(6), 2011, section III, in the
form where the tendon loads are external loads on the rod. A frictionless tendon of
tension ``tau`` (uniform along it) runs at the offset ``r(s)`` from the backbone, in
the material frame, so its path is ``p_t = p + R r`` with the unit tangent

    t = R w / |w|,    w = v + u x r + r'              (Rucker & Webster eq. 9).

The tendon loads the rod with the distributed force ``f_t = tau t'`` and moment
``l_t = (R r) x f_t`` along its path, and with the point force ``-tau t`` and moment
``(R r) x (-tau t)`` where it terminates (their eqs. 10-12 and 17). Because ``f_t`` is
the derivative of ``tau t``, the section wrench carried by rod and tendons together,

    N = n + tau t,    M = m + (R r) x tau t,

obeys the rod equations with the external loads only, ``N' + f = 0``,
``M' + p' x N + l = 0``. :mod:`optikin.physics.model` integrates ``n, m`` and
obtains ``u', v'`` from these two equations through the constitutive law (a 6 x 6
linear system, 3 x 3 for a Kirchhoff rod: Rucker & Webster's coupled model).

Assumptions: the tendon is frictionless, inextensible in its effect (only its
tension matters), in continuous contact with its routing (its path is ``p + R r``
at every ``s``), runs from the base (``s = 0``, where it leaves to its actuator) to the
end disk of the segment it belongs to, and passes through intermediate disks
without a kink (the point force a disk would add where the strains jump is
neglected; with straight routing, no torsion and no shear there is none).

For a straight routing at offset ``r`` on a straight-at-rest rod, with no other
load, the equilibrium is a circular arc of curvature ``tau r / (E I)`` carrying the
axial compression ``tau`` (the tendon tangent stays parallel to the backbone's).
"""

from __future__ import annotations

import casadi as ca
from pydantic import Field

from optikin.options import Options


class Tendon(Options):
    """A tendon at a constant distance from the backbone, straight or helical.

    Its position in the cross-section at arc length ``s`` is
    ``offset (cos a, sin a, 0)`` in the material frame with ``a = angle + helix_rate s``
    (``helix_rate = 0``: straight, parallel to the backbone).
    """

    offset: float = Field(gt=0, description="distance from the backbone [m], inside the section radius")
    angle: float = Field(0.0, description="angle of the routing in the cross-section at s = 0, from d1 [rad]")
    helix_rate: float = Field(0.0, description="turn of the routing per unit arc length [rad/m]; 0 = straight")


def routing(tendon: Tendon, s: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Offset ``r(s)`` of a tendon in the material frame and its first two derivatives.

    Parameters
    ----------
    tendon : Tendon
        The routing.
    s : casadi.SX
        Arc length [m] (scalar).

    Returns
    -------
    tuple of casadi.SX
        ``(r, r', r'')``, each ``3 x 1`` [m, -, 1/m].
    """
    a = tendon.angle + tendon.helix_rate * s
    w = tendon.helix_rate
    c, sn = ca.cos(a), ca.sin(a)
    r = tendon.offset * ca.vertcat(c, sn, 0)
    dr = tendon.offset * w * ca.vertcat(-sn, c, 0)
    ddr = -tendon.offset * w * w * ca.vertcat(c, sn, 0)
    return r, dr, ddr


def tangent(tendon: Tendon, v: ca.SX, u: ca.SX, s: ca.SX) -> ca.SX:
    """Unit tangent of the tendon path in the material frame, ``w / |w|`` with ``w = v + u x r + r'``.

    Parameters
    ----------
    tendon : Tendon
        The routing.
    v, u : casadi.SX
        Backbone strains at ``s`` (``3 x 1`` each, material frame).
    s : casadi.SX
        Arc length [m].

    Returns
    -------
    casadi.SX
        ``3 x 1``.
    """
    r, dr, _ = routing(tendon, s)
    w = v + ca.cross(u, r) + dr
    return w / ca.norm_2(w)
