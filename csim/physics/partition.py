"""Coordinate partitioning: the state of a partition, its choice and its linear algebra.

The m coordinates q split into n = m - r independent ones u (``ind``) and r dependent ones
v (``dep``). This module holds what needs no model evaluation:

* :class:`Partition`, the state of a partitioned integration as views into one float and
  one integer array (:func:`partition_state`): the partition, the branch point anchored at
  the last accepted state, the Newton scratch, the failure details. The Python driver
  (:class:`csim.solver.partitioned.PartitionedSystem`) and the compiled kernels lay it out
  with the same function;
* the condition of a dependent block, ||Phi_q||_1 ||Phi_v^-1||_1 (:func:`block_inverse`);
* the choice of the partition (:func:`choose_partition`): the best-conditioned block by
  trying every one, or QR with column pivoting for mechanisms with many candidates;
* the branch tangent dv/du = -Phi_v^-1 Phi_u (:func:`branch_tangent`, through Phi_v's LU
  factors) and the test that a Newton solution continues the branch (:func:`same_branch`);
* the accelerations on the constraints' tangent space (:func:`reduced_accelerations`).

The solves that evaluate the model are in :mod:`csim.physics.branch`. Matrices are flat and
row-major: Phi_q (r * m), dv/du (r * n), Phi_v's LU factors (r * r, with their pivots).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from csim.physics.jit import jitable, kernel
from csim.physics.linalg import lu_factor, lu_solve
from csim.physics.projection import invert
from csim.physics.status import OK

#: Newton's solution may differ from the branch's prediction by at most this fraction of the
#: predicted (first-order) move (:func:`same_branch`)
BRANCH_CONTINUITY = 0.25
#: ... and dv/du there from dv/du at the start of the piece by at most this fraction of
#: max(1, max |dv/du|) at the start
BRANCH_TANGENT_CHANGE = 1.0
#: the way from the known point to the target is cut in pieces no shorter than this fraction of
#: the longest piece (:func:`csim.physics.branch.follow_branch`)
MIN_PIECE = 2.0**-12
#: ... and no piece moves a coordinate by more than this (rad, or m), by the linear prediction:
#: over a longer move (a trial stage half a turn of a crank ahead) the prediction can lie
#: nearer another assembly than its own, and Newton's solution there pass both tests
MAX_PIECE_MOVE = 0.5
#: restarts from one accepted state, after the branch was lost, before the run fails
MAX_BRANCH_RESTARTS = 2
#: above this many candidate partitions, choose by pivoted QR instead of trying them all
MAX_ENUMERATED_PARTITIONS = 500
#: ... or above this much work for their inversions, C(m, r) r^3 (a few milliseconds, for a choice
#: that a mechanism near a singular configuration makes after every step): QR costs O(m r^2)
MAX_ENUMERATION_WORK = 2e6
SQRT_EPS = 1.4901161193847656e-08
#: the test of :func:`same_branch` a solution failed
BRANCH_JUMP, BRANCH_TURN = 1, 2

# ---- the failure details (Partition.detail), read by csim.solver.failures.failure_message ----
#: [cause code, branch test (BRANCH_JUMP/BRANCH_TURN), coordinate, predicted, solved, measure, bound, max |Phi|],
#: then u (n) at the failed solve, then the independent coordinates' indices (n)
D_CODE, D_TEST, D_COORD, D_PRED, D_SOLVED, D_VALUE, D_BOUND, D_PHI = range(8)
D_HEAD = 8
# ---- the counters (Partition.count) ----
C_REPARTITIONS, C_BRANCH_RESTARTS, C_LOST_RESTARTS, C_LOST_SET, C_PENDING = range(5)
N_COUNT = 5

#: the state of a partitioned integration (see :func:`partition_state` for each field)
Partition = namedtuple("Partition", (
    "qa", "Ta", "Va",  # the branch point at the last accepted state: q (m), dv/du (r n), Phi_v's LU factors (r r)
    "qp", "Tp", "Vp",  # the branch point a piece of the way starts from
    "qe", "Te", "Ve",  # the last solution and its tangent (the anchor once accepted)
    "q", "phi", "J", "lu", "dv", "col", "cinv",  # Newton: iterate (m), Phi (r), Phi_q (r m), LU (r r), scratch
    "pred", "du", "dvl", "dirn", "gam", "u0", "tgt", "uu",  # the prediction and the pieces of the way
    "ym", "yf", "ff", "lost",  # model-call state, full state, its rate (2 m + k each); lost-at state (2 n + k)
    "basis", "resid",  # QR partition choice: orthonormal basis (r r), the columns' residuals (m r)
    "detail", "cause",  # failure details, and those of the breakdown being answered (D_HEAD + 2 n each)
    "MR", "RMR", "cv", "pc", "rp",  # the reduced accelerations: M R (m n), R^T M R (n n), c_v (r), p - M c (m),
    # R^T (p - M c) (n)
    "ind", "dep", "piv", "cand", "best", "old", "count", "npiv",  # integers (npiv: R^T M R's pivots, n)
    "pa", "pp", "pe",  # the pivots of Va, Vp, Ve (r each)
))


@jitable
def partition_sizes(m, r, k):
    """(floats, integers) that :func:`partition_state` lays out for m coordinates, r constraints, k loads."""
    n, s = m - r, 2 * m + k
    floats = 7 * m + 3 * r * n + 2 * r * m + 6 * r * r + 6 * r + 11 * n + 3 * s + k + 2 * D_HEAD + m * n + n * n
    return floats, 3 * n + 7 * r + N_COUNT


@jitable
def _take(buf, at, size):
    """(the view buf[at:at + size], where the next one starts)."""
    return buf[at:at + size], at + size


@jitable
def partition_state(fw, iw, m, r, k):
    """The :class:`Partition` of m coordinates, r constraints and k loads as views into fw and iw.

    fw and iw are at least :func:`partition_sizes` long; nothing is copied (a compiled caller
    builds the views at every use, for the cost of the slices).
    """
    n, s = m - r, 2 * m + k
    qa, a = _take(fw, 0, m)
    Ta, a = _take(fw, a, r * n)
    Va, a = _take(fw, a, r * r)
    qp, a = _take(fw, a, m)
    Tp, a = _take(fw, a, r * n)
    Vp, a = _take(fw, a, r * r)
    qe, a = _take(fw, a, m)
    Te, a = _take(fw, a, r * n)
    Ve, a = _take(fw, a, r * r)
    q, a = _take(fw, a, m)
    phi, a = _take(fw, a, r)
    J, a = _take(fw, a, r * m)
    lu, a = _take(fw, a, r * r)
    dv, a = _take(fw, a, r)
    col, a = _take(fw, a, r)
    cinv, a = _take(fw, a, r * r)
    pred, a = _take(fw, a, m)
    du, a = _take(fw, a, n)
    dvl, a = _take(fw, a, r)
    dirn, a = _take(fw, a, m)
    gam, a = _take(fw, a, r)
    u0, a = _take(fw, a, n)
    tgt, a = _take(fw, a, n)
    uu, a = _take(fw, a, n)
    ym, a = _take(fw, a, s)
    yf, a = _take(fw, a, s)
    ff, a = _take(fw, a, s)
    lost, a = _take(fw, a, 2 * n + k)
    basis, a = _take(fw, a, r * r)
    resid, a = _take(fw, a, m * r)
    detail, a = _take(fw, a, D_HEAD + 2 * n)
    cause, a = _take(fw, a, D_HEAD + 2 * n)
    MR, a = _take(fw, a, m * n)
    RMR, a = _take(fw, a, n * n)
    cv, a = _take(fw, a, r)
    pc, a = _take(fw, a, m)
    rp, a = _take(fw, a, n)
    ind, b = _take(iw, 0, n)
    dep, b = _take(iw, b, r)
    piv, b = _take(iw, b, r)
    cand, b = _take(iw, b, r)
    best, b = _take(iw, b, r)
    old, b = _take(iw, b, n)
    count, b = _take(iw, b, N_COUNT)
    npiv, b = _take(iw, b, n)
    pa, b = _take(iw, b, r)
    pp, b = _take(iw, b, r)
    pe, b = _take(iw, b, r)
    return Partition(qa, Ta, Va, qp, Tp, Vp, qe, Te, Ve, q, phi, J, lu, dv, col, cinv, pred, du, dvl, dirn, gam, u0,
                     tgt, uu, ym, yf, ff, lost, basis, resid, detail, cause, MR, RMR, cv, pc, rp, ind, dep, piv, cand,
                     best, old, count, npiv, pa, pp, pe)


def new_partition(m: int, r: int, k: int) -> Partition:
    """A :class:`Partition` over new zeroed arrays (the Python driver's)."""
    nf, ni = partition_sizes(m, r, k)
    return partition_state(np.zeros(max(nf, 1)), np.zeros(max(ni, 1), np.int64), m, r, k)


# ---------------------------------------------------------------------------------------
# linear algebra of a partition
# ---------------------------------------------------------------------------------------
@kernel
def block_inverse(J, dep, r, m, lu, piv, col, inv):
    """inv = Phi_v^-1 (r * r) of the columns ``dep`` of J (r * m); returns ||Phi_q||_1 ||Phi_v^-1||_1.

    The condition is measured against the whole Jacobian, not Phi_v alone, so that it also
    grows for a single constraint (a 1 x 1 block, whose own condition number is always 1):
    it is 1 for the best-placed block of an orthogonal Jacobian, and infinite where Phi_v is
    singular (inv is then left undefined).
    """
    for i in range(r):
        for j in range(r):
            lu[i * r + j] = J[i * m + dep[j]]
    if not invert(lu, lu, piv, col, inv, r):  # factored in place
        return np.inf
    # 1-norms: the largest absolute column sums
    norm_j = 0.0
    for j in range(m):
        s = 0.0
        for i in range(r):
            s += abs(J[i * m + j])
        norm_j = max(norm_j, s)
    norm_inv = 0.0
    for j in range(r):
        s = 0.0
        for i in range(r):
            s += abs(inv[i * r + j])
        if not s <= norm_inv:  # NaN propagates, as numpy's max
            norm_inv = s
    return norm_j * norm_inv


@kernel
def complement(dep, r, m, ind):
    """ind (m - r,) = the indices 0..m-1 not in dep, ascending (dep ascending too)."""
    a = 0
    b = 0
    for i in range(m):
        if b < r and dep[b] == i:
            b += 1
        else:
            ind[a] = i
            a += 1


@kernel
def n_partitions(m, r):
    """C(m, r), the number of candidate dependent blocks, capped just above MAX_ENUMERATED_PARTITIONS."""
    c = 1
    for i in range(min(r, m - r)):  # C(m, r) = C(m, m - r): the shorter product's partial values stay below it
        c = c * (m - i) // (i + 1)
        if c > MAX_ENUMERATED_PARTITIONS:
            return MAX_ENUMERATED_PARTITIONS + 1
    return c


@kernel
def enumerates(m, r):
    """Whether :func:`choose_partition` tries every dependent block: at most
    :data:`MAX_ENUMERATED_PARTITIONS` of them, and at most :data:`MAX_ENUMERATION_WORK` for
    their inversions (C(m, r) r^3)."""
    c = n_partitions(m, r)
    return c <= MAX_ENUMERATED_PARTITIONS and c * float(r) ** 3 <= MAX_ENUMERATION_WORK


@kernel
def choose_partition(J, r, m, ind, dep, cand, best, lu, piv, col, inv, basis, resid):
    """The partition of coordinates for a Jacobian J (r * m): ind (n,) and dep (r,), ascending.

    The dependent block Phi_v is the one with the smallest condition (:func:`block_inverse`), found by
    trying every choice of r of the m columns in lexicographic order (the first of equal ones)
    when that is cheap (:func:`enumerates`). Beyond that, QR with column pivoting (which
    orders the columns by how much each adds to the rank) picks its first r pivots, a good
    block though not always the best. ``basis`` (r * r) and ``resid`` (m * r) are the QR's
    scratch; ``cand``, ``best``, ``lu``, ``piv``, ``col`` and ``inv`` the enumeration's.
    """
    if not enumerates(m, r):
        _pivoted_qr_columns(J, r, m, dep, basis, resid)
    else:
        for i in range(r):
            cand[i] = i
            best[i] = i
        low = np.inf
        first = True
        while True:
            c = block_inverse(J, cand, r, m, lu, piv, col, inv)
            if first or c < low:
                low = c
                for i in range(r):
                    best[i] = cand[i]
            first = False
            # the next combination in lexicographic order
            i = r - 1
            while i >= 0 and cand[i] == m - r + i:
                i -= 1
            if i < 0:
                break
            cand[i] += 1
            for j in range(i + 1, r):
                cand[j] = cand[j - 1] + 1
        for i in range(r):
            dep[i] = best[i]
    complement(dep, r, m, ind)


@kernel
def _pivoted_qr_columns(J, r, m, dep, basis, resid):
    """dep = the first r pivots of QR with column pivoting of J (r * m), sorted (Businger-Golub:
    each the column with the largest part orthogonal to those chosen, the first of equal ones).

    resid (m * r) holds each column's part orthogonal to the basis so far, row j for column j:
    R_j = J_j - sum_b (q_b . J_j) q_b (classical Gram-Schmidt against the original column),
    brought up to date by one term per chosen column, so that the whole choice costs
    O(m r^2) instead of recomputing every projection for every candidate (O(m r^4)).
    """
    for j in range(m):
        for a in range(r):
            resid[j * r + a] = J[a * m + j]
    for c in range(r):
        big = -1.0
        pick = 0
        for j in range(m):
            if _taken(dep, c, j):
                continue
            norm = 0.0
            for a in range(r):
                norm += resid[j * r + a] * resid[j * r + a]
            if norm > big:
                big = norm
                pick = j
        dep[c] = pick
        norm = np.sqrt(big) if big > 0 else 0.0  # (no NaN: every norm NaN leaves big at -1)
        for a in range(r):  # q_c, the chosen column's orthogonal part normalized
            basis[c * r + a] = resid[pick * r + a] / norm if norm > 0 else 0.0
        for j in range(m):  # R_j -= (q_c . J_j) q_c for the columns still candidates
            if _taken(dep, c + 1, j):
                continue
            dot = 0.0
            for e in range(r):
                dot += basis[c * r + e] * J[e * m + j]
            for a in range(r):
                resid[j * r + a] -= dot * basis[c * r + a]
    for i in range(1, r):  # insertion sort: few entries
        v = dep[i]
        j = i - 1
        while j >= 0 and dep[j] > v:
            dep[j + 1] = dep[j]
            j -= 1
        dep[j + 1] = v


@kernel
def _taken(dep, c, j):
    """Whether column j is among the first c entries of dep."""
    for i in range(c):  # noqa: SIM110 (a loop, not a generator, in the compiled subset)
        if dep[i] == j:
            return True
    return False


@kernel
def dependent_step(J, phi, dep, r, m, lu, piv, dv):
    """dv (r,) from Phi_v dv = Phi (one Newton correction, v <- v - dv); False if Phi_v is singular."""
    for i in range(r):
        dv[i] = phi[i]
        for j in range(r):
            lu[i * r + j] = J[i * m + dep[j]]
    if not lu_factor(lu, r, piv):
        return False
    lu_solve(lu, r, piv, dv)
    return True


@kernel
def branch_tangent(J, ind, dep, r, m, lu, piv, col, T):
    """lu (r * r) = the LU factors of Phi_v (its pivots in piv, r), and T = dv/du = -Phi_v^-1 Phi_u (r * n),
    at the Jacobian J, column by column through the factors (``col`` (r,) is scratch).

    Phi_v^-1 is applied through its factors (:func:`csim.physics.linalg.lu_solve`), not formed: the
    inverse of the 40-loop N-four-bar's 80 x 80 block took 285 us of its factorization's 310 (its
    Jacobian is sparse, the inverse is not), two thirds of each right-hand side of ``minimal``.
    Returns False where Phi_v is singular or T is not finite (the branch folds back: v is no
    function of u there).
    """
    n = m - r
    for i in range(r):
        for j in range(r):
            lu[i * r + j] = J[i * m + dep[j]]
    if not lu_factor(lu, r, piv):
        return False
    ok = True
    for j in range(n):
        for i in range(r):
            col[i] = J[i * m + ind[j]]
        lu_solve(lu, r, piv, col)
        for i in range(r):
            T[i * n + j] = -col[i]
            if not np.isfinite(col[i]):
                ok = False
    return ok


@kernel
def reduced_accelerations(P, M, p, gamma, qdd, r, m):
    """qdd (m,) at the full state of the last solve on the branch (P.qe, with P.Te = dv/du and P.Ve, P.pe the LU
    factors of Phi_v there): the equations of motion projected onto the constraint manifold's tangent space.

    With R = [E_u; dv/du] (m * n: rows u the identity, rows v dv/du), whose columns span the null space of
    Phi_q, and c = [0_u; Phi_v^-1 gamma], every qdd = R udd + c meets Phi_q qdd = gamma, and R^T Phi_q^T = 0
    removes the multipliers from M qdd + Phi_q^T lambda = p:

        (R^T M R) udd = R^T (p - M c),    qdd = R udd + c

    an n x n solve where the KKT system is (m + r) x (m + r) (the same qdd in exact arithmetic; the
    multipliers are not formed). Returns False if R^T M R is singular (M singular on the tangent space, as
    the KKT matrix then is).

    Parameters
    ----------
    P : Partition
        Read: ind, dep, Te, Ve, pe; scratch: MR, RMR, cv, pc, rp, npiv.
    M, p, gamma : ndarray (m * m,), (m,), (r,)
        Mass matrix (row-major), B u - C qd - h, and gamma* (the method's: gamma for minimal).
    qdd : ndarray (>= m,)
        Out.
    """
    n = m - r
    T, ind, dep = P.Te, P.ind, P.dep
    for i in range(r):  # c_v = Phi_v^-1 gamma
        P.cv[i] = gamma[i]
    lu_solve(P.Ve, r, P.pe, P.cv)
    for a in range(m):  # p - M c, and M R: (M R)[:, j] = M[:, u_j] + sum_i M[:, v_i] (dv/du)[i, j]
        s = p[a]
        for i in range(r):
            s -= M[a * m + dep[i]] * P.cv[i]
        P.pc[a] = s
        for j in range(n):
            s = M[a * m + ind[j]]
            for i in range(r):
                s += M[a * m + dep[i]] * T[i * n + j]
            P.MR[a * n + j] = s
    for j in range(n):  # R^T M R and R^T (p - M c): row j of R^T is e_{u_j} + sum_i (dv/du)[i, j] e_{v_i}
        b = P.pc[ind[j]]
        for jj in range(n):
            P.RMR[j * n + jj] = P.MR[ind[j] * n + jj]
        for i in range(r):
            t = T[i * n + j]
            b += t * P.pc[dep[i]]
            for jj in range(n):
                P.RMR[j * n + jj] += t * P.MR[dep[i] * n + jj]
        P.rp[j] = b
    if not lu_factor(P.RMR, n, P.npiv):
        return False
    lu_solve(P.RMR, n, P.npiv, P.rp)
    for j in range(n):  # qdd = R udd + c
        qdd[ind[j]] = P.rp[j]
    for i in range(r):
        s = P.cv[i]
        for j in range(n):
            s += T[i * n + j] * P.rp[j]
        qdd[dep[i]] = s
    return True


@kernel
def _amax(x):
    out = 0.0
    for i in range(x.size):
        v = abs(x[i])
        if not v <= out:
            out = v
    return out


@kernel
def same_branch(qp, Tp, pred, qe, Te, du, dvl, dep, r, detail):
    """Whether Newton's solution qe (with tangent Te) continues the branch from (qp, Tp); OK, or the test it fails.

    Two tests, which a solution on another assembly fails unless the move is so large that
    the prediction lies nearer that assembly than its own (a four-bar's crank moved by 2 rad
    and more: the way is cut to MAX_PIECE_MOVE):

    * the prediction was good: ``max |v - v_pred| <= BRANCH_CONTINUITY max(max |du|, max |dv_lin|)
      + sqrt(eps) max(1, max |v_pred|)``. On the branch v(u) - v_pred is the remainder of the
      prediction, of third order in the move; another assembly lies a finite distance away
      whatever the move (the floor is the resolution of v, for a move of zero);
    * the branch turned by less than its own slope: ``max |(dv/du)_end - (dv/du)_start| <=
      BRANCH_TANGENT_CHANGE max(1, max |(dv/du)_start|)`` (another closure has another slope).

    On a failure, detail [D_TEST, D_COORD, D_PRED, D_SOLVED, D_VALUE, D_BOUND] say which test,
    with its numbers, and the coordinate that moved most from the prediction.
    """
    jump = 0.0
    v_max = 0.0
    for i in range(r):
        d = abs(qe[dep[i]] - pred[dep[i]])
        if not d <= jump:
            jump = d
        v_max = max(v_max, abs(pred[dep[i]]))
    bound = BRANCH_CONTINUITY * max(_amax(du), _amax(dvl)) + SQRT_EPS * max(1.0, v_max)
    code = OK
    value = 0.0
    if not jump <= bound:
        code, value = BRANCH_JUMP, jump
    else:
        turn = 0.0
        for i in range(Te.size):
            d = abs(Te[i] - Tp[i])
            if not d <= turn:
                turn = d
        bound = BRANCH_TANGENT_CHANGE * max(1.0, _amax(Tp))
        if not turn <= bound:
            code, value = BRANCH_TURN, turn
    if code != OK:
        worst = 0
        for i in range(qe.size):
            if abs(qe[i] - pred[i]) > abs(qe[worst] - pred[worst]):
                worst = i
        detail[D_TEST] = code
        detail[D_COORD] = worst
        detail[D_PRED] = pred[worst]
        detail[D_SOLVED] = qe[worst]
        detail[D_VALUE] = value
        detail[D_BOUND] = bound
    return code
