"""Tsitouras' 5(4) Runge-Kutta pair ("Tsit5"), for scipy's ``RungeKutta`` machinery.

Ch. Tsitouras, "Runge-Kutta pairs of order 5(4) satisfying only the first column
simplifying assumption", Computers & Mathematics with Applications 62 (2011) 770-775: seven
stages with the last one evaluated at the new point (first same as last, six new
evaluations a step), a 4th-order embedded solution for the error, and a free 4th-order
interpolant. It is the default explicit solver of DifferentialEquations.jl and diffrax,
tuned for a smaller principal error than Dormand-Prince 5(4) (scipy's RK45) at the same
cost. The coefficients are in :mod:`csim.physics.tableaus` (numbers only), which the
compiled kernels step with the same rules (:mod:`csim.fast.kernels.explicit`).

The tests (tests/test_tsit5.py) check the pair's order conditions through its convergence
order on problems with known solutions, the interpolant against the step's end, and that
both backends take the same steps.
"""
from __future__ import annotations

from scipy.integrate._ivp.rk import RungeKutta

from csim.physics.tableaus import ERROR_ESTIMATOR_ORDER, TSIT5_A, TSIT5_B, TSIT5_C, TSIT5_E, TSIT5_P


class Tsit5(RungeKutta):
    """Tsitouras' explicit Runge-Kutta 5(4) pair with its 4th-order interpolant.

    Used as scipy's ``RK45`` is: ``Tsit5(fun, t0, y0, t_bound, rtol=..., atol=...,
    max_step=..., first_step=...)``, advanced by ``step()``, ``dense_output()`` for the
    last step (see :mod:`csim.solver.integrators`).
    """

    order = 5
    error_estimator_order = ERROR_ESTIMATOR_ORDER
    n_stages = 6
    C = TSIT5_C
    A = TSIT5_A
    B = TSIT5_B
    E = TSIT5_E  # the error estimate h K^T E (its sign does not matter)
    P = TSIT5_P
