"""Time integrators, by name: scipy's adaptive solvers and a classic fixed-step RK4.

Each integrator is a :class:`scipy.integrate.OdeSolver`: built as
``cls(fun, t0, y0, t_bound, **options)``, advanced by ``step()`` (one accepted step, or
``status = "failed"`` with a message), with ``dense_output()`` interpolating the last step.
The simulation driver (:mod:`csim.solver.simulate`) uses nothing else, so every integrator
gets the same event location, output sampling and failure handling.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK45, DenseOutput, OdeSolver, Radau

from csim.solver.dae import RadauDAE


class CubicHermite(DenseOutput):
    """Cubic Hermite interpolant from the values and derivatives at both ends of a step."""

    def __init__(self, t_old, t, y_old, y, f_old, f):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.y_old, self.y, self.f_old, self.f = y_old, y, f_old, f

    def _call_impl(self, t):
        # Hermite basis in s = (t - t_old)/h
        s = (np.asarray(t) - self.t_old) / self.h
        h00 = (1 + 2 * s) * (1 - s) ** 2
        h10 = s * (1 - s) ** 2
        h01 = s**2 * (3 - 2 * s)
        h11 = s**2 * (s - 1)
        if s.ndim == 0:
            return h00 * self.y_old + h10 * self.h * self.f_old + h01 * self.y + h11 * self.h * self.f
        return (
            np.outer(self.y_old, h00)
            + np.outer(self.h * self.f_old, h10)
            + np.outer(self.y, h01)
            + np.outer(self.h * self.f, h11)
        )


class RK4(OdeSolver):
    """Classic fourth-order Runge-Kutta with a fixed step.

    Steps of exactly ``step`` from ``t0``; the last one is shortened to end on ``t_bound``.
    Four right-hand-side evaluations per step (the derivative at the end of a step is the
    first stage of the next, and serves the dense output).

    Parameters
    ----------
    fun, t0, y0, t_bound
        As for every :class:`scipy.integrate.OdeSolver`.
    step : float
        Step size [s], > 0.
    """

    def __init__(self, fun, t0, y0, t_bound, step, vectorized=False, **unused):
        super().__init__(fun, t0, y0, t_bound, vectorized)
        if not step > 0:
            raise ValueError("`step` must be positive")
        self.h = float(step)
        self.t_start = t0
        self.n_steps = 0
        self.f = self.fun(self.t, self.y)
        self._last = None

    def _step_impl(self):
        # step on the grid t0 + n h (no accumulated round-off); snap the last step to t_bound
        t, y = self.t, self.y
        t_new = self.t_start + (self.n_steps + 1) * self.h
        if t_new >= self.t_bound - 1e-9 * self.h:
            t_new = self.t_bound
        h = t_new - t
        if not h > 0:
            return False, f"step {self.h:g} s is below the resolution of t = {t:g} s"
        # y_{n+1} = y_n + h/6 (k1 + 2 k2 + 2 k3 + k4)
        k1 = self.f
        k2 = self.fun(t + h / 2, y + h / 2 * k1)
        k3 = self.fun(t + h / 2, y + h / 2 * k2)
        k4 = self.fun(t + h, y + h * k3)
        y_new = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        f_new = self.fun(t_new, y_new)
        self._last = (t, y, k1)
        self.n_steps += 1
        self.t, self.y, self.f = t_new, y_new, f_new
        return True, None

    def _dense_output_impl(self):
        t_old, y_old, f_old = self._last
        return CubicHermite(t_old, self.t, y_old, self.y, f_old, self.f)


@dataclass(frozen=True)
class IntegratorInfo:
    """What the registry knows of one integrator."""

    cls: type
    adaptive: bool
    description: str
    #: solves a Newton iteration per step: a non-finite trial iterate only makes it shrink the step
    implicit: bool = False


#: name -> integrator (``simulation.integrator`` in a case file)
INTEGRATORS: dict[str, IntegratorInfo] = {
    "RK45": IntegratorInfo(RK45, True, "explicit Runge-Kutta 5(4), Dormand-Prince"),
    "DOP853": IntegratorInfo(DOP853, True, "explicit Runge-Kutta 8(5,3), Dormand-Prince"),
    "Radau": IntegratorInfo(Radau, True, "implicit Runge-Kutta Radau IIA, order 5 (stiff)", implicit=True),
    "BDF": IntegratorInfo(BDF, True, "implicit multistep BDF, orders 1-5 (stiff)", implicit=True),
    "LSODA": IntegratorInfo(LSODA, True, "Adams/BDF with automatic stiffness switching"),
    "RK4": IntegratorInfo(RK4, False, "classic Runge-Kutta 4, fixed step `simulation.step`"),
}


#: integrators that also solve DAEs ``D y' = F(t, y)`` (their DAE version)
DAE_INTEGRATORS = {"Radau": "Radau IIA for semi-explicit DAEs of index up to 2 (csim.solver.dae)"}


def _check_dae(name):
    if name not in DAE_INTEGRATORS:
        raise ValueError(f"integrator {name!r} cannot solve a DAE; DAE integrators: {', '.join(DAE_INTEGRATORS)}")


def make_integrator(name, fun, t0, y0, t_bound, *, rtol, atol, step=None, max_step=np.inf, first_step=None,
                    dae=None):
    """Start the integrator ``name`` on ``y' = fun(t, y)`` from (t0, y0) towards ``t_bound``.

    ``rtol``, ``atol`` (scalar or (n,)), ``max_step`` and ``first_step`` apply to the
    adaptive integrators, ``step`` [s] to the fixed-step ones. ``dae`` (a dict with
    ``differential``, the bool mask of the differential rows, and solver options) makes
    ``fun`` the right-hand side F of the DAE ``D y' = F(t, y)``; only the integrators of
    :data:`DAE_INTEGRATORS` accept it.
    """
    try:
        info = INTEGRATORS[name]
    except KeyError:
        raise KeyError(f"unknown integrator {name!r}; valid names: {', '.join(INTEGRATORS)}") from None
    if info.adaptive:
        options = dict(rtol=rtol, atol=atol, max_step=max_step)
        if first_step is not None:
            options["first_step"] = min(first_step, t_bound - t0)
        if dae is not None:
            _check_dae(name)
            return RadauDAE(fun, t0, y0, t_bound, **dae, **options)
        return info.cls(fun, t0, y0, t_bound, **options)
    if dae is not None:
        _check_dae(name)
    return info.cls(fun, t0, y0, t_bound, step=step)
