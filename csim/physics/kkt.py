"""The augmented (KKT) system of the constrained equations of motion.

    [ M      Phi_q^T ] [ qdd    ]   [ p      ]
    [ Phi_q  0       ] [ lambda ] = [ gamma* ],    p = B u - C qd - h

solved by LU with partial pivoting (:mod:`csim.physics.linalg`). Matrices are flat and
row-major: M (m * m), Phi_q (r * m), B (m * k); the sizes come from the vectors.
"""
from __future__ import annotations

from csim.physics.jit import inline_kernel
from csim.physics.linalg import lu_factor, lu_solve


@inline_kernel
def generalized_forces(B, u, cqd, h, p, m, k):
    """p = B u - C qd - h (m,): applied minus velocity-dependent and gravity terms; B flat (m * k)."""
    for i in range(m):
        Q = 0.0
        for kk in range(k):
            Q += B[i * k + kk] * u[kk]
        p[i] = Q - cqd[i] - h[i]


@inline_kernel
def kkt_solve(M, J, p, gamma_star, A, x, piv, m, r):
    """Solve the KKT system; x (m + r,) = [qdd, lambda]. Returns False if it is singular.

    Parameters
    ----------
    M : ndarray (m * m,)
        Mass matrix, row-major.
    J : ndarray (r * m,)
        Constraint Jacobian Phi_q, row-major.
    p : ndarray (m,)
        B u - C qd - h.
    gamma_star : ndarray (r,)
        Right-hand side of the acceleration-level constraint, from the stabilization method.
    A : ndarray ((m + r)^2,)
        Scratch: the KKT matrix, then its LU factors.
    x : ndarray (m + r,)
        Out: [qdd, lambda].
    piv : ndarray (>= m + r,) int
        Scratch: pivots.
    m, r : int
        Coordinates and constraints (arguments, not array sizes, so that compiled code
        that passes constants gets loops of known length).
    """
    n = m + r
    for i in range(m):
        x[i] = p[i]
        for j in range(m):
            A[i * n + j] = M[i * m + j]
        for j in range(r):
            A[i * n + m + j] = J[j * m + i]
    for i in range(r):
        x[m + i] = gamma_star[i]
        for j in range(m):
            A[(m + i) * n + j] = J[i * m + j]
        for j in range(r):
            A[(m + i) * n + m + j] = 0.0
    if not lu_factor(A, n, piv):
        return False
    lu_solve(A, n, piv, x)
    return True


@inline_kernel
def constraint_rates(J, qd, phi_dot, r, m):
    """dPhi/dt = Phi_q qd into phi_dot (r,), with Phi_q flat (r * m)."""
    for i in range(r):
        v = 0.0
        for j in range(m):
            v += J[i * m + j] * qd[j]
        phi_dot[i] = v
