"""Verner's "most efficient" 7(6) Runge-Kutta pair ("Vern7"), for scipy's ``RungeKutta`` machinery.

J. H. Verner, "Numerically optimal Runge-Kutta pairs with interpolants", Numerical
Algorithms 53 (2010) 383-396, pair RKV76.IIa: ten stages a step (the last two at the new
time), a 6th-order embedded solution for the error, and a 7th-order interpolant. The
interpolant needs the derivative at the new point (scipy's last row of K, which the next
step reuses as its first stage) and five more stages, so those are evaluated only for a
step whose dense output is asked for (an output sample or an event inside it), as scipy's
DOP853 does for its own three. Where it pays: tight tolerances on smooth problems, where
its 7th order takes longer steps than a 5(4) pair and fewer evaluations per step than
DOP853's twelve. The coefficients are in :mod:`csim.physics.tableaus` (numbers only).

The tests (tests/test_vern7.py) check the order of the solution, of the embedded solution
and of the interpolant under step refinement on a nonlinear problem with a known solution.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate._ivp.rk import RkDenseOutput, RungeKutta

from csim.physics.tableaus import (
    VERN7_A,
    VERN7_A_EXTRA,
    VERN7_B,
    VERN7_C,
    VERN7_C_EXTRA,
    VERN7_E,
    VERN7_ERROR_ESTIMATOR_ORDER,
    VERN7_P,
)


class Vern7(RungeKutta):
    """Verner's explicit Runge-Kutta 7(6) pair with its 7th-order interpolant.

    Used as scipy's ``DOP853`` is: ``Vern7(fun, t0, y0, t_bound, rtol=..., atol=...,
    max_step=..., first_step=...)``, advanced by ``step()``, ``dense_output()`` for the
    last step (five more evaluations of ``fun``, counted in ``nfev``).
    """

    order = 7
    error_estimator_order = VERN7_ERROR_ESTIMATOR_ORDER
    n_stages = 10
    C = VERN7_C
    A = VERN7_A
    B = VERN7_B
    E = VERN7_E  # the error estimate h K^T E over the ten stages and the new point
    P = VERN7_P

    def _dense_output_impl(self):
        # the extra stages: K_s = f(t_old + c_s h, y_old + h sum_j a_sj K_j), j over the
        # stages, the new point and the extra stages before s
        h, n = self.h_previous, self.n_stages + 1
        K = np.empty((n + VERN7_C_EXTRA.size, self.n), dtype=self.y.dtype)
        K[:n] = self.K
        for s, c in enumerate(VERN7_C_EXTRA):
            dy = K[:n + s].T @ VERN7_A_EXTRA[s, :n + s] * h
            K[n + s] = self.fun(self.t_old + c * h, self.y_old + dy)
        # y(t_old + x h) = y_old + h Q (x, x^2, ..., x^7), Q = K^T P
        return RkDenseOutput(self.t_old, self.t, self.y_old, K.T @ self.P)
