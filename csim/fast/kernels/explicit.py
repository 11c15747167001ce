"""The adaptive explicit Runge-Kutta step of DOP853, RK45, Tsit5 and Vern7: scipy's
``RungeKutta._step_impl`` with each pair's tableau and error estimate.
"""
import numpy as np

from csim.physics.status import OK

from .common import DOP853, H_ABS, HSTEP, NFEV, RK45, TSIT5, VERN7, T, hot, sized, spacing
from .control import MAX_FACTOR, MIN_FACTOR, SAFETY, _error_order
from .dense import _dense_weights
from .system import feval_call
from .tableaus import (
    DOP_A,
    DOP_B,
    DOP_C,
    DOP_E3,
    DOP_E5,
    DOP_NS,
    ERK_A,
    ERK_B,
    ERK_C,
    ERK_E,
    ERK_NS,
    ERK_P,
    V7_A,
    V7_B,
    V7_C,
    V7_E,
    V7_NS,
)


@hot
def _dop853_error(K, y, y_new, tolv, rtol, hstep):
    """scipy DOP853._estimate_error_norm: the scaled error norm of the step."""
    n = y.size
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        sc = tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol
        a5 = 0.0
        a3 = 0.0
        for jj in range(DOP_NS + 1):
            a5 += K[jj, i] * DOP_E5[jj]
            a3 += K[jj, i] * DOP_E3[jj]
        a5 /= sc
        a3 /= sc
        e5 += a5 * a5
        e3 += a3 * a3
    if e5 == 0 and e3 == 0:
        return 0.0
    return abs(hstep) * e5 / np.sqrt((e5 + 0.01 * e3) * n)


@sized
def _rk_stages(A, B, C, ns, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode, locate, w, piv, cs, info):
    """scipy's rk_step with the tableau (A, B, C) of ns stages (DOP853's, or a 5(4) pair's): the
    stages, y_new and f_new = f(t + h, y_new) into K[ns]. Returns the status. (Inlined where
    called: DOP853's tables and stage count stay constants of its loop.)"""
    n = y.size
    for i in range(n):
        K[0, i] = f[i]
    for s in range(1, ns):
        for i in range(n):  # dy = (K[:s]^T a[:s]) h
            acc = 0.0
            for jj in range(s):
                acc += K[jj, i] * A[s, jj]
            ytmp[i] = y[i] + acc * hstep
        cs[NFEV] += 1
        status = feval_call(t + C[s] * hstep, ytmp, rmode, locate, par, pf, pi, w, piv, K[s], info)
        if status != OK:
            return status
    for i in range(n):  # y_new = y + h K[:s]^T B
        acc = 0.0
        for jj in range(ns):
            acc += K[jj, i] * B[jj]
        y_new[i] = y[i] + hstep * acc
    cs[NFEV] += 1
    status = feval_call(t + hstep, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
    if status != OK:
        return status
    for i in range(n):
        K[ns, i] = f_new[i]
    return OK


@hot
def _explicit_step(method, ts_, t_end, rtol, tolv, max_step, y, f, K, F, ytmp, y_new, f_new, par, pf, pi, rmode, locate,
                   w, piv, cs, info):
    """One accepted step of DOP853, RK45, Tsit5 or Vern7 from ts_[T] (scipy's RungeKutta._step_impl,
    the error estimate each one's). Returns (status, t_new, step_ok).

    ts_[H_ABS] carries the step size over; ts_[HSTEP] gets the accepted step. The 5(4) pairs'
    dense output Q = K^T P goes to F[:4] (DOP853's and Vern7's, which need extra stages, are
    built when first needed: _ensure_dense).
    """
    k = method - RK45  # a 5(4) pair's row of the ERK_* tables
    exponent = -1 / (_error_order(method) + 1)
    t = ts_[T]
    min_step = 10 * spacing(t)
    h_abs = ts_[H_ABS]
    if h_abs > max_step:
        h_abs = max_step
    elif h_abs < min_step:
        h_abs = min_step
    rejected = False
    while True:
        if h_abs < min_step:
            ts_[H_ABS] = h_abs
            return OK, t, False
        t_new = t + h_abs
        if t_new - t_end > 0:
            t_new = t_end
        hstep = t_new - t
        h_abs = abs(hstep)
        if method == DOP853:
            status = _rk_stages(DOP_A, DOP_B, DOP_C, DOP_NS, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode,
                                locate, w, piv, cs, info)
        elif method == VERN7:
            status = _rk_stages(V7_A, V7_B, V7_C, V7_NS, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode,
                                locate, w, piv, cs, info)
        else:
            status = _rk_stages(ERK_A[k], ERK_B[k], ERK_C[k], ERK_NS, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf,
                                pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        if method == DOP853:
            err = _dop853_error(K, y, y_new, tolv, rtol, hstep)
        elif method == VERN7:
            err = _erk_error(V7_E, K, y, y_new, tolv, rtol, hstep)
        else:
            err = _erk_error(ERK_E[k], K, y, y_new, tolv, rtol, hstep)
        if err < 1:
            factor = MAX_FACTOR if err == 0 else min(MAX_FACTOR, SAFETY * err ** exponent)
            if rejected:
                factor = min(1.0, factor)
            ts_[H_ABS] = h_abs * factor
            ts_[HSTEP] = hstep
            if method in (RK45, TSIT5):
                _dense_weights(K[:ERK_NS + 1], ERK_P[k], F)
            return OK, t_new, True
        h_abs *= max(MIN_FACTOR, SAFETY * err ** exponent)
        rejected = True


@hot
def _erk_error(E, K, y, y_new, tolv, rtol, hstep):
    """scipy RungeKutta._estimate_error_norm: rms of h K^T E / (atol + max(|y|, |y_new|) rtol), E
    over the stages and the new point."""
    n = y.size
    s = 0.0
    for i in range(n):
        acc = 0.0
        for jj in range(E.size):
            acc += K[jj, i] * E[jj]
        v = acc * hstep / (tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol)
        s += v * v
    return np.sqrt(s / n)
