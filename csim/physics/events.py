"""Chatter: switching events that pile up at one instant, detected from the event record.

Shared by the Python driver (:mod:`csim.solver.simulate`) and the compiled loop
(:mod:`csim.fast.kernels`); the code and its message are :mod:`csim.physics.status`'s.

A load law that switches back and forth at one instant has no consistent mode there: with
its condition holding, the motion drives the switching function to the other side, and
with it not holding, back again. Both vector fields point into the switching surface (a
sliding, or Filippov, state), so no classical solution leaves the instant, and event
location restarts the integration at the same time over and over. Measured on the
quick-return with ``loads.torque: 160000`` (the drive stalls in the cut), with each
integrator and stabilization method: gaps of exactly 0 s, at most 1.2e-11 s with
projection. Left alone such a run went on to ``simulation.max_events`` (100,000 events,
1.7 million right-hand-side evaluations: 0.6 s compiled, 139 s on the Python path).

The rule: the run chatters when its last ``n_chatter`` events (``simulation.chatter_events``)
lie within ``(n_chatter - 1)`` times the time resolution of events, that is, when events
come on average closer together than

    resolution(t) = max(min_step, 64 eps (1 + |t|))  [s],

``simulation.min_step`` (the shortest step an adaptive integrator may take before the run
counts as a step-size collapse; 1e-10 s by default) or, far from t = 0, 16 times the
event location's round-off tolerance 4 eps (1 + |t|). A motion that really switched that
often would need steps shorter than ``min_step`` to follow it; and a burst of distinct
conditions switching together is at most one event per switching function, fewer than the
default ``n_chatter`` = 20.
"""
from __future__ import annotations

from csim.physics.jit import kernel
from csim.physics.status import CHATTER, OK

EPS = 2.220446049250313e-16


@kernel
def event_resolution(t, min_step):
    """Shortest interval [s] at which two events at time t [s] count as distinct instants.

    max(min_step, 64 eps (1 + |t|)): ``min_step`` [s], or 16 times the tolerance of the
    event location (Brent's method to 4 eps (1 + |t|)) where that is larger.
    """
    return max(min_step, 64.0 * EPS * (1.0 + abs(t)))


@kernel
def check_chatter(ev_t, n_ev, n_chatter, min_step, info):
    """Status after the event ``ev_t[n_ev - 1]``: OK, or CHATTER when the last events pile up.

    Parameters
    ----------
    ev_t : ndarray (>= n_ev,)
        Event times [s], in the order they were located (non-decreasing).
    n_ev : int
        Number of events recorded in ``ev_t``.
    n_chatter : int
        Number of consecutive events that must pile up (``simulation.chatter_events``, >= 2).
    min_step : float
        ``simulation.min_step`` [s], the time resolution (see :func:`event_resolution`).
    info : ndarray (2,)
        On CHATTER: [time of the last event [s], span of the last n_chatter events [s]].

    Returns
    -------
    int
        CHATTER when ``ev_t[n_ev - 1] - ev_t[n_ev - n_chatter] <= (n_chatter - 1) *
        resolution``, else OK (also while fewer than n_chatter events are recorded).
    """
    if n_ev < n_chatter:
        return OK
    t_last = ev_t[n_ev - 1]
    span = t_last - ev_t[n_ev - n_chatter]
    # the mean gap of the last n_chatter - 1 intervals is below the time resolution
    if span <= (n_chatter - 1) * event_resolution(t_last, min_step):
        info[0] = t_last
        info[1] = span
        return CHATTER
    return OK


@kernel
def chattering_switches(ev_sw, n_ev, n_chatter, involved):
    """Which switching functions switched in the last ``n_chatter`` events.

    Parameters
    ----------
    ev_sw : ndarray (>= n_ev, n_sw) bool
        ev_sw[e, j]: switching function j switched at event e.
    n_ev, n_chatter : int
        Events recorded, and how many of the last ones to look at.
    involved : ndarray (n_sw,) bool
        Out: involved[j] is True when function j switched in any of those events.
    """
    for j in range(involved.size):
        involved[j] = False
    for e in range(max(0, n_ev - n_chatter), n_ev):
        for j in range(involved.size):
            if ev_sw[e, j]:
                involved[j] = True
