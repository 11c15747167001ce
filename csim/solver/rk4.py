"""The classic fixed-step fourth-order Runge-Kutta method, as a scipy ``OdeSolver``."""
from __future__ import annotations

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver


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
