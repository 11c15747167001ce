"""Run a case through the compiled kernels and return the usual :class:`Trajectory`.

Python packs the system (parameters, load laws, stabilizer gains) into arrays, enters the
compiled loop once, and turns its status code into the same message the Python driver
(:func:`csim.solver.simulate.integrate`) gives for the same failure.
"""
from __future__ import annotations

import numpy as np

from csim.fast.module import load_module
from csim.fast.support import SWITCHING_CODES
from csim.solver.settings import IntegrationSettings, Trajectory, output_times
from csim.solver.system import ConstrainedSystem

STAB_CODES = {"none": 0, "baumgarte": 1, "sliding_mode": 2, "projection": 3}
INTEGRATOR_CODES = {"DOP853": 0, "RK4": 1}
#: switching-function kinds of csim.loads.LoadLaw, in its order: lower bound, upper bound, velocity
_LO, _HI, _POS, _NEG = 0, 1, 2, 3


def _gains(value, r: int) -> np.ndarray:
    """A stabilizer gain (scalar or (r,)) as an (r,) float array."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float), (r,)), dtype=float)


def pack_problem(system: ConstrainedSystem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(par, pf, pi)``: the problem as the flat arrays of :mod:`csim.fast.kernels`."""
    r = system.r
    sw_load, sw_kind, sw_value = [], [], []
    for k, law in enumerate(system.loads.laws):  # in the order of csim.loads.LoadLaw.switching
        lo, hi = law.window
        if np.isfinite(lo):
            sw_load.append(k), sw_kind.append(_LO), sw_value.append(lo)
        if np.isfinite(hi):
            sw_load.append(k), sw_kind.append(_HI), sw_value.append(hi)
        if law.velocity == "positive":
            sw_load.append(k), sw_kind.append(_POS), sw_value.append(0.0)
        elif law.velocity == "negative":
            sw_load.append(k), sw_kind.append(_NEG), sw_value.append(0.0)
    stab = system.stabilizer
    g1 = g2 = g3 = np.zeros(r)
    sw_fn, width = 0, 1.0
    metric, proj_tol, proj_iter = 0, 0.0, 0
    if stab.name == "baumgarte":
        g1, g2 = _gains(stab.d, r), _gains(stab.w, r)
    elif stab.name == "sliding_mode":
        g1, g2, g3 = _gains(stab.Lambda, r), _gains(stab.K, r), _gains(stab.k, r)
        sw_fn = SWITCHING_CODES[stab.switching]
        width = 1.0 if stab.width is None else float(stab.width)
    elif stab.name == "projection":
        metric, proj_tol, proj_iter = int(stab.metric == "mass"), stab.tol, stab.max_iter
    pf = np.concatenate((system.loads.magnitudes, g1, g2, g3, [width, proj_tol], sw_value)).astype(float)
    pi = np.array([STAB_CODES[stab.name], sw_fn, metric, proj_iter, len(sw_load), *sw_load, *sw_kind],
                  dtype=np.int64)
    return np.ascontiguousarray(system.par, dtype=float), pf, pi


def _messages(code: int, info: np.ndarray, settings: IntegrationSettings, stabilizer) -> str:
    """The Python driver's message for a status code of the compiled loop."""
    a, b = float(info[0]), float(info[1])
    s = settings
    if code == 1:
        return f"blow-up: non-finite right-hand side at t = {a:.6g} s (max |y| = {b:.3g})"
    if code == 2:
        return f"blow-up: non-finite state at t = {a:.6g} s"
    if code == 3:
        return (f"constraint violation: max |Phi| = {a:.3g} at t = {b:.6g} s exceeds simulation.max_phi = "
                f"{s.max_phi:g}; the joints have drifted apart (stabilize, or tighten the tolerances)")
    if code == 4:
        return (f"step-size collapse: an accepted step of {a:.3g} s at t = {b:.6g} s is below simulation.min_step "
                f"= {s.min_step:g} s (a singular configuration, or stiffness beyond this integrator)")
    if code == 5:
        return (f"more than simulation.max_steps = {s.max_steps} steps by t = {a:.6g} s: "
                f"the motion is too fast or too stiff for these settings (raise max_steps to go on)")
    if code == 6:
        return (f"integrator {s.integrator} failed at t = {a:.6g} s: "
                f"Required step size is less than spacing between numbers.")
    if code == 7:
        return ("singular KKT matrix: the constraint Jacobian Phi_q lost rank (a singular "
                "configuration of the mechanism) or M is singular")
    if code == 8:
        return "projection: singular constraint Jacobian"
    if code == 9:
        return (f"projection: Gauss-Newton did not reach max |Phi| <= {stabilizer.tol:g} in "
                f"{stabilizer.max_iter} iterations (max |Phi| = {a:.3e})")
    if code == 10:
        return (f"more than simulation.max_events = {s.max_events} switching events "
                f"by t = {a:.6g} s: the load law chatters")
    if code == 11:
        return f"integrator RK4 failed at t = {a:.6g} s: step {s.step:g} s is below the resolution of t = {a:g} s"
    if code == 12:
        return f"numerical error after t = {b:.6g} s: LinAlgError: Singular matrix"
    if code == 13:
        return f"numerical error after t = {a:.6g} s: ValueError: f(a) and f(b) must have different signs"
    return f"compiled integration failed with status {code}"


def _arguments(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings, max_steps: int) -> tuple:
    """The arguments of the kernel ``integrate`` (see its docstring)."""
    par, pf, pi = pack_problem(system)
    t_out = output_times(settings.t_end, settings.output_dt)
    locate = settings.events and system.loads.n_switches > 0
    iset = np.array([int(locate), settings.event_samples, settings.max_events, max_steps], dtype=np.int64)
    fset = np.array([settings.t_end, settings.rtol, settings.atol, settings.step, settings.max_step,
                     np.nan if settings.first_step is None else settings.first_step, settings.max_phi,
                     settings.min_step], dtype=float)
    return (INTEGRATOR_CODES[settings.integrator], np.ascontiguousarray(y0, dtype=float), t_out, par, pf, pi,
            iset, fset)


def prepare(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings) -> None:
    """Load the compiled module and its machine code (compiling it on a cold cache).

    numba loads or compiles a function on its first call; a call that stops after zero
    steps does that without integrating, so that a run's wall time is the run's alone.
    """
    mod = load_module(system.model.definition)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        mod.integrate(*_arguments(system, y0, settings, max_steps=0))


def integrate_compiled(system: ConstrainedSystem, y0: np.ndarray, settings: IntegrationSettings) -> Trajectory:
    """:func:`csim.solver.simulate.integrate`, in compiled code (same arguments and result).

    The caller has checked the combination with :func:`csim.fast.support.unsupported`.
    """
    mod = load_module(system.model.definition)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        n_rec, ts, ys, modes, n_ev, ev_t, ev_sw, nfev, nsteps, code, info = mod.integrate(
            *_arguments(system, y0, settings, settings.max_steps))
    labels = system.loads.switch_labels
    status, message = "success", f"reached t_end = {settings.t_end:g} s"
    if code != 0:
        status, message = "failed", _messages(int(code), info, settings, system.stabilizer)
    return Trajectory(
        t=ts[:n_rec].copy(), y=ys[:n_rec].copy(), mode=modes[:n_rec].copy(),
        status=status, message=message, nfev=int(nfev), njev=0, nlu=0, nsteps=int(nsteps),
        event_times=[float(x) for x in ev_t[:n_ev]],
        event_labels=["; ".join(labels[j] for j in np.flatnonzero(row)) for row in ev_sw[:n_ev]],
    )
