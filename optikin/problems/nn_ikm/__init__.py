"""Problem kind ``nn_ikm``: the hybrid inverse kinematics of seed 004 against exact tip IK solvers.

Lakhal et al. 2016, section V, Fig. 10, Table III, eq. (11): NN1 maps the tip to the
end of section 1, NN2-NN4 map both to every ``(Z_k, theta_k, psi_k)``, and eqs.
(7)-(9) turn them into leg lengths. The baselines are solver presets of the
``nonlinear`` family solving the tip-position IK (:mod:`optikin.ik.formulation`) for
the admissible configuration nearest the straight mid-range pose (redundancy
``rest``, every leg within Table I), from that pose, on the first ``exact_samples``
held-out tips. Every method's lengths are clipped to Table I and realised through
the exact forward kinematics (:func:`~optikin.ik.platform.realise`, Newton on
every platform) before its tip error is measured. What both nn kinds share
(statuses, MSEs, tip errors) is described in :mod:`optikin.problems.nn_shared`.

``data`` (source ``fig7``, :class:`~optikin.baselines.nn_database.Fig7Params`)::

    data:
      source: fig7
      seed: 2016                # every draw and the split
      samples: 1500000          # candidate draws per platform
      params:
        z_range_mm: [0, 25]     # the wide box of Fig. 7
        angle_range_deg: [-45, 45]
        require_upright: true
        coupling: platform      # or section, or tubes (the tube-driven database)
        split: [0.7, 0.15, 0.15]

or (source ``cosserat``, :class:`~optikin.data.cosserat_nn.CosseratNNParams`) the postures of a
Cosserat-rod CBHA, with the vertebra-model database the networks train on::

    data:
      source: cosserat
      seed: 2016
      samples: 400              # Cosserat postures (70 / 15 / 15)
      params:
        rod: {pressure_range: [0.0, 1.2e+5], payload: 0.0}   # CosseratMarkerParams
        model_samples: 200000   # data.samples of the vertebra-model database
        model: {z_range_mm: [0, 45], angle_range_deg: [-110, 110], coupling: platform}

``options`` (all optional, :class:`~optikin.problems.nn_shared.NNOptions`)::

    variants: [seed, adam]      # training settings (optikin.baselines.nn_models.SETTINGS; also seed-raw, adam-wide)
    setting: full               # or small: two widths, 15 epochs (tests, notebooks)
    penalty: 1.0e-3             # lambda of eq. (11)
    store: null                 # folder of trained models (relative to the working directory):
                                # loaded when it matches the problem, otherwise trained and written
    exact_samples: 200          # test samples given to the exact solvers (the first ones)
    latency_repeats: 50         # one-sample calls timed for the latency
    direct: true                # cosserat source: Table IV's direct-mlp row (tip -> tube lengths)

On the ``cosserat`` source the targets are Cosserat tips and every method's lengths are
driven on the Cosserat arm (:mod:`optikin.problems.nn_ikm.run`), beside seed 004 Table IV's
constant-curvature and direct-mlp rows.
"""

from __future__ import annotations

from optikin.problems import ProblemContext, ProblemKind, figures_of, preset_row, register_kind
from optikin.problems.nn_ikm.report import report
from optikin.problems.nn_ikm.run import run
from optikin.problems.nn_shared import NNOptions
from optikin.results import Result


def solve(ctx: ProblemContext) -> Result:
    """Train (or load) the networks, run the baselines, and report them."""
    return report(run(ctx))


register_kind(
    ProblemKind(
        name="nn_ikm",
        summary="seed 004 hybrid inverse kinematics (MLPs NN1-NN4, eq. 11) against exact tip IK solvers",
        run=solve,
        backend_families=("nonlinear",),
        preset_baseline=preset_row,
        default_solver=None,
        options=NNOptions,
        data_family="nn_database",
        figures=figures_of("optikin.problems.nn_ikm.figures"),
    )
)
