"""What a run is asked to do and what the driver gives back: plain data, no solver imports.

The case file (:mod:`csim.case`) builds :class:`IntegrationSettings`; both drivers (the
Python one in :mod:`csim.solver.simulate` and the compiled one in :mod:`csim.fast`) return
a :class:`Trajectory` sampled at :func:`output_times`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class IntegrationSettings:
    """How to integrate (the validated ``simulation`` section of a case file).

    Parameters
    ----------
    integrator : str
        Registry name, see :data:`csim.solver.integrators.INTEGRATORS`.
    t_end : float
        End time [s] (the run starts at t = 0).
    rtol, atol : float
        Tolerances of the adaptive integrators (atol in the units of each state).
    step : float
        Step [s] of the fixed-step integrators.
    max_step : float
        Largest step of the adaptive integrators [s].
    first_step : float or None
        First step of the adaptive integrators [s]; ``None`` lets the integrator choose.
    events : bool
        Locate the switching instants of the load laws and restart there.
    max_events : int
        Stop with a failure after this many events (chattering of a switching law).
    chatter_events : int
        Stop with a failure (chatter) when this many consecutive events lie closer together,
        on average, than ``min_step`` (:func:`csim.physics.events.check_chatter`).
    max_steps : int
        Stop with a failure after this many accepted steps (a run far too fast or stiff for
        its settings, which would otherwise go on for hours).
    event_samples : int
        Interior points of each step at which the switching functions are checked, beside
        its end (0: the end only; a function that crosses and re-crosses inside a step is
        then missed).
    max_phi : float
        Stop with a failure when max |Phi| exceeds this after a step [unit of Phi].
    min_step : float
        Stop with a failure when an adaptive integrator accepts a step shorter than this
        [s] (step-size collapse).
    output_dt : float
        Output sampling interval [s].
    """

    integrator: str = "DOP853"
    t_end: float = 5.0
    rtol: float = 1e-8
    atol: float = 1e-8
    step: float = 1e-3
    max_step: float = np.inf
    first_step: float | None = None
    events: bool = True
    max_events: int = 100_000
    chatter_events: int = 20
    max_steps: int = 1_000_000
    event_samples: int = 4
    max_phi: float = 0.1
    min_step: float = 1e-10
    output_dt: float = 0.01


@dataclass
class Trajectory:
    """Raw output of :func:`integrate`.

    Attributes
    ----------
    t : ndarray (N,)
        Output times [s].
    y : ndarray (N, n_state)
        States at the output times.
    mode : ndarray (N, n_switches) bool
        Load-law conditions in force at each output time.
    status : {"success", "failed"}
    message : str
    failure : str
        The kind of a failed run (:data:`csim.result.FAILURES`, from its status code or where it
        was raised); ``""`` for a success, or where the kind is not known (then
        :class:`csim.result.Result` reads it from the message).
    nfev : int
        Right-hand-side evaluations, all of them (stages, Jacobian differences, restarts).
    njev, nlu, nsteps : int
        Jacobian evaluations, LU decompositions (implicit integrators), accepted steps.
    event_times : list of float
    event_labels : list of str
        What switched at each event.
    """

    t: np.ndarray
    y: np.ndarray
    mode: np.ndarray
    status: str
    message: str
    failure: str = ""
    nfev: int = 0
    njev: int = 0
    nlu: int = 0
    nsteps: int = 0
    event_times: list = field(default_factory=list)
    event_labels: list = field(default_factory=list)


def output_times(t_end: float, dt: float) -> np.ndarray:
    """Uniform output grid 0, dt, 2 dt, ... ending exactly at ``t_end``."""
    n = int(np.floor(t_end / dt * (1 + 1e-12)))
    t = np.arange(n + 1) * dt
    if t_end - t[-1] > 1e-9 * dt:
        t = np.append(t, t_end)
    else:
        t[-1] = t_end
    return t
