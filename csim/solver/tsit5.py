"""Tsitouras' 5(4) Runge-Kutta pair ("Tsit5"), for scipy's ``RungeKutta`` machinery.

Ch. Tsitouras, "Runge-Kutta pairs of order 5(4) satisfying only the first column
simplifying assumption", Computers & Mathematics with Applications 62 (2011) 770-775: seven
stages with the last one evaluated at the new point (first same as last, six new
evaluations a step), a 4th-order embedded solution for the error, and a free 4th-order
interpolant. It is the default explicit solver of DifferentialEquations.jl and diffrax,
tuned for a smaller principal error than Dormand-Prince 5(4) (scipy's RK45) at the same
cost. The coefficients are those of the paper (as printed to 16 digits and more by
diffrax); the interpolant's weights b_i(theta) are the paper's factored polynomials,
expanded here into the power basis that :class:`scipy.integrate._ivp.rk.RkDenseOutput`
evaluates (y(t_old + theta h) = y_old + h sum_i K_i sum_j P_ij theta^(j+1)).

The tests (tests/test_tsit5.py) check the pair's order conditions through its convergence
order on problems with known solutions, and the interpolant against the step's end.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import polynomial as poly
from scipy.integrate._ivp.rk import RungeKutta

_C = np.array([0.0, 0.161, 0.327, 0.9, 0.9800255409045096857298102862870245954942, 1.0])
_A = np.zeros((6, 6))
_A[1, :1] = [0.161]
_A[2, :2] = [-0.008480655492356988544426874250230774675121, 0.3354806554923569885444268742502307746751]
_A[3, :3] = [2.897153057105493432130432594192938764925, -6.359448489975074843148159912383825625953,
             4.362295432869581411017727318190886861028]
_A[4, :4] = [5.325864828439256604428877920840511317836, -11.74888356406282787774717033978577296189,
             7.495539342889836208304604784564358155659, -0.09249506636175524925650207933207191611350]
_A[5, :5] = [5.861455442946420028659251486982647890394, -12.92096931784710929170611868178335939542,
             8.159367898576158643180400794539253485182, -0.07158497328140099722453054252582973869127,
             -0.02826905039406838290900305721271224146718]
#: the 5th-order weights (the solution carried on)
_B = np.array([0.09646076681806522951816731316512876333712, 0.01,
               0.4798896504144995747752495322905965199130, 1.379008574103741893192274821856872770756,
               -3.290069515436080679901047585711363850116, 2.324710524099773982415355918398765796109])
#: the embedded 4th-order weights, over the seven stages (the last at the new point)
_B_HAT = np.array([0.09468075576583945807478876255758922856118, 0.009183565540343253096776363936645313759814,
                   0.4877705284247615707855642599631228241517, 1.234297566930478985655109673884237654036,
                   -2.707712349983525454881109975059321670690, 1.866628418170587035753719399566211498666,
                   1 / 66])


def _interpolant_weights() -> np.ndarray:
    """P (7, 4): the power-basis coefficients of theta^1..theta^4 of each weight b_i(theta),
    expanded from the paper's factored form: a scale times a product of two polynomials."""
    square = [0.0, 0.0, 1.0]  # theta^2
    roots = poly.polyfromroots
    factored = [
        (-1.0530884977290216, roots([0.0, 1.3299890189751412]), [0.7139816917074209, -1.4364028541716351, 1.0]),
        (0.1017, square, [1.2949852507374631, -2.1966568338249754, 1.0]),
        (2.490627285651252793, square, [1.57803468208092486, -2.38535645472061657, 1.0]),
        (-16.54810288924490272, roots([1.21712927295533244, 0.61620406037800089]), square),
        (47.37952196281928122, roots([1.203071208372362603, 0.658047292653547382]), square),
        (-34.87065786149660974, roots([1.2, 0.666666666666666667]), square),
        (2.5, roots([1.0, 0.6]), square),
    ]
    P = np.zeros((7, 4))
    for i, (scale, first, second) in enumerate(factored):
        coefficients = scale * poly.polymul(first, second)  # theta^0 .. theta^4, the first 0
        P[i, :] = np.pad(coefficients, (0, 5 - coefficients.size))[1:5]
    return P


class Tsit5(RungeKutta):
    """Tsitouras' explicit Runge-Kutta 5(4) pair with its 4th-order interpolant.

    Used as scipy's ``RK45`` is: ``Tsit5(fun, t0, y0, t_bound, rtol=..., atol=...,
    max_step=..., first_step=...)``, advanced by ``step()``, ``dense_output()`` for the
    last step (see :mod:`csim.solver.integrators`).
    """

    order = 5
    error_estimator_order = 4
    n_stages = 6
    C = _C
    A = _A
    B = _B
    E = np.append(_B, 0.0) - _B_HAT  # the error estimate h K^T E (its sign does not matter)
    P = _interpolant_weights()
