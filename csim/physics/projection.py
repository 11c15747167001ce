"""Projection onto the constraint manifold: the Gauss-Newton correction and its stopping rules.

With the metric W (the identity, or the mass matrix M), one correction of a residual res
(Phi for positions, Phi_q qd + Phi_t for velocities) is

    dq = W^-1 Phi_q^T (Phi_q W^-1 Phi_q^T)^-1 res,

the smallest step in the W-norm that removes res to first order. Positions iterate
q <- q - dq until max |Phi| <= tol or dq is down to the round-off of q; velocities need
one correction (the velocity constraint is linear in qd). Matrices are flat, row-major.
:func:`project` is the whole projection, which both backends run with their model handle
(:mod:`csim.physics.model`).
"""
from __future__ import annotations

from csim.physics.jit import jitable, kernel
from csim.physics.kkt import constraint_rates
from csim.physics.linalg import lu_factor, lu_solve
from csim.physics.model import model_jacobian, model_mass, model_phi, model_phi_t
from csim.physics.status import OK, PROJ_NO_CONVERGENCE, PROJ_SINGULAR, SINGULAR_MASS

EPS = 2.220446049250313e-16


@kernel
def max_abs(x):
    """max |x_i| (0 for an empty x); NaN if any entry is NaN, as numpy's max."""
    out = 0.0
    for i in range(x.size):
        v = abs(x[i])
        if v != v:
            return v
        if v > out:
            out = v
    return out


@kernel
def at_round_off(dq, q):
    """Whether a Newton correction dq is down to the round-off of q: max |dq| <= 8 eps max(1, max |q|).

    Phi evaluated at large coordinates (a crank after many turns) carries a round-off of
    about eps |q|, below which no correction can go.
    """
    return max_abs(dq) <= 8 * EPS * max(1.0, max_abs(q))


@kernel
def invert(M, LU, piv, col, Minv, m):
    """Minv = M^-1 (m * m), column by column through the LU factors of M (copied into LU).

    ``col`` (m,) is scratch. Returns False if M is singular.
    """
    for i in range(m * m):
        LU[i] = M[i]
    if not lu_factor(LU, m, piv):
        return False
    for c in range(m):
        for i in range(m):
            col[i] = 1.0 if i == c else 0.0
        lu_solve(LU, m, piv, col)
        for i in range(m):
            Minv[i * m + c] = col[i]
    return True


@kernel
def correction(J, Winv, mass_metric, res, WJt, S, z, piv, dq, r, m):
    """dq (m,) = W^-1 J^T (J W^-1 J^T)^-1 res, with W^-1 = Winv (mass metric) or the identity.

    Parameters
    ----------
    J : ndarray (r * m,)
        Constraint Jacobian Phi_q.
    Winv : ndarray (m * m,)
        M^-1 (read only when ``mass_metric``).
    res : ndarray (r,)
        The residual to remove.
    WJt, S, z, piv : ndarray (m * r,), (r * r,), (r,), (>= r,) int
        Scratch.
    dq : ndarray (m,)
        Out: the correction.

    r, m : int
        Constraints and coordinates.

    Returns False if J W^-1 J^T is singular (J has lost rank).
    """
    for i in range(m):
        for c in range(r):
            if mass_metric:
                v = 0.0
                for j in range(m):
                    v += Winv[i * m + j] * J[c * m + j]
                WJt[i * r + c] = v
            else:
                WJt[i * r + c] = J[c * m + i]
    for a in range(r):
        for b in range(r):
            v = 0.0
            for j in range(m):
                v += J[a * m + j] * WJt[j * r + b]
            S[a * r + b] = v
    for a in range(r):
        z[a] = res[a]
    if not lu_factor(S, r, piv):
        return False
    lu_solve(S, r, piv, z)
    for i in range(m):
        v = 0.0
        for c in range(r):
            v += WJt[i * r + c] * z[c]
        dq[i] = v
    return True


@jitable(inline=True)  # one compiled caller per backend, called once per step
def project(model, q, qd, tol, mass_metric, max_iter, m, r, M, LU, Winv, piv, col, phi, J, WJt, S, z, dq, phi_dot):
    """Project (q, qd) (m,) in place onto Phi = 0 and Phi_q qd + Phi_t = 0. Returns (code, max |Phi| of the last
    iterate). Phi and Phi_t are the model's at the handle's time (a drive row q_j - f_j(t) and its -f_j'(t)).

    Positions by Gauss-Newton until max |Phi| <= ``tol`` or the correction is down to the
    round-off of q (at most ``max_iter`` corrections), then velocities by one correction,
    both in the metric W = M (``mass_metric``) or the identity. Codes: OK, SINGULAR_MASS,
    PROJ_SINGULAR (J W^-1 J^T singular), PROJ_NO_CONVERGENCE.

    Parameters
    ----------
    M, LU, Winv : ndarray (m * m,)
        Scratch: the mass matrix, its LU factors, M^-1 (read only with the mass metric).
    piv, col : ndarray (>= max(m, r),) int, (m,)
        Scratch.
    phi, J, WJt, S, z, dq, phi_dot : ndarray (r,), (r * m,), (m * r,), (r * r,), (r,), (m,), (r,)
        Scratch (Phi, Phi_q and the correction's).
    """
    if mass_metric:  # W^-1 = M^-1
        model_mass(model, q, M)
        if not invert(M, LU, piv, col, Winv, m):
            return SINGULAR_MASS, 0.0
    converged = False
    mx = 0.0
    for _ in range(max_iter + 1):
        model_phi(model, q, phi)
        mx = max_abs(phi)
        if mx <= tol:
            converged = True
            break
        model_jacobian(model, q, J)
        if not correction(J, Winv, mass_metric, phi, WJt, S, z, piv, dq, r, m):
            return PROJ_SINGULAR, mx
        for i in range(m):
            q[i] -= dq[i]
        if at_round_off(dq, q):  # |Phi| cannot go lower: its round-off grows with |q|
            converged = True
            break
    if not converged:
        return PROJ_NO_CONVERGENCE, mx
    model_jacobian(model, q, J)
    constraint_rates(J, qd, phi_dot, r, m)
    model_phi_t(model, q, z)  # d/dt Phi = Phi_q qd + Phi_t (Phi_t: drive rows only); z is scratch until the correction
    for i in range(r):
        phi_dot[i] += z[i]
    if not correction(J, Winv, mass_metric, phi_dot, WJt, S, z, piv, dq, r, m):
        return PROJ_SINGULAR, mx
    for i in range(m):
        qd[i] -= dq[i]
    return OK, mx
