"""The integration loop: start, segments between restarts, steps, their acceptance and
checks, events, sampling, restarts and repartitioning (:func:`integrate`).
"""
import numpy as np

from csim.fast.layout import GGL, PARTITIONED, PI_FEVAL, PI_NC, PI_ND, PI_NL, PI_NQ, PI_NSW, PI_SYS, W_END
from csim.physics import branch
from csim.physics.events import check_chatter
from csim.physics.partition import D_HEAD
from csim.physics.status import INTERRUPTED, MAX_EVENTS, MAX_STEPS, OK, RK4_RESOLUTION, STEP_TOO_SMALL
from csim.physics.steps import check_step

from .calls import kinetic
from .common import (
    CONSTANT,
    DOP853,
    H_ABS,
    HSTEP,
    I_OUT,
    N_CS,
    N_EV,
    N_REC,
    N_TS,
    NFEV,
    NJEV,
    NLU,
    NSTEPS,
    RADAU,
    RK4,
    RK45,
    SEG_START,
    SEG_STEPS,
    T_OLD,
    T_STOP,
    TSIT5,
    VERN7,
    T,
    allocating,
    copy_row,
    hot,
    loop,
)
from .control import _error_order, _initial_step
from .dense import _ensure_dense, dense_eval
from .events import _event_state, _find_event, _record_event
from .explicit import _explicit_step
from .radau import R_ROWS, _n_differential, _radau_start, _radau_step
from .rk4 import _rk4_step
from .system import (
    _failure_details,
    _max_phi,
    _partition_after_step,
    _partition_call,
    _repartition,
    feval_call,
    full_state,
    ggl_consistent,
    int_workspace,
    mode_at,
    project,
)
from .tableaus import DOP_NX, DOP_POWER
from .variant import COMPILED


@hot
def _sample(ts_, t_out, dense_kind, y_old, y, f_new, mode, rmode, locate, projects, par, pf, pi, w, piv, K, F, Fh, ytmp,
            yp, dense, tr, ys, modes, cs, info):
    """Record the output times in (t_old, t_stop] from the step's dense output (projected, for projection and
    GGL)."""
    t_old, t, t_stop = ts_[T_OLD], ts_[T], ts_[T_STOP]
    FF = Fh if dense_kind == RK4 else F
    while cs[I_OUT] < t_out.size and t_out[cs[I_OUT]] <= t_stop:
        t_i = t_out[cs[I_OUT]]
        if t_i == t and t_stop == t:
            for i in range(y.size):
                ytmp[i] = y[i]
        else:
            status = _ensure_dense(dense[0], dense_kind, t_old, t - t_old, y_old, y, f_new, rmode, locate, par, pf, pi,
                                   w, piv, K, F, ytmp, cs, info)
            if status != OK:
                return status
            dense[0] = True
            dense_eval(dense_kind, t_i, t_old, t - t_old, y_old, FF, ytmp)
        if _projects_samples(projects, pi):
            code = project(ytmp, yp, t_i, par, pf, pi, w, piv, info)
            if code != OK:
                return code
            copy_row(yp, ys, cs[N_REC])
        else:
            code, yv = full_state(ytmp, par, pf, pi, w, piv)
            if code != OK:
                return code
            copy_row(yv, ys, cs[N_REC])
        tr[cs[N_REC]] = t_i
        for jj in range(mode.size):
            modes[cs[N_REC], jj] = mode[jj]
        cs[N_REC] += 1
        cs[I_OUT] += 1
    return OK


@hot
def _projects_samples(projects, pi):
    """Whether the recorded samples are projected: for projection, and for GGL (whose dense output satisfies the
    constraints only to the interpolation error, GGLSystem.output_state)."""
    return projects or pi[PI_SYS] == GGL


@hot
def _start(y0, y, yp, mode, projects, par, pf, pi, w, piv, tr, ys, modes, info):
    """The integrated state y from the full initial state y0: projected (projection), partitioned and reduced
    (minimal), made consistent (GGL, under the load laws that hold at y0), else y0 itself; then its mode, and
    the record of it. Returns the status."""
    if pi[PI_SYS] == PARTITIONED:
        model, P, r, m, k, tol, max_iter, _ = _partition_call(par, pf, pi, w, piv)
        code = branch.start(model, P, y0, y, r, m, k, tol, max_iter)
        if code != OK:
            return code
    elif pi[PI_SYS] == GGL:
        for i in range(y0.size):
            y[i] = y0[i]
        code = mode_at(y, par, pf, pi, w, piv, mode)
        if code == OK:
            code = ggl_consistent(0.0, y, mode, yp, par, pf, pi, w, piv, info)
        if code != OK:
            return code
    else:
        for i in range(y.size):
            y[i] = y0[i]
    if projects:
        code = project(y, yp, 0.0, par, pf, pi, w, piv, info)
        if code != OK:
            return code
        for i in range(y.size):
            y[i] = yp[i]
    code = mode_at(y, par, pf, pi, w, piv, mode)
    if code != OK:
        return code
    if _projects_samples(projects, pi):  # the recorded sample, projected as every recorded sample is
        code = project(y, yp, 0.0, par, pf, pi, w, piv, info)
        if code != OK:
            return code
        copy_row(yp, ys, np.int64(0))  # (not a literal: copy_row is compiled once, for int64)
    else:
        code, yv = full_state(y, par, pf, pi, w, piv)
        if code != OK:
            return code
        copy_row(yv, ys, np.int64(0))
    tr[0] = 0.0
    for jj in range(mode.size):
        modes[0, jj] = mode[jj]
    return OK


@hot
def _start_segment(method, ts_, y, f, t_end, rtol, atol, max_step, first_step, tolv, par, pf, pi, rmode, locate, w, piv,
                   ytmp, f1, scl, RM, RJ, cs, info):
    """Start the integrator at (t, y): tolerances, f(t, y), the first step of DOP853 and Radau, and
    Radau's Jacobian. Returns the status."""
    n = y.size
    status, yv = full_state(y, par, pf, pi, w, piv)
    if status != OK:
        return status
    scale_w = max(1.0, abs(kinetic(yv, par, pi, w)))  # the work states are in J: atol scaled to the energy
    nd = _n_differential(pi, n)  # the work states are the last differential rows
    for i in range(n):
        tolv[i] = atol * scale_w if nd - pi[PI_NL] - pi[PI_ND] <= i < nd else atol
    cs[NFEV] += 1
    status = feval_call(ts_[T], y, rmode, locate, par, pf, pi, w, piv, f,
                   info)
    if status != OK:
        return status
    ts_[H_ABS] = 0.0
    ts_[SEG_START] = ts_[T]
    cs[SEG_STEPS] = 0
    if method != RK4:
        status, h = _initial_step(ts_[T], y, f, t_end, rtol, tolv, max_step, first_step, par, pf, pi, rmode, locate, w,
                                  piv, ytmp, f1, scl, cs, info, _error_order(method), nd)
        ts_[H_ABS] = h
    if status == OK and method == RADAU:
        status = _radau_start(ts_, y, f, tolv, rtol, RM, RJ, par, pf, pi, rmode, locate, w, piv, cs, info)
    return status


@hot
def _take_step(method, ts_, t_end, rtol, tolv, fixed_h, max_step, y, f, K, F, y_old, ytmp, y_new, f_new, RM, RJ, RLR,
               RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info):
    """One step of the integrator from (t, y), or scipy's empty step at t_end.

    Returns (status, t_new, step_ok, dense kind); step_ok is False where no step can be
    taken (DOP853's or Radau's step below the spacing of t, RK4's below the resolution of t).
    """
    if ts_[T] == t_end:  # scipy: an empty step to t_bound
        for i in range(y.size):
            y_new[i] = y[i]
            f_new[i] = f[i]
        ts_[HSTEP] = 0.0
        return OK, t_end, True, CONSTANT
    if method in (DOP853, RK45, TSIT5, VERN7):
        status, t_new, ok = _explicit_step(method, ts_, t_end, rtol, tolv, max_step, y, f, K, F, ytmp, y_new, f_new,
                                           par, pf, pi, rmode, locate, w, piv, cs, info)
    elif method == RADAU:
        status, t_new, ok = _radau_step(ts_, t_end, rtol, tolv, max_step, y, f, F, y_old, y_new, f_new, RM, RJ, RLR,
                                        RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info)
    else:
        status, t_new, ok = _rk4_step(ts_, t_end, fixed_h, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode, locate, w,
                                      piv, cs, info)
    return status, t_new, ok, method


@hot
def _after_step(ts_, y, f, f_new, yp, projects, par, pf, pi, rmode, locate, w, piv, cs, info):
    """Go on from the accepted step: project and hand the state back (projection); anchor the branch and
    maybe choose the partition again (minimal); else keep f_new. Returns (status, restart)."""
    if pi[PI_SYS] == PARTITIONED:
        code, restart = _partition_after_step(y, par, pf, pi, w, piv)
        if code != OK or restart:
            return code, restart
    if not projects:
        for i in range(y.size):
            f[i] = f_new[i]
        return OK, False
    code = project(y, yp, ts_[T], par, pf, pi, w, piv, info)
    if code != OK:
        return code, False
    for i in range(y.size):
        y[i] = yp[i]
    cs[NFEV] += 1
    return feval_call(ts_[T], y, rmode, locate, par, pf, pi, w, piv, f, info), False


@hot
def _accept_step(ts_, t_new, dense_kind, y, y_old, y_new, f, f_new, Fh, dense, t_end, adaptive, max_phi, min_step, par,
                 pf, pi, w, piv, info):
    """Take the step to (t_new, y_new) (y_old keeps the state before it) and check it (csim.physics.steps);
    the cubic Hermite data of an RK4 step into Fh. Returns the status."""
    n = y.size
    for i in range(n):
        y_old[i] = y[i]
        y[i] = y_new[i]
    ts_[T] = t_new
    status, max_phi_now = _max_phi(t_new, y, par, pf, pi, w, piv)
    if status != OK:
        return status
    status = check_step(y, max_phi_now, ts_[HSTEP], t_new, t_end, adaptive, max_phi, min_step, info)
    if status != OK:
        return status
    if dense_kind == RK4:  # the cubic Hermite interpolant's data
        for i in range(n):
            Fh[0, i] = y_old[i]
            Fh[1, i] = f[i]
            Fh[2, i] = y[i]
            Fh[3, i] = f_new[i]
    dense[0] = False
    ts_[T_STOP] = t_new
    return OK


@hot
def _after_event(ts_, y, ev_t, ev_sw, n_chatter, max_events, min_step, par, pf, pi, w, piv, cs, info):
    """After an event recorded at index cs[N_EV]: anchor the partitioned system at the event state (maybe in a
    new partition; on a failure the event is not counted, its conditions stay flipped, as the Python driver
    leaves them), count the event, and check for chatter and too many events. Returns the status."""
    if pi[PI_SYS] == PARTITIONED:
        status, _ = _partition_after_step(y, par, pf, pi, w, piv)
        if status != OK:
            for jj in range(ev_sw.shape[1]):
                ev_sw[cs[N_EV], jj] = False
            return status
    cs[N_EV] += 1
    status = check_chatter(ev_t, cs[N_EV], n_chatter, min_step, info)
    if status != OK:
        return status
    if cs[N_EV] > max_events:
        info[0] = ts_[T]
        return MAX_EVENTS
    return OK


@hot
def _accept(ts_, y, ya):
    """ya = y, the state a restart goes back to after a breakdown of the partition; returns its time."""
    for i in range(y.size):
        ya[i] = y[i]
    return ts_[T]


#: steps between two looks at ``control`` (the interrupt request, the time reached): reading
#: one element costs nothing next to a step, and a few hundred steps take milliseconds (the
#: interpreted loop, whose step takes a millisecond or more, looks at every step)
POLL_STEPS = 256 if COMPILED else 1


@allocating  # _record_event may grow the records: numba's allocator
def _event_restart(t_a, ts_, dense_kind, y_old, y, ya, F, Fh, projects, mode, roots, has_root, ev_t, ev_sw, n_chatter,
                   max_events, min_step, par, pf, pi, w, piv, ytmp, yp, cs, info):
    """Move to the located event's state, accept it, record the event and check the events'
    count and chattering. Returns (status, t_a, ev_t, ev_sw): the accepted time (t_a as given
    where the event's state failed) and the event records (grown where full)."""
    status = _event_state(ts_, dense_kind, y_old, y, F, Fh, projects, par, pf, pi, w, piv, ytmp, yp, info)
    if status != OK:
        return status, t_a, ev_t, ev_sw
    t_a = _accept(ts_, y, ya)
    ev_t, ev_sw = _record_event(ts_[T], mode, roots, has_root, ev_t, ev_sw, cs[N_EV])
    if pi[PI_SYS] == GGL:  # the multipliers of the new mode (a load that jumps changes lambda at once)
        status = ggl_consistent(ts_[T], y, mode, yp, par, pf, pi, w, piv, info)
        if status != OK:
            return status, t_a, ev_t, ev_sw
    status = _after_event(ts_, y, ev_t, ev_sw, n_chatter, max_events, min_step, par, pf, pi, w, piv, cs, info)
    return status, t_a, ev_t, ev_sw


@hot
def _poll(control, ts_, cs, info):
    """Every POLL_STEPS steps: the time reached to control[1] (every sample up to it is
    recorded), and INTERRUPTED where control[0] asks to stop; else OK."""
    if cs[NSTEPS] % POLL_STEPS == 0:
        control[1] = ts_[T]
        if control[0] != 0.0:
            info[0] = ts_[T]
            return INTERRUPTED
    return OK


@hot
def _count_step(method, ok, t_new, max_steps, ts_, cs, info):
    """Count a step taken; MAX_STEPS beyond max_steps, or why the step could not be taken
    (``ok`` False: RK4's step below the time's resolution, else the step size below the
    smallest allowed); else OK."""
    cs[NSTEPS] += 1
    if cs[NSTEPS] > max_steps:
        info[0] = t_new if ok else ts_[T]
        return MAX_STEPS
    if not ok:
        info[0] = ts_[T]
        return RK4_RESOLUTION if method == RK4 else STEP_TOO_SMALL
    return OK


@loop
def integrate(method, y0, t_out, par, pf, pi, projects, iset, fset, control):
    """Integrate from t = 0, state y0 (n,), sampling at t_out (csim.solver.simulate.integrate).

    The problem arrays as in the package docstring; ``projects``: project after every step; ``iset`` = [locate,
    event_samples, max_events, max_steps, chatter_events]; ``fset`` = [t_end, rtol, atol, step, max_step,
    first_step (NaN: automatic), max_phi, min_step]; ``control`` (2,), shared with the calling thread (this
    runs without the GIL): every POLL_STEPS steps control[1] = the time reached, and a nonzero control[0]
    (Ctrl-C) ends the run, INTERRUPTED with the samples so far. Returns (n_rec, ts, ys, modes, n_ev, ev_t,
    ev_switched, nfev, nsteps, status, info, njev, nlu)."""
    locate, n_interior, max_events, max_steps, n_chatter = iset[0] != 0, iset[1], iset[2], iset[3], iset[4]
    t_end, rtol, atol, fixed_h, max_step, first_step, max_phi, min_step = fset[0], fset[1], fset[2], fset[3], \
        fset[4], fset[5], fset[6], fset[7]
    partitioned = pi[PI_SYS] == PARTITIONED
    if pi[PI_FEVAL] == 0:
        raise ValueError("pi[PI_FEVAL], the address of feval, is not set (csim.fast.runner._arguments sets it)")
    n_free = pi[PI_NQ] - pi[PI_NC] if partitioned else pi[PI_NQ]  # the integrated state: 2 n_free + k (+ 2 r)
    n, n_sw = 2 * n_free + pi[PI_NL] + pi[PI_ND] + (2 * pi[PI_NC] if pi[PI_SYS] == GGL else 0), pi[PI_NSW]
    w = np.zeros(pi[W_END])
    # the KKT solve's pivots, then the partition's integers
    piv = np.zeros(int_workspace(pi), np.int64)
    tr, ys, modes = np.empty(t_out.size), np.empty((t_out.size, y0.size)), np.zeros((t_out.size, n_sw), np.bool_)
    ev_t, ev_sw = np.empty(16), np.zeros((16, n_sw), np.bool_)
    # info: [t, a value, the failure's details..., the last time the right-hand side was non-finite (NaN: never)]
    info, ts_, cs = np.zeros(3 + D_HEAD + 2 * n_free), np.zeros(N_TS), np.zeros(N_CS, np.int64)
    info[info.size - 1] = np.nan
    y, ytmp, yp, f, f_new, y_new, y_old, ya = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), \
        np.empty(n), np.empty(n), np.empty(n)
    K, F, Fh = np.empty((DOP_NX, n)), np.empty((DOP_POWER, n)), np.empty((4, n))
    nr = n if method == RADAU else 0  # Radau's rows, Jacobian, LU factors (real and complex) and their pivots
    RM, RJ, RLR, RLC = np.zeros((R_ROWS, nr)), np.zeros(nr * nr), np.zeros(nr * nr), np.zeros(nr * nr, np.complex128)
    rpiv, rcv = np.zeros(2 * nr, np.int64), np.zeros(nr, np.complex128)
    tolv, scl = np.empty(n), np.empty(n)
    mode, mode_b = np.zeros(n_sw, np.bool_), np.zeros(n_sw, np.bool_)
    rmode = mode if locate else np.zeros(n_sw, np.bool_)  # the right-hand side's mode, or a scratch it overwrites
    roots, has_root, dense = np.empty(n_sw), np.zeros(n_sw, np.bool_), np.zeros(1, np.bool_)
    status = _start(y0, y, yp, mode, projects, par, pf, pi, w, piv, tr, ys, modes, info)
    cs[I_OUT] = 1
    if status == OK:
        cs[N_REC] = 1
    t_a = 0.0
    while status == OK and ts_[T] < t_end:
        restarted = False
        t_a = _accept(ts_, y, ya)
        status = _start_segment(method, ts_, y, f, t_end, rtol, atol, max_step, first_step, tolv, par, pf, pi, rmode,
                                locate, w, piv, ytmp, f_new, scl, RM, RJ, cs, info)
        while status == OK:
            status = _poll(control, ts_, cs, info)
            if status != OK:
                break
            ts_[T_OLD] = ts_[T]
            status, t_new, ok, dense_kind = _take_step(method, ts_, t_end, rtol, tolv, fixed_h, max_step, y, f, K, F,
                                                       y_old, ytmp, y_new, f_new, RM, RJ, RLR, RLC, rpiv, rcv, par, pf,
                                                       pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                break
            status = _count_step(method, ok, t_new, max_steps, ts_, cs, info)
            if status != OK:
                break
            status = _accept_step(ts_, t_new, dense_kind, y, y_old, y_new, f, f_new, Fh, dense, t_end,
                                  method != RK4, max_phi, min_step, par, pf, pi, w, piv, info)
            if status != OK:
                break
            event = False
            if locate:
                status, event = _find_event(ts_, n_interior, dense_kind, y_old, y, f_new, mode, mode_b, rmode, locate,
                                            par, pf, pi, w, piv, K, F,
                                            Fh, ytmp, roots, has_root, dense, cs, info)
                if status != OK:
                    break
            status = _sample(ts_, t_out, dense_kind, y_old, y, f_new, mode, rmode, locate, projects, par, pf, pi, w,
                             piv, K, F, Fh, ytmp, yp, dense, tr, ys,
                             modes, cs, info)
            if status != OK:
                break
            if event:  # restart from the event state with the switched conditions flipped
                status, t_a, ev_t, ev_sw = _event_restart(t_a, ts_, dense_kind, y_old, y, ya, F, Fh, projects, mode,
                                                          roots, has_root, ev_t, ev_sw, n_chatter, max_events,
                                                          min_step, par, pf, pi, w, piv, ytmp, yp, cs, info)
                restarted = status == OK
                break
            status, restart = _after_step(ts_, y, f, f_new, yp, projects, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status == OK:
                t_a = _accept(ts_, y, ya)
            if restart:
                restarted = True
                break
            if t_new >= t_end:
                break
        if partitioned and branch.is_breakdown(status):
            # a stage left the region of the partition: restart from the last accepted state
            ts_[T] = t_a
            status = _repartition(ya, y, par, pf, pi, w, piv)
            restarted = status == OK
        if not restarted:
            break
    if partitioned and status != OK:
        _failure_details(pi, w, piv, info)
    return cs[N_REC], tr, ys, modes, cs[N_EV], ev_t, ev_sw, cs[NFEV], cs[NSTEPS], status, info, cs[NJEV], cs[NLU]
