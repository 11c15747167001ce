"""The elimination formulation's solve (the paper's eqs. 8-10), the same code on both backends.

The coordinates split into independent u (n = m - r) and dependent v (r). With the null-space
matrix R (m * n), whose rows u are the identity and whose rows v are dv/du = -Phi_v^-1 Phi_u,
the equations of motion premultiplied by R^T and the acceleration-level constraint give

    [R^T M ] qdd = [R^T p ]
    [Phi_q ]       [gamma*]

an m x m system for qdd, and the dependent rows give the multipliers,
Phi_v^T lambda = (p - M qdd)_v.

The partition is the state of an :data:`EliminationState` (:func:`elimination_state`: views
into one float and one integer array): chosen at the first solve
(:func:`csim.physics.partition.choose_partition`) or fixed by ``formulation.independent``, kept
while ||Phi_q||_1 ||Phi_v^-1||_1 <= ``max_condition``, chosen again (counted) where that is
exceeded. The Python path (:class:`csim.solver.formulations.Elimination`) and the compiled
kernels (:func:`csim.fast.kernels.system.eliminated`) call :func:`eliminate` alike. Matrices
are flat, row-major.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from csim.physics.jit import inline_kernel, jitable, kernel
from csim.physics.linalg import lu_factor, lu_solve
from csim.physics.partition import block_inverse, choose_partition, complement
from csim.physics.status import ELIMINATION_FIXED_SINGULAR, ELIMINATION_NO_BLOCK, ELIMINATION_SINGULAR, OK

#: the counters (EliminationState.count): whether the partition is set, how many times it was chosen again
E_CHOSEN, E_REPARTITIONS = 0, 1

#: the elimination's state: the partition u (ind, n) and v (dep, r), Phi_v^-1 (V, r r) and dv/du (T, r n) of
#: the last solve, (p - M qdd)_v (res, r); scratch of block_inverse (lu, piv, col) and of choose_partition
#: (cand, best, inv, basis, resid); the counters
EliminationState = namedtuple("EliminationState", (
    "V", "T", "res", "lu", "col", "inv", "basis", "resid",  # floats
    "ind", "dep", "piv", "cand", "best", "count",  # integers
))


@jitable
def elimination_sizes(m, r):
    """(floats, integers) that :func:`elimination_state` lays out for m coordinates and r constraints."""
    n = m - r
    return 4 * r * r + r * n + 2 * r + m * r, n + 4 * r + 2


@jitable
def elimination_state(fw, iw, m, r):
    """The :data:`EliminationState` of m coordinates and r constraints as views into fw and iw (at least
    :func:`elimination_sizes` long); nothing is copied."""
    n = m - r
    a, b = r * r, r * r + r * n
    V, T, res = fw[:a], fw[a:b], fw[b:b + r]
    a = b + r
    lu, col, inv = fw[a:a + r * r], fw[a + r * r:a + r * r + r], fw[a + r * r + r:a + 2 * r * r + r]
    a += 2 * r * r + r
    basis, resid = fw[a:a + r * r], fw[a + r * r:a + r * r + m * r]
    ind, dep, piv = iw[:n], iw[n:n + r], iw[n + r:n + 2 * r]
    cand, best, count = iw[n + 2 * r:n + 3 * r], iw[n + 3 * r:n + 4 * r], iw[n + 4 * r:n + 4 * r + 2]
    return EliminationState(V, T, res, lu, col, inv, basis, resid, ind, dep, piv, cand, best, count)


def new_elimination(m: int, r: int) -> EliminationState:
    """An :data:`EliminationState` over new zeroed arrays (the Python path's)."""
    nf, ni = elimination_sizes(m, r)
    return elimination_state(np.zeros(max(nf, 1)), np.zeros(ni, np.int64), m, r)


@kernel
def _choose(J, E, r, m):
    """E.ind, E.dep = the best partition for J (csim.physics.partition.choose_partition)."""
    choose_partition(J, r, m, E.ind, E.dep, E.cand, E.best, E.lu, E.piv, E.col, E.inv, E.basis, E.resid)


# inlined (numba's IR) into their one compiled caller, the kernels' ``eliminated`` called by address: passed on
# to a call, each array of the state is a struct of seven words (the right-hand side 263 -> 226 ns, m = 3, r = 2)
@inline_kernel
def _partition(J, E, fixed, given, max_condition, r, m):
    """Set E's partition for J and E.V = Phi_v^-1; returns the status code.

    The first call takes ``given`` (n,) ascending (``fixed``) or chooses; every call keeps the
    partition while ||Phi_q||_1 ||Phi_v^-1||_1 <= ``max_condition``, else chooses again (a fixed
    one fails).
    """
    if E.count[E_CHOSEN] == 0:
        if fixed:
            for j in range(m - r):
                E.ind[j] = given[j]
            complement(E.ind, m - r, m, E.dep)
        else:
            _choose(J, E, r, m)
        E.count[E_CHOSEN] = 1
    cond = block_inverse(J, E.dep, r, m, E.lu, E.piv, E.col, E.V)
    if cond > max_condition:
        if fixed:
            return ELIMINATION_FIXED_SINGULAR
        _choose(J, E, r, m)
        E.count[E_REPARTITIONS] += 1
        cond = block_inverse(J, E.dep, r, m, E.lu, E.piv, E.col, E.V)
        if cond > max_condition:
            return ELIMINATION_NO_BLOCK
    return OK


@inline_kernel
def eliminate(M, J, p, gamma_star, E, fixed, given, max_condition, A, x, piv, m, r):
    """x (m + r,) = [qdd, lambda] by the elimination (module docstring); returns the status code.

    Parameters
    ----------
    M, J, p, gamma_star : ndarray (m * m,), (r * m,), (m,), (r,)
        Mass matrix, Phi_q, B u - C qd - h, and the method's gamma*.
    E : EliminationState
        The partition's state (read and updated).
    fixed : bool
        Whether the independent coordinates are ``given`` (formulation.independent).
    given : ndarray (n,) int
        Those coordinates, ascending (read only when ``fixed``).
    max_condition : float
        The largest ||Phi_q||_1 ||Phi_v^-1||_1 kept.
    A : ndarray (>= m * m,)
        Scratch: [R^T M; Phi_q], then its LU factors.
    x : ndarray (>= m + r,)
        Out.
    piv : ndarray (>= m,) int
        Scratch.
    m, r : int
        Coordinates and constraints.
    """
    code = _partition(J, E, fixed, given, max_condition, r, m)
    if code != OK:
        return code
    n = m - r
    ind, dep, V, T = E.ind, E.dep, E.V, E.T
    for i in range(r):  # T = dv/du = -Phi_v^-1 Phi_u (r * n)
        for j in range(n):
            s = 0.0
            for c in range(r):
                s += V[i * r + c] * J[c * m + ind[j]]
            T[i * n + j] = -s
    for a in range(n):  # the rows R^T M qdd = R^T p, R^T = [E, T^T] over (u, v)
        u = ind[a]
        b = p[u]
        for k in range(m):
            A[a * m + k] = M[u * m + k]
        for i in range(r):
            t = T[i * n + a]
            v = dep[i]
            b += t * p[v]
            for k in range(m):
                A[a * m + k] += t * M[v * m + k]
        x[a] = b
    for c in range(r):  # the rows Phi_q qdd = gamma*
        for k in range(m):
            A[(n + c) * m + k] = J[c * m + k]
        x[n + c] = gamma_star[c]
    if not lu_factor(A, m, piv):
        return ELIMINATION_SINGULAR
    lu_solve(A, m, piv, x)
    res = E.res  # (p - M qdd)_v
    for j in range(r):
        v = dep[j]
        s = p[v]
        for k in range(m):
            s -= M[v * m + k] * x[k]
        res[j] = s
    for c in range(r):  # Phi_v^T lambda = (p - M qdd)_v: lambda = V^T res
        s = 0.0
        for j in range(r):
            s += V[j * r + c] * res[j]
        x[m + c] = s
    return OK
