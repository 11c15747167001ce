"""The equations of the stabilized index-2 formulation of Gear, Gupta and Leimkuhler (GGL).

With the state x = [q, v, W, mu, lambda] (2 m + k + 2 r) the DAE ``D x' = F(t, x)`` is

    q' = v - Phi_q^T mu                     (m)
    M v' = p - Phi_q^T lambda               (m),   p = B u - C v - h
    W' = u * B^T v                          (k, the loads' work: written by the caller)
    0  = Phi(q)                             (r)
    0  = Phi_q v                            (r)

:func:`ggl_equations` writes every row but the work's, from the model's terms at (q, v).
Both backends call it: :class:`csim.solver.ggl_system.GGLSystem` and the compiled kernels'
right-hand side (:mod:`csim.fast.kernels.system`). Matrices are flat, row-major.
"""
from __future__ import annotations

from csim.physics.jit import inline_kernel
from csim.physics.linalg import lu_factor, lu_solve


@inline_kernel
def ggl_equations(M, J, p, phi, phi_dot, v, mu, lam, LU, piv, q_dot, v_dot, alg, m, r):
    """The GGL rows of F. Returns False where M is singular (``v_dot`` is then undefined).

    Parameters
    ----------
    M : ndarray (m * m,)
        Mass matrix.
    J : ndarray (r * m,)
        Constraint Jacobian Phi_q.
    p : ndarray (m,)
        B u - C v - h.
    phi, phi_dot : ndarray (r,)
        Phi(q) and Phi_q v [unit of Phi, per second].
    v, mu, lam : ndarray (m,), (r,), (r,)
        The velocities and the two multipliers.
    LU : ndarray (m * m,)
        Scratch: the LU factors of M.
    piv : ndarray (m,) int
        Scratch: their pivots.
    q_dot, v_dot : ndarray (m,)
        Out: v - Phi_q^T mu and M^-1 (p - Phi_q^T lambda).
    alg : ndarray (2 r,)
        Out: [Phi, Phi_q v].
    """
    for i in range(m):  # q' = v - Phi_q^T mu;  the right-hand side p - Phi_q^T lambda
        a = v[i]
        b = p[i]
        for j in range(r):
            a -= J[j * m + i] * mu[j]
            b -= J[j * m + i] * lam[j]
        q_dot[i] = a
        v_dot[i] = b
    for i in range(r):
        alg[i] = phi[i]
        alg[r + i] = phi_dot[i]
    for i in range(m * m):
        LU[i] = M[i]
    if not lu_factor(LU, m, piv):
        return False
    lu_solve(LU, m, piv, v_dot)  # M v' = p - Phi_q^T lambda
    return True
