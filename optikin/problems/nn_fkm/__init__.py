"""Problem kind ``nn_fkm``: the hybrid forward kinematics of seed 004 against exact platform solvers.

Lakhal et al. 2016, section IV, Fig. 9, Table II: a forward network per section
predicts the platform variables ``(Z_k, theta_k, psi_k)`` from the leg lengths; the
tip follows by the exact chain of eq. (5). The baselines are solver presets of the
``nonlinear`` family (``newton``, ``gauss-newton``, ``lm``, ``trf``, ``ipopt``,
``sqpmethod``, or a user's own) solving eqs. (7)-(9) of every platform
(:mod:`optikin.ik.platform`) from their linearisation
(:func:`~optikin.ik.platform.linearised_start`), on the first ``exact_samples``
held-out arms, given the true legs and (``tube_sensors``) the legs the percentage split of
Fig. 6 gets from the arms' six tube lengths (rows ``-fig9``), beside seed 004 Table IV's
constant-curvature model of the tube lengths. What both nn kinds share (statuses, MSEs, tip errors) is described
in :mod:`optikin.problems.nn_shared`.

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
    store: null                 # folder of trained models (relative to the working directory):
                                # loaded when it matches the problem, otherwise trained and written
    exact_samples: 200          # test samples given to the exact solvers (the first ones)
    latency_repeats: 50         # one-sample calls timed for the latency
    tube_sensors: true          # also the pipeline of Fig. 9: legs split from the six tube lengths
                                # (rows -fig9) and seed 004 Table IV's constant-curvature row
    direct: true                # cosserat source: Table IV's direct-mlp row (tube lengths -> tip)

On the ``cosserat`` source every method reads the six tube lengths only (Fig. 9) and is
scored on the Cosserat tips (:mod:`optikin.data.cosserat_nn`).
"""

from __future__ import annotations

from optikin.problems import ProblemContext, ProblemKind, figures_of, preset_row, register_kind
from optikin.problems.nn_fkm.report import report
from optikin.problems.nn_fkm.run import run
from optikin.problems.nn_shared import NNOptions
from optikin.results import Result


def solve(ctx: ProblemContext) -> Result:
    """Train (or load) the networks, run the baselines, and report them."""
    return report(run(ctx))


register_kind(
    ProblemKind(
        name="nn_fkm",
        summary="seed 004 hybrid forward kinematics (MLP per section) against exact platform solvers",
        run=solve,
        backend_families=("nonlinear",),
        preset_baseline=preset_row,
        default_solver=None,
        options=NNOptions,
        data_family="nn_database",
        figures=figures_of("optikin.problems.nn_fkm.figures"),
    )
)
