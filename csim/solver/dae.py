"""Radau IIA (3 stages, order 5) for semi-explicit DAEs in mass-matrix form.

Solves

    D y' = F(t, y),    D = diag(differential)

where ``differential[i]`` is True for a differential row (D_ii = 1) and False for an
algebraic row (D_ii = 0, the equation ``0 = F_i(t, y)``). The intended use is the
stabilized index-2 (Gear-Gupta-Leimkuhler) form of a constrained mechanical system,

    q' = v - Phi_q^T mu,    M v' = p - Phi_q^T lambda,    0 = Phi(q),    0 = Phi_q v,

whose multipliers mu and lambda are index-2 algebraic variables.

The method is scipy's :class:`scipy.integrate.Radau` (Hairer and Wanner's RADAU5 in the
formulation of scipy's ``_ivp/radau.py``: the transformed simplified Newton iteration, the
embedded third-order error estimate, the predictive step-size controller, the Jacobian
reuse and the collocation-polynomial dense output), extended to the mass matrix D as in
RADAU5 (Hairer, Wanner, *Solving Ordinary Differential Equations II*, Sec. IV.8 and VI.6):

* the iteration matrices are ``MU_REAL/h D - J`` and ``MU_COMPLEX/h D - J``;
* the error estimate is ``(MU_REAL/h D - J)^-1 (F(t, y) + D Z^T E / h)``;
* the tolerance scale of index-2 algebraic components is divided by h, in the Newton
  convergence test and in the error norm alike (RADAU5's treatment of index-2 variables,
  which converge with order 3 only: measured with the plain scale they would cut the step
  far below what the differential variables need).

On top of RADAU5, every accepted step satisfies the algebraic equations at its end to an
absolute tolerance ``algebraic_tol``: the method is stiffly accurate (the last stage is the
step end), so the Newton iteration is continued until ``max |F_alg(t + h, y + Z_3)|`` is
below it. For the GGL form this keeps |Phi(q)| and |Phi_q v| at round-off level at every
step without any projection.

With every row differential (``D = I``) the algorithm is exactly scipy's Radau, step for
step (up to rounding; the visible differences are that ``nfev`` here also counts the
evaluations of the finite-difference Jacobian, and that its difference step is not scaled
down with atol below sqrt(eps) 1e-5, see ``JAC_DIFFERENTIAL_THRESHOLD``).

The Butcher constants, the transformation matrices and the dense-output coefficients are
scipy's (:mod:`csim.physics.radau`, which the compiled Radau reads too), so that this
module does not depend on scipy's private names beside ``num_jac``.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver
from scipy.integrate._ivp.common import num_jac
from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
from scipy.sparse import issparse

from csim.physics.radau import (
    DAE_ALGEBRAIC,
    DAE_DIVERGED,
    DAE_ERROR_TEST,
    DAE_NO_CONVERGENCE,
    DAE_NONFINITE_F,
    DAE_NONFINITE_INCREMENT,
    DAE_SINGULAR_MATRIX,
    DAE_SINGULAR_REPEATED,
    DAE_SLOW,
    DAE_ZERO_COLUMNS,
    JAC_ALGEBRAIC_THRESHOLD,
    JAC_DIFFERENTIAL_THRESHOLD,
    JAC_MAX_FACTOR,
    MAX_SINGULAR,
    MU_COMPLEX,
    MU_REAL,
    NEWTON_MAXITER,
    NOISE_FACTOR,
    ROUNDOFF_FACTOR,
    TI,
    TI_COMPLEX,
    TI_REAL,
    C,
    E,
    P,
    T,
)
from csim.solver.failures import dae_step_message

EPS = np.finfo(float).eps

# --- Radau IIA, 3 stages: scipy's constants (csim.physics.radau): the nodes C, the error
# weights E, the eigenvalues MU of A^-1, the transformations W = TI Z, Z = T W, and the dense
# output y(t_old + x h) = y_old + (Z^T P) [x, x^2, x^3]
MIN_FACTOR = 0.2  # largest decrease of the step after an error-test failure
MAX_FACTOR = 10  # largest increase of the step
class DifferenceJacobian:
    """dF/dy by forward differences (scipy's ``num_jac``), its step factors capped.

    scipy multiplies the difference step of a variable that F does not depend on by 10 at
    every Jacobian, without bound: over a long run the step of such a variable (a work
    state, a governor's shaft angle under a drive) reaches infinity, the trial state is not
    finite, and the integration stops ("array must not contain infs or NaNs"). The factor
    is capped at :data:`JAC_MAX_FACTOR`. Serves :class:`RadauDAE` and, through
    :func:`csim.solver.integrators.make_integrator`, scipy's Radau and BDF.

    Parameters
    ----------
    fun : callable (t, y) -> (n,)
        The right-hand side.
    threshold : float or ndarray (n,)
        The smallest |y_j| the difference step scales with (scipy uses atol).
    columns : callable (t, Y (n, c)) -> (n, c), optional
        F at each column of Y (default: ``fun`` column by column).
    """

    def __init__(self, fun, threshold, columns=None):
        self.fun, self.threshold, self.factor = fun, threshold, None
        self.columns = columns or (lambda t, Y: np.column_stack([fun(t, Y[:, j]) for j in range(Y.shape[1])]))

    def __call__(self, t: float, y: np.ndarray, f: np.ndarray | None = None) -> np.ndarray:
        """dF/dy (n, n) at (t, y); ``f`` = F(t, y) where the caller has it."""
        J, factor = num_jac(self.columns, t, y, self.fun(t, y) if f is None else f, self.threshold, self.factor)
        self.factor = np.minimum(factor, JAC_MAX_FACTOR)
        return J


def _detail(reason: int, t: float, h: float = np.nan, value: float = np.nan, tol: float = np.nan,
            residual: float = np.nan, columns=()) -> np.ndarray:
    """A failed step's details in the layout of :mod:`csim.physics.radau` (DAE_REASON ...), which the compiled
    Radau fills in too, for :func:`csim.solver.failures.dae_step_message`."""
    return np.array([reason, t, h, value, tol, residual, len(columns), *columns], dtype=float)


def _rms(x: np.ndarray) -> np.float64:
    """Root-mean-square norm (scipy's ``norm``); a numpy float, so that 0 ** -0.25 is inf."""
    return np.linalg.norm(x) / x.size**0.5 if x.size else np.float64(0.0)


def predict_factor(h_abs, h_abs_old, error_norm, error_norm_old):
    """Step-size factor of the predictive (Gustafsson) controller, as in scipy's Radau.

    ``factor = min(1, h/h_old (err_old/err)^(1/4)) err^(-1/4)``; the one-step formula
    ``err^(-1/4)`` where there is no previous step (or error) to compare with.
    """
    if error_norm_old is None or h_abs_old is None or error_norm == 0:
        multiplier = 1
    else:
        multiplier = h_abs / h_abs_old * (error_norm_old / error_norm) ** 0.25
    with np.errstate(divide="ignore"):
        return min(1, multiplier) * error_norm**-0.25


class RadauDenseOutput(DenseOutput):
    """The collocation polynomial of one step (cubic in t), as in scipy's Radau.

    Parameters
    ----------
    t_old, t : float
        Ends of the step.
    y_old : ndarray, shape (n,)
        State at ``t_old``.
    Q : ndarray, shape (n, 3)
        ``Z^T P``, coefficients of ``x, x^2, x^3`` with ``x = (t - t_old)/h``.
    """

    def __init__(self, t_old, t, y_old, Q):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.Q = Q
        self.y_old = y_old

    def _call_impl(self, t):
        # y(t) = y_old + Q [x, x^2, x^3]^T,  x = (t - t_old)/h   (Q already carries h)
        x = (t - self.t_old) / self.h
        powers = np.cumprod(np.repeat(x[None, ...], 3, axis=0), axis=0)
        y = self.Q @ powers
        return y + (self.y_old if y.ndim == 1 else self.y_old[:, None])


class RadauDAE(OdeSolver):
    """Implicit Runge-Kutta Radau IIA of order 5 for ``D y' = F(t, y)``, D diagonal 0/1.

    A :class:`scipy.integrate.OdeSolver`: advanced by :meth:`step`, interpolated over the
    last step by :meth:`dense_output`, usable from ``scipy.integrate.solve_ivp`` with
    ``method=RadauDAE, differential=...``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> ndarray, shape (n,)``: the right-hand side F. Rows where
        ``differential`` is True give y_i'; the others are the algebraic equations
        ``0 = F_i(t, y)``, in the units of the constraint functions.
    t0 : float
        Initial time.
    y0 : array_like, shape (n,)
        Initial state. It should be consistent: the algebraic equations satisfied (and the
        hidden constraints of the index-2 variables, e.g. lambda from the acceleration-level
        constraint). A small inconsistency costs tiny first steps; a large one can make the
        first step fail (the message then reports ``max |F_alg(t0, y0)|``).
    t_bound : float
        End time; also sets the direction of integration.
    differential : array_like of bool, shape (n,)
        True for a differential row, False for an algebraic row.
    max_step : float, optional
        Largest step size (default: unbounded).
    rtol : float, optional
        Relative tolerance (scalar).
    atol : float or array_like, shape (n,), optional
        Absolute tolerance. For index-2 algebraic components the scale
        ``atol + rtol |y|`` is divided by the step size (see Notes).
    jac : callable, optional
        ``jac(t, y) -> ndarray, shape (n, n)``, the Jacobian dF/dy (a sparse matrix is
        densified). Default: forward differences (scipy's ``num_jac``), whose evaluations
        of ``fun`` are counted in ``nfev``, with the difference step of y_j about
        ``sqrt(eps) max(|y_j|, atol_j, 1e-5)`` (``1e-3`` for algebraic variables): never
        scaled down with atol below the resolution of F, as RADAU5's is not.
    first_step : float, optional
        First step size; default: scipy's initial-step heuristic applied to the
        differential rows only (see Notes).
    algebraic_tol : float, optional
        Absolute tolerance on ``max |F_alg|`` at the end of every accepted step, in the
        units of the algebraic equations (default 1e-12). It is raised, row by row, to the
        round-off level ``100 eps |J_alg| |y|`` of the equation where that is larger, so
        that equations with large terms cannot make every step fail.
    index2 : array_like of bool, shape (n,), optional
        Which algebraic components are of index 2 (their tolerance scale is divided by h).
        True is allowed only on algebraic rows. Default: every algebraic component, as
        in the GGL formulation.
    vectorized : bool, optional
        Whether ``fun`` accepts ``y`` of shape (n, k) (used by the finite-difference
        Jacobian only).

    Attributes
    ----------
    n : int
        Number of equations.
    t, y : float, ndarray (n,)
        Current time and state.
    t_old : float or None
        Start of the last step (None before the first).
    status : {"running", "finished", "failed"}
    direction : float
        +1 or -1.
    nfev, njev, nlu : int
        Right-hand-side evaluations (single points, the finite-difference Jacobian's
        included), Jacobian evaluations, LU decompositions.
    differential, index2 : ndarray (n,) bool
        The row kinds.

    Notes
    -----
    *Index-2 scaling.* Radau IIA converges with order 5 in the differential components of
    an index-2 problem but only with order 3 in the index-2 algebraic ones, whose error
    estimate is correspondingly large. Hairer's RADAU5 therefore divides their scale by h
    (multiplies their error by h); so does this class, in the Newton convergence norm and
    in the error norm. Measured with the plain scale they would force steps several times
    shorter (on the GGL pendulum at rtol = atol = 1e-8: about 3500 steps instead of 850)
    for no gain in the differential components. The price is that these components
    carry an error of about the scale divided by h: in the GGL form mu, zero in the exact
    solution, comes out of the order of rtol / h. Index-1 algebraic components
    (``index2`` False) keep the plain scale.

    *Constraint accuracy.* Once the simplified Newton iteration meets scipy's convergence
    test, F is evaluated at the step end ``(t + h, y + Z_3)``; if an algebraic residual
    there exceeds ``algebraic_tol`` the iteration goes on (within ``NEWTON_MAXITER``
    iterations in all), re-checking after each increment. If it does not get there, the
    attempt counts as a Newton failure: the Jacobian is refreshed if it is stale, else the
    step is halved. The end-point evaluation serves as F at the start of the next step
    (scipy makes it after accepting a step), so the check costs nothing on a step that
    passes it at once and is accepted.

    *Initial step.* scipy's heuristic (Hairer, Norsett, Wanner, Sec. II.4) for an order-3
    error estimate, on the differential rows only: the algebraic rows have no derivative
    to extrapolate with. With no differential row, ``1e-4 |t_bound - t0|``. An over-long
    first step is caught by the error test like any other.

    *Failures.* A singular iteration matrix, a non-finite F or a diverging iteration halve
    the step (after a Jacobian refresh if it was stale). A step below ten times the spacing
    of floating-point numbers at t (or below ``10 eps |t_bound - t0|``), or
    ``MAX_SINGULAR`` singular iteration matrices within one step, end the run with
    ``status = "failed"`` and a message naming the cause; nothing is raised.
    """

    def __init__(self, fun, t0, y0, t_bound, differential, *, max_step=np.inf, rtol=1e-3, atol=1e-6,
                 jac=None, first_step=None, algebraic_tol=1e-12, index2=None, vectorized=False):
        super().__init__(fun, t0, y0, t_bound, vectorized)
        n = self.n

        # --- options ---------------------------------------------------------------------
        diff = np.asarray(differential)
        if diff.dtype != bool or diff.shape != (n,):
            raise ValueError(f"`differential` must be a boolean array of shape ({n},).")
        self.differential = diff.copy()
        self.algebraic = ~diff
        if index2 is None:
            index2 = self.algebraic.copy()
        else:
            index2 = np.asarray(index2)
            if index2.dtype != bool or index2.shape != (n,):
                raise ValueError(f"`index2` must be a boolean array of shape ({n},) or None.")
            if np.any(index2 & diff):
                raise ValueError("`index2` may be True only on algebraic rows.")
            index2 = index2.copy()
        self.index2 = index2
        self.d = diff.astype(float)  # the diagonal of D

        if not np.isscalar(rtol) or not rtol > 0:
            raise ValueError("`rtol` must be a positive scalar.")
        if rtol < 100 * EPS:
            warnings.warn(f"`rtol` is too small; setting `rtol = {100 * EPS}`.", stacklevel=2)
            rtol = 100 * EPS
        atol = np.asarray(atol, dtype=float)
        if atol.ndim > 0 and atol.shape != (n,):
            raise ValueError(f"`atol` must be a scalar or an array of shape ({n},).")
        if np.any(atol < 0) or not np.all(np.isfinite(atol)):
            raise ValueError("`atol` must be non-negative and finite.")
        if not max_step > 0:
            raise ValueError("`max_step` must be positive.")
        if first_step is not None:
            if not first_step > 0:
                raise ValueError("`first_step` must be positive.")
            if first_step > abs(t_bound - t0):
                raise ValueError("`first_step` exceeds bounds.")
        if not (np.isscalar(algebraic_tol) and np.isfinite(algebraic_tol) and algebraic_tol > 0):
            raise ValueError("`algebraic_tol` must be positive.")
        if jac is not None and not callable(jac):
            raise ValueError("`jac` must be None or a callable jac(t, y).")
        self.rtol, self.atol = float(rtol), atol
        # num_jac's difference step is about sqrt(eps) max(|y|, threshold) per variable, with the
        # threshold floored independently of atol (see JAC_DIFFERENTIAL_THRESHOLD)
        self._jac_threshold = np.maximum(atol, np.where(self.algebraic, JAC_ALGEBRAIC_THRESHOLD,
                                                        JAC_DIFFERENTIAL_THRESHOLD))
        self.max_step = max_step
        self.algebraic_tol = float(algebraic_tol)

        # --- start -----------------------------------------------------------------------
        self.interval = abs(t_bound - t0)
        self.f = self.fun(self.t, self.y)
        self.h_abs = float(first_step) if first_step is not None else self._initial_step(t_bound)
        self.h_abs_old = None
        self.error_norm_old = None
        # Newton tolerance on the scaled increment (scipy's choice)
        self.newton_tol = max(10 * EPS / rtol, min(0.03, rtol**0.5))
        self._differences = DifferenceJacobian(self.fun, self._jac_threshold, columns=self._fun_columns)
        self._user_jac = jac
        self.J = self.jac(self.t, self.y, self.f)
        self.current_jac = True
        self.LU_real = self.LU_complex = None
        self.y_old = None
        self.Z = None
        self.sol = None

    # --- pieces ----------------------------------------------------------------------------
    def jac(self, t, y, f):
        """dF/dy at (t, y), shape (n, n): the user's, else forward differences."""
        self.njev += 1
        if self._user_jac is not None:
            J = self._user_jac(t, y)
            J = J.toarray() if issparse(J) else np.asarray(J, dtype=float)
            if J.shape != (self.n, self.n):
                raise ValueError(f"`jac` is expected to have shape {(self.n, self.n)}, "
                                 f"but actually has {J.shape}.")
            return J

        return self._differences(t, y, f)

    def _fun_columns(self, t, Y):
        """F at the columns of Y, each counted as one evaluation."""
        self.nfev += Y.shape[1]
        return self.fun_vectorized(t, Y)

    @property
    def jac_factor(self):
        """The difference steps' factors of the last Jacobian (None before the first)."""
        return self._differences.factor

    def _lu(self, A):
        """LU factors of A, or None where A is singular or not finite."""
        self.nlu += 1
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", LinAlgWarning)
                lu, piv = lu_factor(A, overwrite_a=True, check_finite=True)
        except (ValueError, np.linalg.LinAlgError):
            return None
        if np.any(np.diag(lu) == 0):
            return None
        return lu, piv

    def _initial_step(self, t_bound):
        """scipy's ``select_initial_step`` (order 3) on the differential rows.

        Returns ``min(100 h0, h1, |t_bound - t0|, max_step)`` with ``h0 = 0.01 |y0|/|f0|``
        and ``h1 = (0.01 / max(|f0|, |f'|))^(1/4)`` in the scaled RMS norm, ``f'``
        estimated by one explicit Euler step of length h0.
        """
        interval = abs(t_bound - self.t)
        if interval == 0:
            return 0.0
        diff = self.differential
        if not diff.any():
            return min(1e-4 * interval, self.max_step)
        atol = self.atol[diff] if self.atol.ndim else self.atol
        y0, f0 = self.y[diff], self.f[diff]
        scale = atol + np.abs(y0) * self.rtol
        d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, interval)
        y1 = self.y.copy()
        y1[diff] += h0 * self.direction * f0
        f1 = self.fun(self.t + h0 * self.direction, y1)[diff]
        d2 = _rms((f1 - f0) / scale) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1 / 4)
        return min(100 * h0, h1, interval, self.max_step)

    def _scale(self, y_abs, h_abs):
        """Tolerance scale ``atol + rtol |y|``, divided by h on the index-2 components."""
        scale = self.atol + y_abs * self.rtol
        scale = np.array(scale, dtype=float) if scale.ndim else np.full(self.n, float(scale))
        scale[self.index2] /= h_abs
        return scale

    def _solve_collocation(self, t, t_new, y, h, Z0, scale, J, LU_real, LU_complex, alg_tol):
        """Simplified Newton iteration for the stage increments Z, shape (3, n).

        Solves the collocation equations ``(A^-1 (x) D) Z = h F(t + C h, y + Z)`` in the
        eigenbasis of A^-1 (``W = TI Z``): one real and one complex linear system per
        iteration. Returns ``(converged, n_iter, Z, rate, f_end, reason)``; ``f_end`` is
        F at the step end when it was evaluated (algebraic rows present), ``reason`` says
        why the iteration failed. ``J`` is the Jacobian of the iteration matrices' factors.
        """
        n = y.shape[0]
        d = self.d
        M_real = MU_REAL / h
        M_complex = MU_COMPLEX / h
        t_stage = t + h * C
        t_stage[-1] = t_new  # exactly the step end (stiffly accurate: stage 3 = step end)
        alg = self.algebraic
        check_alg = alg.any()

        # the increments that the round-off of F alone produces, |(MU_REAL/h D - J)^-1 r| with
        # r = NOISE_FACTOR eps |J| |y|: an iteration whose increment is down to them has
        # converged as far as floating point allows (with tight tolerances, the round-off of
        # Phi at large coordinates turns into multiplier increments of about r / (h atol))
        noise = np.abs(lu_solve(LU_real, NOISE_FACTOR * EPS * (np.abs(J) @ np.abs(y)), check_finite=False))
        noise_norm = _rms(noise / scale)

        W = TI @ Z0
        Z = Z0
        F = np.empty((3, n))
        dW = np.empty_like(W)
        dW_norm_old = None
        rate = None
        polishing = False  # the increment test is met; driving F_alg at the end below alg_tol
        f_end = None
        for k in range(NEWTON_MAXITER):
            for i in range(3):
                F[i] = f_end if (i == 2 and f_end is not None) else self.fun(t_stage[i], y + Z[i])
            if not np.all(np.isfinite(F)):
                return False, k + 1, Z, rate, None, (DAE_NONFINITE_F,)

            # residuals of the transformed system:
            #   f_real    = (TI_REAL F)    - MU_REAL/h    D W_0
            #   f_complex = (TI_COMPLEX F) - MU_COMPLEX/h D (W_1 + i W_2)
            f_real = F.T @ TI_REAL - M_real * d * W[0]
            f_complex = F.T @ TI_COMPLEX - M_complex * d * (W[1] + 1j * W[2])
            # increments: (MU/h D - J) dW = f
            dW_real = lu_solve(LU_real, f_real, check_finite=False)  # F checked finite above
            dW_complex = lu_solve(LU_complex, f_complex, check_finite=False)
            dW[0] = dW_real
            dW[1] = dW_complex.real
            dW[2] = dW_complex.imag

            dW_norm = _rms(dW / scale)
            if dW_norm_old is not None and dW_norm_old > 0:
                rate = dW_norm / dW_norm_old
            if not np.isfinite(dW_norm):
                return False, k + 1, Z, rate, None, (DAE_NONFINITE_INCREMENT,)
            # divergence, or convergence too slow to reach newton_tol within the limit
            # (scipy's test; not applied while polishing, where the increments are tiny)
            at_noise = dW_norm <= noise_norm
            if not polishing and not at_noise and rate is not None and (
                    rate >= 1 or rate ** (NEWTON_MAXITER - k) / (1 - rate) * dW_norm > self.newton_tol):
                return False, k + 1, Z, rate, None, (DAE_DIVERGED if rate >= 1 else DAE_SLOW,)

            W += dW
            Z = T @ W

            if polishing or at_noise or (rate is not None and rate / (1 - rate) * dW_norm < self.newton_tol):
                if not check_alg:
                    return True, k + 1, Z, rate, None, None
                polishing = True
                # the algebraic residual at the step end: max |F_alg(t + h, y + Z_3)| <= alg_tol
                f_end = self.fun(t_new, y + Z[2])
                if not np.all(np.isfinite(f_end)):
                    return False, k + 1, Z, rate, None, (DAE_NONFINITE_F,)
                excess = np.abs(f_end[alg]) / alg_tol
                if np.max(excess) <= 1:
                    return True, k + 1, Z, rate, f_end, None
            dW_norm_old = dW_norm

        if polishing:
            i = int(np.argmax(excess))
            reason = (DAE_ALGEBRAIC, abs(f_end[alg][i]), alg_tol[i])
        else:
            reason = (DAE_NO_CONVERGENCE,)
        return False, NEWTON_MAXITER, Z, rate, None, reason

    # --- one step --------------------------------------------------------------------------
    def _step_impl(self):
        t, y, f = self.t, self.y, self.f
        min_step, h_abs, h_abs_old, error_norm_old = self._step_bounds(t)

        J = self.J
        LU_real, LU_complex = self.LU_real, self.LU_complex
        current_jac = self.current_jac
        # tolerance on the algebraic residuals, raised to their round-off level
        alg = self.algebraic
        alg_tol = np.maximum(self.algebraic_tol, ROUNDOFF_FACTOR * EPS * (np.abs(J[alg]) @ np.abs(y)))

        rejected = False
        newton_failure = None  # the reason of the last failed Newton attempt
        n_singular = 0
        while True:
            if h_abs < min_step:
                return False, self._too_small_message(t, h_abs, newton_failure)

            h = h_abs * self.direction
            t_new = t + h
            if self.direction * (t_new - self.t_bound) > 0:
                t_new = self.t_bound
            h = t_new - t
            h_abs = np.abs(h)

            # Newton start: the previous step's collocation polynomial, extrapolated
            Z0 = np.zeros((3, self.n)) if self.sol is None else self.sol(t + h * C).T - y
            scale = self._scale(np.abs(y), h_abs)

            converged = False
            while not converged:
                if LU_real is None or LU_complex is None:
                    # iteration matrices MU_REAL/h D - J and MU_COMPLEX/h D - J
                    LU_real = self._lu(MU_REAL / h * np.diag(self.d) - J)
                    LU_complex = None if LU_real is None else self._lu(MU_COMPLEX / h * np.diag(self.d) - J)
                if LU_real is None or LU_complex is None:
                    converged, reason = False, (DAE_SINGULAR_MATRIX,)
                    zero = np.flatnonzero(self.algebraic & ~J.any(axis=0))
                    if current_jac and zero.size:  # singular for every h: halving cannot help
                        return False, dae_step_message(_detail(DAE_ZERO_COLUMNS, t, columns=zero))
                    n_singular += 1
                    if n_singular >= MAX_SINGULAR:
                        return False, dae_step_message(_detail(DAE_SINGULAR_REPEATED, t, value=n_singular))
                else:
                    converged, n_iter, Z, rate, f_end, reason = self._solve_collocation(
                        t, t_new, y, h, Z0, scale, J, LU_real, LU_complex, alg_tol)
                if not converged:
                    if current_jac:
                        break
                    J = self.jac(t, y, f)
                    current_jac = True
                    LU_real = LU_complex = None

            if not converged:
                newton_failure = reason
                h_abs *= 0.5
                LU_real = LU_complex = None
                continue

            y_new = y + Z[-1]
            error_norm = self._error_norm(t, y, y_new, f, Z, h, LU_real, rejected)
            safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)

            if not np.isfinite(error_norm):
                newton_failure = None
                h_abs *= MIN_FACTOR
                LU_real = LU_complex = None
                rejected = True
            elif error_norm > 1:
                newton_failure = None
                factor = predict_factor(h_abs, h_abs_old, error_norm, error_norm_old)
                h_abs *= max(MIN_FACTOR, safety * factor)
                LU_real = LU_complex = None
                rejected = True
            else:
                break

        # --- accepted: next step size, Jacobian reuse ----------------------------------------
        recompute_jac = n_iter > 2 and rate is not None and rate > 1e-3
        factor = predict_factor(h_abs, h_abs_old, error_norm, error_norm_old)
        factor = min(MAX_FACTOR, safety * factor)
        if not recompute_jac and factor < 1.2:
            factor = 1  # keep h, and with it the LU factors
        else:
            LU_real = LU_complex = None

        f_new = f_end if f_end is not None else self.fun(t_new, y_new)
        if recompute_jac:
            J = self.jac(t_new, y_new, f_new)
        self._accept(t, y, t_new, y_new, f_new, Z, h_abs * factor, error_norm, J, recompute_jac, LU_real, LU_complex)
        return True, None

    def _step_bounds(self, t: float) -> tuple[float, float, float | None, float | None]:
        """(smallest step, first step to try, previous step and error norm for the step-size
        predictor; None where the step was clipped to the bounds).

        The smallest step is ten times the spacing of numbers at t (scipy's), and not below ten
        eps times the whole interval (where t = 0 the spacing alone would allow 1e-322)."""
        min_step = 10 * max(np.abs(np.nextafter(t, self.direction * np.inf) - t), EPS * self.interval)
        if self.h_abs > self.max_step:
            return min_step, self.max_step, None, None
        if self.h_abs < min_step:
            return min_step, min_step, None, None
        return min_step, self.h_abs, self.h_abs_old, self.error_norm_old

    def _too_small_message(self, t: float, h_abs: float, newton_failure: tuple | None) -> str:
        """Why the step fell below the smallest one (:func:`csim.solver.failures.dae_step_message`): the last
        Newton failure ``(reason, value, tolerance)``, and on the first step the question whether the initial
        state is consistent."""
        reason, *values = newton_failure or (DAE_ERROR_TEST,)
        alg = self.algebraic
        residual = np.max(np.abs(self.f[alg])) if self.t_old is None and alg.any() else np.nan  # first step: y0?
        return dae_step_message(_detail(reason, t, h_abs, *values, residual=residual))

    def _error_norm(self, t, y, y_new, f, Z, h, LU_real, rejected: bool) -> float:
        """The scaled rms of the error estimate err = (MU_REAL/h D - J)^-1 (F(t, y) + D Z^T E / h),
        refined after a rejection to (MU_REAL/h D - J)^-1 (F(t, y + err) + D Z^T E / h)
        (non-finite: the step is rejected)."""
        ZE = Z.T @ E / h
        error = lu_solve(LU_real, f + self.d * ZE, check_finite=False)
        scale = self._scale(np.maximum(np.abs(y), np.abs(y_new)), abs(h))
        error_norm = _rms(error / scale)
        if rejected and error_norm > 1:
            error = lu_solve(LU_real, self.fun(t, y + error) + self.d * ZE, check_finite=False)
            error_norm = _rms(error / scale)
        return error_norm

    def _accept(self, t, y, t_new, y_new, f_new, Z, h_abs_next, error_norm, J, current_jac, LU_real, LU_complex):
        """Move to the accepted step: the state, the next step size, the Jacobian and LU factors
        kept for reuse, and the collocation dense output."""
        self.h_abs_old = self.h_abs
        self.error_norm_old = error_norm
        self.h_abs = h_abs_next
        self.y_old = y
        self.t, self.y, self.f = t_new, y_new, f_new
        self.Z = Z
        self.LU_real, self.LU_complex = LU_real, LU_complex
        self.current_jac = current_jac
        self.J = J
        self.t_old = t
        self.sol = RadauDenseOutput(self.t_old, self.t, self.y_old, Z.T @ P)

    def _dense_output_impl(self):
        return self.sol
