"""Reference equilibria of a clamped Cosserat rod, relaxed by PyElastica.

Each case in :data:`CASES` is a straight rod (length 0.3 m, solid circular section of radius 10 mm,
E = 1 MPa, shear modulus G = E/3, density 1000 kg/m^3) clamped at the origin and loaded by a tip force,
a tip couple and/or gravity. PyElastica (Gazzola et al., "Forward and inverse problems in the mechanics
of soft filaments", R. Soc. open sci. 5:171628, 2018) integrates the damped rod dynamics with its
PositionVerlet stepper and AnalyticalLinearDamper until the nodes stop moving; the relaxed nodes and
directors are written to ``tests/data/pyelastica/<case>_n<elements>.npz``.

As an independent check, every case (all are planar) is also solved as a continuous planar Reissner rod
(the same stiffnesses: shear alpha_c*G*A with PyElastica's alpha_c = 27/28, axial E*A, bending E*I) by a
boundary-value solver, once with the linear law and once with PyElastica's dilatation-scaled law; its nodes
are stored beside PyElastica's as ``continuum_positions`` and ``continuum_positions_pyelastica_law``.

Run ``python tools/pyelastica_reference.py`` (all cases, 50, 100 and 200 elements) or
``python tools/pyelastica_reference.py --cases tip_force_small --elements 50 --out /tmp/ref``.
The file format and the cases are described in ``tests/data/pyelastica/README.md``.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_bvp

LENGTH = 0.3  # m
RADIUS = 0.01  # m
YOUNGS_MODULUS = 1.0e6  # Pa
SHEAR_MODULUS = YOUNGS_MODULUS / 3.0  # Pa, as PyElastica's ``shear_modulus`` argument
DENSITY = 1000.0  # kg/m^3
ALPHA_C = 27.0 / 28.0  # PyElastica's built-in shear correction factor (Kaneko 1975, Poisson ratio 0.5)
GRAVITY = 9.81  # m/s^2

DAMPING = 15.0  # 1/s, AnalyticalLinearDamper(uniform_damping_constant=...): about 2.4x the first bending frequency
RAMP_TIME = 0.2  # s, tip force and tip couple ramp linearly from zero (gravity is applied at once)
COURANT = 0.5  # dt = COURANT * element length / axial wave speed sqrt(E / rho)
CHECK_EVERY = 0.05  # s of simulated time between convergence checks
SPEED_TOL = 1.0e-7  # m/s, max node speed at the end
DRIFT_TOL = 1.0e-8  # m, change of the tip position over the last 10 % of the simulated time
MIN_TIME = 1.0  # s
MAX_TIME = 30.0  # s

DEFAULT_DATA_DIR = Path(__file__).resolve().parent.parent / "tests" / "data" / "pyelastica"


@dataclass(frozen=True)
class Case:
    """One load case.

    Attributes
    ----------
    name : str
        File stem of the case.
    description : str
        One line for humans.
    base_angle_deg : float
        Clamp orientation: the base frame is R_y(base_angle), a rotation about the global +y axis, so the rod
        starts along (sin a, 0, cos a) with first director (cos a, 0, -sin a). 0 deg is straight up +z.
    tip_force : tuple of float
        Dead (fixed, global-frame) force on the last node [N].
    tip_couple_material : tuple of float
        Follower couple on the last element, components in that element's material frame (d1, d2, d3) [N m].
    gravity : tuple of float
        Gravitational acceleration, global frame [m/s^2], acting on PyElastica's lumped nodal masses.
    """

    name: str
    description: str
    base_angle_deg: float = 0.0
    tip_force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tip_couple_material: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0)


CASES: dict[str, Case] = {
    c.name: c
    for c in [
        Case("tip_force_small", "tip force 0.01 N along +x, no gravity", tip_force=(0.01, 0.0, 0.0)),
        Case("tip_force_large", "tip force 0.05 N along +x, no gravity (large deflection)", tip_force=(0.05, 0.0, 0.0)),
        Case(
            "tip_couple_x",
            "follower tip couple 1e-4 N m about the material d1 (x) axis, no gravity",
            tip_couple_material=(1.0e-4, 0.0, 0.0),
        ),
        Case(
            "tip_force_couple_y",
            "tip force 0.01 N along +x plus follower tip couple 5e-5 N m about the material d2 (y) axis",
            tip_force=(0.01, 0.0, 0.0),
            tip_couple_material=(0.0, 5.0e-5, 0.0),
        ),
        Case(
            "gravity_horizontal",
            "clamped along +x, sagging under gravity (0, 0, -9.81)",
            base_angle_deg=90.0,
            gravity=(0.0, 0.0, -GRAVITY),
        ),
        Case(
            "gravity_45deg_tip_force",
            "clamped at 45 deg between +x and +z, gravity (0, 0, -9.81) plus tip force 0.005 N along -z",
            base_angle_deg=45.0,
            tip_force=(0.0, 0.0, -0.005),
            gravity=(0.0, 0.0, -GRAVITY),
        ),
    ]
}


def base_frame(case: Case) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rod direction (d3) and normal (d1) at the clamp, global frame.

    Parameters
    ----------
    case : Case
        The load case.

    Returns
    -------
    direction, normal : ndarray, shape (3,)
        Unit tangent and first director of the straight rest configuration.
    """
    a = np.deg2rad(case.base_angle_deg)
    return np.array([np.sin(a), 0.0, np.cos(a)]), np.array([np.cos(a), 0.0, -np.sin(a)])


def time_step(n_elements: int, courant: float = COURANT) -> float:
    """Time step [s] for ``n_elements`` elements: ``courant`` times the axial wave's transit time of one element."""
    return courant * (LENGTH / n_elements) / np.sqrt(YOUNGS_MODULUS / DENSITY)


def relax(case: Case, n_elements: int, dt: float, n_steps: int | None = None) -> dict[str, Any]:
    """Relax one case with PyElastica's damped PositionVerlet dynamics.

    Parameters
    ----------
    case : Case
        The load case.
    n_elements : int
        Number of rod elements (n); the rod has n + 1 nodes.
    dt : float
        Time step [s].
    n_steps : int, optional
        Run exactly this many steps instead of stopping on the convergence test (used to reproduce a
        shipped file).

    Returns
    -------
    dict
        ``positions`` (n+1, 3) [m], ``directors`` (n, 3, 3) (row i of ``directors[k]`` is director d_i of
        element k in global components), the loads, and the run's statistics (steps, simulated time, wall
        and process CPU time of the relaxation after numba's compilation, the machine's 1-minute load average at its
        start, final max node speed, tip drift over the last 10 % of the simulated time).
    """
    import elastica as ea

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    class TipFollowerCouple(ea.NoForces):
        """Couple on the last element, in its material frame, ramped linearly over ``ramp_up_time``."""

        def __init__(self, couple: NDArray[np.float64], ramp_up_time: float) -> None:
            super().__init__()
            self.couple = couple
            self.ramp_up_time = ramp_up_time

        def apply_torques(self, system: Any, time: np.float64 = np.float64(0.0)) -> None:
            system.external_torques[:, -1] += min(1.0, float(time) / self.ramp_up_time) * self.couple

    def build() -> tuple[Any, Any]:
        sim = Simulator()
        direction, normal = base_frame(case)
        rod = ea.CosseratRod.straight_rod(
            n_elements,
            np.zeros(3),
            direction,
            normal,
            LENGTH,
            RADIUS,
            DENSITY,
            youngs_modulus=YOUNGS_MODULUS,
            shear_modulus=SHEAR_MODULUS,
        )
        sim.append(rod)
        sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
        if any(case.tip_force):
            sim.add_forcing_to(rod).using(
                ea.EndpointForces, np.zeros(3), np.array(case.tip_force), ramp_up_time=RAMP_TIME
            )
        if any(case.tip_couple_material):
            sim.add_forcing_to(rod).using(TipFollowerCouple, np.array(case.tip_couple_material), ramp_up_time=RAMP_TIME)
        if any(case.gravity):
            sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array(case.gravity))
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=DAMPING, time_step=dt)
        sim.finalize()
        return sim, rod

    stepper = ea.PositionVerlet()
    warm_sim, _ = build()  # numba compiles (or loads its cache) here, outside the timed run
    t_warm = 0.0
    for _ in range(3):
        t_warm = stepper.step(warm_sim, t_warm, dt)

    sim, rod = build()
    per_check = max(1, int(round(CHECK_EVERY / dt)))
    t = 0.0
    steps = 0
    tips = [rod.position_collection[:, -1].copy()]
    load_average = os.getloadavg()[0]
    start, start_cpu = time.perf_counter(), time.process_time()
    while True:
        for _ in range(per_check if n_steps is None else min(per_check, n_steps - steps)):
            t = stepper.step(sim, t, dt)
            steps += 1
        tips.append(rod.position_collection[:, -1].copy())
        if n_steps is not None:
            if steps >= n_steps:
                break
            continue
        speed = float(np.linalg.norm(rod.velocity_collection, axis=0).max())
        drift = float(np.linalg.norm(tips[-1] - tips[int(round(0.9 * (len(tips) - 1)))]))
        if t >= MIN_TIME and speed < SPEED_TOL and drift < DRIFT_TOL:
            break
        if t >= MAX_TIME:
            raise RuntimeError(f"{case.name}: not converged after {t:.1f} s (speed {speed:.2e}, drift {drift:.2e})")
    wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu

    k_window = int(round(0.9 * (len(tips) - 1)))
    return {
        "positions": rod.position_collection.T.copy(),
        "directors": np.transpose(rod.director_collection, (2, 0, 1)).copy(),
        "tip_force": np.array(case.tip_force),
        "tip_couple_material": np.array(case.tip_couple_material),
        "gravity": np.array(case.gravity),
        "base_direction": base_frame(case)[0],
        "base_normal": base_frame(case)[1],
        "n_elements": n_elements,
        "length": LENGTH,
        "radius": RADIUS,
        "youngs_modulus": YOUNGS_MODULUS,
        "shear_modulus": SHEAR_MODULUS,
        "density": DENSITY,
        "dt": dt,
        "steps": steps,
        "simulated_time": t,
        "wall_time": wall,
        "cpu_time": cpu,
        "load_average_1min": load_average,
        "damping_constant": DAMPING,
        "ramp_time": RAMP_TIME,
        "max_node_speed": float(np.linalg.norm(rod.velocity_collection, axis=0).max()),
        "tip_drift_last_10pct": float(np.linalg.norm(tips[-1] - tips[k_window])),
        "drift_window": t * (len(tips) - 1 - k_window) / (len(tips) - 1),
        "pyelastica_version": importlib.metadata.version("pyelastica"),
    }


def continuum_positions(case: Case, s_nodes: NDArray[np.float64], pyelastica_law: bool = False) -> NDArray[np.float64]:
    """Planar continuous Cosserat (Reissner) rod equilibrium of a case, for checking PyElastica's answer.

    All cases bend in one plane. The rod is solved in the (a, z) plane, a being the lateral axis (global x,
    or -y for a couple about d1), with tangent angle theta about the plane's normal; unknowns a, z, theta,
    internal force (n_a, n_z) [N] and bending moment m [N m], all functions of the reference arclength s:
    ``r' = nu1 d1 + nu3 d3``, ``theta' = m / (E I)``, ``n' = -rho A g``, ``m' = -(r' x n)``, with the linear law
    ``nu1 = n.d1 / (alpha_c G A)``, ``nu3 = 1 + n.d3 / (E A)``; clamp r(0) = 0, theta(0) = base angle; free end
    n(L) = tip force, m(L) = tip couple. With ``pyelastica_law`` the stresses carry PyElastica's dilatation
    factors (Gazzola et al. 2018, section 2: the section shrinks as the rod stretches): ``n = Q^T S (nu - e3) / e`` and
    ``m = B kappa / e^3`` with the dilatation ``e = |r'|``.

    Parameters
    ----------
    case : Case
        The load case.
    s_nodes : ndarray, shape (m,)
        Reference arclengths at which to report the centreline [m].
    pyelastica_law : bool
        Use PyElastica's dilatation-scaled constitutive law instead of the linear one.

    Returns
    -------
    ndarray, shape (m, 3)
        Centreline positions, global frame [m].
    """
    area = np.pi * RADIUS**2
    ei = YOUNGS_MODULUS * area**2 / (4.0 * np.pi)
    ea_, ga = YOUNGS_MODULUS * area, ALPHA_C * SHEAR_MODULUS * area
    about_d1 = case.tip_couple_material[0] != 0.0
    if about_d1:  # bending about d1 = +x: lateral axis a = -y, plane normal (z x a) = +x
        force = (-case.tip_force[1], case.tip_force[2])
        couple, q = case.tip_couple_material[0], (-case.gravity[1], case.gravity[2])
    else:  # bending about d2 = +y: lateral axis a = +x
        force = (case.tip_force[0], case.tip_force[2])
        couple, q = case.tip_couple_material[1], (case.gravity[0], case.gravity[2])
    f_dist = DENSITY * area * np.array(q)
    theta0 = np.deg2rad(case.base_angle_deg)

    def rhs(_s: NDArray[np.float64], y: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
        _, _, th, na, nz, m = y
        d3 = np.array([np.sin(th), np.cos(th)])
        d1 = np.array([np.cos(th), -np.sin(th)])
        n1, n3 = na * d1[0] + nz * d1[1], na * d3[0] + nz * d3[1]
        e = np.ones_like(th)
        for _ in range(6 if pyelastica_law else 1):  # fixed point on the dilatation, |e - 1| ~ 1e-3
            nu1, nu3 = e * n1 / ga, 1.0 + e * n3 / ea_
            e = np.hypot(nu1, nu3) if pyelastica_law else e
        ra, rz = nu1 * d1 + nu3 * d3
        zero = np.zeros_like(th)
        return np.array(
            [ra, rz, m * e**3 / ei, zero - scale * f_dist[0], zero - scale * f_dist[1], -(rz * na - ra * nz)]
        )

    def bc(y0: NDArray[np.float64], y1: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
        return np.array(
            [y0[0], y0[1], y0[2] - theta0, y1[3] - scale * force[0], y1[4] - scale * force[1], y1[5] - scale * couple]
        )

    s = np.linspace(0.0, LENGTH, 201)
    y = np.zeros((6, s.size))
    y[0], y[1], y[2] = s * np.sin(theta0), s * np.cos(theta0), theta0
    for scale in np.linspace(0.05, 1.0, 20):  # load continuation from the straight rod
        sol = solve_bvp(lambda x, yy: rhs(x, yy, scale), lambda a, b: bc(a, b, scale), s, y, tol=1e-8, max_nodes=100000)
        if not sol.success:
            raise RuntimeError(f"{case.name}: continuum BVP failed at load scale {scale:.2f}: {sol.message}")
        s, y = sol.x, sol.y
    a, z = sol.sol(s_nodes)[:2]
    if about_d1:
        return np.stack([np.zeros_like(a), -a, z], axis=1)
    return np.stack([a, np.zeros_like(a), z], axis=1)


def write_case(result: dict[str, Any], case: Case, out_dir: Path) -> Path:
    """Write one relaxed case as ``<case>_n<elements>.npz``.

    Parameters
    ----------
    result : dict
        Output of :func:`relax`.
    case : Case
        The load case.
    out_dir : Path
        Destination folder (created if missing).

    Returns
    -------
    Path
        The written file.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{case.name}_n{result['n_elements']}.npz"
    s_nodes = np.linspace(0.0, LENGTH, result["n_elements"] + 1)
    np.savez_compressed(
        path,
        case=case.name,
        description=case.description,
        base_angle_deg=case.base_angle_deg,
        continuum_positions=continuum_positions(case, s_nodes),
        continuum_positions_pyelastica_law=continuum_positions(case, s_nodes, pyelastica_law=True),
        **result,
    )
    return path


def main(argv: list[str] | None = None) -> None:
    """Relax the requested cases and print a markdown summary table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--elements", nargs="+", type=int, default=[50, 100, 200])
    parser.add_argument("--courant", type=float, default=COURANT, help="dt = courant * element length / sqrt(E / rho)")
    parser.add_argument("--out", type=Path, default=DEFAULT_DATA_DIR)
    args = parser.parse_args(argv)
    print(
        "| case | n | dt [s] | steps | sim. time [s] | wall [s] | CPU [s] | max speed [m/s] | tip drift last 10% [m] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for n in args.elements:
        for name in args.cases:
            case = CASES[name]
            dt = time_step(n, args.courant)
            r = relax(case, n, dt)
            write_case(r, case, args.out)
            print(
                f"| {name} | {n} | {dt:.3g} | {r['steps']} | {r['simulated_time']:.2f} | {r['wall_time']:.2f} "
                f"| {r['cpu_time']:.2f} | {r['max_node_speed']:.1e} | {r['tip_drift_last_10pct']:.1e} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
