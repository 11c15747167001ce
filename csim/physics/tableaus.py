"""Explicit Runge-Kutta tableaus that the compiled kernels step with scipy's ``RungeKutta`` rules.

Numbers only (no numba, no scipy import). Each pair is the data of a
:class:`scipy.integrate._ivp.rk.RungeKutta` subclass: nodes C (s,), stage matrix A (s, s),
weights B (s,) of the solution carried on, error weights E (s + 1,) over the stages and the
new point (the error estimate is h K^T E), and the dense output's power-basis weights P
(s + 1, 4): y(t_old + x h) = y_old + h sum_i K_i sum_j P_ij x^(j+1).

- ``RK45``: Dormand and Prince's 5(4) pair with Shampine's interpolant, as scipy's ``RK45``
  (``tests/test_tsit5.py`` checks these are scipy's numbers).
- ``TSIT5``: Tsitouras' 5(4) pair (Computers & Mathematics with Applications 62 (2011)
  770-775): seven stages with the last at the new point, a 4th-order embedded solution, and
  a free 4th-order interpolant. The coefficients are the paper's (as printed to 16 digits and
  more by diffrax); the interpolant's weights b_i(x) are the paper's factored polynomials,
  expanded here into the power basis. :class:`csim.solver.tsit5.Tsit5` is scipy's machinery on
  these numbers.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import polynomial as poly

# ---- Dormand-Prince 5(4), scipy's RK45 ----
RK45_C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1])
RK45_A = np.array([
    [0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]])
RK45_B = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
RK45_E = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
RK45_P = np.array([
    [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0, 0, 0, 0],
    [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])

# ---- Tsitouras 5(4) ----
TSIT5_C = np.array([0.0, 0.161, 0.327, 0.9, 0.9800255409045096857298102862870245954942, 1.0])
TSIT5_A = np.zeros((6, 6))
TSIT5_A[1, :1] = [0.161]
TSIT5_A[2, :2] = [-0.008480655492356988544426874250230774675121, 0.3354806554923569885444268742502307746751]
TSIT5_A[3, :3] = [2.897153057105493432130432594192938764925, -6.359448489975074843148159912383825625953,
                  4.362295432869581411017727318190886861028]
TSIT5_A[4, :4] = [5.325864828439256604428877920840511317836, -11.74888356406282787774717033978577296189,
                  7.495539342889836208304604784564358155659, -0.09249506636175524925650207933207191611350]
TSIT5_A[5, :5] = [5.861455442946420028659251486982647890394, -12.92096931784710929170611868178335939542,
                  8.159367898576158643180400794539253485182, -0.07158497328140099722453054252582973869127,
                  -0.02826905039406838290900305721271224146718]
#: the 5th-order weights (the solution carried on)
TSIT5_B = np.array([0.09646076681806522951816731316512876333712, 0.01,
                    0.4798896504144995747752495322905965199130, 1.379008574103741893192274821856872770756,
                    -3.290069515436080679901047585711363850116, 2.324710524099773982415355918398765796109])
#: the embedded 4th-order weights, over the seven stages (the last at the new point)
TSIT5_B_HAT = np.array([0.09468075576583945807478876255758922856118, 0.009183565540343253096776363936645313759814,
                        0.4877705284247615707855642599631228241517, 1.234297566930478985655109673884237654036,
                        -2.707712349983525454881109975059321670690, 1.866628418170587035753719399566211498666,
                        1 / 66])
#: the error weights: the estimate h K^T E (its sign does not matter)
TSIT5_E = np.append(TSIT5_B, 0.0) - TSIT5_B_HAT


def _tsit5_interpolant() -> np.ndarray:
    """P (7, 4): the power-basis coefficients of x^1..x^4 of each weight b_i(x), expanded from
    the paper's factored form: a scale times a product of two polynomials."""
    square = [0.0, 0.0, 1.0]  # x^2
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
        coefficients = scale * poly.polymul(first, second)  # x^0 .. x^4, the first 0
        P[i, :] = np.pad(coefficients, (0, 5 - coefficients.size))[1:5]
    return P


TSIT5_P = _tsit5_interpolant()
#: both pairs' embedded error is of order 4: the step factor is err^(-1/5)
ERROR_ESTIMATOR_ORDER = 4
