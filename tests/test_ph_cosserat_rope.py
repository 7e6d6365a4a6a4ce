"""The ``cosserat`` rope-chain source: two Cosserat CBHAs loaded by the rope they hold.

Independent references: the equilibrium of each arm solved again, cold, by the CasADi
virtual-machine shooting under the reported tip force (it reaches the recorded tip, and its
clamp carries the tip force plus the arm's weight, the arm's force balance); the catenary
between the recorded tips pulls the tips with the reported forces (the fixed point); the
``cosserat`` marker source's own recording of the same seed when the rope weighs nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.curves.catenary import catenary
from optikin.data.cosserat_markers import CosseratMarkerParams, cosserat_cbha_arm, cosserat_recording
from optikin.data.cosserat_rope import HALF_TURN, CosseratRopeParams, actuation, cosserat_rope_chain
from optikin.data.sources import DATA_SOURCES
from optikin.errors import InputDataError
from optikin.physics import Loads, ShootingOptions, ShootingSolver
from optikin.problems.ph_shared import problem_variant
from optikin.runner import solve
from optikin.algebra import quat_multiply

PARAMS = CosseratRopeParams()


@pytest.fixture(scope="module")
def chain():
    return cosserat_rope_chain(PARAMS, 5, 11)


def test_the_source_is_registered_in_the_rope_chain_family():
    assert {"synthetic", "cosserat"} <= set(DATA_SOURCES["rope_chains"].names())


def test_rope_hangs_between_the_true_tips_and_pulls_them_by_its_end_tensions(chain):
    tips = np.stack([chain.arm1.truth.tip_position, chain.arm2.truth.tip_position], axis=1)
    np.testing.assert_allclose(chain.rope_truth[:, 0], tips[:, 0], atol=1e-12)
    np.testing.assert_allclose(chain.rope_truth[:, -1], tips[:, 1], atol=1e-12)
    weight = PARAMS.rope_mass_per_length * 9.81
    for i in range(len(chain)):
        on_tips = catenary(tips[i, 0], tips[i, 1], PARAMS.rope_length).end_forces(weight)
        np.testing.assert_allclose(chain.tip_forces[i], np.stack(on_tips), atol=1e-6)
    np.testing.assert_allclose(chain.tip_forces.sum(axis=1)[:, 2], -weight * PARAMS.rope_length, atol=1e-6)
    np.testing.assert_allclose(chain.arm2.truth.vertebrae[:, 0], [[0.4, 0.0, 0.0]] * len(chain), atol=1e-15)


def test_each_arm_is_in_equilibrium_under_the_rope(chain):
    """Solved again cold by the VM shooting: same tip; the clamp carries the tip force and the arm's weight."""
    g = np.array(PARAMS.gravity)
    weight = PARAMS.mass_per_length * PARAMS.length * g
    for k, (arm_rec, position) in enumerate(((chain.arm1, (0.0, 0.0, 0.0)), (chain.arm2, (0.4, 0.0, 0.0)))):
        orientation = tuple(quat_multiply(HALF_TURN, np.array(PARAMS.base_orientation))) if k else (1.0, 0, 0, 0)
        arm = cosserat_cbha_arm(PARAMS).model_copy(update={"base_position": position, "base_orientation": orientation})
        solver = ShootingSolver(arm, ShootingOptions(steps_per_segment=PARAMS.steps_per_segment, compiled=False))
        pressures = arm_rec.truth.configurations.reshape(len(chain), 2, 3)
        for i in (0, len(chain) - 1):
            force = chain.tip_forces[i, k]
            sol = solver.solve(Loads(tip_force=tuple(force), actuation=tuple(actuation(PARAMS, pressures)[i])))
            assert sol.ok
            np.testing.assert_allclose(sol.positions[-1], arm_rec.truth.tip_position[i], atol=2e-8)
            # the rod just after the clamp also carries the pull of its chambers on the base cap, along d3(0)
            chambers = PARAMS.chamber_area * pressures[i, 0].sum() * np.array([0.0, 0.0, 1.0])
            np.testing.assert_allclose(sol.base_wrench[:3], force + weight + chambers, atol=1e-6)


def test_a_weightless_rope_leaves_arm_1_the_cosserat_marker_recording():
    params = CosseratRopeParams(rope_mass_per_length=0.0, rope_length=2.0)
    chain = cosserat_rope_chain(params, 4, 3)
    alone = cosserat_recording(CosseratMarkerParams(), 4, np.random.default_rng([3, 0]))
    assert chain.coupling_iterations == 1 and np.all(chain.tip_forces == 0)
    for name in ("base_position", "tip_position", "tip_orientation", "markers", "tube_markers", "tube_lengths"):
        np.testing.assert_allclose(getattr(chain.arm1, name), getattr(alone, name), atol=1e-12, err_msg=name)


def test_tips_the_rope_cannot_reach_name_the_posture():
    with pytest.raises(InputDataError, match=r"sample \d+: rope_length: the tips are"):
        cosserat_rope_chain(CosseratRopeParams(rope_length=0.3, end_offset=0.02), 3, 11)


def test_the_problem_file_runs_and_its_links_meet(tmp_path):
    result, _ = solve(str(problem_variant("cbha-rope-chain-cosserat", tmp_path, samples=3, baselines=[])))
    assert result.status == ["ok"] * 3
    a = result.arrays
    np.testing.assert_allclose(a["arm1_ph_points"][:, -1], a["rope_ph_points"][:, 0], atol=1e-13)
    np.testing.assert_allclose(a["rope_ph_points"][:, -1], a["arm2_ph_points"][:, 0], atol=1e-13)
    assert np.all(a["arm1_marker_distance"] < 0.015) and np.all(a["arm2_marker_distance"] < 0.015)
