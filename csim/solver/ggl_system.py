"""The stabilized index-2 formulation of Gear, Gupta and Leimkuhler (GGL).

The position constraint is kept as an equation beside the velocity constraint, with a
second multiplier mu that makes the system solvable:

    q' = v - Phi_q^T mu                     (m)
    v' = M^-1 (p - Phi_q^T lambda)          (m)
    W' = u * B^T v                          (k, work of the loads)
    0  = Phi(q)                             (r)
    0  = Phi_q v                            (r)

State x = [q, v, W, mu, lambda] (2 m + k + 2 r). On the exact solution mu = 0 and v = q'.
This is a DAE of index 2; :class:`csim.solver.dae.RadauDAE` solves it with both constraints
enforced at every stage, so Phi and Phi_q v stay at the Newton tolerance without drift and
without any correction after the step.
"""
from __future__ import annotations

import numpy as np

from csim.physics.ggl import ggl_equations
from csim.physics.kkt import constraint_rates
from csim.physics.linalg import as_core
from csim.physics.status import GGL_SINGULAR_MASS, PROJ_NO_CONVERGENCE, PROJ_SINGULAR, SINGULAR_MASS
from csim.solver.failures import failure
from csim.solver.methods.projection import Projection
from csim.solver.system import ConstrainedSystem


class GGLSystem(ConstrainedSystem):
    """The GGL DAE ``D x' = F(t, x)`` of a mechanism (``differential`` marks the rows of D).

    Parameters are those of :class:`ConstrainedSystem`; the stabilizer is a
    :class:`csim.solver.stabilizers.GGL` and carries the constraint tolerance.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._projection = Projection(projection_metric="mass")
        self._projection.metric_fixed_by = "ggl"

    @property
    def n_state(self) -> int:
        return 2 * self.m + self.k + 2 * self.r

    @property
    def differential(self) -> np.ndarray:
        return np.arange(self.n_state) < 2 * self.m + self.k

    def dae_options(self) -> dict:
        return dict(differential=self.differential, algebraic_tol=self.stabilizer.tol)

    def failure_method(self, code: int):
        """The projection's failures quote its settings (the mass metric, fixed by ggl), the others the stabilizer's."""
        return self._projection if code in (PROJ_NO_CONVERGENCE, PROJ_SINGULAR, SINGULAR_MASS) else self.stabilizer

    def to_full(self, x: np.ndarray) -> np.ndarray:
        return x[:2 * self.m + self.k]

    def output_state(self, t: float, x: np.ndarray) -> np.ndarray:
        """The recorded [q, qd, W]: on the manifold, as every step ends.

        Samples between step ends come from the integrator's dense output, a polynomial
        that satisfies the constraints only to the interpolation error; they are projected
        (mass metric) before they are recorded. The integration itself is never corrected.
        """
        q, v, W = self.split(self.to_full(x))
        q, v = self._projection.project(self.model, self.par, q, v, t=t)
        return np.concatenate((q, v, W))

    def start(self, y_full: np.ndarray) -> np.ndarray:
        """Consistent DAE state at t = 0 from a full state [q, qd, W]; see :meth:`_consistent`."""
        y_full = np.asarray(y_full, dtype=float)
        return self._consistent(0.0, y_full, self.mode_at(y_full))

    def restart(self, t: float, x: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """Consistent DAE state at a switching event, with the multipliers of the new ``mode``.

        A load that jumps changes lambda at once; restarting with the old mode's lambda
        would hand Radau an inconsistent algebraic variable.
        """
        return self._consistent(t, self.to_full(x), mode)

    def _consistent(self, t: float, y_full: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """(q, v) projected onto the manifold (mass metric), mu = 0, lambda from the KKT system."""
        q, qd, W = self.split(y_full)
        q, v = self._projection.project(self.model, self.par, q, qd, t=t)
        _, lam, *_ = self._solve(q, v, self.load_values(t, q, v, mode))
        return np.concatenate((q, v, W, np.zeros(self.r), lam))

    def rhs(self, t: float, x: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """F(t, x) (n_state,): the differential right-hand sides, then Phi and Phi_q v
        (:func:`csim.physics.ggl.ggl_equations`, which the compiled kernels call too)."""
        model, par, m, k, r = self.model, self.par, self.m, self.k, self.r
        q, v = x[:m], np.ascontiguousarray(x[m:2 * m])
        mu, lam = x[2 * m + k:2 * m + k + r], x[2 * m + k + r:]
        u = self.load_values(t, q, v, mode)
        M = as_core(model.mass(q, par))
        phi_q = as_core(model.phi_q(q, par))
        B = model.load_matrix(q, par)
        # p = B u - C v - h
        p = as_core(B @ u - model.velocity_terms(q, v, par) - model.gravity(q, par))
        phi_dot = np.empty(r)
        constraint_rates(phi_q, v, phi_dot, r, m)
        F = np.empty(self.n_state)
        if not ggl_equations(M, phi_q, p, as_core(model.phi(q, par)), phi_dot, v, as_core(mu), as_core(lam),
                             np.empty(m * m), np.zeros(m, np.int64), F[:m], F[m:2 * m], F[2 * m + k:], m, r):
            raise failure(GGL_SINGULAR_MASS, t, 0.0, None)
        F[2 * m:2 * m + k] = u * (B.T @ v)
        return F
