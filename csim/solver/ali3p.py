"""The trapezoidal rule of the index-3 augmented Lagrangian method with projections (ALI3-P).

Cuadrado, Cardenal and Bayo, "Modeling and solution methods for efficient real-time
simulation of multibody dynamics", Multibody System Dynamics 1 (1997) 259-280. One step of
length h from (q_n, qd_n, qdd_n):

1. The trapezoidal rule ties velocities and accelerations to the new positions:
       qd  = (2/h) q + qd^,      qd^  = -((2/h) q_n + qd_n)
       qdd = (4/h^2) q + qdd^,   qdd^ = -((4/h^2) q_n + (4/h) qd_n + qdd_n)
2. Newton-Raphson on the equations of motion with the augmented multipliers, scaled by h^2/4:
       f(q) = (h^2/4) [M qdd + Phi_q^T (lambda* + alpha Phi) - p] = 0
   with alpha set from the method's relative penalty at the predictor
   (:func:`~csim.solver.methods.augmented_lagrangian.penalty_factor`), the tangent
   f_q = M + (h/2) C + (h^2/4) (Phi_q^T alpha Phi_q + K),  C = -dp/dqd and
   K = -dp/dq by finite differences at the predictor, the rest at each iterate, and
   lambda* <- lambda* + alpha Phi after each iteration.
3. Projections with W = M + (h/2) C + (h^2/4) K at the converged positions:
       f_q qd  = W qd*,                              (onto Phi_q qd = 0)
       f_q qdd = W qdd* + (h^2/4) Phi_q^T alpha gamma   (onto Phi_q qdd = gamma)
The load work W_k (energy balance) is integrated by the same trapezoidal rule.

The class follows scipy's ``OdeSolver`` contract (``step()``, ``dense_output()``, ``status``,
``t``, ``y``) so that :mod:`csim.solver.simulate` drives it like every other integrator; its
state is the full state [q, qd, W]. It needs the system (its model and full constraint set:
:class:`csim.solver.methods.augmented_lagrangian.AugmentedLagrangianSystem`) and the load
conditions in force, ``mode``.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.integrate import OdeSolver

from csim.errors import SimulationFailure
from csim.solver.methods.augmented_lagrangian import penalty_factor
from csim.solver.rk4 import CubicHermite


class ALI3P(OdeSolver):
    """ALI3-P with a fixed step (the last one shortened to end on ``t_bound``).

    Parameters
    ----------
    fun, t0, y0, t_bound
        As for every :class:`scipy.integrate.OdeSolver`; ``fun`` is counted, not used for the
        step (the step solves its own equations).
    step : float
        Step size h [s], > 0.
    system : AugmentedLagrangianSystem
    mode : ndarray (n_switches,) bool or None
        The load conditions held during the steps (None: evaluated at each step's start).
    """

    def __init__(self, fun, t0, y0, t_bound, step, system=None, mode=None, vectorized=False, **unused):
        super().__init__(fun, t0, y0, t_bound, vectorized)
        if not step > 0:
            raise ValueError("`step` must be positive")
        if system is None or not hasattr(system, "accelerations"):
            raise ValueError("the trapezoidal integrator runs stabilization.method augmented_lagrangian only")
        self.h, self.t_start, self.n_steps = float(step), t0, 0
        #: evaluations of the equations of motion (Newton residuals, accelerations): the
        #: "RHS evaluations" of a run, as fun's calls are for the other integrators
        self.n_residuals = 1
        self.system, self.mode = system, mode
        m = system.m
        q, qd = self.y[:m], self.y[m:2 * m]
        self.qdd, self.lam, self.power = self._start(q, qd)
        self._last = None

    # -- pieces -------------------------------------------------------------------------
    def _mode(self, y):
        return self.system.mode_at(y) if self.mode is None else self.mode

    def _start(self, q, qd):
        """qdd, the full set's multipliers and the loads' power at the initial state."""
        s = self.system
        p, u = s.forces(self.t, q, qd, self._mode(self.y))
        M = s.model.mass(q, s.par)
        qdd, lam = s.accelerations(M, s.phi_q_all(q), p, s.gamma_all(q, qd))
        return qdd, lam, u * (s.model.load_matrix(q, s.par).T @ qd)

    def _force_derivatives(self, t, q, qd, mode):
        """C = -d(B u)/dqd and K = -d(B u)/dq (m, m) of the applied loads, by forward differences.

        The force elements (springs, dampers) make a problem stiff; the inertial and gravity
        terms of p are left out of the tangent (a modified Newton converges without them),
        and a mechanism without loads has C = K = 0.
        """
        s, m = self.system, self.system.m
        C, K = np.zeros((m, m)), np.zeros((m, m))
        if s.k == 0:
            return C, K

        def applied(q_, qd_):
            return s.model.load_matrix(q_, s.par) @ s.load_values(t, q_, qd_, mode)

        f0 = applied(q, qd)
        for j in range(m):
            for x, out in ((qd, C), (q, K)):
                d = 1e-7 * max(1.0, abs(x[j]))
                x[j] += d
                out[:, j] = -(applied(q, qd) - f0) / d
                x[j] -= d
        return C, K

    # -- the OdeSolver contract ---------------------------------------------------------
    def _step_impl(self):
        s = self.system
        m = s.m
        t_old, y_old = self.t, self.y
        n = self.n_steps + 1
        t_new = self.t_start + n * self.h
        if t_new > self.t_bound or self.t_bound - t_new < 1e-9 * self.h:
            t_new = self.t_bound
        h = t_new - t_old
        mode = self._mode(y_old)
        q0, qd0, W0 = y_old[:m], y_old[m:2 * m], y_old[2 * m:]
        try:
            q, qd, qdd, lam = self._newton(t_new, q0, qd0, self.qdd, h, mode)
        except SimulationFailure as exc:
            return False, str(exc)
        _, u = s.forces(t_new, q, qd, mode)
        power = u * (s.model.load_matrix(q, s.par).T @ qd)
        W = W0 + 0.5 * h * (self.power + power)
        y_new = np.concatenate((q, qd, W))
        f_old = np.concatenate((qd0, self.qdd, self.power))
        f_new = np.concatenate((qd, qdd, power))
        self._last = (t_old, t_new, y_old, y_new, f_old, f_new)
        self.t, self.y, self.qdd, self.lam, self.power = t_new, y_new, qdd, lam, power
        self.n_steps = n
        return True, None

    def _newton(self, t, q0, qd0, qdd0, h, mode):
        """The step's positions by Newton-Raphson, then the projected velocities and accelerations."""
        s = self.system
        method = s.stabilizer
        par = s.par
        qd_hat = -(2.0 / h * q0 + qd0)
        qdd_hat = -(4.0 / h**2 * q0 + 4.0 / h * qd0 + qdd0)
        q = q0 + h * qd0 + 0.5 * h * h * qdd0  # predictor
        lam = self.lam.copy()
        c = 0.25 * h * h
        qd, qdd = 2.0 / h * q + qd_hat, 4.0 / h**2 * q + qdd_hat
        C, K = self._force_derivatives(t, q, qd, mode)
        alpha = penalty_factor(method.penalty, s.model.mass(q, par), s.phi_q_all(q), c)
        last = np.inf
        for _ in range(method.max_iter):
            qd, qdd = 2.0 / h * q + qd_hat, 4.0 / h**2 * q + qdd_hat
            M, J, phi = s.model.mass(q, par), s.phi_q_all(q), s.phi_all(q)
            p, _ = s.forces(t, q, qd, mode)
            # f(q) = (h^2/4) [M qdd + Phi_q^T (lambda* + alpha Phi) - p]
            f = c * (M @ qdd + J.T @ (lam + alpha * phi) - p)
            self.n_residuals += 1
            # tangent f_q = M + (h/2) C + (h^2/4) (Phi_q^T alpha Phi_q + K), at the current iterate
            # (near a singular configuration Phi_q turns quickly)
            factor = self._factor(M + 0.5 * h * C + c * (alpha * (J.T @ J) + K), t)
            dq = scipy.linalg.lu_solve(factor, -f, check_finite=False)
            q = q + dq
            lam = lam + alpha * s.phi_all(q)
            self.njev += 1
            if not np.all(np.isfinite(q)):
                raise SimulationFailure(f"augmented_lagrangian: Newton-Raphson diverged at t = {t:.6g} s "
                                        f"(a smaller simulation.step, or a smaller stabilization.penalty)", "newton")
            size, bound = np.max(np.abs(dq)), method.tol * (1.0 + np.max(np.abs(q)))
            # converged; or stalled at the round-off floor, which the penalty's conditioning
            # raises above the tolerance near a singular configuration
            if size <= bound or (size <= 100.0 * bound and size > 0.5 * last):
                break
            last = size
        else:
            raise SimulationFailure(f"augmented_lagrangian: Newton-Raphson did not converge in {method.max_iter} "
                                    f"iterations at t = {t:.6g} s (last correction {np.max(np.abs(dq)):.3g}; a smaller "
                                    f"simulation.step, or a larger stabilization.al_tol)", "newton")
        qd, qdd = 2.0 / h * q + qd_hat, 4.0 / h**2 * q + qdd_hat
        # projections onto Phi_q qd = 0 and Phi_q qdd = gamma, with the matrix at the converged q
        M, J = s.model.mass(q, par), s.phi_q_all(q)
        W = M + 0.5 * h * C + c * K
        factor = self._factor(W + c * alpha * (J.T @ J), t)
        qd = self._project(factor, W, J, c * alpha, qd, np.zeros(J.shape[0]))
        qdd = self._project(factor, W, J, c * alpha, qdd, s.gamma_all(q, qd))
        return q, qd, qdd, lam

    def _project(self, factor, W, J, beta, x_star, target, iterations: int = 10):
        """x closest to x_star in the metric W with J x = target, by the augmented Lagrangian
        iteration (W + beta J^T J) x = W x* + J^T (beta target - sigma), sigma <- sigma +
        beta (J x - target): the first iterate is ALI3-P's projection, the next ones remove
        the O(|W| / beta) residual it leaves."""
        sigma = np.zeros(J.shape[0])
        rhs0 = W @ x_star
        scale = 1.0 + np.max(np.abs(x_star), initial=0.0)
        for _ in range(iterations):
            x = scipy.linalg.lu_solve(factor, rhs0 + J.T @ (beta * target - sigma), check_finite=False)
            residual = J @ x - target
            if np.max(np.abs(residual), initial=0.0) <= 1e-14 * scale:
                break
            sigma += beta * residual
        return x

    def _factor(self, A, t):
        with np.errstate(all="ignore"):
            factor = scipy.linalg.lu_factor(A, check_finite=False)
        self.nlu += 1
        if not np.all(np.isfinite(factor[0])) or np.min(np.abs(np.diag(factor[0]))) == 0.0:
            raise SimulationFailure(f"augmented_lagrangian: singular tangent matrix at t = {t:.6g} s", "singular")
        return factor

    def _dense_output_impl(self):
        return CubicHermite(*self._last)
