"""Radau IIA of order 5: scipy's ``Radau`` (simplified Newton on the transformed stages,
the difference Jacobian of ``num_jac`` capped as :class:`csim.solver.dae.DifferenceJacobian`
caps it, the error estimate and step-size predictor).
"""
import numpy as np

from csim.physics import radau as coefficients
from csim.physics.linalg import lu_factor, lu_solve
from csim.physics.radau import (
    JAC_MAX_FACTOR,
    MU_COMPLEX,
    MU_REAL,
    NEWTON_MAXITER,
    NUM_JAC_DIFF_BIG,
    NUM_JAC_DIFF_REJECT,
    NUM_JAC_DIFF_SMALL,
    NUM_JAC_FACTOR_DECREASE,
    NUM_JAC_FACTOR_INCREASE,
    NUM_JAC_MIN_FACTOR,
)
from csim.physics.status import NONFINITE_RHS, OK

from .common import (
    EPS,
    H_ABS,
    HSTEP,
    NFEV,
    NJEV,
    NLU,
    R_CURRENT_JAC,
    R_ERR_OLD,
    R_H_OLD,
    R_LU_OK,
    R_NEWTON_TOL,
    R_SOL,
    R_SOL_H,
    R_SOL_T,
    RADAU,
    T,
    hot,
    spacing,
)
from .control import MAX_FACTOR, MIN_FACTOR
from .dense import _dense_weights, dense_eval
from .system import feval_call

# Radau IIA coefficients, scipy's (csim.physics.radau)
RAD_C = np.ascontiguousarray(coefficients.C)
RAD_E = np.ascontiguousarray(coefficients.E)
RAD_T = np.ascontiguousarray(coefficients.T)
RAD_TI = np.ascontiguousarray(coefficients.TI)
RAD_TI_COMPLEX = np.ascontiguousarray(coefficients.TI_COMPLEX)
RAD_P = np.ascontiguousarray(coefficients.P)


# Radau's rows of RM (3 rows: the three stages): Newton's start Z0, the stage increments Z,
# W = T^-1 Z, its Newton increment dW, the stage derivatives F; the error scale, the error,
# E^T Z / h, a trial state, two difference columns, the difference step factors
R_Z0, R_Z, R_W, R_DW, R_F = 0, 3, 6, 9, 12
R_SCALE, R_ERR, R_ZE, R_YT, R_FC, R_FC2, R_FACTOR, R_ROWS = range(15, 23)


# ---------------------------------------------------------------------------------------
# Radau IIA of order 5: scipy's Radau (step, Newton iteration, error estimate, step-size
# control, dense output) with csim's capped forward-difference Jacobian
# (csim.solver.dae.DifferenceJacobian: scipy's num_jac)
# ---------------------------------------------------------------------------------------
@hot
def _radau_rms(M, row0, rows, scale):
    """scipy's norm(M[row0:row0 + rows] / scale): the root mean square over all rows x n entries."""
    n = scale.size
    s = 0.0
    for a in range(rows):
        for i in range(n):
            v = M[row0 + a, i] / scale[i]
            s += v * v
    return np.sqrt(s / (rows * n))


@hot
def _radau_column(t, yt, j, value, f, fc, par, pf, pi, rmode, locate, w, piv, cs, info):
    """One difference column: fc = F(t, yt) with yt[j] = value, then num_jac's (max_diff, scale):
    the largest |fc - f| and max(|f|, |fc|) where it is. Returns (status, max_diff, scale); a
    non-finite column is no failure (status OK)."""
    yt[j] = value
    cs[NFEV] += 1
    status = feval_call(t, yt, rmode, locate, par, pf, pi, w, piv, fc, info)
    if status == NONFINITE_RHS:
        status = OK
    best, at = -1.0, 0
    for i in range(f.size):
        v = abs(fc[i] - f[i])
        if v > best:
            best, at = v, i
    return status, best, max(abs(f[at]), abs(fc[at]))


@hot
def _radau_jacobian(t, y, f, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info):
    """J = df/dy (RJ, n * n row-major) by scipy's num_jac, column by column, its step factors
    (RM[R_FACTOR]) capped at JAC_MAX_FACTOR as csim.solver.dae.DifferenceJacobian does. Returns the status.

    Each column's step h_j = (y_j + factor_j y_scale_j) - y_j, y_scale_j = sign(f_j) max(atol_j, |y_j|);
    where the largest difference is below EPS^0.875 of the values, a ten times larger step is
    tried and kept if its difference is relatively larger; then the factor grows (x10) where
    the difference is below EPS^0.75 of the values and shrinks (x0.1) where above EPS^0.25.
    A non-finite column is kept as it is (the Newton iteration then fails and the step shrinks).
    """
    n = y.size
    cs[NJEV] += 1
    factor, yt, fc, fc2 = RM[R_FACTOR], RM[R_YT], RM[R_FC], RM[R_FC2]
    for i in range(n):
        yt[i] = y[i]
    for j in range(n):
        y_scale = (1.0 if f[j] >= 0 else -1.0) * max(tolv[j], abs(y[j]))
        hj = (y[j] + factor[j] * y_scale) - y[j]
        while hj == 0:
            factor[j] *= NUM_JAC_FACTOR_INCREASE
            hj = (y[j] + factor[j] * y_scale) - y[j]
        status, max_diff, scale = _radau_column(t, yt, j, y[j] + hj, f, fc, par, pf, pi, rmode, locate, w, piv, cs,
                                                info)
        if status != OK:
            return status
        if max_diff < NUM_JAC_DIFF_REJECT * scale:
            new_factor = NUM_JAC_FACTOR_INCREASE * factor[j]
            h_new = (y[j] + new_factor * y_scale) - y[j]
            status, max_diff_new, scale_new = _radau_column(t, yt, j, y[j] + h_new, f, fc2, par, pf, pi, rmode, locate,
                                                            w, piv, cs, info)
            if status != OK:
                return status
            if max_diff * scale_new < max_diff_new * scale:
                factor[j], hj, max_diff, scale = new_factor, h_new, max_diff_new, scale_new
                for i in range(n):
                    fc[i] = fc2[i]
        yt[j] = y[j]
        for i in range(n):
            RJ[i * n + j] = (fc[i] - f[i]) / hj
        if max_diff < NUM_JAC_DIFF_SMALL * scale:
            factor[j] *= NUM_JAC_FACTOR_INCREASE
        elif max_diff > NUM_JAC_DIFF_BIG * scale:
            factor[j] *= NUM_JAC_FACTOR_DECREASE
        factor[j] = min(max(factor[j], NUM_JAC_MIN_FACTOR), JAC_MAX_FACTOR)
    return OK


@hot
def _radau_lu(h, RJ, RLR, RLC, rpiv, n, cs):
    """LU factors of MU_REAL / h I - J (RLR) and MU_COMPLEX / h I - J (RLC); False if one is singular."""
    mr = MU_REAL / h
    mc = MU_COMPLEX / h
    for i in range(n):
        for j in range(n):
            RLR[i * n + j] = -RJ[i * n + j]
            RLC[i * n + j] = -RJ[i * n + j]
        RLR[i * n + i] += mr
        RLC[i * n + i] += mc
    cs[NLU] += 2
    ok_real = lu_factor(RLR, n, rpiv[:n])
    return ok_real and lu_factor(RLC, n, rpiv[n:])


@hot
def _radau_newton(t, y, h, scale, tol, RM, RLR, RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info):
    """scipy's solve_collocation_system: the stage increments Z (RM[R_Z:R_Z + 3]) by the simplified
    Newton iteration from Z0 (RM[R_Z0:]), in the variables W = T^-1 Z, where the iteration matrix
    splits into one real and one complex system. Returns (status, converged, iterations, rate)."""
    n = y.size
    mr = MU_REAL / h
    mc = MU_COMPLEX / h
    yt, F = RM[R_YT], RM[R_F:R_F + 3]
    for i in range(n):  # W = TI Z0, Z = Z0
        for a in range(3):
            acc = 0.0
            for b in range(3):
                acc += RAD_TI[a, b] * RM[R_Z0 + b, i]
            RM[R_W + a, i] = acc
            RM[R_Z + a, i] = RM[R_Z0 + a, i]
    dw_norm_old, rate, converged, k = -1.0, np.nan, False, 0
    while k < NEWTON_MAXITER:
        finite = True
        for s in range(3):
            for i in range(n):
                yt[i] = y[i] + RM[R_Z + s, i]
            cs[NFEV] += 1
            status = feval_call(t + h * RAD_C[s], yt, rmode, locate, par, pf, pi, w, piv, F[s], info)
            if status == NONFINITE_RHS:
                finite = False
            elif status != OK:
                return status, False, k + 1, rate
        if not finite:
            break
        # f_real = F^T TI_REAL - MU_REAL / h W_0; f_complex = F^T TI_COMPLEX - MU_COMPLEX / h (W_1 + i W_2)
        for i in range(n):
            fr = 0.0
            fcx = 0j
            for s in range(3):
                fr += F[s, i] * RAD_TI[0, s]
                fcx += F[s, i] * RAD_TI_COMPLEX[s]
            RM[R_DW, i] = fr - mr * RM[R_W, i]
            rcv[i] = fcx - mc * (RM[R_W + 1, i] + 1j * RM[R_W + 2, i])
        lu_solve(RLR, n, rpiv[:n], RM[R_DW])
        lu_solve(RLC, n, rpiv[n:], rcv)
        for i in range(n):
            RM[R_DW + 1, i] = rcv[i].real
            RM[R_DW + 2, i] = rcv[i].imag
        dw_norm = _radau_rms(RM, R_DW, 3, scale)
        if dw_norm_old >= 0:
            rate = dw_norm / dw_norm_old
            if rate >= 1 or rate ** (NEWTON_MAXITER - k) / (1 - rate) * dw_norm > tol:
                break
        for i in range(n):  # W += dW; Z = T W
            for a in range(3):
                RM[R_W + a, i] += RM[R_DW + a, i]
            for a in range(3):
                acc = 0.0
                for b in range(3):
                    acc += RAD_T[a, b] * RM[R_W + b, i]
                RM[R_Z + a, i] = acc
        if dw_norm == 0 or (dw_norm_old >= 0 and rate / (1 - rate) * dw_norm < tol):
            converged = True
            break
        dw_norm_old = dw_norm
        k += 1
    return OK, converged, min(k + 1, NEWTON_MAXITER), rate


@hot
def _radau_predict(h_abs, h_abs_old, error_norm, error_norm_old):
    """scipy's predict_factor (the predictive Gustafsson controller); NaN stands for None."""
    if error_norm == 0:
        return np.inf
    multiplier = 1.0
    if error_norm_old == error_norm_old and h_abs_old == h_abs_old:
        multiplier = h_abs / h_abs_old * (error_norm_old / error_norm) ** 0.25
    return min(1.0, multiplier) * error_norm ** -0.25


@hot
def _radau_start(ts_, y, f, tolv, rtol, RM, RJ, par, pf, pi, rmode, locate, w, piv, cs, info):
    """A new Radau integrator at (t, y): scipy's __init__ after the first step size (the Jacobian
    from a fresh difference factor, no LU, no dense output to start Newton from). Returns the status."""
    ts_[R_H_OLD] = np.nan
    ts_[R_ERR_OLD] = np.nan
    ts_[R_NEWTON_TOL] = max(10 * EPS / rtol, min(0.03, rtol ** 0.5))
    cs[R_LU_OK] = 0
    cs[R_SOL] = 0
    cs[R_CURRENT_JAC] = 1
    for i in range(y.size):
        RM[R_FACTOR, i] = EPS ** 0.5
    return _radau_jacobian(ts_[T], y, f, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)


@hot
def _radau_solve(t, y, f, h, scale, tolv, newton_tol, RM, RJ, RLR, RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv,
                 cs, info):
    """Newton on the collocation system at step h, with a new Jacobian (and LU factors) once if
    it does not converge with the current ones. Returns (status, converged, n_iter, rate)."""
    n = y.size
    converged, n_iter, rate = False, 0, np.nan
    while not converged:
        lu_ok = True
        if cs[R_LU_OK] == 0:
            lu_ok = _radau_lu(h, RJ, RLR, RLC, rpiv, n, cs)
            cs[R_LU_OK] = 1 if lu_ok else 0
        if lu_ok:
            status, converged, n_iter, rate = _radau_newton(t, y, h, scale, newton_tol, RM, RLR, RLC, rpiv, rcv, par,
                                                            pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, n_iter, rate
        if not converged:
            if cs[R_CURRENT_JAC] == 1:
                break
            status = _radau_jacobian(t, y, f, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, n_iter, rate
            cs[R_CURRENT_JAC] = 1
            cs[R_LU_OK] = 0
    return OK, converged, n_iter, rate


@hot
def _radau_error(t, h, y, f, y_new, tolv, rtol, rejected, RM, RLR, rpiv, par, pf, pi, rmode, locate, w, piv, cs, info):
    """y_new = y + Z_3 and the error estimate's norm: (E^T Z / h + f) solved with the real factor,
    once more from f at y + error after a rejected step (scipy's Radau). Returns (status, err_norm)."""
    n = y.size
    scale, err, ze = RM[R_SCALE], RM[R_ERR], RM[R_ZE]
    for i in range(n):
        y_new[i] = y[i] + RM[R_Z + 2, i]
        acc = 0.0
        for a in range(3):
            acc += RM[R_Z + a, i] * RAD_E[a]
        ze[i] = acc / h
        err[i] = f[i] + ze[i]
        scale[i] = tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol
    lu_solve(RLR, n, rpiv[:n], err)
    err_norm = _radau_rms(RM, R_ERR, 1, scale)
    if rejected and err_norm > 1:
        for i in range(n):
            RM[R_YT, i] = y[i] + err[i]
        cs[NFEV] += 1
        status = feval_call(t, RM[R_YT], rmode, locate, par, pf, pi, w, piv, err, info)
        if status != OK and status != NONFINITE_RHS:
            return status, err_norm
        for i in range(n):
            err[i] += ze[i]
        lu_solve(RLR, n, rpiv[:n], err)
        err_norm = _radau_rms(RM, R_ERR, 1, scale)
    return OK, err_norm


@hot
def _radau_step(ts_, t_end, rtol, tolv, max_step, y, f, F, y_old, y_new, f_new, RM, RJ, RLR, RLC, rpiv, rcv, par, pf,
                pi, rmode, locate, w, piv, cs, info):
    """One accepted Radau step from ts_[T] (scipy's Radau._step_impl). Returns (status, t_new, step_ok).

    The Newton iteration starts from the last step's dense output, extrapolated (its data: Q in
    F[:3], y_old, ts_[R_SOL_T], ts_[R_SOL_H]); the accepted step's Q = Z^T P goes to F[:3].
    """
    n = y.size
    t = ts_[T]
    min_step = 10 * spacing(t)
    if ts_[H_ABS] > max_step:
        h_abs, h_abs_old, err_old = max_step, np.nan, np.nan
    elif ts_[H_ABS] < min_step:
        h_abs, h_abs_old, err_old = min_step, np.nan, np.nan
    else:
        h_abs, h_abs_old, err_old = ts_[H_ABS], ts_[R_H_OLD], ts_[R_ERR_OLD]
    scale = RM[R_SCALE]
    rejected = False
    converged = False
    n_iter, rate, err_norm, safety, t_new = 0, np.nan, 0.0, 0.0, t
    while True:
        if h_abs < min_step:
            return OK, t, False
        t_new = t + h_abs
        if t_new - t_end > 0:
            t_new = t_end
        h = t_new - t
        h_abs = abs(h)
        for a in range(3):  # Z0: the last step's dense output at t + c h, less y (zero at a start)
            if cs[R_SOL] == 1:
                dense_eval(RADAU, t + h * RAD_C[a], ts_[R_SOL_T], ts_[R_SOL_H], y_old, F, RM[R_Z0 + a])
            for i in range(n):
                RM[R_Z0 + a, i] = RM[R_Z0 + a, i] - y[i] if cs[R_SOL] == 1 else 0.0
        for i in range(n):
            scale[i] = tolv[i] + abs(y[i]) * rtol
        status, converged, n_iter, rate = _radau_solve(t, y, f, h, scale, tolv, ts_[R_NEWTON_TOL], RM, RJ, RLR,
                                                       RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        if not converged:
            h_abs *= 0.5
            cs[R_LU_OK] = 0
            continue
        status, err_norm = _radau_error(t, h, y, f, y_new, tolv, rtol, rejected, RM, RLR, rpiv, par, pf, pi, rmode,
                                        locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
        if err_norm > 1:
            h_abs *= max(MIN_FACTOR, safety * _radau_predict(h_abs, h_abs_old, err_norm, err_old))
            cs[R_LU_OK] = 0
            rejected = True
        else:
            break
    recompute_jac = n_iter > 2 and rate > 1e-3
    factor = min(MAX_FACTOR, safety * _radau_predict(h_abs, h_abs_old, err_norm, err_old))
    if not recompute_jac and factor < 1.2:
        factor = 1.0
    else:
        cs[R_LU_OK] = 0
    cs[NFEV] += 1
    status = feval_call(t_new, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
    if status != OK and status != NONFINITE_RHS:
        return status, t, True
    if recompute_jac:
        status = _radau_jacobian(t_new, y_new, f_new, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        cs[R_CURRENT_JAC] = 1
    else:
        cs[R_CURRENT_JAC] = 0
    ts_[R_H_OLD] = ts_[H_ABS]
    ts_[R_ERR_OLD] = err_norm
    ts_[H_ABS] = h_abs * factor
    ts_[HSTEP] = h
    _dense_weights(RM[R_Z:R_Z + 3], RAD_P, F)  # the dense output y_old + Q (x, x^2, x^3), Q = Z^T P
    ts_[R_SOL_T] = t
    ts_[R_SOL_H] = h
    cs[R_SOL] = 1
    return OK, t_new, True
