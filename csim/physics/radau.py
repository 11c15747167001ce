"""The constants of Radau IIA of order 5 and of its forward-difference Jacobian (no numba, no scipy import).

The compiled Radau of :mod:`csim.fast.kernels` is scipy's ``Radau`` (``scipy.integrate._ivp.radau``)
step for step, with the Jacobian of scipy's ``num_jac`` whose step factors are capped as
:class:`csim.solver.dae.DifferenceJacobian` caps them. The coefficients are scipy's
(``tests/test_fast_radau.py`` compares them with scipy's module; :mod:`csim.solver.dae`
reads them too): the collocation nodes C (the Radau IIA nodes, the roots of the Radau
polynomial), the error weights E, the eigenvalues of the inverse of the Butcher matrix (one
real, MU_REAL, and a complex pair, MU_COMPLEX), the transformation T (A^-1 = T diag(MU) T^-1
in real form) and its inverse TI, and the interpolation matrix P of the dense output
y_old + Z^T P (x, x^2, x^3).
"""
from __future__ import annotations

import numpy as np

S6 = 6 ** 0.5
#: collocation nodes
C = np.array([(4 - S6) / 10, (4 + S6) / 10, 1])
#: error estimate weights: err = (f0 + E^T Z / h) solved with MU_REAL / h I - J
E = np.array([-13 - 7 * S6, -13 + 7 * S6, -1]) / 3
MU_REAL = 3 + 3 ** (2 / 3) - 3 ** (1 / 3)
MU_COMPLEX = (3 + 0.5 * (3 ** (1 / 3) - 3 ** (2 / 3)) - 0.5j * (3 ** (5 / 6) + 3 ** (7 / 6)))
T = np.array([
    [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
    [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
    [1, 1, 0]])
TI = np.array([
    [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
    [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
    [0.50287263494578682, -2.57192694985560522, 0.59603920482822492]])
TI_REAL = TI[0]
TI_COMPLEX = TI[1] + 1j * TI[2]
P = np.array([
    [13 / 3 + 7 * S6 / 3, -23 / 3 - 22 * S6 / 3, 10 / 3 + 5 * S6],
    [13 / 3 - 7 * S6 / 3, -23 / 3 + 22 * S6 / 3, 10 / 3 - 5 * S6],
    [1 / 3, -8 / 3, 10 / 3]])
NEWTON_MAXITER = 6

EPS = np.finfo(float).eps
#: scipy's num_jac: a column whose largest difference is below EPS^0.875 of the values is tried again
#: with a ten times larger step; the step factor grows below EPS^0.75 and shrinks above EPS^0.25
NUM_JAC_DIFF_REJECT = EPS ** 0.875
NUM_JAC_DIFF_SMALL = EPS ** 0.75
NUM_JAC_DIFF_BIG = EPS ** 0.25
NUM_JAC_MIN_FACTOR = 1e3 * EPS
NUM_JAC_FACTOR_INCREASE = 10
NUM_JAC_FACTOR_DECREASE = 0.1
#: num_jac multiplies the difference step of a variable that F does not depend on (a work
#: state) by 10 at every Jacobian; csim caps it so that it stays finite over long runs
JAC_MAX_FACTOR = 1e-1
