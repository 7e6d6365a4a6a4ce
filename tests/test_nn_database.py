"""The learning database of seed 004 Fig. 7: only admissible rows, exactly the admissible draws, a clean split.

Independent references: Table I typed in again from the paper; the leg lengths of the
printed eqs. (7)-(9); the attachment heights from the matrix of eq. (5) written out in
numpy (not the code that builds the database); the section ends from a product of
4x4 matrices of eq. (5).
"""

from __future__ import annotations

import numpy as np
import pytest

from optikin.arms.cbha import CBHAGeometry, printed_leg_lengths
from optikin.baselines.nn_database import DatabaseSpec, build_database, draw_candidates

Q_MIN_MM = [8.5, 8.5, 8.5, 7, 7, 7, 8.5, 10, 6.5, 8, 8, 7.5, 7.5, 7, 7, 6.5]
Q_MAX_MM = [19.5, 19.5, 19.5, 16.5, 16.5, 16.5, 20, 22, 16, 20.5, 20.5, 19, 19, 18, 18, 16]
SQ3 = np.sqrt(3.0)
U = np.array([[-1.0, 0.0, 0.0], [0.5, SQ3 / 2, 0.0], [0.5, -SQ3 / 2, 0.0]])  # eq. (3) over r
RADII = np.linspace(0.040, 0.029, 17)  # eq. (2): r_max at vertebra 1, r_min at vertebra 17
SMALL = DatabaseSpec(candidates=40_000, seed=5)


def eq5(Z, theta, psi):
    """Seed 004 eq. (5), one 4x4 matrix per sample."""
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    T = np.zeros(np.shape(Z) + (4, 4))
    T[..., 0, :] = np.stack([ct, st * sp, st * cp, 0 * Z], -1)
    T[..., 1, :] = np.stack([0 * Z, cp, -sp, 0 * Z], -1)
    T[..., 2, :] = np.stack([-st, sp * ct, ct * cp, Z], -1)
    T[..., 3, 3] = 1.0
    return T


def printed_legs(P: np.ndarray, k: int) -> np.ndarray:
    """(n, 3) leg lengths of platform k (0-based) by the printed eqs. (7)-(9)."""
    return np.stack(printed_leg_lengths(P[:, 0], P[:, 1], P[:, 2], RADII[k], RADII[k + 1]), axis=1)


def heights(P: np.ndarray, k: int) -> np.ndarray:
    """(n, 3) heights of the upper attachment points over the lower vertebra (eqs. 3-5)."""
    T = eq5(P[:, 0], P[:, 1], P[:, 2])
    return np.einsum("nj,mj->nm", T[:, 2, :3], RADII[k + 1] * U) + T[:, 2, 3][:, None]


def within_table_i(L: np.ndarray, k: int) -> np.ndarray:
    return np.all((L >= Q_MIN_MM[k] / 1000) & (L <= Q_MAX_MM[k] / 1000), axis=1)


@pytest.fixture(scope="module")
def db():
    return build_database(CBHAGeometry(), SMALL)


def test_every_row_within_table_i_and_upright_by_the_printed_equations(db):
    assert len(db) > 100
    for k in range(16):
        P = db.configurations[:, 3 * k : 3 * k + 3]
        L = printed_legs(P, k)
        assert within_table_i(L, k).all(), f"platform {k + 1}"
        assert (heights(P, k) >= 0).all(), f"platform {k + 1}"
        np.testing.assert_allclose(db.leg_lengths[:, 3 * k : 3 * k + 3], L, rtol=0, atol=1e-12)


def test_keeps_exactly_the_admissible_draws(db):
    """Recounting the same draws with the printed equations gives the kept counts, and the first
    kept draws are the database's rows in order."""
    for k in (0, 3, 8, 15):
        P = draw_candidates(SMALL, k)
        lo, hi = SMALL.box()
        assert (P >= lo).all() and (P <= hi).all()
        within = within_table_i(printed_legs(P, k), k)
        admissible = within & (heights(P, k) >= 0).all(axis=1)
        assert db.kept_table_i[k] == within.sum()
        assert db.kept[k] == admissible.sum()
        np.testing.assert_array_equal(db.configurations[:, 3 * k : 3 * k + 3], P[admissible][: len(db)])
    assert len(db) == db.kept.min()


def test_section_ends_are_the_exact_chain_of_eq5(db):
    for i in (0, len(db) // 2, len(db) - 1):
        T = np.eye(4)
        ends = []
        for k, (Z, theta, psi) in enumerate(db.configurations[i].reshape(-1, 3)):
            T = T @ eq5(Z, theta, psi)
            if k in (7, 15):
                ends.append(T[:3, 3])
        np.testing.assert_allclose(db.section_ends[i], ends, atol=1e-15)


def test_split_is_a_seeded_70_15_15_partition(db):
    parts = [db.train, db.validation, db.test]
    joined = np.concatenate(parts)
    assert np.array_equal(np.sort(joined), np.arange(len(db)))
    assert [abs(len(p) / len(db) - f) < 0.01 for p, f in zip(parts, (0.70, 0.15, 0.15))] == [True] * 3
    again = build_database(CBHAGeometry(), SMALL)
    assert np.array_equal(again.test, db.test) and np.array_equal(again.configurations, db.configurations)
    other = build_database(CBHAGeometry(), DatabaseSpec(candidates=40_000, seed=6))
    assert not np.array_equal(other.configurations[:10], db.configurations[:10])


def test_table_i_alone_keeps_folded_poses_the_upright_condition_removes(db):
    spec = DatabaseSpec(candidates=40_000, seed=5, require_upright=False)
    loose = build_database(CBHAGeometry(), spec)
    assert np.array_equal(loose.kept, loose.kept_table_i)
    assert np.array_equal(loose.kept_table_i, db.kept_table_i)
    assert (db.kept < db.kept_table_i).all()
    folded = np.concatenate(
        [(heights(loose.configurations[:, 3 * k : 3 * k + 3], k) < 0).any(axis=1) for k in range(16)]
    )
    assert folded.any()


def test_section_coupling_shares_one_draw_per_section():
    db = build_database(CBHAGeometry(), DatabaseSpec(candidates=150_000, seed=3, coupling="section"))
    P = db.configurations.reshape(len(db), 16, 3)
    assert np.array_equal(P[:, :8], np.repeat(P[:, :1], 8, axis=1))
    assert np.array_equal(P[:, 8:], np.repeat(P[:, 8:9], 8, axis=1))
    for k in range(16):
        assert within_table_i(printed_legs(P[:, k], k), k).all()
    assert db.kept_per_section() == tuple(db.kept)


def test_ranges_narrower_than_the_feasible_box_are_refused():
    with pytest.raises(ValueError, match="platform 1"):
        build_database(CBHAGeometry(), DatabaseSpec(candidates=1000, angle_range=(-0.1, 0.1)))
    with pytest.raises(ValueError, match="split"):
        DatabaseSpec(split=(0.8, 0.15, 0.15))
