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

# --- Radau for DAEs (csim.solver.dae.RadauDAE, and the compiled Radau on a DAE) ---
MAX_SINGULAR = 5  # singular iteration matrices in a row (within one step) before giving up
# Smallest finite-difference threshold of an algebraic variable. Multipliers start at 0, and
# a difference step of sqrt(eps) atol would fall below the resolution of F: a zero Jacobian
# column makes MU/h D - J singular for every h (RADAU5 floors |y| at 1e-5 for the same reason).
JAC_ALGEBRAIC_THRESHOLD = 1e-3
# Smallest finite-difference threshold of a differential variable. scipy's Radau uses atol, so
# that a coordinate at 0 (an angle that starts at 0, a velocity at rest) is perturbed by
# sqrt(eps) atol: with atol = 1e-9 that is 1.5e-17, below the round-off of F (eps |F|) and
# lost entirely where the coordinate is added to others (sin(beta + Theta) with Theta = 0).
# The column then holds round-off divided by the step (an error of 2e5 in entries of 3e6 on
# Andrews' mechanism), the simplified Newton iteration contracts at a rate of about 0.15 to
# 0.3 whatever the step size, and the step collapses. RADAU5 perturbs y_j by
# sqrt(eps max(1e-5, |y_j|)), independently of atol; the same floor here makes the step at
# least sqrt(eps) 1e-5 = 1.5e-13.
JAC_DIFFERENTIAL_THRESHOLD = 1e-5
# Absolute residual an algebraic row can be driven to in floating point: this many eps
# times the size of its terms, |J_alg| |y| (used where that is above `algebraic_tol`).
ROUNDOFF_FACTOR = 100
# Round-off of F, in eps times the size of its terms |J| |y|, for the Newton increments it
# alone produces (below which the iteration cannot tell convergence from noise).
NOISE_FACTOR = 8

#: why Radau for DAEs (csim.solver.dae, csim.fast.kernels.radau) could not take a step: the reason of its
#: STEP_TOO_SMALL (csim.physics.status), first of that failure's details (csim.solver.failures.dae_step_message
#: reads them; 0: scipy's plain case)
(DAE_ERROR_TEST, DAE_NONFINITE_F, DAE_NONFINITE_INCREMENT, DAE_DIVERGED, DAE_SLOW, DAE_NO_CONVERGENCE, DAE_ALGEBRAIC,
 DAE_SINGULAR_MATRIX, DAE_ZERO_COLUMNS, DAE_SINGULAR_REPEATED) = range(1, 11)
#: the details' layout: [reason, t, h, value, tolerance, max |F_alg(t0, y0)| (NaN after the first step),
#: the count of the columns listed, the columns...]
DAE_REASON, DAE_T, DAE_H, DAE_VALUE, DAE_TOL, DAE_RESIDUAL0, DAE_NCOLS, DAE_COLS = range(8)
