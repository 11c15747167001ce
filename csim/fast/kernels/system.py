"""The system the loop integrates: the right-hand side at a state (KKT solve, gamma* of the
method, load laws), the switching functions, the projection, and the partitioned system of
``minimal`` (its state y = [u, ud, W] turned into the full state where the loop needs it).
"""
import numpy as np

from csim.fast.layout import (
    CONSTRAINED,
    ELIMINATION,
    GGL,
    PARTITIONED,
    PI_DRV,
    PI_ELIM,
    PI_FEVAL,
    PI_FORM,
    PI_FORM_F,
    PI_FORM_I,
    PI_FPAR,
    PI_GAINS,
    PI_HEAD,
    PI_IPAR,
    PI_MK,
    PI_NC,
    PI_ND,
    PI_NFPAR,
    PI_NGAINS,
    PI_NIPAR,
    PI_NL,
    PI_NQ,
    PI_NSW,
    PI_SYS,
    W_A,
    W_B,
    W_COL,
    W_CQD,
    W_DQ,
    W_END,
    W_G,
    W_GAM,
    W_GS,
    W_H,
    W_J,
    W_L,
    W_M,
    W_M2,
    W_P,
    W_PART,
    W_PD,
    W_PHI,
    W_PT,
    W_S,
    W_S2,
    W_SD,
    W_SQ,
    W_U,
    W_WINV,
    W_WJT,
    W_X,
    W_YM,
    W_Z,
)
from csim.physics import branch
from csim.physics.elimination import eliminate, elimination_sizes, elimination_state
from csim.physics.ggl import ggl_equations
from csim.physics.kkt import constraint_rates, generalized_forces, kkt_solve
from csim.physics.loads import load_rates, load_values, mode_of, switching_functions
from csim.physics.partition import C_PENDING, partition_sizes, partition_state, reduced_accelerations
from csim.physics.projection import max_abs
from csim.physics.projection import project as project_state
from csim.physics.status import GGL_SINGULAR_MASS, NONFINITE_RHS, OK, SINGULAR_KKT, TANGENT_MASS_SINGULAR
from csim.physics.steps import all_finite

from .calls import call_eliminated, call_feval, loads_, method_gamma_star, model_handle, phi_at, terms
from .common import LOCATED, addressed, hot, inlined, rhs_root, sized


# ---------------------------------------------------------------------------------------
# the partitioned system (minimal coordinates): its state in w and piv, the core's calls
# ---------------------------------------------------------------------------------------
@hot
def _partition(pi, w, piv):
    """The partition's state (csim.physics.partition.Partition) as views of w and piv."""
    m, r = pi[PI_NQ], pi[PI_NC]
    return partition_state(w[pi[W_PART]:pi[W_END]], piv[m + r:], m, r, pi[PI_NL])


@hot
def _partition_call(par, pf, pi, w, piv):
    """(handle, P, r, m, k, tol, max_iter, max_condition): what every core call of csim.physics.branch takes.

    The method's settings (csim.solver.methods.minimal): fpar = [tol, max_condition], ipar = [max_iter].
    The handle's time is 0: ``minimal`` takes no drives (its rows do not depend on t).
    """
    P = _partition(pi, w, piv)
    fpar, ipar = pf[pi[PI_FPAR]:], pi[pi[PI_IPAR]:]
    return model_handle(par, pi, w, P.ym, 0.0), P, pi[PI_NC], pi[PI_NQ], pi[PI_NL], fpar[0], ipar[0], fpar[1]


@inlined
def int_workspace(pi):
    """The size of the integer workspace piv: the KKT solve's pivots (m + r), then the partition's integers
    (minimal's), or the elimination's, which are fewer."""
    m, r = pi[PI_NQ], pi[PI_NC]
    return m + r + max(partition_sizes(m, r, pi[PI_NL])[1], elimination_sizes(m, r)[1])


# Compiled on its own and called through its address (call_eliminated), as feval: linked into the right-hand
# side, the elimination's call tree (the partition's choice, its inverses) was optimized again inside every
# entry point that evaluates it, and the sized copies of each (13 s more of the cold compile on 2 cores).
@addressed
def eliminated(pf, pi, w, piv):
    """[qdd, lambda] into w[W_X:] by the elimination (csim.physics.elimination), from the terms, p and gamma*
    in w; its state (csim.physics.elimination.elimination_state) lies where minimal's partition does, in
    w[W_PART:] and piv after the KKT pivots (the plain system only: the compiled elimination does not run with
    minimal). Returns the status code."""
    nq, nc = pi[PI_NQ], pi[PI_NC]
    at = pi[PI_FORM_I]
    E = elimination_state(w[pi[W_PART]:pi[W_END]], piv[nq + nc:], nq, nc)  # (minimal's region: never both)
    return eliminate(w[pi[W_M]:pi[W_M] + nq * nq], w[pi[W_J]:pi[W_J] + nc * nq], w[pi[W_P]:pi[W_P] + nq],
                     w[pi[W_GS]:pi[W_GS] + nc], E, pi[at] == 1, pi[at + 1:at + 1 + nq - nc],
                     pf[pi[PI_FORM_F]], w[pi[W_A]:pi[W_A] + nq * nq], w[pi[W_X]:pi[W_X] + nq + nc], piv[:nq], nq, nc)


# The partitioned system's branches in the functions of every step call a function of their own:
# numba zeroes all of a function's variables at each call, and the partition's views (a tuple of
# 48 arrays) would cost every caller a memset of kilobytes even where it is not partitioned.
@inlined
def full_state(y, par, pf, pi, w, piv):
    """(code, the full state [q, qd, W] of the integrated state y): y itself, or for the partitioned
    system its dependent coordinates solved on the branch (csim.physics.branch.to_full), in P.yf."""
    if pi[PI_SYS] == PARTITIONED:
        return _partitioned_full_state(y, par, pf, pi, w, piv)
    return OK, y


@hot
def _partitioned_full_state(y, par, pf, pi, w, piv):
    """:func:`full_state` of the partitioned system."""
    model, P, r, m, k, tol, max_iter, _ = _partition_call(par, pf, pi, w, piv)
    return branch.to_full(model, P, y, P.yf, r, m, k, tol, max_iter), P.yf


@hot
def _partitioned_rhs(t, y, mode, located, par, pf, pi, w, piv, f):
    """dy/dt = [ud, udd, dW/dt] (2 n + k,) of the partitioned system: the rhs at the full state, with the
    accelerations from the equations of motion on the tangent space (csim.physics.partition.reduced_accelerations,
    an n x n solve), reduced."""
    code, yf = full_state(y, par, pf, pi, w, piv)
    if code != OK:
        return code
    nq, nc = pi[PI_NQ], pi[PI_NC]
    P = _partition(pi, w, piv)
    _rhs_inputs(t, yf, mode, located, par, pf, pi, w, nq, nc)
    if not reduced_accelerations(P, w[pi[W_M]:pi[W_M] + nq * nq], w[pi[W_P]:pi[W_P] + nq], w[pi[W_GS]:pi[W_GS] + nc],
                                 w[pi[W_X]:pi[W_X] + nq], nc, nq):
        return TANGENT_MASS_SINGULAR
    _rhs_outputs(yf, pi, w, P.ff, nq, nc)
    branch.reduce(P, P.ff, f, nc, nq, pi[PI_NL])
    return OK


@hot
def _partition_after_step(y, par, pf, pi, w, piv):
    """csim.physics.branch.after_step at the accepted state y: (code, restart)."""
    model, P, r, m, k, tol, max_iter, max_condition = _partition_call(par, pf, pi, w, piv)
    return branch.after_step(model, P, y, r, m, k, tol, max_iter, max_condition)


@hot
def _repartition(ya, y, par, pf, pi, w, piv):
    """y = the accepted state ya, then csim.physics.branch.repartition from it after a breakdown; returns the code."""
    for i in range(y.size):
        y[i] = ya[i]
    model, P, r, m, k, tol, max_iter, _ = _partition_call(par, pf, pi, w, piv)
    return branch.repartition(model, P, y, r, m, k, tol, max_iter)


@hot
def _failure_details(pi, w, piv, info):
    """info[2:] = the partition's failure details, for the message (a function without reference counting:
    the views of w must not be counted by a caller that counts, as integrate does)."""
    detail = _partition(pi, w, piv).detail
    for i in range(detail.size):
        info[2 + i] = detail[i]


@inlined
def _pending(pi, w, piv):
    """The breakdown of a full state met where no code could be returned (a switching function's value), cleared."""
    if pi[PI_SYS] == PARTITIONED:
        return _set_pending(pi, w, piv, np.int64(OK))  # (not a literal: compiled once, for int64)
    return OK


@hot
def _set_pending(pi, w, piv, code):
    """Set the partitioned system's pending breakdown to ``code``; returns the one it replaces."""
    P = _partition(pi, w, piv)
    before = P.count[C_PENDING]
    P.count[C_PENDING] = code
    return before


# ---------------------------------------------------------------------------------------
# the model at a state: switching functions, right-hand side
# ---------------------------------------------------------------------------------------
@hot
def switching_from(y, pf, pi, w):
    """Switching functions into w[W_G:] from s and S = ds/dq^T in w (loads_ or terms evaluated) and qd in y."""
    n_sw, nq, nl = pi[PI_NSW], pi[PI_NQ], pi[PI_NL]
    w_sd, w_g = pi[W_SD], pi[W_G]
    load_rates(w[pi[W_SQ]:pi[W_SQ] + nq * nl], y[nq:2 * nq], w[w_sd:w_sd + nl], nq, nl)
    switching_functions(w[pi[W_S]:pi[W_S] + nl], w[w_sd:w_sd + nl], pi[PI_HEAD:PI_HEAD + n_sw],
                        pi[PI_HEAD + n_sw:PI_HEAD + 2 * n_sw], pf[nl:nl + n_sw], w[w_g:w_g + n_sw])


@hot
def mode_at(y, par, pf, pi, w, piv, mode):
    """The load-law conditions that hold at state y (switching functions left in w[W_G:]); returns the code."""
    code, yv = full_state(y, par, pf, pi, w, piv)
    if code != OK:
        return code
    loads_(yv, par, pi, w)
    switching_from(yv, pf, pi, w)
    mode_of(w[pi[W_G]:pi[W_G] + pi[PI_NSW]], mode)
    return OK


@sized
def _rhs_inputs(t, y, mode, located, par, pf, pi, w, nq, nc):
    """What the solve for the accelerations reads, into w at (t, y): the model's terms, the load values u (the
    laws held in ``mode``, or evaluated at y where not ``located``), p = B u - C qd - h, d/dt Phi and gamma*
    (inlined where called, as :func:`_rhs_sized`)."""
    nl = pi[PI_NL]
    terms(t, y, par, pi, w)
    qd = y[nq:2 * nq]
    B = w[pi[W_B]:pi[W_B] + nq * nl]
    J = w[pi[W_J]:pi[W_J] + nc * nq]
    if not located:
        switching_from(y, pf, pi, w)
        mode_of(w[pi[W_G]:pi[W_G] + pi[PI_NSW]], mode)
    u = w[pi[W_U]:pi[W_U] + nl]
    load_values(pf[:nl], mode, pi[PI_HEAD:PI_HEAD + pi[PI_NSW]], w[pi[W_L]:pi[W_L] + nl], u)
    p = w[pi[W_P]:pi[W_P] + nq]
    generalized_forces(B, u, w[pi[W_CQD]:pi[W_CQD] + nq], w[pi[W_H]:pi[W_H] + nq], p, nq, nl)
    phi_dot = w[pi[W_PD]:pi[W_PD] + nc]
    constraint_rates(J, qd, phi_dot, nc, nq)
    for i in range(nc):  # d/dt Phi = Phi_q qd + Phi_t (Phi_t: drive rows only)
        phi_dot[i] += w[pi[W_PT] + i]
    gains = pf[pi[PI_GAINS]:pi[PI_GAINS] + pi[PI_NGAINS]]
    fpar = pf[pi[PI_FPAR]:pi[PI_FPAR] + pi[PI_NFPAR]]
    ipar = pi[pi[PI_IPAR]:pi[PI_IPAR] + pi[PI_NIPAR]]
    method_gamma_star(pi[PI_MK], nc, w[pi[W_GAM]:pi[W_GAM] + nc], w[pi[W_PHI]:pi[W_PHI] + nc], phi_dot, gains, fpar,
                      ipar, w[pi[W_GS]:pi[W_GS] + nc], pi)


@sized
def _rhs_outputs(y, pi, w, f, nq, nc):
    """f = [qd, qdd, u * B^T qd, tau qd_j] from the accelerations (and the drives' multipliers) in w[W_X:]."""
    nl = pi[PI_NL]
    qd = y[nq:2 * nq]
    x = w[pi[W_X]:pi[W_X] + nq + nc]
    sdot = w[pi[W_SD]:pi[W_SD] + nl]
    load_rates(w[pi[W_B]:pi[W_B] + nq * nl], qd, sdot, nq, nl)
    for i in range(nq):
        f[i] = qd[i]
        f[nq + i] = x[i]
    for kk in range(nl):  # dW/dt = u * (B^T qd), the power of each load
        f[2 * nq + kk] = w[pi[W_U] + kk] * sdot[kk]
    nd = pi[PI_ND]
    for kk in range(nd):  # dW_d/dt = tau qd_j, tau = -lambda_d: the power of each drive (csim.solver.driven)
        f[2 * nq + nl + kk] = -x[nq + nc - nd + kk] * qd[pi[pi[PI_DRV] + kk]]


@sized
def _rhs_sized(t, y, mode, located, par, pf, pi, w, piv, f, nq, nc):
    """:func:`rhs` for nq coordinates and nc constraints (inlined where called: constants there fix the loops)."""
    _rhs_inputs(t, y, mode, located, par, pf, pi, w, nq, nc)
    nk = nq + nc
    if pi[PI_FORM] == ELIMINATION:
        code = call_eliminated(pi[PI_ELIM], pf, pi, w, piv)
        if code != OK:
            return code
    elif not kkt_solve(w[pi[W_M]:pi[W_M] + nq * nq], w[pi[W_J]:pi[W_J] + nc * nq], w[pi[W_P]:pi[W_P] + nq],
                       w[pi[W_GS]:pi[W_GS] + nc], w[pi[W_A]:pi[W_A] + nk * nk], w[pi[W_X]:pi[W_X] + nk], piv, nq, nc):
        return SINGULAR_KKT
    _rhs_outputs(y, pi, w, f, nq, nc)
    return OK


@hot
@rhs_root
def rhs(t, y, mode, located, par, pf, pi, w, piv, f):
    """dy/dt = [qd, qdd, u * B^T qd] at time t into f; [qdd, lambda] left in w[W_X:] (by the KKT system, or the
    elimination). Returns OK or the solve's failure code.

    The load laws are held in ``mode``; with ``located`` False they are evaluated at y
    itself (``mode`` is then overwritten: pass a scratch array). For the commonest sizes
    (:data:`SIZED`) the sizes are constants of a copy of the code each (loops of known length,
    as plain C has them); other ones run with the sizes read from pi.
    """
    nq, nc = pi[PI_NQ], pi[PI_NC]
    if nq == 3 and nc == 2:
        return _rhs_sized(t, y, mode, located, par, pf, pi, w, piv, f, 3, 2)
    if nq == 2 and nc == 1:
        return _rhs_sized(t, y, mode, located, par, pf, pi, w, piv, f, 2, 1)
    return _rhs_sized(t, y, mode, located, par, pf, pi, w, piv, f, nq, nc)


# Compiled on its own and called through its address (feval_call): numba links the LLVM IR of a
# callee into each of its callers, and this one has a dozen, each of which then carried the right-hand
# side's closure (the cold compile 286 s -> 206 s on 2 cores, 2026-11-26, the steps' times unchanged).
# (Not inlined by numba either: that changed the register allocation of rhs itself and made the RK4 row
# 15 % slower, measured alternately.)
@addressed
def feval(t, y, mode, located, par, pf, pi, w, piv, f, info):
    """rhs plus the driver's check of a non-finite result (info = [t, max |y|] then, and t also in info's last
    slot, which only a non-finite result writes: the integrate's message of a failed Radau names it, as the
    Python path's does)."""
    if pi[PI_SYS] == PARTITIONED:
        code = _partitioned_rhs(t, y, mode, located, par, pf, pi, w, piv, f)
    elif pi[PI_SYS] == GGL:
        code = _ggl_rhs(t, y, mode, located, par, pf, pi, w, piv, f)
    else:
        code = rhs(t, y, mode, located, par, pf, pi, w, piv, f)
    if code == OK and not all_finite(f):
        code = NONFINITE_RHS
        info[info.size - 1] = t
    if code != OK:
        info[0] = t
        info[1] = max_abs(y)
    return code


@inlined
def feval_call(t, y, mode, located, par, pf, pi, w, piv, f, info):
    """:func:`feval` called through its address pi[PI_FEVAL] (:func:`.calls.call_feval`): what its callers call."""
    return call_feval(pi[PI_FEVAL], t, y, mode, located, par, pf, pi, w, piv, f, info)


@inlined
def plain_feval(t, y, mode, located, par, pf, pi, w, piv, f, info):
    """:func:`feval_call` as the plain system's right-hand side at a full state [q, qd, W], whatever the
    system integrated (pi[PI_SYS], which feval reads, set to CONSTRAINED for the call and then restored):
    GGL's multipliers, and the samples' recorded quantities of every method."""
    system = pi[PI_SYS]
    pi[PI_SYS] = CONSTRAINED
    code = feval_call(t, y, mode, located, par, pf, pi, w, piv, f, info)
    pi[PI_SYS] = system
    return code


# ---------------------------------------------------------------------------------------
# GGL's DAE (csim.solver.ggl_system.GGLSystem): x = [q, v, W, mu, lambda]
# ---------------------------------------------------------------------------------------
@hot
def _ggl_rhs(t, x, mode, located, par, pf, pi, w, piv, f):
    """F(t, x) (2 m + k + 2 r,) of GGL's DAE (csim.physics.ggl.ggl_equations): [v - Phi_q^T mu,
    M^-1 (p - Phi_q^T lambda), u * B^T v, Phi, Phi_q v]. Returns OK or GGL_SINGULAR_MASS."""
    nq, nc = pi[PI_NQ], pi[PI_NC]
    _rhs_inputs(t, x, mode, located, par, pf, pi, w, nq, nc)  # the terms, u, p and Phi_q v at [q, v, W]
    n0 = 2 * nq + pi[PI_NL]
    q_dot, v_dot = w[pi[W_DQ]:pi[W_DQ] + nq], w[pi[W_X]:pi[W_X] + nq]
    if not ggl_equations(w[pi[W_M]:pi[W_M] + nq * nq], w[pi[W_J]:pi[W_J] + nc * nq], w[pi[W_P]:pi[W_P] + nq],
                         w[pi[W_PHI]:pi[W_PHI] + nc], w[pi[W_PD]:pi[W_PD] + nc], x[nq:2 * nq], x[n0:n0 + nc],
                         x[n0 + nc:n0 + 2 * nc], w[pi[W_M2]:pi[W_M2] + nq * nq], piv, q_dot, v_dot,
                         f[n0:n0 + 2 * nc], nq, nc):
        return GGL_SINGULAR_MASS
    _rhs_outputs(x, pi, w, f, nq, nc)  # [v, v', u * B^T v]
    for i in range(nq):
        f[i] = q_dot[i]
    return OK


@hot
def ggl_consistent(t, y, mode, yp, par, pf, pi, w, piv, info):
    """y = GGL's consistent state at time t from its [q, v, W] under the load laws ``mode``
    (GGLSystem._consistent): (q, v) projected in the mass metric, mu = 0, lambda from the KKT system.
    ``yp`` (n,) is scratch. Returns the status."""
    code = project(y, yp, t, par, pf, pi, w, piv, info)  # (GGL's fpar[0], ipar: its projection's settings)
    if code != OK:
        return code
    nq, nc = pi[PI_NQ], pi[PI_NC]
    n0 = 2 * nq + pi[PI_NL]
    for i in range(n0):
        y[i] = yp[i]
    # lambda: the KKT solve of the plain system's right-hand side at [q, v, W], through feval's address, so that
    # the loop links none of it
    code = plain_feval(t, y[:n0], mode, LOCATED, par, pf, pi, w, piv, yp[:n0], info)
    if code != OK:
        return code
    for i in range(nc):
        y[n0 + i] = 0.0
        y[n0 + nc + i] = w[pi[W_X] + nq + i]
    return OK


# ---------------------------------------------------------------------------------------
# projection onto Phi = 0, Phi_q qd + Phi_t = 0 (csim.solver.methods.projection)
# ---------------------------------------------------------------------------------------
@hot
def project(y, out, t, par, pf, pi, w, piv, info):
    """out = y at time t with (q, qd) projected (csim.physics.projection.project: onto the drives at t too);
    returns the status code.

    On a failure info = [max |Phi| of the last iterate, t], as the status messages read them.
    The method's settings: fpar[0] the tolerance on max |Phi|, ipar = [mass metric (0/1),
    iteration limit].
    """
    fpar = pf[pi[PI_FPAR]:pi[PI_FPAR] + pi[PI_NFPAR]]
    ipar = pi[pi[PI_IPAR]:pi[PI_IPAR] + pi[PI_NIPAR]]
    for i in range(y.size):
        out[i] = y[i]
    nq, nc, nl = pi[PI_NQ], pi[PI_NC], pi[PI_NL]
    model = model_handle(par, pi, w, w[pi[W_YM]:pi[W_YM] + 2 * nq + nl], t)
    code, mx = project_state(model, out[:nq], out[nq:2 * nq], fpar[0], ipar[0] == 1, ipar[1], nq, nc,
                             w[pi[W_M]:pi[W_M] + nq * nq], w[pi[W_M2]:pi[W_M2] + nq * nq],
                             w[pi[W_WINV]:pi[W_WINV] + nq * nq], piv, w[pi[W_COL]:pi[W_COL] + nq],
                             w[pi[W_PHI]:pi[W_PHI] + nc], w[pi[W_J]:pi[W_J] + nc * nq],
                             w[pi[W_WJT]:pi[W_WJT] + nq * nc], w[pi[W_S2]:pi[W_S2] + nc * nc],
                             w[pi[W_Z]:pi[W_Z] + nc], w[pi[W_DQ]:pi[W_DQ] + nq], w[pi[W_PD]:pi[W_PD] + nc])
    if code != OK:
        return _project_failed(code, mx, t, info)
    return OK


@hot
def _project_failed(code, max_phi, t, info):
    """info = [max |Phi|, t] of a failed projection; returns its code."""
    info[0] = max_phi
    info[1] = t
    return code


@hot
def _max_phi(t, y, par, pf, pi, w, piv):
    """(code, max |Phi|) of the mechanism's rows (not the drives', as the Python path's
    ConstrainedSystem.max_phi) at time t and the integrated state y (NaN where y is not finite:
    the step check says so)."""
    if not all_finite(y):
        return OK, np.nan
    code, yv = full_state(y, par, pf, pi, w, piv)
    if code != OK:
        return code, np.nan
    phi_at(t, yv, par, pi, w)
    return OK, max_abs(w[pi[W_PHI]:pi[W_PHI] + pi[PI_NC] - pi[PI_ND]])
