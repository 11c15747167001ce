"""Minimal coordinates: the dependent coordinates on their assembly branch, and the partition's life.

The core of ``stabilization.method: minimal`` (coordinate partitioning, Wehage and Haug),
written once for both backends: the Python driver
(:class:`csim.solver.partitioned.PartitionedSystem`) and the compiled kernels call these
functions with their own model handle (:mod:`csim.physics.model`) and a
:class:`csim.physics.partition.Partition`. Every function returns a status code of
:mod:`csim.physics.status` (OK, or the failure, with its details in ``P.detail``).

*Newton for v.* With the independent coordinates u held, v solves Phi(u, v) = 0:

    Phi_v(q_i) (v_{i+1} - v_i) = -Phi(q_i)

until max |Phi| <= tol, or the correction is down to the round-off of q.

*The assembly branch.* A closed loop can be assembled in several ways for the same u, and
Newton converges to whichever its start leads it to. Every solve therefore starts from the
branch's prediction at a point (u_a, v_a) known to be on it, its Taylor polynomial in u,

    v_pred = v_a + (dv/du)_a du + 1/2 Phi_v^-1 gamma(q_a, [du, (dv/du)_a du]),
    (dv/du)_a = -Phi_v^-1 Phi_u  at (u_a, v_a),   du = u - u_a

(along u(s) = u_a + s du, Phi(q(s)) = 0 twice differentiated gives Phi_v v'' = gamma), and
its solution must pass :func:`csim.physics.partition.same_branch`. Where it does not (or
Newton fails), the way from u_a to u is cut in half and the branch followed along the pieces
(:func:`follow_branch`). The point is the last accepted state (:func:`after_step` anchors
it there). Before, Newton started from the last solution, whatever evaluation it came from:
on Andrews' mechanism a rejected trial step 1.3 rad of crank angle ahead left its solution
on the other closure of a loop, and the run went on there and reported success.

*The partition.* It is chosen at the start and again (the integration restarts from the same
state) when ||Phi_q||_1 ||Phi_v^-1||_1 exceeds ``max_condition`` after a step, or when a
solve breaks down (:func:`repartition`): where no better partition exists after a branch
was lost, the integration restarts in the same one (a fresh start takes another step), at
most MAX_BRANCH_RESTARTS times from one state, then the run fails naming the change of branch.
"""
from __future__ import annotations

from csim.physics.jit import jitable
from csim.physics.linalg import lu_solve
from csim.physics.model import model_gamma, model_jacobian, model_phi
from csim.physics.partition import (
    C_BRANCH_RESTARTS,
    C_LOST_RESTARTS,
    C_LOST_SET,
    C_REPARTITIONS,
    D_CODE,
    D_HEAD,
    D_PHI,
    MAX_BRANCH_RESTARTS,
    MAX_PIECE_MOVE,
    MIN_PIECE,
    block_inverse,
    branch_tangent,
    choose_partition,
    dependent_step,
    same_branch,
)
from csim.physics.projection import at_round_off, max_abs
from csim.physics.status import (
    BRANCH_LEFT,
    BRANCH_LOST,
    DEPENDENT_NO_CONVERGENCE,
    DEPENDENT_NONFINITE,
    DEPENDENT_SINGULAR,
    NO_BETTER_PARTITION,
    OK,
)
from csim.physics.steps import all_finite


@jitable
def is_breakdown(code):
    """Whether a failed solve is a breakdown of the partition, which the drivers answer by choosing the
    partition again at the last accepted state and restarting (:func:`repartition`), not a failed run."""
    return DEPENDENT_SINGULAR <= code <= BRANCH_LEFT  # the three codes in a row (csim.physics.status)


@jitable
def solve_dependent(model, P, q, r, m, tol, max_iter, max_condition):
    """Newton-Raphson for v = q[P.dep] with u = q[P.ind] held, in place. Returns (code, iterations).

    Phi and Phi_q at the solution are left in P.phi and P.J. Codes: OK, DEPENDENT_NONFINITE,
    DEPENDENT_NO_CONVERGENCE (after ``max_iter`` corrections), DEPENDENT_SINGULAR (Phi_v
    singular, or its condition ||Phi_v||_1 ||Phi_v^-1||_1 above ``max_condition``: pass inf
    to check only for an exactly singular block).
    """
    for iteration in range(max_iter + 1):
        model_phi(model, q, P.phi)
        if not (all_finite(P.phi) and all_finite(q)):
            return DEPENDENT_NONFINITE, iteration
        model_jacobian(model, q, P.J)
        if max_abs(P.phi) <= tol:
            return OK, iteration
        if iteration == max_iter:
            return DEPENDENT_NO_CONVERGENCE, iteration
        if max_condition < 1e308 and _block_condition(P, r, m) > max_condition:
            return DEPENDENT_SINGULAR, iteration
        if not dependent_step(P.J, P.phi, P.dep, r, m, P.lu, P.piv, P.dv):
            return DEPENDENT_SINGULAR, iteration
        for i in range(r):
            q[P.dep[i]] -= P.dv[i]
        if at_round_off(P.dv, q):  # converged to the round-off of Phi at these coordinates
            model_phi(model, q, P.phi)
            model_jacobian(model, q, P.J)
            return OK, iteration + 1
    return DEPENDENT_NO_CONVERGENCE, max_iter


@jitable
def _block_condition(P, r, m):
    """||Phi_v||_1 ||Phi_v^-1||_1 of the dependent block of P.J (the 1-norm condition number)."""
    rel = block_inverse(P.J, P.dep, r, m, P.lu, P.piv, P.col, P.cinv)  # ||Phi_q||_1 ||Phi_v^-1||_1
    norm_q = 0.0
    norm_v = 0.0
    for j in range(m):
        s = 0.0
        for i in range(r):
            s += abs(P.J[i * m + j])
        norm_q = max(norm_q, s)
    for j in range(r):
        s = 0.0
        for i in range(r):
            s += abs(P.J[i * m + P.dep[j]])
        norm_v = max(norm_v, s)
    return rel / norm_q * norm_v if norm_q > 0 else rel


@jitable
def predict(model, P, u, r, m):
    """P.pred = the branch's second-order prediction of q at the independent coordinates u, from (P.qp, P.Tp, and
    Phi_v's factors P.Vp, P.pp).

    Also P.du = u - u_p and P.dvl = (dv/du)_p du, the first-order move (module docstring).
    """
    n = m - r
    for j in range(n):
        P.du[j] = u[j] - P.qp[P.ind[j]]
    for i in range(m):
        P.pred[i] = P.qp[i]
    for j in range(n):
        P.dirn[P.ind[j]] = P.du[j]
        P.pred[P.ind[j]] = u[j]
    for i in range(r):
        s = 0.0
        for j in range(n):
            s += P.Tp[i * n + j] * P.du[j]
        P.dvl[i] = s
        P.dirn[P.dep[i]] = s
    model_gamma(model, P.qp, P.dirn, P.gam)
    lu_solve(P.Vp, r, P.pp, P.gam)  # Phi_v^-1 gamma
    for i in range(r):
        P.pred[P.dep[i]] += P.dvl[i] + 0.5 * P.gam[i]


@jitable
def predicted_solve(model, P, u, r, m, tol, max_iter):
    """Newton from the prediction at u (:func:`predict`); the solution and its tangent into (P.qe, P.Te, and
    Phi_v's factors P.Ve, P.pe).

    Returns OK, a Newton failure, DEPENDENT_SINGULAR where the solution's Phi_v is singular,
    or BRANCH_LEFT where it fails :func:`csim.physics.partition.same_branch`.
    """
    predict(model, P, u, r, m)
    for i in range(m):
        P.q[i] = P.pred[i]
    code, _ = solve_dependent(model, P, P.q, r, m, tol, max_iter, 1e309)
    if code != OK:
        return code
    for i in range(m):
        P.qe[i] = P.q[i]
    if not branch_tangent(P.J, P.ind, P.dep, r, m, P.Ve, P.pe, P.col, P.Te):
        return DEPENDENT_SINGULAR
    if same_branch(P.qp, P.Tp, P.pred, P.qe, P.Te, P.du, P.dvl, P.dep, r, P.detail) != OK:
        return BRANCH_LEFT
    return OK


@jitable
def _copy(src, dst):
    for i in range(src.size):
        dst[i] = src[i]


@jitable
def follow_branch(model, P, u, r, m, tol, max_iter):
    """v at the independent coordinates u on the branch through the anchor (P.qa, P.Ta, P.Va, P.pa), into P.qe.

    Newton starts from the branch's prediction and its solution must pass the branch test.
    Where it does not (or Newton fails), the way from u_a to u is cut in half, the branch
    followed to the midpoint, and the rest taken from there, the pieces growing again after
    each success: a continuation along the straight line from u_a to u, in pieces that move
    no coordinate by more than MAX_PIECE_MOVE by the linear prediction. A move the first solve
    accepts costs one Newton solve and one tangent. Returns the code of the last failed piece
    when a piece would have to be shorter than MIN_PIECE of the longest (the branch folds
    back or ends before u, or Newton cannot converge); DEPENDENT_NONFINITE at once.
    """
    n = m - r
    _copy(P.qa, P.qp)
    _copy(P.Ta, P.Tp)
    _copy(P.Va, P.Vp)
    _copy(P.pa, P.pp)
    move = 0.0
    for j in range(n):
        P.u0[j] = P.qa[P.ind[j]]
        P.uu[j] = u[j]
        move = max(move, abs(u[j] - P.u0[j]))
    for i in range(r):
        s = 0.0
        for j in range(n):
            s += P.Ta[i * n + j] * (u[j] - P.u0[j])
        move = max(move, abs(s))
    longest = 1.0 if move <= MAX_PIECE_MOVE else MAX_PIECE_MOVE / move
    done = 0.0
    piece = longest
    while True:
        reach = min(1.0, done + piece)
        for j in range(n):
            P.tgt[j] = P.uu[j] if reach == 1.0 else P.u0[j] + reach * (P.uu[j] - P.u0[j])
        code = predicted_solve(model, P, P.tgt, r, m, tol, max_iter)
        if code != OK:
            if code == DEPENDENT_NONFINITE or piece / 2 < MIN_PIECE * longest:
                _failed(P, code, P.uu, n)
                return code
            piece /= 2
            continue
        if reach == 1.0:
            return OK
        _copy(P.qe, P.qp)
        _copy(P.Te, P.Tp)
        _copy(P.Ve, P.Vp)
        _copy(P.pe, P.pp)
        done = reach
        piece = min(2 * piece, longest)


@jitable
def _failed(P, code, u, n):
    """Record a failed solve at the independent coordinates u in P.detail (the messages read it)."""
    P.detail[D_CODE] = code
    P.detail[D_PHI] = max_abs(P.phi)
    for j in range(n):
        P.detail[D_HEAD + j] = u[j]
        P.detail[D_HEAD + n + j] = P.ind[j]


@jitable
def to_full(model, P, y, yf, r, m, k, tol, max_iter):
    """yf (2 m + k,) = [q, qd, W] of the integrated state y = [u, ud, W] (2 n + k,); returns the code.

    v is solved on the branch (:func:`follow_branch`, the solution also left in P.qe with
    its tangent), vd from Phi_q qd = 0: vd = (dv/du) ud.
    """
    n = m - r
    code = follow_branch(model, P, y, r, m, tol, max_iter)
    if code != OK:
        return code
    for i in range(m):
        yf[i] = P.qe[i]
    for j in range(n):
        yf[m + P.ind[j]] = y[n + j]
    for i in range(r):
        s = 0.0
        for j in range(n):
            s += P.Te[i * n + j] * y[n + j]
        yf[m + P.dep[i]] = s
    for i in range(k):
        yf[2 * m + i] = y[2 * n + i]
    return OK


@jitable
def reduce(P, yf, y, r, m, k):
    """y = [u, ud, W] (2 n + k,) of a full state (or rate) yf = [q, qd, W] (2 m + k,)."""
    n = m - r
    for j in range(n):
        y[j] = yf[P.ind[j]]
        y[n + j] = yf[m + P.ind[j]]
    for i in range(k):
        y[2 * n + i] = yf[2 * m + i]


@jitable
def anchor_at(model, P, q, r, m):
    """Make q (on the manifold) the branch point later solves start from; DEPENDENT_SINGULAR if Phi_v is."""
    _copy(q, P.qa)
    model_jacobian(model, P.qa, P.J)
    if not branch_tangent(P.J, P.ind, P.dep, r, m, P.Va, P.pa, P.col, P.Ta):
        for j in range(m - r):
            P.uu[j] = q[P.ind[j]]
        _failed(P, DEPENDENT_SINGULAR, P.uu, m - r)
        return DEPENDENT_SINGULAR
    return OK


@jitable
def start(model, P, y0, y, r, m, k, tol, max_iter):
    """Partition at q0 and keep u0, ud0 (v0 is solved by plain Newton: a perturbed start is projected).

    y0 (2 m + k,) is the full initial state, y (2 n + k,) gets the integrated one. The assembly
    the run keeps is the one Newton reaches from the given v0.
    """
    _copy(y0[:m], P.q)
    model_jacobian(model, P.q, P.J)
    choose_partition(P.J, r, m, P.ind, P.dep, P.cand, P.best, P.lu, P.piv, P.col, P.cinv, P.basis, P.resid)
    code, _ = solve_dependent(model, P, P.q, r, m, tol, max_iter, 1e309)
    if code != OK:
        for j in range(m - r):
            P.uu[j] = P.q[P.ind[j]]
        _failed(P, code, P.uu, m - r)
        return code
    _copy(P.q, P.qe)
    code = anchor_at(model, P, P.q, r, m)
    reduce(P, y0, y, r, m, k)
    return code


@jitable
def choose_again(model, P, r, m):
    """Choose the best partition at the last solution P.qe and anchor there. Returns (code, changed)."""
    n = m - r
    for j in range(n):
        P.old[j] = P.ind[j]
    model_jacobian(model, P.qe, P.J)
    choose_partition(P.J, r, m, P.ind, P.dep, P.cand, P.best, P.lu, P.piv, P.col, P.cinv, P.basis, P.resid)
    code = anchor_at(model, P, P.qe, r, m)
    changed = False
    for j in range(n):
        if P.ind[j] != P.old[j]:
            changed = True
    if changed:
        P.count[C_REPARTITIONS] += 1
    return code, changed


@jitable
def after_step(model, P, y, r, m, k, tol, max_iter, max_condition):
    """Anchor the branch at the accepted state y; choose the partition again when Phi_v has turned ill-conditioned.

    Returns (code, restart): with restart True, y is the state in a new partition and the
    integration restarts from it. It restarts only when a better-conditioned partition
    exists; while the current one is the best there is, it goes on.
    """
    code = to_full(model, P, y, P.yf, r, m, k, tol, max_iter)
    if code != OK:
        return code, False
    _copy(P.qe, P.qa)  # the accepted state, with its tangent
    _copy(P.Te, P.Ta)
    _copy(P.Ve, P.Va)
    _copy(P.pe, P.pa)
    model_jacobian(model, P.qe, P.J)
    if block_inverse(P.J, P.dep, r, m, P.lu, P.piv, P.col, P.cinv) <= max_condition:
        return OK, False
    code, changed = choose_again(model, P, r, m)
    if code != OK or not changed:
        return code, False
    reduce(P, P.yf, y, r, m, k)
    return OK, True


@jitable
def repartition(model, P, y, r, m, k, tol, max_iter):
    """Restart from the accepted state y after a breakdown (code in P.detail) at a later stage; returns the code.

    In a better partition where there is one (y is then the state in it). Otherwise, after
    BRANCH_LEFT, in the same partition (a fresh integrator start takes a different step), at
    most MAX_BRANCH_RESTARTS times from the same state. NO_BETTER_PARTITION and BRANCH_LOST
    when nothing can carry the integration on (the breakdown's details kept in P.detail).
    """
    _copy(P.detail, P.cause)
    cause = int(P.cause[D_CODE])
    code = to_full(model, P, y, P.yf, r, m, k, tol, max_iter)
    if code != OK:
        return code
    code, changed = choose_again(model, P, r, m)
    if code != OK:
        return code
    if changed:
        reduce(P, P.yf, y, r, m, k)
        return OK
    _copy(P.cause, P.detail)
    if cause != BRANCH_LEFT:
        return NO_BETTER_PARTITION
    same = P.count[C_LOST_SET] == 1
    for i in range(y.size):
        if P.lost[i] != y[i]:
            same = False
    restarts = P.count[C_LOST_RESTARTS] + 1 if same else 1
    if restarts > MAX_BRANCH_RESTARTS:
        return BRANCH_LOST
    _copy(y, P.lost)
    P.count[C_LOST_RESTARTS] = restarts
    P.count[C_LOST_SET] = 1
    P.count[C_BRANCH_RESTARTS] += 1
    reduce(P, P.yf, y, r, m, k)
    return OK
