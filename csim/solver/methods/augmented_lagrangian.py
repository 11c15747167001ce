"""``augmented_lagrangian``: the index-3 augmented Lagrangian formulation with projections (ALI3-P).

Bayo, Garcia de Jalon and Serna (1988); Cuadrado, Cardenal and Bayo (1997). The equations
of motion hold with multipliers lambda* + alpha Phi:

    M qdd + Phi_q^T (lambda* + alpha Phi) = p,      lambda*_{i+1} = lambda*_i + alpha Phi_{i+1}

discretised by the trapezoidal rule and solved by Newton-Raphson on the positions at each
step (:class:`csim.solver.ali3p.ALI3P`), then the velocities and accelerations are
projected onto Phi_q qd = 0 and Phi_q qdd = gamma. The leading matrix
M + (h^2/4) Phi_q^T alpha Phi_q stays regular where Phi_q loses rank, so the method works
with every non-trivial constraint equation, the redundant ones of an overconstrained
mechanism included, and through singular configurations.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from csim.errors import SimulationFailure
from csim.solver.methods.base import Method, option
from csim.solver.system import ConstrainedSystem


@dataclasses.dataclass(frozen=True)
class AugmentedLagrangianOptions:
    penalty: float = option(1e4, "the constraints' penalty against inertia: alpha (h^2/4) |Phi_q|^2 over the mass "
                                 "matrix's largest diagonal entry; its iteration converges like 1/(1 + penalty "
                                 "sigma^2) where sigma is the smallest singular value of Phi_q/|Phi_q|, so near a "
                                 "singular configuration a large one is needed", "-", gt=0.0)
    al_tol: float = option(1e-9, "Newton-Raphson tolerance on the largest position correction of a step "
                                  "(relative to 1 + |q|)", "-", gt=0.0)
    al_max_iter: int = option(20, "Newton-Raphson iteration limit per step", "-", gt=0)


class AugmentedLagrangian(Method):
    """The index-3 augmented Lagrangian formulation with projections (ALI3-P).

    Parameters
    ----------
    penalty : float
        The penalty relative to inertia (dimensionless): alpha = penalty max(diag M) /
        ((h^2/4) max(diag Phi_q^T Phi_q)) for the step h, and the same without h^2/4 at the
        acceleration level.
    al_tol : float
        Newton-Raphson tolerance on max |dq| / (1 + max |q|).
    al_max_iter : int
        Newton-Raphson iteration limit per step.
    """

    name = "augmented_lagrangian"
    rank = 45
    Options = AugmentedLagrangianOptions
    integrators = ("trapezoidal",)

    def __init__(self, penalty=1e4, al_tol=1e-9, al_max_iter=20):
        super().__init__(penalty=penalty, al_tol=al_tol, al_max_iter=al_max_iter)
        self.penalty, self.tol, self.max_iter = float(penalty), float(al_tol), int(al_max_iter)

    @classmethod
    def system_class(cls):
        return AugmentedLagrangianSystem


class AugmentedLagrangianSystem(ConstrainedSystem):
    """The mechanism with every non-trivial constraint equation, for :class:`csim.solver.ali3p.ALI3P`.

    :meth:`use_constraints` hands it the full set (:class:`csim.solver.integrity.ConstraintWatch`);
    until then it uses the model's own. Accelerations and multipliers at an instant come from
    the augmented Lagrangian iteration at the acceleration level, which converges to the
    minimum-norm multipliers where Phi_q is rank-deficient.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.watch = None

    def use_constraints(self, watch) -> None:
        """Integrate with every equation of ``watch`` (kept and removed), not only the model's;
        the samples record them all."""
        self.watch = watch
        self.r_recorded = len(watch.labels)

    # -- the full constraint set --------------------------------------------------------
    def phi_all(self, q: np.ndarray) -> np.ndarray:
        """Phi (n_all,) of every non-trivial equation."""
        return self.model.phi(q, self.par) if self.watch is None else self.watch.phi(q)

    def phi_q_all(self, q: np.ndarray) -> np.ndarray:
        """Phi_q (n_all, m)."""
        return self.model.phi_q(q, self.par) if self.watch is None else self.watch.phi_q(q)

    def gamma_all(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """gamma = -(dPhi_q/dt) qd (n_all,): the model's on the kept rows, the watch's on the removed ones."""
        gamma_kept = self.model.gamma(q, qd, self.par)
        return gamma_kept if self.watch is None else self.watch.gamma(gamma_kept, q, qd)

    def forces(self, t: float, q: np.ndarray, qd: np.ndarray, mode: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, u): p = B u - C qd - h (m,) and the loads u (k,)."""
        u = self.load_values(t, q, qd, mode)
        return self._generalized(q, qd, u, self.model.load_matrix(q, self.par)), u

    def _generalized(self, q, qd, u, B):
        """p = B u - C qd - h (m,) for the loads u with their matrix B (m, k)."""
        return B @ u - self.model.velocity_terms(q, qd, self.par) - self.model.gravity(q, self.par)

    def accelerations(self, M: np.ndarray, J: np.ndarray, p: np.ndarray, gamma: np.ndarray,
                      lam0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """qdd (m,) and the multipliers (n_all,) of M qdd + J^T lam = p, J qdd = gamma.

        The augmented Lagrangian iteration (M + J^T alpha J) qdd = p + J^T (alpha gamma - lam),
        lam <- lam + alpha (J qdd - gamma): every increment of lam lies in the range of J, so
        from lam0 = 0 it converges to the minimum-norm multipliers where J is rank-deficient.
        """
        import scipy.linalg

        alpha = penalty_factor(self.stabilizer.penalty, M, J, 1.0)
        lam = np.zeros(J.shape[0]) if lam0 is None else lam0.copy()
        with np.errstate(all="ignore"):
            factor = scipy.linalg.lu_factor(M + alpha * (J.T @ J), check_finite=False)
        if not np.all(np.isfinite(factor[0])) or np.min(np.abs(np.diag(factor[0])), initial=1.0) == 0.0:
            raise SimulationFailure("augmented_lagrangian: M + alpha Phi_q^T Phi_q is singular (the mass matrix is "
                                    "singular on the constraints' null space)", "singular")
        for _ in range(5 * self.stabilizer.max_iter):
            qdd = scipy.linalg.lu_solve(factor, p + J.T @ (alpha * gamma - lam), check_finite=False)
            residual = J @ qdd - gamma
            lam += alpha * residual
            if np.max(np.abs(residual), initial=0.0) <= 1e-12 * (1.0 + np.max(np.abs(qdd), initial=0.0)):
                break
        return qdd, lam

    def _solve(self, q, qd, u):
        """qdd, the minimum-norm multipliers and the residuals of every equation (for the samples)."""
        model, par = self.model, self.par
        M = model.mass(q, par)
        B = model.load_matrix(q, par)
        p = self._generalized(q, qd, u, B)
        J = self.phi_q_all(q)
        qdd, lam = self.accelerations(M, J, p, self.gamma_all(q, qd))
        return qdd, lam, self.phi_all(q), J @ qd, B @ u, B


def penalty_factor(penalty: float, M: np.ndarray, J: np.ndarray, c: float) -> float:
    """alpha = penalty max(diag M) / (c max(diag J^T J)): the penalty ``penalty`` times the
    inertia, per unit of c alpha J^T J (c = h^2/4 in a step, 1 at the acceleration level)."""
    inertia = float(np.max(np.abs(np.diag(M)), initial=0.0)) or 1.0
    stiffness = float(np.max(np.sum(J * J, axis=0), initial=0.0)) or 1.0
    return penalty * inertia / (c * stiffness)
