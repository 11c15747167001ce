"""The simulation driver: step an integrator, locate switching events, sample the output.

One loop serves every integrator of :mod:`csim.solver.integrators`:

1. take one accepted step of the integrator;
2. with event location on, check whether any switching function of the load laws has
   left the sign its mode says; if so, find the earliest zero on the step's dense output
   (Brent's method), cut the step there, flip the conditions that switched, and restart
   the integrator from the event state (the right-hand side is smooth between events);
   stop when the events pile up at one instant (a chattering law,
   :func:`csim.physics.events.check_chatter`);
3. sample the dense output at the requested output times inside the (cut) step.

With event location off, the load laws are evaluated at every right-hand-side call and the
integrator steps over the discontinuities as best it can.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.integrate import BDF, Radau
from scipy.integrate._ivp.rk import RungeKutta
from scipy.optimize import brentq

from csim.errors import PartitionBreakdown, SimulationFailure
from csim.physics import status as st
from csim.physics.events import chattering_switches, check_chatter
from csim.physics.steps import check_step
from csim.solver import failures
from csim.solver.integrators import INTEGRATORS, make_integrator
from csim.solver.rk4 import RK4
from csim.solver.settings import IntegrationSettings, Trajectory, output_times
from csim.solver.system import ConstrainedSystem

__all__ = ["IntegrationSettings", "Trajectory", "integrate", "output_times"]

EPS = np.finfo(float).eps


class _Counter:
    """Wraps the right-hand side to count every evaluation and stop on a non-finite one.

    An explicit integrator fed NaN derivatives shrinks its step forever instead of failing,
    so a non-finite value stops the run at once. An implicit integrator evaluates trial
    Newton iterates that may leave the region where the model is finite; it rejects the
    iteration and shrinks the step itself, so with ``implicit`` the value is passed on and
    only remembered (``non_finite_at``) for the message should the integrator fail later.
    """

    def __init__(self, fun: Callable, implicit: bool = False):
        self.fun = fun
        self.implicit = implicit
        self.n = 0
        self.non_finite_at: float | None = None

    def __call__(self, t, y):
        self.n += 1
        f = self.fun(t, y)
        if not np.all(np.isfinite(f)):
            if self.implicit:
                self.non_finite_at = t
                return f
            raise failures.failure(st.NONFINITE_RHS, t, np.max(np.abs(y)), None)
        return f


def integrate(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings,
              progress: Callable[[float], None] | None = None) -> Trajectory:
    """Integrate ``system`` from t = 0, state ``y0``, to ``settings.t_end``.

    Never raises for a failure of the integration itself: a failed run comes back with
    ``status = "failed"``, a message naming the cause, and the output up to the failure.
    """
    run = _Run(system, settings, y0, progress)
    status, message, failure = "success", f"reached t_end = {settings.t_end:g} s", ""
    # blow-ups are detected and reported below; numpy's overflow warnings would only add noise
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        try:
            # the system's own state: projected onto the manifold, reduced, or extended by multipliers
            run.y = system.start(run.y)
            run.mode[:] = system.mode_at(run.y)
            run.record(run.t, run.y)
            while run.t < settings.t_end and run.i_out <= len(run.t_out) and run.segment():
                pass  # each segment ends at an event, a restart, the end or a failure
        except SimulationFailure as exc:
            status, message, failure = "failed", str(exc), exc.kind
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            # a solve of the system raises LinAlgError; brentq (event location) and the integrators, ValueError
            status, message = "failed", f"numerical error after t = {run.t:.6g} s: {type(exc).__name__}: {exc}"
            failure = ("singular" if isinstance(exc, np.linalg.LinAlgError) else
                       "event location" if isinstance(exc, ValueError) else "other")
        except KeyboardInterrupt:
            status, message = "failed", f"interrupted by the user after t = {run.t:.6g} s"
            failure = "interrupted"
    return run.trajectory(status, message, failure)


class _Run:
    """The state of one integration: the last accepted (t, y), the mode of the load
    conditions, the samples, the events and the counters. :meth:`segment` runs the
    integrator from (t, y) until the end, an event or a restart."""

    def __init__(self, system: ConstrainedSystem, settings: IntegrationSettings, y0: np.ndarray,
                 progress: Callable[[float], None] | None):
        self.system, self.settings, self.progress = system, settings, progress
        self.t_out = output_times(settings.t_end, settings.output_dt)
        self.t, self.y = 0.0, np.array(y0, dtype=float)
        self.n_state = self.y.size
        self.mode = np.zeros(system.loads.n_switches, bool)
        self.locate = settings.events and system.loads.n_switches > 0
        self.adaptive = INTEGRATORS[settings.integrator].adaptive
        self.ts, self.ys, self.modes = [], [], []
        self.i_out = 1
        self.counters = dict(njev=0, nlu=0, nsteps=0)
        self.nfev = 0
        self.events_t, self.events_label, self.events_sw = [], [], []  # events_sw: the functions that switched

    def record(self, t_i: float, y_i: np.ndarray) -> None:
        """One output sample (the system's full state at t_i)."""
        y_full = self.system.output_state(t_i, y_i)  # may raise: nothing is appended then
        self.ts.append(t_i)
        self.ys.append(y_full)
        self.modes.append(self.mode.copy())

    def segment(self) -> bool:
        """Run an integrator from (t, y) until t_end (False), or until an event, a new partition
        or a state it cannot take over (True: start another segment)."""
        system, settings = self.system, self.settings
        frozen = self.mode.copy()
        fun = (lambda t_, y_: system.rhs(t_, y_, frozen)) if self.locate else system.rhs_unlocated
        implicit = INTEGRATORS[settings.integrator].implicit or system.dae_options() is not None
        counter, solver = _Counter(fun, implicit), None
        try:
            solver = make_integrator(
                settings.integrator, counter, self.t, self.y, settings.t_end,
                rtol=settings.rtol, atol=_atol(settings.atol, system, self.y),
                step=settings.step, max_step=settings.max_step, first_step=settings.first_step,
                dae=system.dae_options(), system=system, mode=frozen if self.locate else None,
            )
            while solver.status == "running":
                self._step(solver, counter)
                restart = self._after_step(solver)
                if restart:
                    return True
            return False
        except PartitionBreakdown as exc:
            # minimal coordinates: a stage left the region of the current partition
            self.y = system.repartition(self.y, exc)
            return True
        finally:  # count the work of every segment, the failed one included
            self.nfev += counter.n + getattr(solver, "n_residuals", 0)  # ALI3-P evaluates its own
            if solver is not None:
                self.counters["njev"] += solver.njev
                self.counters["nlu"] += solver.nlu

    def _step(self, solver, counter: _Counter) -> None:
        """One accepted step of ``solver``, checked (:func:`_check_step`); a failed step raises."""
        settings = self.settings
        msg = solver.step()
        self.counters["nsteps"] += 1
        if self.counters["nsteps"] > settings.max_steps:
            raise failures.failure(st.MAX_STEPS, solver.t, 0.0, settings)
        if solver.status == "failed":
            if counter.non_finite_at is not None:
                msg += failures.non_finite_note(counter.non_finite_at)
            raise SimulationFailure(
                f"integrator {settings.integrator} failed at t = {solver.t:.6g} s: {msg}",
                st.KINDS[st.RK4_RESOLUTION if settings.integrator == "RK4" else st.STEP_TOO_SMALL])
        _check_step(self.system, solver, settings, self.adaptive)

    def _after_step(self, solver) -> bool:
        """Locate an event in the step, sample the output up to it (or the step's end), and go
        on: True where the integrator must start again (an event, a restart)."""
        system = self.system
        t_new = solver.t
        dense, t_stop, switched = None, t_new, []
        if self.locate:  # its dense output (built to look inside the step) serves the samples too
            dense, t_event, switched = _find_event(system, solver, self.mode, self.settings.event_samples)
            t_stop = t_new if t_event is None else t_event
        dense = self._sample(solver, dense, t_stop)
        if self.progress is not None:
            self.progress(t_stop)
        if switched:  # (the event was found on the dense output, which exists then)
            self._event(dense(t_stop) if t_stop < t_new else solver.y.copy(), t_stop, switched)
            return True
        # the accepted state first: a breakdown raised by after_step repartitions from it
        self.t, self.y = t_new, solver.y.copy()
        self.y, action = system.after_step(self.t, self.y)
        # e.g. a new partition, or a state the solver cannot take over
        return action == "restart" or (action == "swap" and not _swap_state(solver, self.y))

    def _sample(self, solver, dense, t_stop: float):
        """The output times in (t_old, t_stop], from the step's end or its dense output (built
        here where the step has none yet, and returned for the event that may follow)."""
        t_out, t_new = self.t_out, solver.t
        while self.i_out < len(t_out) and t_out[self.i_out] <= t_stop:
            if t_out[self.i_out] == t_new and t_stop == t_new:
                y_i = solver.y
            else:
                dense = dense or solver.dense_output()
                y_i = dense(t_out[self.i_out])
            self.record(t_out[self.i_out], y_i)
            self.i_out += 1
        return dense

    def _event(self, y: np.ndarray, t: float, switched: list[int]) -> None:
        """Restart from the event state (t, y) with the switched conditions flipped, checked
        for chatter and for the most events."""
        settings, labels = self.settings, self.system.loads.switch_labels
        self.t, self.y = t, y  # the event state first: a breakdown raised by restart repartitions from it
        for j in switched:
            self.mode[j] = not self.mode[j]
        self.y = self.system.restart(t, y, self.mode)
        self.events_t.append(t)
        self.events_label.append("; ".join(labels[j] for j in switched))
        self.events_sw.append(switched)
        _check_chatter(self.events_t, self.events_sw, labels, settings)
        if len(self.events_t) > settings.max_events:
            raise failures.failure(st.MAX_EVENTS, t, 0.0, settings)

    def trajectory(self, status: str, message: str, failure: str) -> Trajectory:
        """What was recorded, with the run's status."""
        return Trajectory(
            t=np.array(self.ts), y=np.array(self.ys).reshape(len(self.ts), self.n_state),
            mode=np.array(self.modes).reshape(len(self.ts), len(self.mode)),
            status=status, message=message, failure=failure, nfev=self.nfev, **self.counters,
            event_times=self.events_t, event_labels=self.events_label,
        )


def _atol(atol: float, system: ConstrainedSystem, y: np.ndarray) -> np.ndarray:
    """Absolute tolerance per state: ``atol`` for q and qd, scaled to the energy for W.

    The work states are integrated only for the energy balance; they are measured in J,
    so their absolute tolerance is atol times the system's energy scale.
    """
    q, qd, _ = system.split(system.to_full(y))
    scale = max(1.0, abs(system.model.kinetic_energy(q, qd, system.par)))
    tol = np.full(y.size, float(atol))
    tol[system.work_slice] *= scale
    return tol


def _check_step(system: ConstrainedSystem, solver, settings: IntegrationSettings, adaptive: bool) -> None:
    """Stop a run that has diverged: non-finite state, constraints torn apart, step collapse."""
    y = np.ascontiguousarray(solver.y, dtype=float)
    max_phi = system.max_phi(y) if np.all(np.isfinite(y)) else np.nan
    info = np.zeros(2)
    code = check_step(y, max_phi, solver.t - solver.t_old, solver.t, solver.t_bound, adaptive, settings.max_phi,
                      settings.min_step, info)
    if code != st.OK:
        raise failures.failure(code, info[0], info[1], settings, system.stabilizer)


def _check_chatter(events_t: list, events_sw: list, labels: list, settings: IntegrationSettings) -> None:
    """Stop a run whose last ``settings.chatter_events`` events pile up at one instant (chatter).

    The rule is :func:`csim.physics.events.check_chatter`'s, on the last events only (it reads
    no others); the message names the switching functions that switched in them.
    """
    n = min(len(events_t), settings.chatter_events)
    last_t = np.array(events_t[-n:], dtype=float)
    info = np.zeros(2)
    if check_chatter(last_t, n, settings.chatter_events, settings.min_step, info) == st.OK:
        return
    last_sw = np.zeros((n, len(labels)), bool)
    for e, switched in enumerate(events_sw[-n:]):
        last_sw[e, switched] = True
    involved = np.zeros(len(labels), bool)
    chattering_switches(last_sw, n, n, involved)
    switches = [labels[j] for j in np.flatnonzero(involved)]
    raise failures.failure(st.CHATTER, info[0], info[1], settings, switches=switches)


def _swap_state(solver, y) -> bool:
    """Hand a (projected) state to a running integrator in place of its own; False if it cannot.

    One-step methods (scipy's explicit Runge-Kutta pairs and csim's Tsit5 and Vern7, RK4,
    Radau) carry (y, f) into the next step
    (Radau also its last dense output, used only as the Newton start). BDF's history is a
    difference array whose row 0 is y. LSODA's state is inside Fortran (the case validation
    rejects projection with LSODA).
    """
    if isinstance(solver, (RungeKutta, RK4, Radau)):
        solver.y, solver.f = y.copy(), solver.fun(solver.t, y)
        return True
    if isinstance(solver, BDF):
        solver.D[0] = y
        solver.y = y.copy()
        return True
    return False


def _find_event(system, solver, mode, n_interior):
    """The earliest switch inside the integrator's last step.

    The mode is checked at ``n_interior`` equally spaced points of the step's dense output
    and at its end, so that a switching function that crosses zero and back within one
    step (a velocity sign near a dead centre) is not missed. Returns
    ``(dense, t_event, switched)``, or ``(dense, None, [])`` without a switch; ``dense`` is
    the step's dense output where it was built (None otherwise), for the output samples.
    """
    t_old, t_new = solver.t_old, solver.t
    dense = solver.dense_output() if n_interior else None
    a = t_old
    for i in range(1, n_interior + 2):
        b = t_new if i == n_interior + 1 else t_old + (t_new - t_old) * i / (n_interior + 1)
        y_b = solver.y if b == t_new else dense(b)
        disagree = np.flatnonzero(system.mode_at(y_b) != mode)
        if disagree.size:
            dense = dense or solver.dense_output()
            t_event, switched = _locate(system, dense, a, b, disagree, mode)
            return dense, t_event, switched
        a = b
    return dense, None, []


def _locate(system, dense, t_old, t_new, candidates, mode):
    """Earliest zero of the switching functions ``candidates`` in (t_old, t_new].

    Returns the event time and the indices of the functions that switch there (those
    whose zeros coincide to within 4 eps in time).
    """
    roots = {}
    for j in candidates:
        def g(tau, j=j):
            return system.switching(dense(tau))[j]

        g_old = g(t_old)
        if (g_old > 0) == mode[j]:
            roots[j] = brentq(g, t_old, t_new, xtol=4 * EPS, rtol=4 * EPS)
        else:
            # the state at the start of the step is already on the other side (the
            # previous event was located a hair early): it switches at once
            roots[j] = t_old
    t_event = min(roots.values())
    tol = 4 * EPS * max(1.0, abs(t_event)) + 4 * EPS
    switched = [j for j, r in roots.items() if r - t_event <= tol]
    return t_event, switched
