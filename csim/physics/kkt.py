"""The augmented (KKT) system of the constrained equations of motion.

    [ M      Phi_q^T ] [ qdd    ]   [ p      ]
    [ Phi_q  0       ] [ lambda ] = [ gamma* ],    p = B u - C qd - h

solved by LU with partial pivoting (:mod:`csim.physics.linalg`).
"""
from __future__ import annotations

from csim.physics.jit import kernel
from csim.physics.linalg import lu_factor, lu_solve


@kernel
def generalized_forces(B, u, cqd, h, p):
    """p = B u - C qd - h (m,): applied minus velocity-dependent and gravity terms."""
    m, k = B.shape
    for i in range(m):
        Q = 0.0
        for kk in range(k):
            Q += B[i, kk] * u[kk]
        p[i] = Q - cqd[i] - h[i]


@kernel
def kkt_solve(M, J, p, gamma_star, A, x, piv):
    """Solve the KKT system; x (m + r,) = [qdd, lambda]. Returns False if it is singular.

    Parameters
    ----------
    M : ndarray (m, m)
        Mass matrix.
    J : ndarray (r, m)
        Constraint Jacobian Phi_q.
    p : ndarray (m,)
        B u - C qd - h.
    gamma_star : ndarray (r,)
        Right-hand side of the acceleration-level constraint, from the stabilization method.
    A : ndarray (m + r, m + r)
        Scratch: the KKT matrix, then its LU factors.
    x : ndarray (m + r,)
        Out: [qdd, lambda].
    piv : ndarray (m + r,) int
        Scratch: pivots.
    """
    m = M.shape[0]
    r = J.shape[0]
    for i in range(m):
        x[i] = p[i]
        for j in range(m):
            A[i, j] = M[i, j]
        for j in range(r):
            A[i, m + j] = J[j, i]
    for i in range(r):
        x[m + i] = gamma_star[i]
        for j in range(m):
            A[m + i, j] = J[i, j]
        for j in range(r):
            A[m + i, m + j] = 0.0
    if not lu_factor(A, piv):
        return False
    lu_solve(A, piv, x)
    return True


@kernel
def constraint_rates(J, qd, phi_dot):
    """dPhi/dt = Phi_q qd into phi_dot (r,)."""
    r, m = J.shape
    for i in range(r):
        v = 0.0
        for j in range(m):
            v += J[i, j] * qd[j]
        phi_dot[i] = v
