"""The other entry points: the recorded quantities at the output samples
(:func:`evaluate_samples`, for :func:`csim.pipeline.assemble_result`), and the right-hand side
and the projection at one state, for the tests and the benchmark.

:func:`evaluate_samples` and :func:`rhs_entry` call the right-hand side through feval's address
(pi[PI_FEVAL], :func:`csim.fast.runner.pack_problem` sets it), as the loop does, as the plain
system's (:func:`.system.plain_feval`: every method's samples are full states [q, qd, W]); each
linking the right-hand side's whole call tree into its own and optimizing it again took 2 s more
of the cold compile on the 2-core machine (2026-11-27). :func:`rhs_repeat`, the
benchmark's timing loop, calls it directly: what it times is the right-hand side alone.
"""
import numpy as np

from csim.fast.layout import (
    PI_FEVAL,
    PI_NC,
    PI_NL,
    PI_NO,
    PI_NQ,
    PI_NSW,
    W_B,
    W_END,
    W_PD,
    W_PHI,
    W_U,
    W_X,
)
from csim.physics.status import NONFINITE_RHS, OK

from .calls import kinetic, observe, potential
from .common import LOCATED, allocating, copy_row, inlined
from .system import int_workspace, plain_feval, project, rhs


# ---------------------------------------------------------------------------------------
# the recorded quantities at the output samples (csim.pipeline.assemble_result)
# ---------------------------------------------------------------------------------------
@allocating
def evaluate_samples(ts, ys, modes, par, pf, pi):
    """Everything a result records at each sample, from the same right-hand side the loop ran.

    Parameters
    ----------
    ts : ndarray (N,)
        Sample times [s] (the load laws may depend on t).
    ys : ndarray (N, 2 m + k)
        Recorded states [q, qd, W].
    modes : ndarray (N, n_sw) bool
        The load laws held at each sample.

    Returns
    -------
    ok : ndarray (N,) bool
        False where the formulation's solve failed (the KKT matrix, or the elimination's block, singular; the
        row's other outputs are then NaN).
    x : ndarray (N, m + r)
        [qdd, lambda].
    phi, phi_dot : ndarray (N, r)
        Phi and Phi_q qd.
    u : ndarray (N, k)
        Load values.
    Q : ndarray (N, m)
        Generalized applied forces B u.
    energy : ndarray (N, 2)
        Kinetic and potential energy [J].
    obs : ndarray (N, 2 o)
        The observables and their rates (evaluated at every sample, singular or not).
    """
    N = ys.shape[0]
    nq, nc, nl, no = pi[PI_NQ], pi[PI_NC], pi[PI_NL], pi[PI_NO]
    nk = nq + nc
    w = np.zeros(pi[W_END])
    piv = np.zeros(int_workspace(pi), np.int64)
    f = np.empty(ys.shape[1])
    mode = np.empty(pi[PI_NSW], np.bool_)
    ok = np.ones(N, np.bool_)
    x, Q = np.full((N, nk), np.nan), np.full((N, nq), np.nan)
    phi, phi_dot = np.full((N, nc), np.nan), np.full((N, nc), np.nan)
    u, energy = np.full((N, nl), np.nan), np.full((N, 2), np.nan)
    obs = np.empty((N, 2 * no))
    info = np.zeros(2)
    _require_feval(pi)
    for i in range(N):
        y = ys[i]
        if no > 0:
            observe(y, par, pi, obs[i])
        for j in range(mode.size):  # (element by element: numba's slice assignment from an array compiles
            mode[j] = modes[i, j]  # the formatting of its shape mismatch message, 1.5 s of the warm-up)
        if plain_feval(ts[i], y, mode, LOCATED, par, pf, pi, w, piv, f, info) not in (OK, NONFINITE_RHS):
            ok[i] = False  # (a non-finite result is recorded as it is)
            continue
        copy_row(w[pi[W_X]:], x, i)
        copy_row(w[pi[W_PHI]:], phi, i)
        copy_row(w[pi[W_PD]:], phi_dot, i)
        copy_row(w[pi[W_U]:], u, i)
        for a in range(nq):  # Q = B u, B (m, k) row-major
            acc = 0.0
            for kk in range(nl):
                acc += w[pi[W_B] + a * nl + kk] * w[pi[W_U] + kk]
            Q[i, a] = acc
        energy[i, 0] = kinetic(y, par, pi, w)
        energy[i, 1] = potential(y, par, pi, w)
    return ok, x, phi, phi_dot, u, Q, energy, obs


@inlined
def _require_feval(pi):
    """A ValueError where feval's address pi[PI_FEVAL] is not set (a call through 0 would crash)."""
    if pi[PI_FEVAL] == 0:
        raise ValueError("pi[PI_FEVAL], the address of feval, is not set (csim.fast.runner.pack_problem sets it)")


# ---------------------------------------------------------------------------------------
# entry points for the tests and the benchmark
# ---------------------------------------------------------------------------------------
@allocating
def rhs_entry(t, y, mode, par, pf, pi):
    """dy/dt and [qdd, lambda] at time t and one state [q, qd, W] (mode held), for comparison with the Python
    path: the status (NONFINITE_RHS where dy/dt is not finite), dy/dt and [qdd, lambda]. Its arguments have
    feval's types (``FEVAL_TYPES``: a float t, writable contiguous float arrays), as it calls feval by address."""
    w = np.zeros(pi[W_END])
    piv = np.zeros(int_workspace(pi), np.int64)
    f = np.empty(y.size)
    _require_feval(pi)
    code = plain_feval(t, y, mode.copy(), LOCATED, par, pf, pi, w, piv, f, np.zeros(2))
    return code, f, w[pi[W_X]:pi[W_X] + pi[PI_NQ] + pi[PI_NC]].copy()


@allocating
def rhs_repeat(y, mode, par, pf, pi, n_eval):
    """n_eval evaluations of the right-hand side (a timing loop for the benchmark)."""
    w = np.zeros(pi[W_END])
    piv = np.zeros(int_workspace(pi), np.int64)
    f = np.empty(y.size)
    acc = 0.0
    for _ in range(n_eval):
        rhs(0.0, y, mode, LOCATED, par, pf, pi, w, piv, f)
        acc += f[pi[PI_NQ]]
    return acc


@allocating
def project_entry(y, par, pf, pi):
    w = np.zeros(pi[W_END])
    piv = np.zeros(int_workspace(pi), np.int64)
    out = np.empty(y.size)
    info = np.zeros(2)
    code = project(y, out, 0.0, par, pf, pi, w, piv, info)
    return code, info[0], out
