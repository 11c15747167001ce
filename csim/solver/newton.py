"""Newton-Raphson for the dependent coordinates of a partition q = (u, v).

With the independent coordinates u held fixed, the dependent ones v solve Phi(u, v) = 0:

    Phi_v(q_i) (v_{i+1} - v_i) = -Phi(q_i),

and the dependent velocities follow from Phi_q qd = 0 by one linear solve,

    Phi_v vd = -Phi_u ud.

The consistent initial state and the minimal-coordinate method both use it; each turns a
:class:`DependentSolveError` into its own message.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.model.numeric import NumericModel

EPS = np.finfo(float).eps


def at_round_off(dq: np.ndarray, q: np.ndarray) -> bool:
    """Whether a Newton correction dq is down to the round-off of q (nothing left to gain).

    Phi evaluated at large angles (a crank after many turns) carries a round-off of about
    eps |q|, so a fixed tolerance on |Phi| can become unreachable; the size of the step
    tells when the iteration has converged anyway.
    """
    return bool(np.max(np.abs(dq), initial=0.0) <= 8 * EPS * max(1.0, np.max(np.abs(q))))


@dataclass
class DependentSolution:
    """The solved coordinates.

    Attributes
    ----------
    q : ndarray (m,)
        Coordinates with v solved [rad or m].
    phi_q : ndarray (r, m)
        Phi_q at ``q``.
    iterations : int
        Newton corrections applied.
    residual : float
        max |Phi(q)| [unit of Phi].
    """

    q: np.ndarray
    phi_q: np.ndarray
    iterations: int
    residual: float


class DependentSolveError(Exception):
    """Newton-Raphson for v failed.

    Attributes
    ----------
    reason : {"singular", "no_convergence", "non_finite"}
    q : ndarray (m,)
        The last iterate.
    phi : ndarray (r,)
        Phi at the last iterate.
    """

    def __init__(self, reason: str, q: np.ndarray, phi: np.ndarray):
        super().__init__(reason)
        self.reason, self.q, self.phi = reason, q, phi


def solve_dependent(model: NumericModel, par: np.ndarray, q: np.ndarray, dependent: np.ndarray, tol: float,
                    max_iter: int, max_condition: float = np.inf) -> DependentSolution:
    """Solve Phi(u, v) = 0 for v = q[dependent], starting from ``q``.

    Converged when max |Phi| <= ``tol``, or when a correction is down to the round-off of q
    (:func:`at_round_off`).

    Parameters
    ----------
    model : NumericModel
    par : ndarray (n_par,)
    q : ndarray (m,)
        Start: u as given, v the first guess. Not modified.
    dependent : ndarray of int (r,)
        Indices of v in q.
    tol : float
        Tolerance on max |Phi| [unit of Phi].
    max_iter : int
        Newton corrections at most.
    max_condition : float
        Phi_v counts as singular when its 2-norm condition number exceeds this (the default,
        inf, checks only for an exactly singular matrix and saves the SVD).

    Raises
    ------
    DependentSolveError
    """
    q = np.array(q, dtype=float)
    for iteration in range(max_iter + 1):
        phi = model.phi(q, par)
        if not np.all(np.isfinite(phi)) or not np.all(np.isfinite(q)):
            raise DependentSolveError("non_finite", q, phi)
        phi_q = model.phi_q(q, par)
        residual = float(np.max(np.abs(phi), initial=0.0))
        if residual <= tol:
            return DependentSolution(q, phi_q, iteration, residual)
        if iteration == max_iter:
            raise DependentSolveError("no_convergence", q, phi)
        phi_v = phi_q[:, dependent]
        if np.isfinite(max_condition) and np.linalg.cond(phi_v) > max_condition:
            raise DependentSolveError("singular", q, phi)
        try:
            dv = np.linalg.solve(phi_v, phi)
        except np.linalg.LinAlgError:
            raise DependentSolveError("singular", q, phi) from None
        q[dependent] -= dv
        if at_round_off(dv, q):  # converged to the round-off of Phi at these coordinates
            phi = model.phi(q, par)
            return DependentSolution(q, model.phi_q(q, par), iteration + 1, float(np.max(np.abs(phi), initial=0.0)))
    raise AssertionError("unreachable")  # the loop returns or raises at iteration == max_iter


def dependent_velocities(phi_q: np.ndarray, qd: np.ndarray, dependent: np.ndarray) -> np.ndarray:
    """qd with vd solved from Phi_v vd = -Phi_u ud (the ud entries of ``qd`` as given).

    Raises
    ------
    numpy.linalg.LinAlgError
        Phi_v is singular.
    """
    independent = np.setdiff1d(np.arange(qd.size), dependent)
    out = np.array(qd, dtype=float)
    out[dependent] = -np.linalg.solve(phi_q[:, dependent], phi_q[:, independent] @ out[independent])
    return out
