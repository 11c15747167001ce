"""An overconstrained mechanism's constraints, with the independent rows chosen again as it moves.

A linkage such as Bricard's has more non-trivial closure equations than the rank of their
Jacobian. The model keeps an independent subset chosen at the start; at a configuration
where that subset loses rank (while the full set does not) a solver using it alone goes
wrong: the KKT system becomes singular, or the motion leaves the manifold along a direction
only a removed equation sees.

:class:`RedundantModel` wraps the numeric model so that every solver of the Python path
(the KKT and elimination formulations, the projection, GGL, the Newton solves of the initial
conditions) sees ``rank`` rows chosen among **all** the equations at the configuration it is
evaluated at: the chosen rows are kept while their Jacobian is well conditioned
(sigma_min / sigma_max >= :data:`KEEP_RATIO`) and chosen again by QR with column pivoting of
Phi_q^T otherwise. Any independent subset gives the same accelerations where the equations
are consistent, so a change of rows between two evaluations changes nothing but the
multipliers' basis; what a run records is the full set's Phi, Phi_q qd and the
minimum-norm multipliers (:meth:`recorded`).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

#: the chosen rows are kept while sigma_min / sigma_max of their Jacobian is above this
KEEP_RATIO = 0.3


class RedundantModel:
    """A :class:`csim.model.numeric.NumericModel` whose constraints are chosen rows of the full set.

    Parameters
    ----------
    model : NumericModel
        The model (its Phi: the rows kept at the start).
    watch : csim.solver.integrity.ConstraintWatch
        Every non-trivial equation, with gamma of the removed rows.
    par : ndarray (n_par,)
        The run's parameter values (the watch's functions have them built in).
    """

    def __init__(self, model, watch, par):
        self._model, self.watch = model, watch
        self.n_recorded = len(watch.labels)
        self.rows = np.asarray(watch.kept, dtype=int)
        self._at: tuple[bytes, np.ndarray] | None = None
        self.row_changes = 0
        self._par = np.asarray(par, dtype=float)

    def __getattr__(self, name):  # every other model function is the model's own
        return getattr(self._model, name)

    @property
    def n_constraints(self) -> int:
        return self.rows.size

    # -- the chosen rows ------------------------------------------------------------------
    def _jacobian(self, q: np.ndarray) -> np.ndarray:
        """Phi_q of the full set at q (the last one is cached: phi and phi_q come in pairs)."""
        key = np.asarray(q, dtype=float).tobytes()
        if self._at is None or self._at[0] != key:
            self._at = (key, self.watch.phi_q(q))
            self._choose(self._at[1])
        return self._at[1]

    def _choose(self, J: np.ndarray) -> None:
        """Keep the current rows while they are well conditioned, else the best by pivoted QR."""
        if _ratio(J[self.rows]) >= KEEP_RATIO:
            return
        _, _, piv = scipy.linalg.qr(J.T, pivoting=True, mode="economic")
        rows = np.sort(piv[:self.rows.size])
        if _ratio(J[rows]) > _ratio(J[self.rows]):
            self.rows = rows
            self.row_changes += 1

    def selected(self, q: np.ndarray) -> np.ndarray:
        """The rows (indices into the full set) used at q."""
        self._jacobian(q)
        return self.rows

    def phi(self, q, par):
        return self.watch.phi(q)[self.selected(q)]

    def phi_q(self, q, par):
        return self._jacobian(q)[self.rows]

    def gamma_all(self, q, qd) -> np.ndarray:
        """gamma (n_all,) of every equation."""
        return self.watch.gamma(self._model.gamma(q, qd, self._par), q, qd)

    def gamma(self, q, qd, par):
        return self.gamma_all(q, qd)[self.selected(q)]

    def recorded(self, q: np.ndarray, qd: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, Phi_q qd, multipliers) of the full set (n_all,) from the chosen rows' multipliers.

        The constraint force Phi_q,chosen^T lam is written as Phi_q,all^T lam_all with the
        minimum-norm lam_all: the pseudo-inverse of Phi_q,all^T truncated at the rank, the chosen
        rows' count. (Least squares at round-off, ``lstsq``'s cut, kept the dependent singular
        value, 1e-11 to 1e-10 of the largest off the manifold by the integration's error: it gave
        the chosen rows' multipliers with the others at 0, and so multipliers and reactions that
        jumped where the rows were chosen again, and that differed from one method to another.)
        """
        J = self._jacobian(q)
        U, s, Vt = np.linalg.svd(J.T, full_matrices=False)
        k = min(self.rows.size, s.size)
        lam_all = Vt[:k].T @ ((U[:, :k].T @ (J[self.rows].T @ lam)) / s[:k])
        return self.watch.phi(q), J @ qd, lam_all


def _ratio(J: np.ndarray) -> float:
    """sigma_min / sigma_max of J (r, m), r <= m; 0 for a zero matrix."""
    if J.size == 0:
        return 1.0
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0
