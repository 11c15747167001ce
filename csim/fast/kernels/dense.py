"""Dense output of a step: each integrator's interpolant, built when first needed, and its
evaluation at a time inside the step.
"""
from csim.physics.status import OK
from csim.physics.tableaus import VERN7_P

from .common import CONSTANT, DOP853, NFEV, RADAU, RK45, TSIT5, VERN7, hot, inlined
from .system import feval_call
from .tableaus import DOP_A_EXTRA, DOP_C_EXTRA, DOP_D, DOP_NS, DOP_NX, DOP_POWER, V7_A_EXTRA, V7_C_EXTRA, V7_NS, V7_P


@hot
def _dense_weights(M, P, F):
    """Q^T = (M^T P)^T into F[:P.shape[1]]: the power-basis weights of a step's dense output from
    its stages M (s, n) (Radau's Z, an explicit pair's K) and the method's P (s, powers)."""
    for i in range(M.shape[1]):
        for p in range(P.shape[1]):
            acc = 0.0
            for a in range(P.shape[0]):
                acc += M[a, i] * P[a, p]
            F[p, i] = acc


@hot
def dense_eval(kind, tau, t_old, h, y_old, F, out):
    """The last step's interpolant at tau into out (kind: DOP853, RK4 (Hermite), RADAU, RK45, TSIT5, VERN7 or
    CONSTANT)."""
    n = y_old.size
    if kind == CONSTANT:
        for i in range(n):
            out[i] = y_old[i]
        return
    x = (tau - t_old) / h
    if kind == RADAU:  # scipy's RadauDenseOutput: y_old + Q (x, x^2, x^3), Q^T in F[:3]
        for i in range(n):
            out[i] = F[0, i] * x + F[1, i] * (x * x) + F[2, i] * (x * x * x) + y_old[i]
        return
    if kind in (RK45, TSIT5):  # scipy's RkDenseOutput: y_old + h Q (x, x^2, x^3, x^4), Q^T in F[:4]
        x2 = x * x
        x3 = x2 * x
        for i in range(n):
            out[i] = h * (F[0, i] * x + F[1, i] * x2 + F[2, i] * x3 + F[3, i] * (x3 * x)) + y_old[i]
        return
    if kind == VERN7:  # scipy's RkDenseOutput: y_old + h Q (x, ..., x^7), Q^T in F[:7], by Horner
        for i in range(n):
            v = 0.0
            for p in range(VERN7_P.shape[1] - 1, -1, -1):
                v = (v + F[p, i]) * x
            out[i] = h * v + y_old[i]
        return
    if kind == DOP853:
        # scipy's Dop853DenseOutput: nested products with x and 1 - x over F reversed
        for i in range(n):
            v = 0.0
            for p in range(DOP_POWER):
                v += F[DOP_POWER - 1 - p, i]
                if p % 2 == 0:
                    v *= x
                else:
                    v *= 1 - x
            out[i] = v + y_old[i]
    else:
        # cubic Hermite from F = [y_old, f_old, y_new, f_new]
        h00 = (1 + 2 * x) * (1 - x) ** 2
        h10 = x * (1 - x) ** 2
        h01 = x**2 * (3 - 2 * x)
        h11 = x**2 * (x - 1)
        for i in range(n):
            out[i] = h00 * F[0, i] + h10 * h * F[1, i] + h01 * F[2, i] + h11 * h * F[3, i]


@inlined
def _extra_stages(A, C, first, t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K, ytmp, info):
    """The stages an interpolant adds after a step (DOP853's three, Vern7's five) into
    K[first:]: K_s = f(t_old + c_s h, y_old + h sum_j a_sj K_j), j over every stage before s
    (the step's own, its new point and the extra stages before s). Returns the status."""
    n = y_old.size
    for e in range(C.size):
        s = first + e
        for i in range(n):
            acc = 0.0
            for jj in range(s):
                acc += K[jj, i] * A[e, jj]
            ytmp[i] = y_old[i] + acc * h
        code = feval_call(t_old + C[e] * h, ytmp, mode, locate, par, pf, pi, w, piv, K[s], info)
        if code != OK:
            return code
    return OK


@hot
def _dop_dense(t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info):
    """scipy's DOP853._dense_output_impl: three extra stages, then the interpolant F (7, n)."""
    n = y_old.size
    code = _extra_stages(DOP_A_EXTRA, DOP_C_EXTRA, DOP_NS + 1, t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K,
                         ytmp, info)
    if code != OK:
        return code
    for i in range(n):
        dy = y[i] - y_old[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2 * dy - h * (f[i] + K[0, i])
        for r in range(DOP_POWER - 3):
            acc = 0.0
            for jj in range(DOP_NX):
                acc += DOP_D[r, jj] * K[jj, i]
            F[3 + r, i] = h * acc
    return OK


@hot
def _vern7_dense(t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info):
    """Vern7's dense output (csim.solver.vern7): five extra stages after the ten and the new
    point in K[:11], then Q = K^T P into F[:7]."""
    code = _extra_stages(V7_A_EXTRA, V7_C_EXTRA, V7_NS + 1, t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K,
                         ytmp, info)
    if code != OK:
        return code
    _dense_weights(K[:V7_P.shape[0]], V7_P, F)
    return OK


@hot
def _ensure_dense(dense_ready, dense_kind, t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, cs,
                  info):
    """The step's dense output, built on its first use (DOP853's three extra stages, Vern7's five);
    returns the status.

    RK4's Hermite data, an empty step's constant and the 5(4) pairs' interpolant need no evaluation.
    """
    if dense_ready:
        return OK
    if dense_kind == VERN7:
        cs[NFEV] += V7_C_EXTRA.size
        return _vern7_dense(t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info)
    if dense_kind != DOP853:
        return OK
    cs[NFEV] += DOP_C_EXTRA.size
    return _dop_dense(t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info)
