"""Reference equilibria of a two-segment tendon robot, computed by the C++ code of tdcr-modeling.

tdcr-modeling (https://github.com/SvenLilge/tdcr-modeling, MIT licence) is the reference implementation of
Rao, Peyron, Lilge and Burgner-Kahrs, "How to model tendon-driven continuum robots and benchmark modelling
performance", Frontiers in Robotics and AI 7:630245, 2021 (doi 10.3389/frobt.2020.630245). Its class
``CosseratRodModel`` (``c++/src/cosseratrodmodel.cpp``) solves the Cosserat rod with tendon loads of Rucker &
Webster (IEEE T-RO 27(6), 2011): a shear-extensible backbone, ``Kse = diag(GA, GA, EA)``,
``Kbt = diag(EI, EI, 2GI)`` with ``G = E / 2.6``, straight tendons at a constant offset, three per segment, that
end at the segment's last disk with a point force and moment; shooting on ``(v(0), u(0))`` with GSL's
Levenberg-Marquardt, the ODE integrated by GSL's adaptive RKF45 from disk to disk.

This script

1. extracts ``c++/`` of tdcr-modeling at :data:`COMMIT` from a git repository (``--source``: a clone, bare or not,
   or a URL to clone),
2. compiles ``src/cosseratrodmodel.cpp`` unmodified with a small driver (:data:`DRIVER`, our code: it only sets
   the parameters, calls ``CosseratRodModel::forwardKinematics`` from the straight rod and prints the disk frames;
   where that solve fails, as it does on the larger cases, the loads are ramped from zero in 10 steps, each solve
   started from the last solution), and a second time
   with the integrator's error control tightened from ``(abs 1e-6, rel 1e-3)`` to ``(1e-12, 1e-12)`` (the only
   change, a text substitution) to measure how far the published setting is from the converged ODE solution,
3. runs every case of :data:`CASES` with both builds and writes ``tests/data/tdcr/<case>.json``,
4. runs the MATLAB implementation of the same model, ``matlab/Models/VC/VC_solver.m`` (ode45 and fsolve), in GNU
   Octave as its ``matlab/main.m`` does, on the robot of ``matlab/Parameters/tdcr_2segments.m``, for every case of
   :data:`MATLAB_CASES` (:data:`MATLAB_DRIVER` sets the tensions and the tip force), unmodified and with ode45's
   tolerances tightened from 1e-6 to 1e-10, and writes ``tests/data/tdcr/matlab_vc_<case>.json``.

Requires g++, the Eigen 3 headers, GSL and Octave (Debian: ``apt-get install g++ libeigen3-dev libgsl-dev
octave``; about five minutes, mostly Octave). Run
``python tools/tdcr_reference.py --source https://github.com/SvenLilge/tdcr-modeling`` (or a local clone);
``--out DIR`` writes elsewhere, ``--only cpp`` or ``--only matlab`` runs one of the two. The file format is
described in ``tests/data/tdcr/README.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

COMMIT = "379d34a68c47d95629eb59e8d8ad9965f66947c0"
"""tdcr-modeling, 30 January 2023 (the head of its default branch)."""

DEFAULT_SOURCE = "https://github.com/SvenLilge/tdcr-modeling"
DEFAULT_OUT = Path(__file__).resolve().parent.parent / "tests" / "data" / "tdcr"
PUBLISHED_CONTROL = "gsl_odeiv2_control_y_new (1e-6, 1e-3)"
TIGHT_CONTROL = "gsl_odeiv2_control_y_new (1e-12, 1e-12)"
PUBLISHED_ODESET = "odeset('AbsTol',1e-6,'RelTol',1e-6,'InitialStep',0.005)"
TIGHT_ODESET = "odeset('AbsTol',1e-10,'RelTol',1e-10,'InitialStep',0.005)"

DRIVER = r"""
#include "cosseratrodmodel.h"
#include <cstdio>
#include <iostream>
#include <string>

#define RAMP 10

// One case per line of stdin:
// name L1 L2 E disks1 disks2 pitch1 pitch2 ro q1..q6 fx fy fz lx ly lz
int main()
{
    std::string name;
    while (std::cin >> name)
    {
        std::array<double, 2> length, pitch;
        std::array<int, 2> disks;
        double E, ro;
        Eigen::MatrixXd q(6, 1);
        Eigen::Vector3d f, l;
        std::cin >> length[0] >> length[1] >> E >> disks[0] >> disks[1] >> pitch[0] >> pitch[1] >> ro;
        for (int i = 0; i < 6; i++) std::cin >> q(i, 0);
        for (int i = 0; i < 3; i++) std::cin >> f(i);
        for (int i = 0; i < 3; i++) std::cin >> l(i);
        // The routing of tdcr-modeling's default robot: 90, -30 and 210 degrees in each segment.
        std::vector<Eigen::Vector3d> routing;
        for (int k = 0; k < 2; k++)
        {
            routing.push_back(Eigen::Vector3d(0, pitch[k], 0));
            routing.push_back(Eigen::Vector3d(pitch[k] * std::cos(-M_PI / 6), pitch[k] * std::sin(-M_PI / 6), 0));
            routing.push_back(Eigen::Vector3d(pitch[k] * std::cos(7 * M_PI / 6), pitch[k] * std::sin(7 * M_PI / 6), 0));
        }
        CosseratRodModel model;
        model.setRobotParameters(length, E, routing, disks, pitch, ro);
        // From the straight rod first, as tdcr-modeling does. Where its Levenberg-Marquardt fails from there, the
        // loads ramp from zero in RAMP equal steps, each solve started from the last solution through
        // setDefaultInitValues. Entries below 1e-12 of that start are set to zero: GSL's forward-difference
        // Jacobian steps by sqrt(eps) |x_j|, which for a start like 1e-33 is no step at all.
        Eigen::MatrixXd frames;
        int ramp = 0;
        bool ok = model.forwardKinematics(frames, q, f, l);
        if (!ok)
        {
            ramp = RAMP;
            for (int k = 1; k <= RAMP; k++)
            {
                double a = double(k) / RAMP;
                ok = model.forwardKinematics(frames, a * q, a * f, a * l);
                Eigen::MatrixXd start = model.getFinalInitValues();
                for (int i = 0; i < 6; i++)
                    if (std::abs(start(0, i)) < 1e-12) start(0, i) = 0.0;
                model.setDefaultInitValues(start);
            }
        }
        Eigen::MatrixXd init = model.getFinalInitValues();
        Eigen::MatrixXd residual;
        model.get_res(residual, init.transpose());
        std::printf("case %s %d %.17g %d\n", name.c_str(), ok ? 1 : 0, model.getFinalResudial(), ramp);
        std::printf("residual");
        for (int i = 0; i < 6; i++) std::printf(" %.17g", residual(i, 0));
        std::printf("\ninit");
        for (int i = 0; i < 6; i++) std::printf(" %.17g", init(0, i));
        std::printf("\n");
        for (int k = 0; k < frames.cols() / 4; k++)
        {
            std::printf("frame");
            for (int i = 0; i < 3; i++) std::printf(" %.17g", frames(i, 4 * k + 3));
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) std::printf(" %.17g", frames(i, 4 * k + j));
            std::printf("\n");
        }
        std::printf("end\n");
        std::fflush(stdout);
    }
    return 0;
}
"""


MATLAB_DRIVER = """
addpath('{models}');
addpath('{parameters}');
tdcr_2segments;  % the robot of the article; F and Ftex are set below
F = [{tensions}];
Ftex = [{tip_force}];
param = setup_param_vc(0,0,0,0,sum(L),ro,ri,m_bb(1),E,nu,0,r_disk,m_disk(1),n_disk,L,r1(1:3),r2(1:3),r3(1:3));
Fc = [F(1:3);F(4:6)]';
[y, init, exitflag] = VC_solver([0;0;1;0;0;0], Fc, Ftex, L, param);
res = boundcond(size(y,1), Fc(:,2), Ftex, 2, y, [param.tendon.r1 param.tendon.r2 param.tendon.r3], param);
printf('robot'); printf(' %.17g', [L(1) L(2) E nu ro r_disk g]); printf('\\n');
printf('routing'); printf(' %.17g', [r1(1:3) r2(1:3) r3(1:3)]); printf('\\n');
printf('exitflag %d\\n', exitflag);
printf('residual'); printf(' %.17g', res); printf('\\n');
printf('init'); printf(' %.17g', init); printf('\\n');
for i = 1:size(y,1)
  printf('point'); printf(' %.17g', y(i,[19 1:12])); printf('\\n');
end
"""
"""Runs the MATLAB code's ``VC_solver`` as its ``matlab/main.m`` does, on the robot of
``matlab/Parameters/tdcr_2segments.m``, with the case's tensions and tip force, and prints its output."""


@dataclass(frozen=True)
class MatlabCase:
    """One equilibrium of the MATLAB model (the robot of ``tdcr_2segments.m``; no tip moment in ``VC_solver``)."""

    name: str
    tensions: tuple[float, float, float, float, float, float]
    tip_force: tuple[float, float, float] = (0.0, 0.0, 0.0)  # N, base frame
    note: str = ""


MATLAB_CASES = (
    MatlabCase("one_tendon", (8, 0, 0, 0, 0, 0), note="the tensions of tdcr_2segments.m"),
    MatlabCase("two_tendons", (2, 0, 0, 0, 1, 0), note="the tensions of matlab/main.m"),
    MatlabCase("three_tendons", (3, 1, 0, 0, 0, 2), note="antagonistic pair in segment 1"),
    MatlabCase("two_tendons_tip_force", (2, 0, 0, 0, 1, 0), tip_force=(0.05, -0.05, -0.1), note="with a tip force"),
)


@dataclass(frozen=True)
class Robot:
    """The parameters ``CosseratRodModel::setRobotParameters`` takes (SI units)."""

    length: tuple[float, float]  # m, per segment
    youngs_modulus: float  # Pa
    disks: tuple[int, int]  # per segment; the model reports a frame at each disk
    pitch_radius: tuple[float, float]  # m, tendon offset per segment
    backbone_radius: float  # m


DEFAULT_ROBOT = Robot((0.1, 0.1), 60e9, (10, 10), (0.008, 0.006), 0.0005)
"""The constructor defaults of ``CosseratRodModel`` and ``TendonDrivenRobot`` (a nitinol backbone)."""
EXAMPLE_ROBOT = Robot((0.2, 0.2), 54e9, (10, 10), (0.01, 0.01), 0.0007)
"""The robot of tdcr-modeling's ``c++/main.cpp`` and ``matlab/Parameters/tdcr_2segments.m``."""


@dataclass(frozen=True)
class Case:
    """One equilibrium: tensions [N] (tendons 1-3 end at the end of segment 1, 4-6 at the tip), tip wrench."""

    name: str
    robot: Robot
    tensions: tuple[float, float, float, float, float, float]
    tip_force: tuple[float, float, float] = (0.0, 0.0, 0.0)  # N, base frame
    tip_moment: tuple[float, float, float] = (0.0, 0.0, 0.0)  # N m, base frame
    note: str = ""


CASES = (
    Case("one_tendon_segment1", DEFAULT_ROBOT, (3, 0, 0, 0, 0, 0), note="bends segment 1, segment 2 stays straight"),
    Case("one_tendon_segment2", DEFAULT_ROBOT, (0, 0, 0, 2, 0, 0), note="tendon to the tip, planar"),
    Case("two_tendons", DEFAULT_ROBOT, (2, 0, 0, 0, 1, 0), note="tdcr-modeling's matlab/main.m tensions; spatial"),
    Case("three_tendons", DEFAULT_ROBOT, (3, 1, 0.5, 0, 0, 2), note="antagonistic pair in segment 1; spatial"),
    Case(
        "two_tendons_tip_force",
        DEFAULT_ROBOT,
        (2, 0, 0, 0, 1, 0),
        tip_force=(0.05, -0.03, -0.1),
        note="with a tip force",
    ),
    Case(
        "tip_force_and_moment",
        DEFAULT_ROBOT,
        (0, 2.5, 0, 1.5, 0, 0),
        tip_force=(-0.04, 0.0, -0.05),
        tip_moment=(0.0, 0.002, 0.001),
        note="with a tip force and a tip moment (torsion)",
    ),
    Case("example_robot_main_cpp", EXAMPLE_ROBOT, (4, 0, 0, 0, 2, 0), note="c++/main.cpp's robot and tensions"),
    Case(
        "example_robot_main_m",
        EXAMPLE_ROBOT,
        (2, 0, 0, 0, 1, 0),
        note="matlab/main.m's robot and tensions, as matlab_vc_two_tendons",
    ),
)


def extract(source: str, work: Path) -> Path:
    """The folder holding ``c++/`` and ``matlab/`` of tdcr-modeling at :data:`COMMIT`, extracted under ``work``."""
    repo = Path(source)
    if not repo.exists():
        repo = work / "tdcr-modeling.git"
        subprocess.run(["git", "clone", "--bare", "--quiet", source, str(repo)], check=True)
    target = work / "tdcr-modeling"
    target.mkdir()
    archive = subprocess.run(
        ["git", "-C", str(repo), "archive", COMMIT, "c++", "matlab"], check=True, capture_output=True
    )
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive.stdout, check=True)
    return target


def build(cpp: Path, work: Path, tight: bool) -> Path:
    """Compile the driver with ``cosseratrodmodel.cpp`` (error control tightened when ``tight``)."""
    source = (cpp / "src" / "cosseratrodmodel.cpp").read_text()
    if PUBLISHED_CONTROL not in source:
        raise RuntimeError(f"{PUBLISHED_CONTROL!r} not found in cosseratrodmodel.cpp")
    variant = work / ("tight" if tight else "published")
    variant.mkdir()
    (variant / "cosseratrodmodel.cpp").write_text(source.replace(PUBLISHED_CONTROL, TIGHT_CONTROL) if tight else source)
    (variant / "driver.cpp").write_text(DRIVER)
    exe = variant / "tdcr_driver"
    subprocess.run(
        ["g++", "-O2", "-std=c++14", f"-I{cpp / 'include'}", "-I/usr/include/eigen3"]
        + [str(variant / "driver.cpp"), str(variant / "cosseratrodmodel.cpp"), "-o", str(exe), "-lgsl", "-lgslcblas"],
        check=True,
    )
    return exe


def run(exe: Path, cases: tuple[Case, ...]) -> dict[str, dict]:
    """Run the driver on ``cases``; per case its success flag, residual, base strains and disk frames."""
    lines = []
    for c in cases:
        r = c.robot
        numbers = [*r.length, r.youngs_modulus, *r.disks, *r.pitch_radius, r.backbone_radius]
        numbers += [*c.tensions, *c.tip_force, *c.tip_moment]
        lines.append(" ".join([c.name] + [repr(float(x)) if not isinstance(x, int) else str(x) for x in numbers]))
    out = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True, text=True, check=True).stdout
    results: dict[str, dict] = {}
    current: dict = {}
    for line in out.splitlines():
        head, *rest = line.split()
        if head == "case":
            current = {
                "success": rest[1] == "1",
                "chi_squared": float(rest[2]),
                "ramp_steps": int(rest[3]),
                "positions": [],
                "rotations": [],
            }
            results[rest[0]] = current
        elif head == "residual":
            current["residual"] = [float(x) for x in rest]
        elif head == "init":
            current["base_v"] = [float(x) for x in rest[:3]]
            current["base_u"] = [float(x) for x in rest[3:]]
        elif head == "frame":
            values = [float(x) for x in rest]
            current["positions"].append(values[:3])
            current["rotations"].append([values[3:6], values[6:9], values[9:12]])
    return results


def run_matlab(matlab: Path, work: Path, cases: tuple[MatlabCase, ...]) -> dict[str, dict]:
    """Run ``VC_solver`` in Octave for each case; its exit flag, residual, base strains, robot and points."""
    results: dict[str, dict] = {}
    for c in cases:
        script = work / f"vc_{c.name}.m"
        script.write_text(
            MATLAB_DRIVER.format(
                models=matlab / "Models" / "VC",
                parameters=matlab / "Parameters",
                tensions=" ".join(repr(float(x)) for x in c.tensions),
                tip_force=";".join(repr(float(x)) for x in c.tip_force),
            )
        )
        out = subprocess.run(
            ["octave-cli", "--no-window-system", "-q", str(script)], capture_output=True, text=True, check=True
        ).stdout
        record: dict = {"s": [], "positions": [], "rotations": []}
        for line in out.splitlines():
            head, *rest = line.split() or [""]
            if head not in ("robot", "routing", "exitflag", "residual", "init", "point"):
                continue  # VC_solver's own messages (its tic/toc)
            values = [float(x) for x in rest]
            if head == "robot":
                keys = ("length_1", "length_2", "youngs_modulus", "poisson_ratio", "backbone_radius", "pitch_radius")
                record["robot"] = dict(zip(keys + ("gravity",), values))
            elif head == "routing":
                record["routing"] = [values[0:3], values[3:6], values[6:9]]
            elif head == "exitflag":
                record["exitflag"] = int(rest[0])
            elif head == "residual":
                record["residual"] = values
            elif head == "init":
                record["base_v"], record["base_u"] = values[:3], values[3:6]
            elif head == "point":
                record["s"].append(values[0])
                record["positions"].append(values[1:4])
                flat = values[4:13]  # reshape(R, 9, 1): column-major
                record["rotations"].append([[flat[i + 3 * j] for j in range(3)] for i in range(3)])
        results[c.name] = record
    return results


def write_matlab(matlab: Path, work: Path, out: Path) -> None:
    """Run :data:`MATLAB_CASES` in Octave, as published and with ode45's tolerances tightened; ``matlab_vc_*.json``."""
    octave = subprocess.run(["octave-cli", "--version"], capture_output=True, text=True, check=True)
    solver = matlab / "Models" / "VC" / "VC_solver.m"
    source = solver.read_text()
    if PUBLISHED_ODESET not in source:
        raise RuntimeError(f"{PUBLISHED_ODESET!r} not found in {solver.name}")
    published = run_matlab(matlab, work, MATLAB_CASES)
    solver.write_text(source.replace(PUBLISHED_ODESET, TIGHT_ODESET))
    tight = run_matlab(matlab, work, MATLAB_CASES)
    solver.write_text(source)
    for case in MATLAB_CASES:
        record = {
            "case": case.name,
            "note": case.note,
            "reference": {
                "repository": DEFAULT_SOURCE,
                "commit": COMMIT,
                "model": "VC_solver (matlab/Models/VC), robot of matlab/Parameters/tdcr_2segments.m",
                "interpreter": octave.stdout.splitlines()[0],
            },
            "tensions": list(case.tensions),
            "tip_force": list(case.tip_force),
            "published": published[case.name],
            "tight_ode_tolerance": tight[case.name],
        }
        path = out / f"matlab_vc_{case.name}.json"
        path.write_text(json.dumps(record, indent=1) + "\n")
        print(f"{path.name}: exitflag {published[case.name]['exitflag']}, tip {published[case.name]['positions'][-1]}")


def write_cpp(cpp: Path, work: Path, out: Path) -> None:
    """Run :data:`CASES` with both builds of the C++ model and write ``<case>.json``."""
    compiler = subprocess.run(["g++", "--version"], capture_output=True, text=True, check=True).stdout.splitlines()[0]
    published = run(build(cpp, work, tight=False), CASES)
    tight = run(build(cpp, work, tight=True), CASES)
    for case in CASES:
        robot = asdict(case.robot)
        r = case.robot
        area = math.pi * r.backbone_radius**2
        second_moment = math.pi * r.backbone_radius**4 / 4
        record = {
            "case": case.name,
            "note": case.note,
            "reference": {
                "repository": DEFAULT_SOURCE,
                "commit": COMMIT,
                "model": "CosseratRodModel (c++/src/cosseratrodmodel.cpp)",
                "compiler": compiler,
            },
            "robot": robot,
            "derived": {
                "shear_modulus": r.youngs_modulus / 2.6,
                "area": area,
                "second_moment": second_moment,
                "torsion_constant": 2 * second_moment,
                "tendon_angles_deg": [90.0, -30.0, 210.0],
            },
            "tensions": list(case.tensions),
            "tip_force": list(case.tip_force),
            "tip_moment": list(case.tip_moment),
            "disk_arc_length": [
                *(r.length[0] * i / r.disks[0] for i in range(r.disks[0] + 1)),
                *(r.length[0] + r.length[1] * i / r.disks[1] for i in range(1, r.disks[1] + 1)),
            ],
            "published": published[case.name],
            "tight_ode_tolerance": tight[case.name],
        }
        path = out / f"{case.name}.json"
        path.write_text(json.dumps(record, indent=1) + "\n")
        tip = published[case.name]["positions"][-1]
        print(f"{path.name}: success {published[case.name]['success']}, tip {tip}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default=DEFAULT_SOURCE, help="tdcr-modeling git repository (path or URL)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    parser.add_argument("--only", choices=("cpp", "matlab"), help="run only the C++ or only the MATLAB model")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        root = extract(args.source, work)
        if args.only != "matlab":
            write_cpp(root / "c++", work, args.out)
        if args.only != "cpp":
            write_matlab(root / "matlab", work, args.out)


if __name__ == "__main__":
    main()
