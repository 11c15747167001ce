"""Radau IIA of order 5: scipy's ``Radau`` (simplified Newton on the transformed stages,
the difference Jacobian of ``num_jac`` capped as :class:`csim.solver.dae.DifferenceJacobian`
caps it, the error estimate and step-size predictor), and on GGL's DAE ``D x' = F(t, x)``
(:data:`csim.fast.layout.GGL`) the algorithm of :class:`csim.solver.dae.RadauDAE` (whose steps it takes
to a few in a thousand: where Newton's increments are at the round-off of the multipliers, the rate that
decides on a new Jacobian is round-off, and LAPACK's LU and csim's round differently).

On a DAE the first ``nd`` rows (:func:`_n_differential`) are differential (D_ii = 1) and the
others algebraic of index 2. What RadauDAE adds to scipy's Radau, each marked ``dae`` below:
the iteration matrices MU / h D - J; the index-2 rows' tolerance scale divided by h; the
difference steps floored independently of atol; the Newton iteration continued until the
algebraic residual at the step's end is within its tolerance (the polish), and stopped as
converged where its increments are down to the round-off of F; a smallest step not below
10 eps times the interval; a rejected step where the error estimate is not finite; and the
reason of a failure, in the details of STEP_TOO_SMALL (:mod:`csim.physics.radau`, DAE_*).
"""
import numpy as np

from csim.fast.layout import GGL, PI_FPAR, PI_NC, PI_SYS
from csim.physics import radau as coefficients
from csim.physics.linalg import lu_factor, lu_solve
from csim.physics.radau import (
    DAE_ALGEBRAIC,
    DAE_COLS,
    DAE_DIVERGED,
    DAE_ERROR_TEST,
    DAE_H,
    DAE_NCOLS,
    DAE_NO_CONVERGENCE,
    DAE_NONFINITE_F,
    DAE_NONFINITE_INCREMENT,
    DAE_REASON,
    DAE_RESIDUAL0,
    DAE_SINGULAR_MATRIX,
    DAE_SINGULAR_REPEATED,
    DAE_SLOW,
    DAE_T,
    DAE_TOL,
    DAE_VALUE,
    DAE_ZERO_COLUMNS,
    JAC_ALGEBRAIC_THRESHOLD,
    JAC_DIFFERENTIAL_THRESHOLD,
    JAC_MAX_FACTOR,
    MAX_SINGULAR,
    MU_COMPLEX,
    MU_REAL,
    NEWTON_MAXITER,
    NUM_JAC_DIFF_BIG,
    NUM_JAC_DIFF_REJECT,
    NUM_JAC_DIFF_SMALL,
    NUM_JAC_FACTOR_DECREASE,
    NUM_JAC_FACTOR_INCREASE,
    NUM_JAC_MIN_FACTOR,
    ROUNDOFF_FACTOR,
)
from csim.physics.radau import NOISE_FACTOR as RADAU_NOISE_FACTOR
from csim.physics.status import (
    NONFINITE_RHS,
    OK,
    STEP_TOO_SMALL,
)

from .common import (
    EPS,
    H_ABS,
    HSTEP,
    NFEV,
    NJEV,
    NLU,
    R_CURRENT_JAC,
    R_ERR_OLD,
    R_FAIL,
    R_FAIL_TOL,
    R_FAIL_VALUE,
    R_H_OLD,
    R_LU_OK,
    R_NEWTON_TOL,
    R_NSING,
    R_SOL,
    R_SOL_H,
    R_SOL_T,
    RADAU,
    SEG_START,
    T,
    hot,
    inlined,
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
# E^T Z / h, a trial state, two difference columns, the difference step factors, the
# difference steps' thresholds; on a DAE the algebraic rows' tolerances, F at the step's end
# (the polish) and the Newton increments of F's round-off
R_Z0, R_Z, R_W, R_DW, R_F = 0, 3, 6, 9, 12
R_SCALE, R_ERR, R_ZE, R_YT, R_FC, R_FC2, R_FACTOR, R_THRESHOLD, R_ALG_TOL, R_F_END, R_NOISE, R_ROWS = range(15, 27)


@inlined
def _n_differential(pi, n):
    """The differential rows of the integrated state (n,): the first 2 m + k of GGL's DAE, else all."""
    if pi[PI_SYS] == GGL:
        return n - 2 * pi[PI_NC]
    return n


@inlined
def _details(info):
    """The failure's details in the loop's info: info[2:], but for its last slot (feval's, csim.fast.kernels.driver)."""
    return info[2:info.size - 1]


@hot
def _dae_failed(reason, t, h, value, tol, residual0, info):
    """STEP_TOO_SMALL with the details of a failed Radau on a DAE (csim.physics.radau, DAE_*): info[0] = t."""
    info[0] = t
    d = _details(info)
    d[DAE_REASON], d[DAE_T], d[DAE_H], d[DAE_VALUE], d[DAE_TOL], d[DAE_RESIDUAL0] = reason, t, h, value, tol, residual0
    d[DAE_NCOLS] = 0.0
    return STEP_TOO_SMALL


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
def _radau_jacobian(t, y, f, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info):
    """J = df/dy (RJ, n * n row-major) by scipy's num_jac, column by column, its step factors
    (RM[R_FACTOR]) capped at JAC_MAX_FACTOR as csim.solver.dae.DifferenceJacobian does. Returns the status.

    Each column's step h_j = (y_j + factor_j y_scale_j) - y_j, y_scale_j = sign(f_j) max(threshold_j, |y_j|)
    (RM[R_THRESHOLD]: atol, floored on a DAE); where the largest difference is below EPS^0.875 of the values,
    a ten times larger step is tried and kept if its difference is relatively larger; then the factor grows
    (x10) where the difference is below EPS^0.75 of the values and shrinks (x0.1) where above EPS^0.25.
    A non-finite column is kept as it is (the Newton iteration then fails and the step shrinks).
    """
    n = y.size
    cs[NJEV] += 1
    factor, threshold, yt, fc, fc2 = RM[R_FACTOR], RM[R_THRESHOLD], RM[R_YT], RM[R_FC], RM[R_FC2]
    for i in range(n):
        yt[i] = y[i]
    for j in range(n):
        y_scale = (1.0 if f[j] >= 0 else -1.0) * max(threshold[j], abs(y[j]))
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
def _radau_lu(h, RJ, RLR, RLC, rpiv, n, nd, cs):
    """LU factors of MU_REAL / h D - J (RLR) and MU_COMPLEX / h D - J (RLC), D = diag(1 on the nd differential
    rows, 0 on the others); False if one is singular (on a DAE the complex one is not factored then)."""
    mr = MU_REAL / h
    mc = MU_COMPLEX / h
    for i in range(n):
        for j in range(n):
            RLR[i * n + j] = -RJ[i * n + j]
            RLC[i * n + j] = -RJ[i * n + j]
        if i < nd:
            RLR[i * n + i] += mr
            RLC[i * n + i] += mc
    # (one call site per factorization: an inlined function's every call site is a copy to compile)
    if nd == n:  # scipy factors both, and counts both
        cs[NLU] += 2
    else:  # dae: RadauDAE counts the factorizations it makes, and takes a non-finite J for singular
        cs[NLU] += 1
        for i in range(n * n):
            if not RJ[i] < np.inf or not RJ[i] > -np.inf:
                return False
    if not lu_factor(RLR, n, rpiv[:n]):
        return False
    if nd != n:
        cs[NLU] += 1
    return lu_factor(RLC, n, rpiv[n:])


@inlined
def _row_size(RJ, y, i):
    """sum_j |J_ij| |y_j|: the size of row i's terms at y (RJ, n * n row-major), for its round-off."""
    n = y.size
    acc = 0.0
    for j in range(n):
        acc += abs(RJ[i * n + j]) * abs(y[j])
    return acc


@hot
def _radau_noise(y, scale, RM, RJ, RLR, rpiv):
    """dae: the scaled rms of the Newton increments that F's round-off alone makes, |(MU_REAL / h D - J)^-1 r|,
    r = NOISE_FACTOR eps |J| |y| (csim.solver.dae.RadauDAE._solve_collocation)."""
    n = y.size
    noise = RM[R_NOISE]
    for i in range(n):
        noise[i] = RADAU_NOISE_FACTOR * EPS * _row_size(RJ, y, i)
    lu_solve(RLR, n, rpiv[:n], noise)
    for i in range(n):
        noise[i] = abs(noise[i])
    return _radau_rms(RM, R_NOISE, 1, scale)


@hot
def _radau_polish(t_new, y, nd, RM, par, pf, pi, rmode, locate, w, piv, cs, info):
    """dae: F at the step's end y + Z_3 into RM[R_F_END]; returns (status, the largest algebraic residual over
    its tolerance RM[R_ALG_TOL], the row where it is; -1 where F is not finite)."""
    n = y.size
    yt, f_end, alg_tol = RM[R_YT], RM[R_F_END], RM[R_ALG_TOL]
    for i in range(n):
        yt[i] = y[i] + RM[R_Z + 2, i]
    cs[NFEV] += 1
    status = feval_call(t_new, yt, rmode, locate, par, pf, pi, w, piv, f_end, info)
    if status == NONFINITE_RHS:
        return OK, np.inf, -1
    excess, at = 0.0, nd
    for i in range(nd, n):
        v = abs(f_end[i]) / alg_tol[i]
        if v > excess:
            excess, at = v, i
    return status, excess, at


@hot
def _radau_increment(h, nd, scale, RM, RLR, RLC, rpiv, rcv):
    """The Newton increment dW (RM[R_DW:R_DW + 3]) from the stages' F (RM[R_F:]) and W (RM[R_W:]): the real and
    the complex system, (MU / h D - J) dW = f with f_real = F^T TI_REAL - MU_REAL / h D W_0 and
    f_complex = F^T TI_COMPLEX - MU_COMPLEX / h D (W_1 + i W_2), D = 1 on the nd differential rows. Returns
    its scaled rms."""
    n = scale.size
    mr = MU_REAL / h
    mc = MU_COMPLEX / h
    for i in range(n):
        fr = 0.0
        fcx = 0j
        for s in range(3):
            fr += RM[R_F + s, i] * RAD_TI[0, s]
            fcx += RM[R_F + s, i] * RAD_TI_COMPLEX[s]
        if i < nd:
            fr -= mr * RM[R_W, i]
            fcx -= mc * (RM[R_W + 1, i] + 1j * RM[R_W + 2, i])
        RM[R_DW, i] = fr
        rcv[i] = fcx
    lu_solve(RLR, n, rpiv[:n], RM[R_DW])
    lu_solve(RLC, n, rpiv[n:], rcv)
    for i in range(n):
        RM[R_DW + 1, i] = rcv[i].real
        RM[R_DW + 2, i] = rcv[i].imag
    return _radau_rms(RM, R_DW, 3, scale)


@hot
def _radau_newton(t, t_new, y, h, scale, tol, RM, RJ, RLR, RLC, rpiv, rcv, ts_, par, pf, pi, rmode, locate, w, piv,
                  cs, info):
    """scipy's solve_collocation_system: the stage increments Z (RM[R_Z:R_Z + 3]) by the simplified
    Newton iteration from Z0 (RM[R_Z0:]), in the variables W = T^-1 Z, where the iteration matrix
    splits into one real and one complex system. Returns (status, converged, iterations, rate).

    On a DAE (RadauDAE's): the last stage at t_new itself, the residuals with D, convergence also where the
    increments are down to F's round-off, then the polish (F at the step's end, RM[R_F_END], which stands for
    the last stage's F in the iterations after it); a failure's reason into cs[R_FAIL] (with its numbers
    in ts_[R_FAIL_VALUE], ts_[R_FAIL_TOL])."""
    n = y.size
    nd = _n_differential(pi, n)
    dae = nd < n
    yt, F = RM[R_YT], RM[R_F:R_F + 3]
    noise_norm = _radau_noise(y, scale, RM, RJ, RLR, rpiv) if dae else -1.0
    for i in range(n):  # W = TI Z0, Z = Z0
        for a in range(3):
            acc = 0.0
            for b in range(3):
                acc += RAD_TI[a, b] * RM[R_Z0 + b, i]
            RM[R_W + a, i] = acc
            RM[R_Z + a, i] = RM[R_Z0 + a, i]
    dw_norm_old, rate, converged, k = -1.0, np.nan, False, 0
    polishing, excess, at = False, 0.0, 0
    cs[R_FAIL] = DAE_NO_CONVERGENCE
    while k < NEWTON_MAXITER:
        finite = True
        for s in range(3):
            if polishing and s == 2:  # dae: F at the step's end, from the polish
                for i in range(n):
                    F[2, i] = RM[R_F_END, i]
                continue
            for i in range(n):
                yt[i] = y[i] + RM[R_Z + s, i]
            cs[NFEV] += 1
            ts = t_new if dae and s == 2 else t + h * RAD_C[s]
            status = feval_call(ts, yt, rmode, locate, par, pf, pi, w, piv, F[s], info)
            if status == NONFINITE_RHS:
                finite = False
            elif status != OK:
                return status, False, k + 1, rate
        if not finite:
            cs[R_FAIL] = DAE_NONFINITE_F
            break
        dw_norm = _radau_increment(h, nd, scale, RM, RLR, RLC, rpiv, rcv)
        if k > 0 and (dw_norm_old > 0 or not dae):  # (RadauDAE: after a nonzero increment; scipy: after any)
            rate = dw_norm / dw_norm_old
        if dae and not dw_norm < np.inf:  # (NaN or inf)
            cs[R_FAIL] = DAE_NONFINITE_INCREMENT
            break
        at_noise = dw_norm <= noise_norm
        if not polishing and not at_noise and rate == rate and (
                rate >= 1 or rate ** (NEWTON_MAXITER - k) / (1 - rate) * dw_norm > tol):
            cs[R_FAIL] = DAE_DIVERGED if rate >= 1 else DAE_SLOW
            break
        for i in range(n):  # W += dW; Z = T W
            for a in range(3):
                RM[R_W + a, i] += RM[R_DW + a, i]
            for a in range(3):
                acc = 0.0
                for b in range(3):
                    acc += RAD_T[a, b] * RM[R_W + b, i]
                RM[R_Z + a, i] = acc
        if polishing or at_noise or dw_norm == 0 or (rate == rate and rate / (1 - rate) * dw_norm < tol):
            if not dae:
                converged = True
                break
            polishing = True  # dae: until max |F_alg| at the step's end is within its tolerance
            status, excess, at = _radau_polish(t_new, y, nd, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, k + 1, rate
            if at < 0:
                cs[R_FAIL] = DAE_NONFINITE_F
                break
            if excess <= 1:
                converged = True
                break
        dw_norm_old = dw_norm
        k += 1
    if not converged and polishing and at >= 0 and cs[R_FAIL] == DAE_NO_CONVERGENCE:
        cs[R_FAIL] = DAE_ALGEBRAIC
        ts_[R_FAIL_VALUE] = abs(RM[R_F_END, at])
        ts_[R_FAIL_TOL] = RM[R_ALG_TOL, at]
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
    from a fresh difference factor, no LU, no dense output to start Newton from). Returns the status.

    The difference steps' thresholds: atol (scipy's), on a DAE floored at JAC_DIFFERENTIAL_THRESHOLD and
    JAC_ALGEBRAIC_THRESHOLD (RadauDAE's)."""
    n = y.size
    nd = _n_differential(pi, n)
    ts_[R_H_OLD] = np.nan
    ts_[R_ERR_OLD] = np.nan
    ts_[R_NEWTON_TOL] = max(10 * EPS / rtol, min(0.03, rtol ** 0.5))
    cs[R_LU_OK] = 0
    cs[R_SOL] = 0
    cs[R_CURRENT_JAC] = 1
    for i in range(n):
        RM[R_FACTOR, i] = EPS ** 0.5
        RM[R_THRESHOLD, i] = tolv[i]
        if nd < n:
            RM[R_THRESHOLD, i] = max(tolv[i], JAC_DIFFERENTIAL_THRESHOLD if i < nd else JAC_ALGEBRAIC_THRESHOLD)
    return _radau_jacobian(ts_[T], y, f, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)


@hot
def _radau_singular(t, n, nd, RJ, cs, info):
    """dae: after a singular iteration matrix, STEP_TOO_SMALL where halving the step cannot help (with a current
    Jacobian, the columns of algebraic variables that F does not depend on) or after MAX_SINGULAR in this step;
    else OK (RadauDAE._step_impl)."""
    if cs[R_CURRENT_JAC] == 1:
        d = _details(info)
        count = 0
        for j in range(nd, n):
            zero = True
            for i in range(n):
                if RJ[i * n + j] != 0.0:
                    zero = False
                    break
            if zero and DAE_COLS + count < d.size:
                d[DAE_COLS + count] = j
                count += 1
        if count:
            status = _dae_failed(np.int64(DAE_ZERO_COLUMNS), t, np.nan, np.nan, np.nan, np.nan, info)
            d[DAE_NCOLS] = count
            return status
    cs[R_NSING] += 1
    if cs[R_NSING] >= MAX_SINGULAR:
        return _dae_failed(np.int64(DAE_SINGULAR_REPEATED), t, np.nan, float(cs[R_NSING]), np.nan, np.nan, info)
    return OK


@hot
def _radau_solve(t, t_new, y, f, h, scale, newton_tol, RM, RJ, RLR, RLC, rpiv, rcv, ts_, par, pf, pi, rmode, locate,
                 w, piv, cs, info):
    """Newton on the collocation system at step h, with a new Jacobian (and LU factors) once if
    it does not converge with the current ones. Returns (status, converged, n_iter, rate)."""
    n = y.size
    nd = _n_differential(pi, n)
    converged, n_iter, rate = False, 0, np.nan
    while not converged:
        lu_ok = True
        if cs[R_LU_OK] == 0:
            lu_ok = _radau_lu(h, RJ, RLR, RLC, rpiv, n, nd, cs)
            cs[R_LU_OK] = 1 if lu_ok else 0
        if lu_ok:
            status, converged, n_iter, rate = _radau_newton(t, t_new, y, h, scale, newton_tol, RM, RJ, RLR, RLC, rpiv,
                                                            rcv, ts_, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, n_iter, rate
        elif nd < n:
            cs[R_FAIL] = DAE_SINGULAR_MATRIX
            status = _radau_singular(t, n, nd, RJ, cs, info)
            if status != OK:
                return status, False, n_iter, rate
        if not converged:
            if cs[R_CURRENT_JAC] == 1:
                break
            status = _radau_jacobian(t, y, f, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, n_iter, rate
            cs[R_CURRENT_JAC] = 1
            cs[R_LU_OK] = 0
    return OK, converged, n_iter, rate


@hot
def _radau_error(t, h, y, f, y_new, tolv, rtol, rejected, nd, RM, RLR, rpiv, par, pf, pi, rmode, locate, w, piv, cs,
                 info):
    """y_new = y + Z_3 and the error estimate's norm: (D E^T Z / h + f) solved with the real factor,
    once more from f at y + error after a rejected step (scipy's Radau); on a DAE the index-2 rows' scale
    divided by |h|. Returns (status, err_norm)."""
    n = y.size
    scale, err, ze = RM[R_SCALE], RM[R_ERR], RM[R_ZE]
    for i in range(n):
        y_new[i] = y[i] + RM[R_Z + 2, i]
        acc = 0.0
        for a in range(3):
            acc += RM[R_Z + a, i] * RAD_E[a]
        ze[i] = acc / h if i < nd else 0.0
        err[i] = f[i] + ze[i]
        scale[i] = tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol
        if i >= nd:
            scale[i] /= abs(h)
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
def _radau_algebraic_tolerances(y, nd, algebraic_tol, RM, RJ):
    """dae: each algebraic row's tolerance at the step's end, algebraic_tol raised to the row's round-off
    ROUNDOFF_FACTOR eps |J_i| |y| (RadauDAE._step_impl), into RM[R_ALG_TOL]."""
    for i in range(nd, y.size):
        RM[R_ALG_TOL, i] = max(algebraic_tol, ROUNDOFF_FACTOR * EPS * _row_size(RJ, y, i))


@hot
def _radau_min_step(ts_, t, t_end, dae):
    """The smallest step: ten times the spacing of the numbers at t (scipy's), on a DAE not below ten eps times
    the integrator's interval (RadauDAE's)."""
    if dae:
        return 10 * max(spacing(t), EPS * abs(t_end - ts_[SEG_START]))
    return 10 * spacing(t)


@hot
def _radau_step(ts_, t_end, rtol, tolv, max_step, y, f, F, y_old, y_new, f_new, RM, RJ, RLR, RLC, rpiv, rcv, par, pf,
                pi, rmode, locate, w, piv, cs, info):
    """One accepted Radau step from ts_[T] (scipy's Radau._step_impl; on a DAE RadauDAE's). Returns (status, t_new,
    step_ok): step_ok False where the step fell below the smallest one (on a DAE with the reason in info[2:]).

    The Newton iteration starts from the last step's dense output, extrapolated (its data: Q in
    F[:3], y_old, ts_[R_SOL_T], ts_[R_SOL_H]); the accepted step's Q = Z^T P goes to F[:3].
    """
    n = y.size
    nd = _n_differential(pi, n)
    dae = nd < n
    t = ts_[T]
    min_step = _radau_min_step(ts_, t, t_end, dae)
    if ts_[H_ABS] > max_step:
        h_abs, h_abs_old, err_old = max_step, np.nan, np.nan
    elif ts_[H_ABS] < min_step:
        h_abs, h_abs_old, err_old = min_step, np.nan, np.nan
    else:
        h_abs, h_abs_old, err_old = ts_[H_ABS], ts_[R_H_OLD], ts_[R_ERR_OLD]
    if dae:
        _radau_algebraic_tolerances(y, nd, pf[pi[PI_FPAR] + 1], RM, RJ)  # (GGL's fpar: [projection tol, ggl_tol])
    scale = RM[R_SCALE]
    # (numpy's scalars, not literals: a callee passed a literal False or 0 was compiled once for it and again for
    # the variable's type; so RADAU, the reasons and OK below)
    rejected = np.bool_(False)
    converged = False
    newton_failure = np.int64(0)  # dae: the reason of the last failed Newton attempt (0: none since the error test)
    cs[R_NSING] = 0
    n_iter, rate, err_norm, safety, t_new = 0, np.nan, 0.0, 0.0, t
    while True:
        if h_abs < min_step:
            if dae:
                _radau_too_small(t, h_abs, newton_failure, y, f, nd, ts_, cs, info)
            return OK, t, False
        t_new = t + h_abs
        if t_new - t_end > 0:
            t_new = t_end
        h = t_new - t
        h_abs = abs(h)
        for a in range(3):  # Z0: the last step's dense output at t + c h, less y (zero at a start)
            if cs[R_SOL] == 1:
                dense_eval(np.int64(RADAU), t + h * RAD_C[a], ts_[R_SOL_T], ts_[R_SOL_H], y_old, F, RM[R_Z0 + a])
            for i in range(n):
                RM[R_Z0 + a, i] = RM[R_Z0 + a, i] - y[i] if cs[R_SOL] == 1 else 0.0
        for i in range(n):
            scale[i] = tolv[i] + abs(y[i]) * rtol
            if i >= nd:  # dae: index-2 rows
                scale[i] /= h_abs
        status, converged, n_iter, rate = _radau_solve(t, t_new, y, f, h, scale, ts_[R_NEWTON_TOL], RM, RJ, RLR,
                                                       RLC, rpiv, rcv, ts_, par, pf, pi, rmode, locate, w, piv, cs,
                                                       info)
        if status == STEP_TOO_SMALL:  # dae: singular for every step (details in info): a step not taken, counted
            return OK, t, False
        if status != OK:
            return status, t, True
        if not converged:
            newton_failure = cs[R_FAIL]
            h_abs *= 0.5
            cs[R_LU_OK] = 0
            continue
        status, err_norm = _radau_error(t, h, y, f, y_new, tolv, rtol, rejected, nd, RM, RLR, rpiv, par, pf, pi,
                                        rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
        if dae and not err_norm < np.inf:  # dae: a non-finite estimate rejects the step
            newton_failure = 0
            h_abs *= MIN_FACTOR
            cs[R_LU_OK] = 0
            rejected = True
        elif err_norm > 1:
            newton_failure = 0
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
    status = _radau_accept(ts_, t, t_new, h, h_abs * factor, err_norm, recompute_jac, dae, y_new, f_new, F, RM, RJ,
                           par, pf, pi, rmode, locate, w, piv, cs, info)
    return status, (t_new if status == OK else t), True


@hot
def _radau_accept(ts_, t, t_new, h, h_next, err_norm, recompute_jac, dae, y_new, f_new, F, RM, RJ, par, pf, pi, rmode,
                  locate, w, piv, cs, info):
    """Go on from the accepted step to (t_new, y_new): f_new (on a DAE the polish's F at the step's end), the
    Jacobian there where it is to be recomputed, the next step h_next, and the dense output's data. Returns
    the status."""
    if dae:
        for i in range(y_new.size):
            f_new[i] = RM[R_F_END, i]
    else:
        cs[NFEV] += 1
        status = feval_call(t_new, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
        if status != OK and status != NONFINITE_RHS:
            return status
    if recompute_jac:
        status = _radau_jacobian(t_new, y_new, f_new, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status
        cs[R_CURRENT_JAC] = 1
    else:
        cs[R_CURRENT_JAC] = 0
    ts_[R_H_OLD] = ts_[H_ABS]
    ts_[R_ERR_OLD] = err_norm
    ts_[H_ABS] = h_next
    ts_[HSTEP] = h
    _dense_weights(RM[R_Z:R_Z + 3], RAD_P, F)  # the dense output y_old + Q (x, x^2, x^3), Q = Z^T P
    ts_[R_SOL_T] = t
    ts_[R_SOL_H] = h
    cs[R_SOL] = 1
    return OK


@hot
def _radau_too_small(t, h_abs, newton_failure, y, f, nd, ts_, cs, info):
    """dae: the details of a step fallen below the smallest one (the last Newton failure's reason, else the error
    test's; on the first step max |F_alg(t0, y0)|) into info[2:], for STEP_TOO_SMALL's message."""
    residual0 = np.nan
    if cs[R_SOL] == 0:  # the first step: suspect the initial state
        residual0 = 0.0
        for i in range(nd, y.size):
            residual0 = max(residual0, abs(f[i]))
    reason = newton_failure if newton_failure else DAE_ERROR_TEST
    value, tol = (ts_[R_FAIL_VALUE], ts_[R_FAIL_TOL]) if reason == DAE_ALGEBRAIC else (np.nan, np.nan)
    _dae_failed(reason, t, h_abs, value, tol, residual0, info)
