"""Newton-Raphson for the dependent coordinates of a partition q = (u, v).

With the independent coordinates u held fixed, the dependent ones v solve Phi(u, v) = 0:

    Phi_v(q_i) (v_{i+1} - v_i) = -Phi(q_i),

and the dependent velocities follow from Phi_q qd = 0 by one linear solve,

    Phi_v vd = -Phi_u ud.

The consistent initial state and the minimal-coordinate method both use it; each turns a
:class:`DependentSolveError` into its own message.

A closed loop has several assemblies for the same u (a four-bar's two closures), and Newton
converges to whichever its start is nearest in its own sense. The minimal-coordinate method
must stay on the assembly it started on, so it solves with :func:`follow_branch`: Newton
from the branch's Taylor polynomial at a point (u_a, v_a) known to be on the branch,

    v_pred = v_a + (dv/du)_a du + 1/2 Phi_v^-1 gamma(q_a, [du, (dv/du)_a du]),
    (dv/du)_a = -Phi_v^-1 Phi_u  at (u_a, v_a),   du = u - u_a,

the solution accepted only where :func:`same_branch` finds it continuous with the branch
(close to the prediction, with a similar slope dv/du); otherwise the way from u_a to u is
cut into shorter pieces and the branch followed along them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.model.numeric import NumericModel
from csim.physics.projection import at_round_off

EPS = np.finfo(float).eps
SQRT_EPS = float(np.sqrt(EPS))


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
        Index in q of the dependent coordinate that moved most from the prediction.
    detail : str
        Which test of :func:`same_branch` failed, with its numbers.
    """

    def __init__(self, q: np.ndarray, phi: np.ndarray, predicted: np.ndarray, detail: str):
        super().__init__("branch", q, phi)
        self.predicted, self.detail = predicted, detail
        self.coordinate = int(np.argmax(np.abs(q - predicted)))


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


# --- following an assembly branch ------------------------------------------------------------

#: Newton's solution may differ from the branch's prediction by at most this fraction of the
#: predicted (first-order) move (:func:`continuity_bound`)
BRANCH_CONTINUITY = 0.25
#: ... and dv/du there from dv/du at the start of the piece by at most this fraction of
#: max(1, max |dv/du|) at the start (:func:`same_branch`)
BRANCH_TANGENT_CHANGE = 1.0
#: the way from the known point to the target is cut in pieces no shorter than this fraction of
#: the longest piece
MIN_PIECE = 2.0**-12
#: ... and no piece moves a coordinate by more than this (rad, or m), by the linear prediction:
#: over a longer move (a trial stage half a turn of a crank ahead) the prediction can lie
#: nearer another assembly than its own, and Newton's solution there pass both tests
MAX_PIECE_MOVE = 0.5


def _amax(x: np.ndarray) -> float:
    """max |x| (0 for an empty array), without np.max's keyword overhead (called at every evaluation)."""
    return float(np.abs(x).max()) if x.size else 0.0


def branch_tangent(phi_q: np.ndarray, independent: np.ndarray, dependent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dv/du = -Phi_v^-1 Phi_u (r, n), how the dependent coordinates move with the independent ones, and Phi_v^-1.

    Raises
    ------
    DependentSolveError
        ``"singular"`` where Phi_v is singular (the branch folds back: v is no function of u).
    """
    try:
        inverse = np.linalg.inv(phi_q[:, dependent])
    except np.linalg.LinAlgError:
        inverse = np.full((dependent.size, dependent.size), np.nan)
    tangent = -inverse @ phi_q[:, independent]
    if not (np.all(np.isfinite(inverse)) and np.all(np.isfinite(tangent))):
        raise DependentSolveError("singular", np.full(phi_q.shape[1], np.nan), np.full(phi_q.shape[0], np.nan))
    return tangent, inverse


def continuity_bound(du: np.ndarray, dv_linear: np.ndarray, v: np.ndarray) -> float:
    """Largest max |v - v_pred| of a Newton solution that counts as the same branch.

    On the branch, v(u) - v_pred is the remainder of the prediction, of third order in the
    move; another assembly lies a finite distance away whatever the move. A solution counts
    as continuous when

        max |v - v_pred| <= BRANCH_CONTINUITY max(max |du|, max |dv_lin|) + sqrt(eps) max(1, max |v|),

    i.e. Newton corrected the prediction by less than a quarter of the predicted first-order
    move (in the coordinates' units, rad or m), plus a floor at the resolution of v for a
    move of zero.

    Parameters
    ----------
    du : ndarray (n,)
        Move of the independent coordinates, u - u_a.
    dv_linear : ndarray (r,)
        Predicted move of the dependent ones, (dv/du)_a du.
    v : ndarray (r,)
        The predicted dependent coordinates.
    """
    return BRANCH_CONTINUITY * max(_amax(du), _amax(dv_linear)) + SQRT_EPS * max(1.0, _amax(v))


@dataclass
class BranchPoint:
    """A point of an assembly branch and its tangent, where the next solves start from.

    Attributes
    ----------
    q : ndarray (m,)
        Coordinates on the branch, Phi(q) = 0 [rad or m].
    tangent : ndarray (r, n)
        dv/du there (:func:`branch_tangent`).
    phi_v_inv : ndarray (r, r)
        Phi_v^-1 there.
    """

    q: np.ndarray
    tangent: np.ndarray
    phi_v_inv: np.ndarray

    @classmethod
    def at(cls, q: np.ndarray, phi_q: np.ndarray, independent: np.ndarray, dependent: np.ndarray) -> BranchPoint:
        """The branch point at coordinates q with Jacobian phi_q (raises DependentSolveError if Phi_v is singular)."""
        return cls(np.array(q, dtype=float), *branch_tangent(phi_q, independent, dependent))

    def predict(self, model: NumericModel, par: np.ndarray, u: np.ndarray, independent: np.ndarray,
                dependent: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The branch's second-order prediction of q at the independent coordinates u.

        Along the straight line u(s) = u_a + s du (u'' = 0), Phi(q(s)) = 0 twice differentiated
        gives Phi_v v'' = gamma(q, q') with q' = [du, (dv/du) du], the model's acceleration-level
        right-hand side, so that

            v_pred = v_a + (dv/du)_a du + 1/2 Phi_v^-1 gamma(q_a, q'),    du = u - u_a.

        Returns
        -------
        predicted : ndarray (m,)
        du : ndarray (n,)
        dv_linear : ndarray (r,)
            (dv/du)_a du, the first-order move.
        """
        du = u - self.q[independent]
        direction = np.empty(self.q.size)
        direction[independent] = du
        direction[dependent] = dv_linear = self.tangent @ du
        predicted = self.q.copy()
        predicted[independent] = u
        predicted[dependent] += dv_linear + 0.5 * (self.phi_v_inv @ model.gamma(self.q, direction, par))
        return predicted, du, dv_linear


def same_branch(start: BranchPoint, predicted: np.ndarray, end: BranchPoint, du: np.ndarray, dv_linear: np.ndarray,
                dependent: np.ndarray) -> tuple[bool, str]:
    """Whether Newton's solution ``end`` continues the branch from ``start``, and if not, why.

    Two tests, which a solution on another assembly fails unless the move is so large that
    the prediction lies nearer that assembly than its own (a four-bar's crank moved by 2 rad
    and more: :func:`follow_branch` cuts moves to MAX_PIECE_MOVE):

    * ``max |v - v_pred| <= continuity_bound`` (the prediction was good);
    * ``max |(dv/du)_end - (dv/du)_start| <= BRANCH_TANGENT_CHANGE max(1, max |(dv/du)_start|)``
      (the branch turned by less than its own slope: another closure has another slope).

    Returns
    -------
    ok : bool
    reason : str
        Empty when ``ok``; otherwise the test that failed, with its numbers.
    """
    jump = _amax(end.q[dependent] - predicted[dependent])
    bound = continuity_bound(du, dv_linear, predicted[dependent])
    if jump > bound:
        return False, f"{jump:.3g} from the branch's prediction (at most {bound:.3g} on the branch)"
    turn = _amax(end.tangent - start.tangent)
    turn_bound = BRANCH_TANGENT_CHANGE * max(1.0, _amax(start.tangent))
    if turn > turn_bound:
        return False, f"with its slope dv/du changed by {turn:.3g} (at most {turn_bound:.3g} on the branch)"
    return True, ""


def _predicted_solve(model, par, point: BranchPoint, u: np.ndarray, independent, dependent, tol, max_iter):
    """Newton from the branch's prediction at ``point`` (:meth:`BranchPoint.predict`), checked by :func:`same_branch`.

    Returns the solution and its BranchPoint; raises BranchLeftError if it lands on another branch.
    """
    predicted, du, dv_linear = point.predict(model, par, u, independent, dependent)
    solution = solve_dependent(model, par, predicted, dependent, tol, max_iter)
    end = BranchPoint.at(solution.q, solution.phi_q, independent, dependent)
    ok, reason = same_branch(point, predicted, end, du, dv_linear, dependent)
    if not ok:
        raise BranchLeftError(solution.q, model.phi(solution.q, par), predicted, reason)
    return solution, end


def follow_branch(model: NumericModel, par: np.ndarray, point: BranchPoint, u: np.ndarray, independent: np.ndarray,
                  dependent: np.ndarray, tol: float, max_iter: int) -> tuple[DependentSolution, BranchPoint]:
    """v at the independent coordinates u on the assembly branch through ``point``.

    Newton starts from the branch's prediction (module docstring) and its solution
    must pass :func:`same_branch`. Where it does not (or Newton fails), the way from u_a to
    u is cut in half, the branch followed to the midpoint, and the rest taken from there,
    the pieces growing again after each success: a continuation along the straight line
    from u_a to u. A move the first solve accepts costs one Newton solve and one tangent.

    Parameters
    ----------
    model, par
        The numeric model and its parameters.
    point : BranchPoint
        Where the branch is known (the last accepted state).
    u : ndarray (n,)
        The independent coordinates to solve at.
    independent, dependent : ndarray of int (n,), (r,)
        The partition.
    tol, max_iter
        Newton tolerance on max |Phi| and iteration limit, as in :func:`solve_dependent`.

    Returns
    -------
    solution : DependentSolution
    end : BranchPoint
        The solution with its tangent (to start later solves from, once accepted).

    Raises
    ------
    DependentSolveError
        Of the last failed piece when a piece would have to be shorter than
        :data:`MIN_PIECE` of the longest (the branch folds back or ends before u, or
        Newton cannot converge); a :class:`BranchLeftError` when that piece's solution was
        on another branch. ``"non_finite"`` at once.
    """
    u = np.asarray(u, dtype=float)
    u0 = point.q[independent]
    # the longest piece, as a fraction of the way: its predicted move at most MAX_PIECE_MOVE
    move = max(_amax(u - u0), _amax(point.tangent @ (u - u0)))
    longest = 1.0 if move <= MAX_PIECE_MOVE else MAX_PIECE_MOVE / move
    done, piece = 0.0, longest
    while True:
        reach = min(1.0, done + piece)
        target = u if reach == 1.0 else u0 + reach * (u - u0)
        try:
            solution, end = _predicted_solve(model, par, point, target, independent, dependent, tol, max_iter)
        except DependentSolveError as exc:
            if exc.reason == "non_finite" or piece / 2 < MIN_PIECE * longest:
                raise
            piece /= 2
            continue
        if reach == 1.0:
            return solution, end
        point, done, piece = end, reach, min(2 * piece, longest)
