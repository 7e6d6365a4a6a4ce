"""Problem kind ``two_arms``: two arms controlled together by one QP per step, for a rope they hold or their tips.

Seed 002's next step ("model-based control of rope using two collaborative continuum robots"):
two arms of the file's ``arm:`` model stand in one frame (``options.arms``: base, orientation,
start, tube radius); one QP per control step over both arms' rates
(:class:`optikin.control.two_arm.TwoArmQP`) drives the task, keeps both arms' configuration and
rate limits, and keeps the two tubes apart by self-collision barrier rows
(:class:`optikin.control.self_collision.TwoTubes`) and, with a rope, the rope's samples off both tubes
(:class:`optikin.control.two_arm.RopeTubes`), and both tubes and the rope off the obstacles of
``options.obstacles`` (the shapes of the ``tracking`` kind, in the shared frame;
:class:`optikin.control.two_arm_obstacles.TwoArmObstacleRows`). Tasks, by the data source (family
``two_arm_references``, :mod:`optikin.problems.two_arms.references`):

* ``rope_loop``: the tips hold a rope (``options.rope``: length, mass per length, slack, floor);
  its lowest point -- the exact catenary's vertex, differentiated through the implicit function
  (:mod:`optikin.curves.catenary_sensitivity`) -- goes around the skipping-rope loop;
* ``tip_waypoints``: each arm's tip follows its own reference through the space both share.

::

    data:
      source: rope_loop             # or tip_waypoints: {rate, waypoints: [[q, ...], [q, ...]], segment_time, hold}
      params: {rate: 500, period: 1.0, cycles: 2, radii: [0.05, 0.07], sideways: [0, 1, 0], ramp: 0.5}
    solver: qp-active-set
    baselines: [no_collision_rows, pseudo_inverse]
    options:
      arms:
        - {base: [-0.2, 0, 0], orientation: [1, 0, 0, 0], start: [..], radius: 0.015}
        - {base: [0.2, 0, 0], orientation: [0, 0, 0, 1], start: [..], radius: 0.015}
      rope: {length: 0.3, mass_per_length: 0.05, slack: 0.03, floor: null}
      gain: 10.0
      posture_weight: 0.001
      collision: {margin: 0.02, gamma: 20.0, pairs: 4, points_per_section: null,
                  rope_pairs: 2, rope_margin: 0.01, rope_exclusion: 0.07,
                  obstacle_margin: 0.01, points_per_obstacle: 3}
      obstacles: [{type: sphere, center: [0, 0.04, 0.12], radius: 0.03}]   # optional

Baselines: ``no_collision_rows`` (the same QP without the self-collision, rope and obstacle rows),
``pseudo_inverse`` (no limits, no rows), ``pseudo_inverse_saturated`` (its command clipped into the joint
QP's boxes: the same rate limits and configuration limits, no rows) and any ``qp`` preset (the joint QP
with that preset's step solver, its row labelled with the preset's name); their collisions are reported
(columns ``collision steps``, ``depth [mm]``), not hidden. Per-step status: ``ok``, or ``failed`` where
the QP found no solution and the arms were held. Criteria of the joint QP: ``no collision`` (the
continuous tubes, between samples too, never touch: least sampled clearance less half the two sample spacings stays
positive), ``within limits`` and, with obstacles, ``no obstacle penetration`` (every body's least
sampled clearance less half its sample spacing stays positive; the rope is checked beyond
``collision.rope_exclusion`` of its grips).
"""

from __future__ import annotations

from optikin.problems import ProblemContext, ProblemKind, figures_of, register_kind
from optikin.problems.two_arms import references, report  # noqa: F401  (references registers its sources)
from optikin.problems.two_arms.options import TwoArmOptions
from optikin.problems.two_arms.run import BASELINES, preset_baseline, run
from optikin.results import Result


def solve(ctx: ProblemContext) -> Result:
    """Run every closed loop of the problem and report it."""
    return report.result(ctx, run(ctx))


register_kind(
    ProblemKind(
        name="two_arms",
        summary="two arms by one QP per step: a rope's lowest point or both tips, with self-collision barriers",
        run=solve,
        backend_families=("qp",),
        default_solver="qp-active-set",
        baselines=BASELINES,
        preset_baseline=preset_baseline,
        options=TwoArmOptions,
        data_family="two_arm_references",
        figures=figures_of("optikin.problems.two_arms.figures"),
        headline=("rms [mm]", "clearance [mm]", "collision steps", "outside limits", "step [us]"),
    )
)
