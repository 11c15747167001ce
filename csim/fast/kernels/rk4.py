"""The classical fixed-step RK4 (:class:`csim.solver.rk4.RK4`, step for step), with the cubic
Hermite dense output.
"""
from csim.physics.status import OK

from .common import HSTEP, NFEV, SEG_START, SEG_STEPS, T, hot
from .system import feval_call


@hot
def _rk4_step(ts_, t_end, fixed_h, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode, locate, w, piv, cs, info):
    """One classic RK4 step on the grid seg_start + n h (csim.solver.rk4.RK4). Returns (status, t_new, step_ok)."""
    n = y.size
    t = ts_[T]
    t_new = ts_[SEG_START] + (cs[SEG_STEPS] + 1) * fixed_h
    if t_new >= t_end - 1e-9 * fixed_h:
        t_new = t_end
    hstep = t_new - t
    if not hstep > 0:
        return OK, t, False
    for i in range(n):
        K[0, i] = f[i]
    for s in range(1, 4):
        c = 1.0 if s == 3 else 0.5
        for i in range(n):
            ytmp[i] = y[i] + (hstep if s == 3 else hstep / 2) * K[s - 1, i]
        cs[NFEV] += 1
        status = feval_call(t + c * hstep, ytmp, rmode, locate, par, pf, pi, w, piv, K[s], info)
        if status != OK:
            return status, t, True
    for i in range(n):
        y_new[i] = y[i] + hstep / 6 * (K[0, i] + 2 * K[1, i] + 2 * K[2, i] + K[3, i])
    cs[NFEV] += 1
    status = feval_call(t_new, y_new, rmode, locate, par, pf, pi, w, piv,
                   f_new, info)
    if status != OK:
        return status, t, True
    cs[SEG_STEPS] += 1
    ts_[HSTEP] = hstep
    return OK, t_new, True
