"""The "hybrid approach" of seed 002 Table III: CBHA tube lengths from the tip position by neural networks.

Seed 002 (section V.B, Table III: PH 0.27 ms, Newton-Raphson 233 ms, hybrid 12 ms
per sample) compares its PH tube lengths with the hybrid approach of seed 004:
networks NN1-NN4 give the platform variables ``(Z_k, theta_k, psi_k)`` from the
tip position (section V, Fig. 10), the leg lengths follow by eqs. (7)-(9), and
"the IKM of the CBHA is obtained by summing the elongations of the
inter-vertebrae": each tube's length is the sum of its legs over the 16
platforms. :func:`hybrid_tube_lengths` does exactly that, one posture per call,
and times each call as the seed's per-sample time.

The networks are the inverse models of a problem file (its database, the ``adam``
setting, its eq. (11) penalty), shipped with the package in :data:`SHIPPED_STORES`
(:mod:`optikin.baselines.nn_store`, plain arrays):

``cbha-nn-ikm``
    the Fig. 7 database of seed 004, every platform drawn independently (185 s of
    training; widths 12/10/4/8, the test MSEs of BENCHMARKS.md, "Inverse kinematics");
``cbha-nn-ikm-coupled``
    the database whose sections bend as one (one draw per section shared by its
    eight platforms; 363 s of training; widths 18/18/20/20, BENCHMARKS.md "Sections
    that bend as one").

Training is seeded; regenerate a store from the repository root with (``NAME`` one of
the two; about 3.4 and 7 min for the whole command on 2 shared cores)::

    rm -rf optikin/data/models/NAME/ikm-adam
    python -c "import yaml; d = yaml.safe_load(open('problems/NAME.yaml')); \\
    d['options'] |= {'variants': ['adam'], 'store': 'optikin/data/models/NAME'}; \\
    d['baselines'] = []; d['name'] = 'NAME-store'; \\
    open('/tmp/NAME-store.yaml', 'w').write(yaml.safe_dump(d))"
    optikin solve /tmp/NAME-store.yaml --out /tmp/NAME-store

A tip position (3 numbers) does not determine the tube lengths: the arm driven by
its 6 tubes (3 per section) reaches one tip with a 3-parameter family of tube
lengths, so any map from the tip position alone errs on some of them. The
``cbha-nn-ikm`` networks err more: trained on platforms drawn independently of each
other (Fig. 7), they have seen little of the strong, coherent bending of an arm
driven by its tubes (every platform of a section at the same fraction of its Table I
range), so on such a recording they extrapolate. The ``cbha-nn-ikm-coupled``
networks have seen sections that bend as one, close to that motion.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import optikin.data
from optikin.arms.cbha import CBHAArm
from optikin.baselines.nn_database import DatabaseSpec
from optikin.baselines.nn_models import SETTINGS, TrainedModel, TrainingSetting, hybrid_inverse_configurations
from optikin.baselines.nn_store import load_models, read_metadata
from optikin.errors import InputDataError

MODELS = Path(optikin.data.__file__).resolve().parent / "models"
SHIPPED_STORES = {name: MODELS / name / "ikm-adam" for name in ("cbha-nn-ikm", "cbha-nn-ikm-coupled")}
"""The inverse models NN1-NN4 (setting ``adam``) of these problem files, shipped with the package."""
SHIPPED_STORE = SHIPPED_STORES["cbha-nn-ikm"]
"""The default: the networks of seed 004's own database (Fig. 7)."""
SHIPPED_SETTING = "adam"
SHIPPED_PENALTY = 1e-3
"""``lambda`` of eq. (11) in ``problems/cbha-nn-ikm.yaml``."""
INVERSE_MODELS = ("ikm_nn1", "ikm_nn2", "ikm_nn3", "ikm_nn4")


def load_hybrid_models(
    arm: CBHAArm,
    store: str | Path = SHIPPED_STORE,
    setting: TrainingSetting = SETTINGS[SHIPPED_SETTING],
    penalty: float = SHIPPED_PENALTY,
) -> list[TrainedModel]:
    """NN1-NN4 of ``store`` (default: the shipped models), checked against ``arm``'s geometry.

    The models are used on postures that are not from their database, so any database
    is accepted (the store's own); the geometry (radii, Table I, sections, tool offset),
    the training setting and the penalty must match. Raises :class:`InputDataError`
    naming the store and the field otherwise, or when the store is missing.
    """
    store = Path(store)
    if not isinstance(arm, CBHAArm):
        raise InputDataError(
            f"the hybrid networks model a CBHA, not {getattr(arm, 'name', arm)!r}", source=str(store), field="arm"
        )
    metadata = read_metadata(store)
    try:
        spec = DatabaseSpec(**metadata["database"])
    except (KeyError, TypeError, ValueError) as exc:
        raise InputDataError(f"unreadable database settings: {exc!r}", source=str(store), field="database") from None
    return load_models(store, arm.geometry, spec, {key: (setting, penalty) for key in INVERSE_MODELS})


def _positions(points: np.ndarray, source: str) -> np.ndarray:
    P = np.asarray(points, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise InputDataError(f"expected positions of shape (N, 3), got {P.shape}", source=source)
    bad = np.argwhere(~np.isfinite(P))
    if bad.size:
        i, j = bad[0]
        raise InputDataError(f"{P[i, j]} is not a finite number", source=source, sample=int(i), field="xyz"[j])
    return P


def hybrid_tube_lengths(
    arm: CBHAArm, tip_positions: np.ndarray, models: list[TrainedModel], section1_ends: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Whole tube lengths ``(N, 3)`` [m] of the tips ``(N, 3)`` (base frame), and seconds per posture ``(N,)``.

    Per posture, one call each (timed): NN1-NN4 (Fig. 10) -> the 48 platform variables ->
    the 48 leg lengths by eqs. (7)-(9) (``arm.leg_lengths``) -> each tube's legs summed
    over the platforms of both sections. The lengths are the networks' own, not clipped
    to Table I. ``section1_ends`` ``(N, 3)`` (base frame), when given (e.g. the marker on
    the vertebra that ends section 1), replace NN1's prediction: the inputs of NN2-NN4
    are then both measured, as the Newton-Raphson comparator's of ``ph_ik``.
    """
    tips = _positions(tip_positions, "tip positions")
    ends = None if section1_ends is None else _positions(section1_ends, "section 1 ends")
    if ends is not None and ends.shape != tips.shape:
        raise InputDataError(f"{len(ends)} section 1 ends for {len(tips)} tips", source="section 1 ends")
    n_platforms = arm.geometry.n_platforms

    def tubes(i: int) -> np.ndarray:
        end = None if ends is None else ends[i : i + 1]
        Q = hybrid_inverse_configurations(models, tips[i : i + 1], end)
        # the networks' own configurations, however far they extrapolate: not checked for plausibility
        return arm.evaluate("leg_lengths", Q, check=False).reshape(n_platforms, 3).sum(axis=0)

    if len(tips):
        tubes(0)  # the first call builds CasADi's buffers: not part of a sample's time
    lengths, seconds = np.empty((len(tips), 3)), np.empty(len(tips))
    for i in range(len(tips)):
        start = time.perf_counter()
        lengths[i] = tubes(i)
        seconds[i] = time.perf_counter() - start
    return lengths, seconds
