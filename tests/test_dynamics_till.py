"""Rod dynamics against the dynamic cantilever of Till, Aloi and Rucker's examples (C++, MIT licence).

``02_Dynamics/00_Cosserat_Rod_PDE/Cpp/main.cpp`` of github.com/JohnDTill/ContinuumRobotExamples
(commit 064f593): a steel rod (E = 200 GPa, G = 80 GPa, r = 1 mm, 8000 kg/m^3, L = 0.5 m) clamped
along +z under gravity along -x, at rest under a 20 g tip mass that is released at t = 0+, BDF-alpha
with alpha = -0.2 and dt = 2 ms, no damping. Their BVP is integrated by Euler's method in ``s``
(first order), so their tip trajectory was computed at 160 and 640 points (their code, the grid
size changed, built with ``g++ -O3``) and is extrapolated here to ``(4 x(640) - x(160)) / 3``;
the tables hold their tip ``(x, z)`` every 0.1 s over 2 s. At their own 40 points the C++ takes
70 us per step on the development machine and its tip starts 0.6 mm off the converged one.
"""

from __future__ import annotations

import numpy as np

from optikin.physics import Loads, Rod, RodArm
from optikin.physics.dynamics import DynamicsOptions, RodDynamics

TILL_640 = np.array(
    [
        (-0.063341928, 0.495219235),
        (0.035113689, 0.498532180),
        (-0.049612711, 0.497166147),
        (0.010464438, 0.499878435),
        (-0.017501766, 0.499659491),
        (-0.024919352, 0.499280754),
        (0.016687445, 0.499677842),
        (-0.053566786, 0.496698335),
        (0.036142269, 0.498485310),
        (-0.060966603, 0.495685163),
        (0.030305223, 0.498919467),
        (-0.042522658, 0.497899076),
        (0.001605825, 0.499996044),
        (-0.007693485, 0.499933375),
        (-0.034486193, 0.498623607),
        (0.024618970, 0.499287288),
        (-0.058499156, 0.496025844),
        (0.037259547, 0.498378987),
        (-0.058064850, 0.496091631),
        (0.023837413, 0.499335956),
        (-0.033528468, 0.498703626),
    ]
)

TILL_160 = np.array(
    [
        (-0.063460280, 0.495231973),
        (0.035000774, 0.498549820),
        (-0.049733657, 0.497171925),
        (0.010333376, 0.499882403),
        (-0.017579866, 0.499659695),
        (-0.025096474, 0.499275008),
        (0.016628620, 0.499681632),
        (-0.053721852, 0.496702764),
        (0.036027638, 0.498505181),
        (-0.061054819, 0.495704580),
        (0.030131533, 0.498938833),
        (-0.042567997, 0.497909301),
        (0.001403669, 0.499996786),
        (-0.007718337, 0.499933419),
        (-0.034699074, 0.498616779),
        (0.024586358, 0.499293323),
        (-0.058673342, 0.496029272),
        (0.037150404, 0.498398104),
        (-0.058132109, 0.496109861),
        (0.023609433, 0.499352609),
        (-0.033490848, 0.498716155),
    ]
)


def test_released_cantilever_follows_the_extrapolated_cpp_reference():
    extrapolated = (4 * TILL_640 - TILL_160) / 3
    assert np.abs(TILL_640 - TILL_160).max() > 1e-4  # their grid error is visible: 0.23 mm at 160 points
    rod = Rod(length=0.5, radius=0.001, youngs_modulus=200e9, shear_modulus=80e9, density=8000.0, gravity=(-9.81, 0, 0))
    dyn = RodDynamics(RodArm.single(rod), DynamicsOptions(dt=2e-3, alpha=-0.2, steps_per_segment=39))
    start = dyn.rest(Loads(tip_force=(-0.02 * 9.81, 0.0, 0.0)))
    trajectory = dyn.simulate(start, np.tile(dyn.load_vector(Loads()), (1000, 1)), keep_shapes=False)
    assert trajectory.complete
    tip = trajectory.tip[::50][:, [0, 2]]
    # 0.09 mm when written (40 points here; 80 points move the tip by 1 um)
    assert np.abs(tip - extrapolated).max() < 2e-4
