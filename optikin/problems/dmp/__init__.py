"""Problem kind ``dmp``: learn a demonstrated motion with DMPs and generalise it (Seleem et al. 2020, secs. III-IV).

The methods under study are the weight regression posed in cvxpy (all weights
at once, optional ridge and bounds) and the gain tuning by a gradient-based
NLP (IPOPT through CasADi, :mod:`optikin.dmp.tuning`); the baselines, run on
the same demonstration, are the closed-form fit (``lstsq``), locally weighted
regression (``lwr``) and Seleem et al.'s genetic algorithm (``genetic``). Each
DMP representation listed in ``variants`` learns the demonstration and is
rolled out: reproduction, and optionally goal switches and a perturbation.

Demonstrations (``data.source``, the ``demonstrations`` family of
:mod:`optikin.data.demonstrations`)::

    data:
      source: imu        # imu | kinect | smooth | gimbal | csv
      seed: 7
      samples: 1000      # imu / kinect / smooth / gimbal
      params: {...}      # the keyword arguments of the source's function (imu: the sections
                         # default to the arm's); csv: {file: demo.csv (relative to the
                         # problem file), content: pose | configuration, units: m,
                         # samples: N (resample)}

Options (all optional; :class:`~optikin.problems.dmp.options.DmpOptions`)::

    variants: [cartesian]   # seed | seed-qd-start | dual-quaternion | cartesian | quaternion | koutras-doulgeri
                            # | rpy | position
    n_basis: 50
    smoothing: null         # cutoff [Hz] of the low-pass applied to the demonstration before learning
                            # (optikin.dmp.smoothing; sensor data), null: learn the samples as given
    gains: {beta: 25, gamma: 6.25, zeta: 4.6, beta_g0: .inf, alpha_s: 0, alpha: 0}
    regression: {method: cvxpy, ridge: 0.0, bound: null}   # bound: |w| <= bound (cvxpy only)
    goal_switches: [{time: 4.0, rotate: [rx, ry, rz], translate: [x, y, z]}]  # new goals relative to the last
    disturbance: {kind: output, start: 5.0, stop: 7.0, amplitude: 1.0, component: 0}  # output: the pose
                            # displaced by amplitude [rad | m] and held (seed 000's "output step disturbance",
                            # Figs. 20-21); force: a step force in eq. (17)
    couplings: {coupled: {alpha_s: 5.0}}   # label -> {alpha_s, alpha, phase_stopping} of each DMP coupled
                                           # to the demonstration (eq. 27) and run against the plain one under
                                           # the disturbance; alpha > 0 needs phase_stopping: seed (eq. 28);
                                           # each reports its peak and final deviation from its own
                                           # undisturbed roll-out and its phase at the end
    tuning: {gains: [beta, gamma, zeta], variant: quaternion, scenario: reproduction,
             max_iterations: 60, screen: 16, starts: 2,    # IPOPT: iterations per start; Latin-hypercube
             population: 20, generations: 15,               # screening points; starts from the best of them
             budget: null, seeds: 1,          # budget: IPOPT's evaluations; the multi-start L-BFGS-B and the GA
                                              # then get the count IPOPT used, each run on `seeds` seeds
             terms: [],                       # [Q_r, Q_d]: tune the seed's quaternion DMP on these terms instead
             goal_diagonal: false,            # beta_g0 tuned as one rate per gap component (eq. 24's diagonal)
             reference: {}}                   # {target: {gain: value}} evaluated on the same eq. (29)
    settle: 5.0     # goal-switch roll-outs last settle x tau; the final errors measure convergence
    tolerance: {position_mm: 0.01, orientation_mrad: 0.01}
    origin_shift: [0, 0, 0]   # the world origin moved to this point of the recording's frame [m]: the
                              # DMPs learn p - origin_shift (a sweep of it: sweeps/dmp-qd-origin.yaml)

The ``seed`` variants (Seleem et al.'s quaternion DMPs on ``Q_r`` and ``Q_d``)
keep ``|Q_d|``, so the tip keeps its distance ``r = 2 |Q_d|`` from the world
origin; their rows carry the structural bound ``| |p(t)| - r |`` over the
demonstration (max and RMS), the least position error the variant can reach on
any recording, labelled a limitation of the variant, not of the data.

Per-roll-out status (one per variant and scenario): ``ok``; ``failed`` for a
non-finite roll-out or a unit quaternion / dual quaternion off by more than
1e-9; ``not_converged`` when a goal-switch roll-out ends farther than the
tolerance from its goal.

Modules: :mod:`~optikin.problems.dmp.options` (the options model),
:mod:`~optikin.problems.dmp.variants` (the DMP of each variant and its errors),
:mod:`~optikin.problems.dmp.run` (learn, roll out, tune),
:mod:`~optikin.problems.dmp.report` (the result) and
:mod:`~optikin.problems.dmp.figures` (drawn from the result's arrays).
"""

from __future__ import annotations

from optikin.data import demonstrations as _demonstrations  # noqa: F401  (registers the data sources)
from optikin.data import cosserat_sensors as _cosserat_sensors  # noqa: F401  (registers cosserat-imu)
from optikin.problems import Baseline, ProblemContext, ProblemKind, baselines_of, figures_of, register_kind
from optikin.problems.dmp import report, run
from optikin.problems.dmp.options import DmpOptions
from optikin.results import Result


def solve(ctx: ProblemContext) -> Result:
    """Run a ``dmp`` problem: :func:`~optikin.problems.dmp.run.solve`, then its result."""
    return report.result(ctx.spec, run.solve(ctx))


register_kind(
    ProblemKind(
        name="dmp",
        summary="learn a demonstrated motion with DMPs (cvxpy regression, NLP gain tuning) and generalise it",
        run=solve,
        backend_families=(),
        default_solver=None,
        baselines=baselines_of(*(Baseline(name, name) for name in ("lstsq", "lwr", "genetic"))),
        options=DmpOptions,
        data_family="demonstrations",
        figures=figures_of("optikin.problems.dmp.figures"),
        headline=(
            "reproduction position max [mm]",
            "structural bound position max [mm]",
            "reproduction orientation max [mrad]",
            "fit time [ms]",
        ),
    )
)
