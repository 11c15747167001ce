"""The choice of a coordinate partition (csim.physics.partition), against independent references:
the binomial coefficient, LAPACK's QR with column pivoting, and trying every block."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.linalg

from csim.physics.partition import (
    MAX_ENUMERATED_PARTITIONS,
    MAX_ENUMERATION_WORK,
    block_inverse,
    choose_partition,
    enumerates,
    n_partitions,
)


def _choose(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r, m = J.shape
    ind, dep = np.empty(m - r, np.int64), np.empty(r, np.int64)
    choose_partition(np.ascontiguousarray(J).ravel(), r, m, ind, dep, np.empty(r, np.int64), np.empty(r, np.int64),
                     np.empty(r * r), np.empty(r, np.int64), np.empty(r), np.empty(r * r), np.empty(r * r),
                     np.empty(m * r))
    return ind, dep


@pytest.mark.parametrize("m, r", [(5, 4), (9, 6), (10, 3), (33, 32), (81, 80), (34, 32), (20, 10), (3, 3)])
def test_the_count_of_blocks_is_the_binomial_coefficient_capped(m, r):
    # the 80 dependent coordinates of the 40-loop N-four-bar have 81 blocks, not "more than 500"
    # (the partial products C(81, 2), C(81, 3), ... exceed the cap on the way to C(81, 80))
    assert n_partitions(m, r) == min(math.comb(m, r), MAX_ENUMERATED_PARTITIONS + 1)


def test_every_block_is_tried_only_where_their_inversions_are_cheap():
    assert enumerates(9, 6) and enumerates(33, 32)  # 33 blocks of 32 x 32: about 1e6 flops
    assert not enumerates(41, 40)  # 41 of 40 x 40: 2.6e6
    assert math.comb(81, 80) <= MAX_ENUMERATED_PARTITIONS and MAX_ENUMERATION_WORK < 81 * 80.0**3
    assert not enumerates(81, 80)  # 81 inversions of 80 x 80: pivoted QR instead
    assert not enumerates(20, 10)  # 184,756 blocks


def test_an_enumerated_choice_is_the_best_conditioned_block():
    rng = np.random.default_rng(3)
    r, m = 3, 7
    J = rng.standard_normal((r, m))
    _, dep = _choose(J)
    scratch = (np.empty(r * r), np.empty(r, np.int64), np.empty(r), np.empty(r * r))
    conditions = {c: block_inverse(J.ravel(), np.array(c, np.int64), r, m, *scratch)
                  for c in itertools.combinations(range(m), r)}
    assert tuple(dep) == min(conditions, key=conditions.get)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("r, extra", [(80, 1), (40, 3), (12, 9)])
def test_the_pivoted_qr_choice_is_lapacks(seed, r, extra):
    # LAPACK's geqp3 pivots on the largest remaining column norm too (Businger-Golub); with
    # columns of distinct sizes the two choose the same r columns
    m = r + extra
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((r, m)) * rng.uniform(0.5, 2.0, m)
    assert not enumerates(m, r)
    ind, dep = _choose(J)
    _, _, perm = scipy.linalg.qr(J, pivoting=True, mode="economic")
    assert sorted(perm[:r]) == list(dep)
    assert sorted([*ind, *dep]) == list(range(m))
    assert np.linalg.cond(J[:, dep]) < 1e6


def test_the_pivoted_qr_choice_passes_over_a_repeated_column():
    r, m = 30, 33
    rng = np.random.default_rng(7)
    J = rng.standard_normal((r, m))
    J[:, 5] = J[:, 4]  # two equal columns: at most one of them can be dependent
    J[:, 9] = 0.0  # a coordinate no constraint involves is independent
    ind, dep = _choose(J)
    assert 9 in ind and not {4, 5} <= set(dep)
    assert np.linalg.matrix_rank(J[:, dep]) == r


@pytest.mark.parametrize("m, r, singular", [(3, 2, False), (5, 2, False), (8, 7, False), (6, 0, False),
                                              (5, 2, True), (8, 5, True)])
def test_the_reduced_accelerations_equal_the_kkt_solution(m, r, singular):
    """(R^T M R) udd = R^T (p - M c), qdd = R udd + c (partition.reduced_accelerations, minimal's right-hand side)
    against the (m + r) KKT system on random problems: the same qdd, on the constraints' acceleration level;
    also where M is singular but regular on the tangent space (``singular``: rank n), as the KKT system is."""
    from csim.physics.partition import branch_tangent, complement, new_partition, reduced_accelerations
    from csim.solver.formulations import KKT

    rng = np.random.default_rng(m * 10 + r)
    A = rng.normal(size=(m, m))
    M, J, p, gamma = A @ A.T + m * np.eye(m), rng.normal(size=(r, m)), rng.normal(size=m), rng.normal(size=r)
    if singular:  # M of rank n = m - r, singular off the tangent space (massless parts the constraints hold)
        B = rng.normal(size=(m, m - r))
        M = B @ B.T
    P = new_partition(m, r, 0)
    P.dep[:] = np.sort(rng.choice(m, size=r, replace=False))
    complement(P.dep, r, m, P.ind)
    assert branch_tangent(J.ravel(), P.ind, P.dep, r, m, P.Ve, P.pe, P.col, P.Te)
    qdd = np.empty(m)
    assert reduced_accelerations(P, M.ravel(), p, gamma, qdd, r, m)
    qdd_kkt, _ = KKT().solve(M, J, p, gamma)
    np.testing.assert_allclose(qdd, qdd_kkt, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(J @ qdd, gamma, atol=1e-11)
