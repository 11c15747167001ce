"""Events: where a switching function leaves the sign its mode says, located on the step's
dense output by ``brentq``, and the event's state and record.
"""
import numpy as np

from csim.fast.layout import PI_NSW, W_G
from csim.physics.status import NO_SIGN_CHANGE, OK

from .calls import loads_
from .common import EPS, RK4, T_OLD, T_STOP, T, allocating, hot
from .dense import _ensure_dense, dense_eval
from .system import _pending, _set_pending, full_state, mode_at, project, switching_from


@hot
def _g_at(j, tau, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp):
    """Switching function j on the dense output at tau (NaN, and the code pending, where the full state fails)."""
    dense_eval(kind, tau, t_old, h, y_old, F, ytmp)
    code, yv = full_state(ytmp, par, pf, pi, w, piv)
    if code != OK:  # (only the partitioned system's full state can fail)
        _set_pending(pi, w, piv, code)
        return np.nan
    loads_(yv, par, pi, w)
    switching_from(yv, pf, pi, w)
    return w[pi[W_G] + j]


@hot
def brentq(j, xa, xb, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp):
    """scipy's brentq (xtol = rtol = 4 eps, 100 iterations) on switching function j: (root, ok)."""
    xtol = 4 * EPS
    rtol = 4 * EPS
    xpre, xcur = xa, xb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre = _g_at(j, xpre, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp)
    fcur = _g_at(j, xcur, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp)
    if fpre == 0:
        return xpre, True
    if fcur == 0:
        return xcur, True
    if (fpre < 0) == (fcur < 0):
        return xcur, False
    for _ in range(100):
        if fpre != 0 and fcur != 0 and ((fpre < 0) != (fcur < 0)):
            xblk = xpre
            fblk = fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre = xcur
            xcur = xblk
            xblk = xpre
            fpre = fcur
            fcur = fblk
            fblk = fpre
        delta = (xtol + rtol * abs(xcur)) / 2
        sbis = (xblk - xcur) / 2
        if fcur == 0 or abs(sbis) < delta:
            return xcur, True
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)  # interpolate
            else:  # extrapolate
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2 * abs(stry) < min(abs(spre), 3 * abs(sbis) - delta):
                spre = scur
                scur = stry
            else:
                spre = sbis
                scur = sbis
        else:
            spre = sbis
            scur = sbis
        xpre = xcur
        fpre = fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        fcur = _g_at(j, xcur, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp)
    return xcur, True


@hot
def _locate(a, b, dense_kind, t_old, h, y_old, FF, mode, mode_b, par, pf, pi, w, piv, ytmp, roots,
            has_root, info):
    """Earliest zero in (a, b] of the switching functions whose mode differs at b. Returns (status, t_event).

    A function already on the other side at a (the last event was located a hair early)
    switches at a. ``roots`` and ``has_root`` record each function's zero.
    """
    t_event = np.inf
    for jj in range(pi[PI_NSW]):
        has_root[jj] = False
        if mode_b[jj] != mode[jj]:
            g_old = _g_at(jj, a, dense_kind, t_old, h, y_old, FF, par, pf, pi, w, piv, ytmp)
            pending = _pending(pi, w, piv)
            if pending != OK:
                return pending, t_event
            if (g_old > 0) == mode[jj]:
                root, ok = brentq(jj, a, b, dense_kind, t_old, h, y_old, FF, par, pf, pi, w, piv, ytmp)
                pending = _pending(pi, w, piv)
                if pending != OK:
                    return pending, t_event
                if not ok:
                    info[0] = t_old + h
                    return NO_SIGN_CHANGE, t_event
            else:
                root = a
            roots[jj] = root
            has_root[jj] = True
            t_event = min(t_event, root)
    return OK, t_event


@hot
def _find_event(ts_, n_interior, dense_kind, y_old, y, f_new, mode, mode_b, rmode, locate, par, pf, pi, w, piv, K, F,
                Fh, ytmp, roots, has_root, dense, cs, info):
    """The earliest switch inside the last step (csim.solver.simulate._find_event). Returns (status, event).

    The mode is checked at ``n_interior`` equally spaced points of the step and at its end,
    so that a function that crosses zero and back within one step is not missed. On an
    event, ts_[T_STOP] is its time. ``dense`` [0] says whether the dense output is built.
    """
    t_old, t = ts_[T_OLD], ts_[T]
    h = t - t_old
    FF = Fh if dense_kind == RK4 else F
    for rep in range(n_interior + 1):
        b = t if rep == n_interior else t_old + (t - t_old) * (rep + 1) / (n_interior + 1)
        if b == t:
            for i in range(y.size):
                ytmp[i] = y[i]
        else:
            status = _ensure_dense(dense[0], dense_kind, t_old, h, y_old, y, f_new, rmode, locate, par, pf, pi, w, piv,
                                   K, F, ytmp, cs, info)
            if status != OK:
                return status, False
            dense[0] = True
            dense_eval(dense_kind, b, t_old, h, y_old, FF, ytmp)
        status = mode_at(ytmp, par, pf, pi, w, piv, mode_b)
        if status != OK:
            return status, False
        found = False
        for jj in range(pi[PI_NSW]):
            if mode_b[jj] != mode[jj]:
                found = True
        if found:
            status = _ensure_dense(dense[0], dense_kind, t_old, h, y_old, y, f_new, rmode, locate, par, pf, pi, w, piv,
                                   K, F, ytmp, cs, info)
            if status != OK:
                return status, False
            dense[0] = True
            a = t_old if rep == 0 else t_old + (t - t_old) * rep / (n_interior + 1)
            status, t_event = _locate(a, b, dense_kind, t_old, h, y_old, FF, mode, mode_b, par, pf, pi, w, piv, ytmp,
                                      roots, has_root, info)
            if status != OK:
                return status, False
            ts_[T_STOP] = t_event
            return OK, True
    return OK, False


@hot
def _event_state(ts_, dense_kind, y_old, y, F, Fh, projects, par, pf, pi, w, piv, ytmp, yp, info):
    """y = the state at the event ts_[T_STOP] (projected, for projection); t = t_stop. Returns the status."""
    t_old, t, t_stop = ts_[T_OLD], ts_[T], ts_[T_STOP]
    if t_stop < t:
        dense_eval(dense_kind, t_stop, t_old, t - t_old, y_old, Fh if dense_kind == RK4 else F, ytmp)
    else:
        for i in range(y.size):
            ytmp[i] = y[i]
    if projects:
        code = project(ytmp, yp, t_stop, par, pf, pi, w, piv, info)
        if code != OK:
            return code
        for i in range(y.size):
            ytmp[i] = yp[i]
    for i in range(y.size):
        y[i] = ytmp[i]
    ts_[T] = t_stop
    return OK


@allocating
def _record_event(t, mode, roots, has_root, ev_t, ev_sw, n_ev):
    """Flip the conditions that switch at t (zeros within 4 eps of it) and record the event.

    Returns the event arrays, grown when full.
    """
    n_sw = mode.size
    if n_ev == ev_t.size:  # grow the event arrays
        new_t = np.empty(2 * ev_t.size)
        new_sw = np.zeros((2 * ev_t.size, n_sw), np.bool_)
        for e in range(n_ev):
            new_t[e] = ev_t[e]
            for jj in range(n_sw):
                new_sw[e, jj] = ev_sw[e, jj]
        ev_t = new_t
        ev_sw = new_sw
    tol_ev = 4 * EPS * max(1.0, abs(t)) + 4 * EPS
    ev_t[n_ev] = t
    for jj in range(n_sw):
        if has_root[jj] and roots[jj] - t <= tol_ev:
            ev_sw[n_ev, jj] = True
            mode[jj] = not mode[jj]
    return ev_t, ev_sw
