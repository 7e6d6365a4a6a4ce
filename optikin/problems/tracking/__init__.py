"""Problem kind ``tracking``: a continuum arm follows a tip reference in closed loop (Seleem et al. 2020, V-VI).

The solver under study is the constrained QP per control step
(:mod:`optikin.control.qp`, any ``qp`` backend preset of :mod:`optikin.solvers.qp`): by default
``qp-active-set`` (DAQP's dual active set on the controller's own buffers, warm-started from the
previous step's active set: the exact QP solution up to rounding), or e.g. ``qp-osqp`` (OSQP updated
in place, which stops at its tolerance) or ``qp-clarabel``; the baselines, run on the same
reference, plant and noise draws, are the paper's MRAC (``mrac``, :mod:`optikin.baselines.mrac`)
started from the same task gain as every other controller, the same MRAC started from the paper's
optimised gains (``mrac_seed``), the plain pseudo-inverse (``pseudo_inverse``) and damped least
squares (``damped_least_squares``); two more controllers on the same footing, listed there too,
are the MPC (``mpc``, :mod:`optikin.control.mpc`: a horizon of ``options.mpc.horizon`` steps, one
sparse QP per step by OSQP) and its nonlinear reference by IPOPT (``mpc_ipopt``,
:mod:`optikin.control.mpc_nlp`), with the QP's gain, limits and obstacles. Each baseline that knows no
limits is also listed saturated (``mrac_saturated``, ``mrac_seed_saturated``, ``pseudo_inverse_saturated``,
``damped_least_squares_saturated``): its command clipped into the QP's box, the same rate limits and the
configuration limits after the step, so that it stays inside them too. A ``qp`` preset listed there
(``qp-osqp``) is the QP controller with that preset's step solver, its row labelled with the preset's name.

The reference (``data``, family ``references`` of :mod:`optikin.data.references`)
is either the forward kinematics of a minimum-jerk configuration path (source
``waypoints``) or the roll-out of a pose DMP learned from the flexible-interface
IMU demonstration (source ``dmp``: params ``task``, ``rate``, ``variant``,
``basis``, ``demonstration_samples``, ``hold``, ``smoothing``; the run starts
from the interface's first configuration), the Kinect chain (``kinect-dmp``), or a
user's recorded demonstration file (source ``csv``: ``file``, ``content``, ``units``,
``task``, ``rate``, ``dmp: {variant, basis, smoothing}`` -- omit it to track the
recording as recorded -- ``hold``, ``max_step``, ``max_duration``,
``start_tolerance``; :mod:`optikin.data.references`)::

    data:
      source: waypoints
      seed: 1                       # sensor-noise draws
      params:
        task: pose                  # pose (dual quaternion, 8 rows) | position (3 rows)
        rate: 500                   # control rate [Hz], 100 .. 1000
        waypoints: [[S1, theta1, phi1, S2, theta2, phi2], ...]   # SI units
        segment_time: 1.5           # seconds per segment (one value or one per segment)
        hold: 1.0                   # seconds at the last waypoint

Options (all optional; :class:`~optikin.problems.tracking.options.TrackingOptions`)::

    start: [..]                  # initial configuration (default: where the reference starts)
    start_offset: [..]           # added to the start
    gain: 10.0                   # K of the QP, pseudo-inverse, DLS and (initially) mrac (scalar or per task row) [1/s]
    damping: 1.0e-4              # lambda of the QP and DLS
    rate_limits: {S: 0.1, theta: 3.14159, phi: 6.28319}   # by name or prefix [m/s, rad/s]
    limit_margin: 1.0e-9         # kept from the configuration limits by the QP (scalar or per variable)
    limit_gain: 1.0              # fraction of the distance to a limit one step may cover (pink: 0.5)
    fallback: hold               # hold | damped_least_squares, when the QP solver fails
    compiled: false              # compile the per-step CasADi Function with gcc
    plant: {length_scale: 1.05, disturbance: [..], disturbance_window: [t_on, t_off],
            configuration_noise: [..], tip_position_noise: 0.0005, tip_angle_noise: 0.005, feedback: tip,
            physics: {type: cosserat, gravity: true, payload: 0.05, ...}}   # a Cosserat rod plant
    mrac: {gain: [..], adaptation: [..], gain_limit: 100, natural_frequency: 10, damping_ratio: 1}
    tolerance: {position_mm: 0.05, orientation_deg: 0.05}   # convergence check on the last 10 % of the run
    obstacles:                   # kept off the whole backbone by the QP (optikin.control.obstacles)
      - type: sphere             # sphere (center, radius), capsule (a, b, radius), box (center, half_extents),
        center: [x, y, z]        # halfspace (point, normal) [m]
        radius: r
        path: [[t, dx, dy, dz], ...]   # optional: offset, linear in time [s, m]
    barrier: {margin: 0.01, gamma: 20.0, points_per_obstacle: 3, points_per_section: null}
    mpc: {horizon: 20, effort_weight: null, solver: osqp, preview: true, eps: 1.0e-3, rho: 0.1,
          max_iter: 4000, polishing: false, ipopt_tolerance: 1.0e-8, ipopt_max_iter: 200}

Per-step status: ``ok``, or ``failed`` where the QP solver failed and the
fallback was applied (the reason is in the notes). The run succeeds when every
step is ``ok`` and the QP meets both criteria of the Result
(:func:`~optikin.problems.tracking.report.success_criteria`): ``converged``
(final errors within ``options.tolerance``) and ``within limits`` (no step on
which its own command kept or took the arm outside the configuration limits);
otherwise ``optikin solve`` exits 1 and a note says which criterion failed and by
how much. The baselines' convergence is a reported metric, not a criterion.
With obstacles a third criterion, ``no penetration``: the QP's backbone, between its samples
too (least sample distance minus half the sample spacing), stays outside every obstacle; every
controller's clearance and penetrations are reported (columns ``clearance [mm]``,
``penetrations``, ``depth [mm]``), and how far the QP's tip stays from a reference that an obstacle
blocks. The MPC baselines are held to the same criterion (``no penetration (mpc)``,
``no penetration (mpc_ipopt)``); a step on which an MPC's horizon failed is counted (column
``fallbacks``) and named in the notes.
"""

from __future__ import annotations

import optikin.data.references  # noqa: F401  (registers the references sources)
from optikin.problems import ProblemContext, ProblemKind, figures_of, register_kind
from optikin.problems.tracking import report
from optikin.problems.tracking.options import TrackingOptions
from optikin.problems.tracking.run import BASELINES, preset_baseline, run
from optikin.results import Result


def solve(ctx: ProblemContext) -> Result:
    """Run every closed loop of the problem and report it."""
    return report.result(ctx, run(ctx))


register_kind(
    ProblemKind(
        name="tracking",
        summary="closed-loop tip tracking: a bounded QP per control step vs MRAC, pseudo-inverse, DLS",
        run=solve,
        backend_families=("qp",),
        default_solver="qp-active-set",
        baselines=BASELINES,
        preset_baseline=preset_baseline,
        options=TrackingOptions,
        data_family="references",
        figures=figures_of("optikin.problems.tracking.figures"),
        headline=("rms [mm]", "final [mm]", "outside limits", "step [us]", "converged", "penetrations", "depth [mm]"),
    )
)
