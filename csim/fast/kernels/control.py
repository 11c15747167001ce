"""Step-size control shared by the adaptive integrators: scipy's first step
(``select_initial_step``), its constants, and each integrator's error-estimator order.
"""
import numpy as np

from csim.physics.status import OK
from csim.physics.tableaus import ERROR_ESTIMATOR_ORDER, VERN7_ERROR_ESTIMATOR_ORDER

from .common import DOP853, NFEV, RADAU, VERN7, hot, inlined
from .system import feval_call

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0


@hot
def _rms(x, scale):
    s = 0.0
    for i in range(x.size):
        v = x[i] / scale[i]
        s += v * v
    return np.sqrt(s) / x.size**0.5  # (np: a float64, which divides by zero as compiled code does)


@hot
def _initial_step(t, y, f, t_end, rtol, tolv, max_step, first_step, par, pf, pi, rmode, locate, w, piv, ytmp, f1, scl,
                  cs, info, order, nd):
    """The first step of DOP853 (error estimator ``order`` 7) or Radau (3): given, or scipy's
    select_initial_step (one evaluation), on the first ``nd`` rows of the state (a DAE's differential
    rows, as csim.solver.dae.RadauDAE; all of an ODE's). Returns (status, h)."""
    n = y.size
    interval = abs(t_end - t)
    if first_step == first_step:  # given (NaN: automatic)
        return OK, min(first_step, interval)
    if interval == 0.0:
        return OK, 0.0
    for i in range(n):
        scl[i] = tolv[i] + abs(y[i]) * rtol
    d0 = _rms(y[:nd], scl[:nd])
    d1 = _rms(f[:nd], scl[:nd])
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, interval)
    for i in range(n):  # (the algebraic rows stay)
        ytmp[i] = y[i] + h0 * f[i] if i < nd else y[i]
    cs[NFEV] += 1
    status = feval_call(t + h0, ytmp, rmode, locate, par, pf, pi, w, piv, f1, info)
    if status != OK:
        return status, 0.0
    for i in range(n):
        f1[i] = f1[i] - f[i]
    d2 = _rms(f1[:nd], scl[:nd]) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1 / (order + 1))
    return OK, min(100 * h0, h1, interval, max_step)


@inlined
def _error_order(method):
    """The order of an adaptive integrator's error estimator (scipy's ``error_estimator_order``):
    DOP853 7, Vern7 6, the 5(4) pairs 4, Radau 3. It sets the first step and the step factor
    err^(-1 / (order + 1))."""
    if method == DOP853:
        return 7
    if method == VERN7:
        return VERN7_ERROR_ESTIMATOR_ORDER
    if method == RADAU:
        return 3
    return ERROR_ESTIMATOR_ORDER
