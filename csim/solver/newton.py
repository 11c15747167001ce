"""Newton-Raphson for the dependent coordinates of a partition q = (u, v), from Python.

The numerics are the core's (:mod:`csim.physics.branch`, :mod:`csim.physics.partition`),
which the compiled kernels run too; this module gives them a Python interface over a
:class:`csim.model.numeric.NumericModel` (:class:`PythonModel`) and turns their status codes
into exceptions:

    Phi_v(q_i) (v_{i+1} - v_i) = -Phi(q_i)        (:func:`solve_dependent`)
    Phi_v vd = -Phi_u ud                          (:func:`dependent_velocities`)

The consistent initial state and the minimal-coordinate method both use it; each turns a
:class:`DependentSolveError` into its own message. :func:`follow_branch` keeps the solution
on the assembly branch through a known point (:class:`BranchPoint`), as the module
docstring of :mod:`csim.physics.branch` explains.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.model.numeric import NumericModel
from csim.physics import branch as core
from csim.physics.partition import (  # noqa: F401 (the constants' old home)
    BRANCH_CONTINUITY,
    BRANCH_TANGENT_CHANGE,
    D_COORD,
    MAX_PIECE_MOVE,
    MIN_PIECE,
    Partition,
    new_partition,
)
from csim.physics.partition import branch_tangent as _tangent_core
from csim.physics.projection import at_round_off  # noqa: F401 (re-exported)
from csim.physics.status import BRANCH_LEFT, DEPENDENT_NONFINITE, DEPENDENT_SINGULAR, OK
from csim.solver.failures import branch_test_text

_REASONS = {DEPENDENT_NONFINITE: "non_finite", DEPENDENT_SINGULAR: "singular"}


class PythonModel:
    """The model evaluations of :mod:`csim.physics.model` for the Python driver: a NumericModel at ``par``
    (and, for a projection onto drives, their rates Phi_t at one instant)."""

    def __init__(self, model: NumericModel, par: np.ndarray, phi_t: np.ndarray | None = None):
        self.model, self.par = model, np.asarray(par, dtype=float)
        self._phi_t = phi_t  # Phi_t (r,) at the instant the handle stands for; None: zero

    def phi_t(self, q, out):
        out[:] = 0.0 if self._phi_t is None else self._phi_t

    def phi(self, q, out):
        out[:] = self.model.phi(q, self.par)

    def jacobian(self, q, out):
        out[:] = np.ravel(self.model.phi_q(q, self.par))

    def gamma(self, q, qd, out):
        out[:] = self.model.gamma(q, qd, self.par)

    def mass(self, q, out):
        out[:] = np.ravel(self.model.mass(q, self.par))


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
    reason : {"singular", "no_convergence", "non_finite", "branch"}
    q : ndarray (m,)
        The last iterate.
    phi : ndarray (r,)
        Phi at the last iterate.
    """

    def __init__(self, reason: str, q: np.ndarray, phi: np.ndarray):
        super().__init__(reason)
        self.reason, self.q, self.phi = reason, q, phi


class BranchLeftError(DependentSolveError):
    """Newton's solution for v left the assembly branch it was followed along (reason ``"branch"``).

    Attributes
    ----------
    q : ndarray (m,)
        The solution Newton converged to, on another branch [rad or m].
    phi : ndarray (r,)
        Phi there.
    predicted : ndarray (m,)
        The branch's prediction it was started from.
    coordinate : int
        Index in q of the coordinate that moved most from the prediction.
    detail : str
        Which branch test failed, with its numbers.
    """

    def __init__(self, q: np.ndarray, phi: np.ndarray, predicted: np.ndarray, detail: str, coordinate: int):
        super().__init__("branch", q, phi)
        self.predicted, self.detail, self.coordinate = predicted, detail, coordinate


def _partition(model: NumericModel, independent, dependent) -> Partition:
    P = new_partition(model.n_coordinates, model.n_constraints, 0)
    P.ind[:] = independent
    P.dep[:] = dependent
    return P


def _error(code: int, P: Partition) -> DependentSolveError:
    """The exception of a failed core solve (the iterate of a Newton failure, the solution of a branch one)."""
    if code == BRANCH_LEFT:
        return BranchLeftError(P.qe.copy(), P.phi.copy(), P.pred.copy(), branch_test_text(P.detail),
                               int(P.detail[D_COORD]))
    return DependentSolveError(_REASONS.get(code, "no_convergence"), P.q.copy(), P.phi.copy())


def _solution(P: Partition, q: np.ndarray, iterations: int) -> DependentSolution:
    return DependentSolution(q.copy(), P.J.reshape(P.phi.size, q.size).copy(), iterations, float(np.max(
        np.abs(P.phi), initial=0.0)))


def solve_dependent(model: NumericModel, par: np.ndarray, q: np.ndarray, dependent: np.ndarray, tol: float,
                    max_iter: int, max_condition: float = np.inf) -> DependentSolution:
    """Solve Phi(u, v) = 0 for v = q[dependent], starting from ``q`` (not modified).

    Converged when max |Phi| <= ``tol``, or when a correction is down to the round-off of q.
    Phi_v counts as singular where it is, or where its condition ||Phi_v||_1 ||Phi_v^-1||_1
    exceeds ``max_condition``.

    Raises
    ------
    DependentSolveError
    """
    m = model.n_coordinates
    dependent = np.asarray(dependent, dtype=np.int64)
    P = _partition(model, np.setdiff1d(np.arange(m), dependent), dependent)
    q = np.array(q, dtype=float)
    code, iterations = core.solve_dependent(PythonModel(model, par), P, q, dependent.size, m, tol, max_iter,
                                            float(max_condition))
    if code != OK:
        P.q[:] = q
        raise _error(code, P)
    return _solution(P, q, iterations)


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


def branch_tangent(phi_q: np.ndarray, independent: np.ndarray,
                   dependent: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """dv/du = -Phi_v^-1 Phi_u (r, n), and Phi_v's LU factors (r, r) with their pivots (r,)
    (:func:`csim.physics.partition.branch_tangent`).

    Raises
    ------
    DependentSolveError
        ``"singular"`` where Phi_v is singular (the branch folds back: v is no function of u).
    """
    r, m = phi_q.shape
    independent, dependent = np.asarray(independent, np.int64), np.asarray(dependent, np.int64)
    lu, piv, T = np.empty(r * r), np.zeros(r, np.int64), np.empty(r * (m - r))
    if not _tangent_core(np.ascontiguousarray(phi_q, dtype=float).ravel(), independent, dependent, r, m, lu, piv,
                         np.empty(r), T):
        raise DependentSolveError("singular", np.full(m, np.nan), np.full(r, np.nan))
    return T.reshape(r, m - r), lu.reshape(r, r), piv


@dataclass
class BranchPoint:
    """A point of an assembly branch and its tangent, where the next solves start from.

    Attributes
    ----------
    q : ndarray (m,)
        Coordinates on the branch, Phi(q) = 0 [rad or m].
    tangent : ndarray (r, n)
        dv/du there (:func:`branch_tangent`).
    phi_v_lu : ndarray (r, r)
        Phi_v's LU factors there (:func:`csim.physics.linalg.lu_factor`).
    phi_v_piv : ndarray (r,) int
        Their pivots.
    """

    q: np.ndarray
    tangent: np.ndarray
    phi_v_lu: np.ndarray
    phi_v_piv: np.ndarray

    @classmethod
    def at(cls, q: np.ndarray, phi_q: np.ndarray, independent: np.ndarray, dependent: np.ndarray) -> BranchPoint:
        """The branch point at coordinates q with Jacobian phi_q (raises DependentSolveError if Phi_v is singular)."""
        return cls(np.array(q, dtype=float), *branch_tangent(phi_q, independent, dependent))

    def state(self, model: NumericModel, independent, dependent) -> Partition:
        """A core Partition anchored here, in the partition (independent, dependent)."""
        P = _partition(model, independent, dependent)
        P.qa[:], P.Ta[:], P.Va[:], P.pa[:] = self.q, self.tangent.ravel(), self.phi_v_lu.ravel(), self.phi_v_piv
        P.qp[:], P.Tp[:], P.Vp[:], P.pp[:] = P.qa, P.Ta, P.Va, P.pa
        return P

    def predict(self, model: NumericModel, par: np.ndarray, u: np.ndarray, independent: np.ndarray,
                dependent: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The branch's second-order prediction of q at the independent coordinates u (core: ``predict``).

        Returns
        -------
        predicted : ndarray (m,)
        du : ndarray (n,)
        dv_linear : ndarray (r,)
            (dv/du)_a du, the first-order move.
        """
        P = self.state(model, independent, dependent)
        core.predict(PythonModel(model, par), P, np.asarray(u, dtype=float), P.dep.size, P.qa.size)
        return P.pred.copy(), P.du.copy(), P.dvl.copy()


def _predicted_solve(model, par, point: BranchPoint, u: np.ndarray, independent, dependent, tol, max_iter):
    """Newton from the branch's prediction at ``point``, checked for continuity with the branch.

    Returns the solution and its BranchPoint; raises BranchLeftError if it lands on another branch.
    """
    P = point.state(model, independent, dependent)
    code = core.predicted_solve(PythonModel(model, par), P, np.asarray(u, dtype=float), P.dep.size, P.qa.size, tol,
                                max_iter)
    return _followed(code, P)


def _followed(code: int, P: Partition) -> tuple[DependentSolution, BranchPoint]:
    if code != OK:
        raise _error(code, P)
    r, m = P.dep.size, P.qe.size
    end = BranchPoint(P.qe.copy(), P.Te.reshape(r, m - r).copy(), P.Ve.reshape(r, r).copy(), P.pe.copy())
    return _solution(P, P.qe, 0), end


def follow_branch(model: NumericModel, par: np.ndarray, point: BranchPoint, u: np.ndarray, independent: np.ndarray,
                  dependent: np.ndarray, tol: float, max_iter: int) -> tuple[DependentSolution, BranchPoint]:
    """v at the independent coordinates u on the assembly branch through ``point`` (core: ``follow_branch``).

    Returns
    -------
    solution : DependentSolution
    end : BranchPoint
        The solution with its tangent.

    Raises
    ------
    DependentSolveError
        Of the last failed piece (a :class:`BranchLeftError` when its solution was on
        another branch).
    """
    P = point.state(model, independent, dependent)
    code = core.follow_branch(PythonModel(model, par), P, np.asarray(u, dtype=float), P.dep.size, P.qa.size, tol,
                              max_iter)
    return _followed(code, P)
