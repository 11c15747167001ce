# ruff: noqa: F821
"""Compiled kernels: KKT right-hand side, stabilizers, projection, DOP853 and RK4 loops.

This file is not imported as it is. :mod:`csim.fast.module` pastes its text after the
generated model functions of one mechanism (:mod:`csim.fast.codegen`: ``terms``, ``phi_``,
``jac``, ``mass``, ``loads_``, ``kinetic`` and the sizes ``NQ``, ``NC``, ``NL``) into one
module, which numba compiles and caches on disk. The names this file uses without
defining them are those.

Everything mirrors the Python path so that both give the same results to round-off:
:class:`csim.solver.system.ConstrainedSystem` (state y = [q, qd, W]),
:class:`csim.solver.formulations.KKT`, :mod:`csim.solver.stabilizers`, scipy's ``DOP853``
(step-size control, error estimate, dense output), :class:`csim.solver.integrators.RK4`
with its cubic Hermite dense output, scipy's ``brentq``, and the event location, sampling
and divergence checks of :func:`csim.solver.simulate.integrate`.

The problem is passed as two flat arrays (no tuples of arrays: numba would count
references to each member at every call)::

    pf = [magnitudes (k), g1 (r), g2 (r), g3 (r), sw_width, proj_tol, sw_value (n_sw)]
    pi = [stab_kind, sw_fn, proj_metric, proj_max_iter, n_sw, sw_load (n_sw), sw_kind (n_sw)]

switching function j of load ``sw_load[j]``: kind 0 is s - lo, 1 hi - s, 2 ds/dt, 3 -ds/dt
(``sw_value`` holds lo or hi). ``stab_kind``: 0 none, 1 baumgarte (g1 = d, g2 = w),
2 sliding_mode (g1 = Lambda, g2 = K, g3 = k; ``sw_fn`` 0 sgn, 1 sat, 2 tanh, 3 atan,
4 sqrt with width ``sw_width``), 3 projection (``proj_metric`` 0 minimum_norm, 1 mass).
The workspace w holds the model terms (offsets W_M ... from the generated part), then the
KKT matrix and right-hand side, the loads, the projection's matrices and the switching
functions (offsets below).
"""
import importlib.util
import math
import os

import numpy as np
from numba import njit


def _dop853_coefficients():
    """scipy's own DOP853 coefficient module, loaded as a file: importing it through its
    package would import all of scipy.integrate (half a second) for a table of numbers."""
    scipy_dir = os.path.dirname(importlib.util.find_spec("scipy").origin)
    path = os.path.join(scipy_dir, "integrate", "_ivp", "dop853_coefficients.py")
    spec = importlib.util.spec_from_file_location("_csim_dop853_coefficients", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_dop = _dop853_coefficients()

# ---- status codes of the integration loop (csim.fast.runner turns them into messages) ----
OK = 0
NONFINITE_RHS = 1  # info: t, max |y|
NONFINITE_STATE = 2  # info: t
MAX_PHI = 3  # info: max |Phi|, t
STEP_COLLAPSE = 4  # info: h, t
MAX_STEPS = 5  # info: t
STEP_TOO_SMALL = 6  # info: t (scipy: "Required step size is less than spacing between numbers.")
SINGULAR_KKT = 7  # info: t
PROJ_SINGULAR = 8  # info: t
PROJ_NO_CONVERGENCE = 9  # info: max |Phi|, t
MAX_EVENTS = 10  # info: t
RK4_RESOLUTION = 11  # info: t
SINGULAR_MASS = 12  # info: t
NO_SIGN_CHANGE = 13  # info: t

EPS = 2.220446049250313e-16

# DOP853 coefficients, the very arrays scipy's DOP853 uses
DOP_NS = _dop.N_STAGES  # 12
DOP_A = np.ascontiguousarray(_dop.A[:DOP_NS, :DOP_NS])
DOP_B = np.ascontiguousarray(_dop.B)
DOP_C = np.ascontiguousarray(_dop.C[:DOP_NS])
DOP_E3 = np.ascontiguousarray(_dop.E3)
DOP_E5 = np.ascontiguousarray(_dop.E5)
DOP_D = np.ascontiguousarray(_dop.D)
DOP_A_EXTRA = np.ascontiguousarray(_dop.A[DOP_NS + 1:])
DOP_C_EXTRA = np.ascontiguousarray(_dop.C[DOP_NS + 1:])
DOP_NX = _dop.N_STAGES_EXTENDED  # 16
DOP_POWER = _dop.INTERPOLATOR_POWER  # 7
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0

# integrators
DOP853 = 0
RK4 = 1


# ---------------------------------------------------------------------------------------
# workspace layout after the model terms (the model part defines W_M ... W_MODEL)
# ---------------------------------------------------------------------------------------
NK = NQ + NC  # size of the KKT system
W_A = W_MODEL  # KKT matrix (NK, NK)
W_X = W_A + NK * NK  # its right-hand side [p, gamma*], then the solution [qdd, lambda]
W_U = W_X + NK  # load values (NL)
W_WINV = W_U + NL  # projection: W^-1 (NQ, NQ)
W_M2 = W_WINV + NQ * NQ  # projection: LU of M (NQ, NQ)
W_WJT = W_M2 + NQ * NQ  # projection: W^-1 Phi_q^T (NQ, NC)
W_S2 = W_WJT + NQ * NC  # projection: Phi_q W^-1 Phi_q^T (NC, NC)
W_Z = W_S2 + NC * NC  # projection: (NC)
W_DQ = W_Z + NC  # projection: correction (NQ)
W_COL = W_DQ + NQ  # projection: a column of the identity (NQ)
W_G = W_COL + NQ  # switching functions (n_sw), last
# offsets in pf
PF_G1 = NL
PF_G2 = NL + NC
PF_G3 = NL + 2 * NC
PF_WIDTH = NL + 3 * NC
PF_PTOL = PF_WIDTH + 1
PF_SW = PF_PTOL + 1


# ---------------------------------------------------------------------------------------
# small dense linear algebra in w (LU with partial pivoting, as LAPACK's getrf/getrs)
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def lu_factor(w, a, n, piv):
    """In-place LU of the row-major n x n matrix at w[a:]; False if a pivot is exactly zero."""
    for c in range(n):
        p = c
        big = abs(w[a + c * n + c])
        for i in range(c + 1, n):
            v = abs(w[a + i * n + c])
            if v > big:
                big = v
                p = i
        piv[c] = p
        if w[a + p * n + c] == 0.0:
            return False
        if p != c:
            for j in range(n):
                tmp = w[a + c * n + j]
                w[a + c * n + j] = w[a + p * n + j]
                w[a + p * n + j] = tmp
        inv = 1.0 / w[a + c * n + c]
        for i in range(c + 1, n):
            w[a + i * n + c] *= inv
            lic = w[a + i * n + c]
            if lic != 0.0:
                for j in range(c + 1, n):
                    w[a + i * n + j] -= lic * w[a + c * n + j]
    return True


@njit(cache=True, error_model="numpy")
def lu_solve(w, a, n, piv, b):
    """Solve with the factors of :func:`lu_factor`; w[b:b + n] is overwritten by the solution."""
    for c in range(n):
        p = piv[c]
        if p != c:
            tmp = w[b + c]
            w[b + c] = w[b + p]
            w[b + p] = tmp
    for i in range(n):
        s = w[b + i]
        for j in range(i):
            s -= w[a + i * n + j] * w[b + j]
        w[b + i] = s
    for i in range(n - 1, -1, -1):
        s = w[b + i]
        for j in range(i + 1, n):
            s -= w[a + i * n + j] * w[b + j]
        w[b + i] = s / w[a + i * n + i]


@njit(cache=True, error_model="numpy")
def all_finite(x):
    """Whether every entry is finite (a loop: numba does not compile all() over a generator)."""
    ok = True
    for i in range(x.size):
        if not math.isfinite(x[i]):
            ok = False
            break
    return ok


@njit(cache=True, error_model="numpy")
def spacing(t):
    """|nextafter(t, +inf) - t| for t >= 0 (numpy's nextafter without its overload)."""
    if t == 0.0:
        return 5e-324
    _, e = math.frexp(t)  # t = m 2^e, 0.5 <= m < 1
    return 2.0 ** (e - 53)


@njit(cache=True, error_model="numpy")
def copy_to(src, dst):
    for i in range(src.size):
        dst[i] = src[i]


@njit(cache=True, error_model="numpy")
def copy_row(src, dst, row):
    for i in range(src.size):
        dst[row, i] = src[i]


@njit(cache=True, error_model="numpy")
def max_abs_range(x, a, n):
    """max |x[a:a + n]| (0 when empty), NaN if any entry is NaN (as numpy's max)."""
    out = 0.0
    for i in range(a, a + n):
        v = abs(x[i])
        if v != v:
            return v
        if v > out:
            out = v
    return out


@njit(cache=True, error_model="numpy")
def max_abs(x):
    return max_abs_range(x, 0, x.size)


# ---------------------------------------------------------------------------------------
# loads, stabilizers, right-hand side
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def switching_from(y, pf, pi, w):
    """Switching functions into w[W_G:] from s and B in w and qd in y."""
    n_sw = pi[4]
    for j in range(n_sw):
        kk = pi[5 + j]
        kind = pi[5 + n_sw + j]
        if kind == 0:
            w[W_G + j] = w[W_S + kk] - pf[PF_SW + j]
        elif kind == 1:
            w[W_G + j] = pf[PF_SW + j] - w[W_S + kk]
        else:
            sdot = 0.0
            for i in range(NQ):
                sdot += w[W_B + i * NL + kk] * y[NQ + i]
            w[W_G + j] = sdot if kind == 2 else -sdot


@njit(cache=True, error_model="numpy")
def mode_at(y, par, pf, pi, w, mode):
    """The load-law conditions that hold at state y (switching functions left in w[W_G:])."""
    loads_(y, par, w)
    switching_from(y, pf, pi, w)
    for j in range(pi[4]):
        mode[j] = w[W_G + j] > 0.0


@njit(cache=True, error_model="numpy")
def switch_fn(kind, s, width):
    if kind == 0:
        return 1.0 if s > 0 else (-1.0 if s < 0 else (0.0 if s == 0 else s))
    if kind == 1:
        return min(1.0, max(-1.0, s / width))
    if kind == 2:
        return math.tanh(width * s)
    if kind == 3:
        return 2.0 / np.pi * math.atan(width * s)
    return s / math.sqrt(s * s + width * width)


@njit(cache=True, error_model="numpy")
def gamma_star(i, gam, phi_i, phi_dot_i, pf, pi):
    """gamma*_i of constraint i (csim.solver.stabilizers)."""
    kind = pi[0]
    if kind == 1:  # baumgarte
        d, wn = pf[PF_G1 + i], pf[PF_G2 + i]
        return gam - 2.0 * d * wn * phi_dot_i - wn**2 * phi_i
    if kind == 2:  # sliding mode
        lam, K, k = pf[PF_G1 + i], pf[PF_G2 + i], pf[PF_G3 + i]
        s = phi_dot_i + lam * phi_i
        return gam - lam * phi_dot_i - K * s - k * switch_fn(pi[1], s, pf[PF_WIDTH])
    return gam


@njit(cache=True, error_model="numpy")
def rhs(y, mode, located, par, pf, pi, w, piv, f):
    """dy/dt into f: [qd, qdd, u * ds/dt]; [qdd, lambda] left in w[W_X:]. Returns OK or SINGULAR_KKT.

    The load laws are held in ``mode``; with ``located`` False they are evaluated at y
    itself (``mode`` is then overwritten: pass a scratch array).
    """
    terms(y, par, w)
    if not located:
        switching_from(y, pf, pi, w)
        for j in range(pi[4]):
            mode[j] = w[W_G + j] > 0.0
    n_sw = pi[4]
    for kk in range(NL):  # u_k = magnitude_k while every condition of load k holds
        w[W_U + kk] = pf[kk]
    for j in range(n_sw):
        if not mode[j]:
            w[W_U + pi[5 + j]] = 0.0
    for i in range(NQ):
        Q = 0.0
        for kk in range(NL):
            Q += w[W_B + i * NL + kk] * w[W_U + kk]
        w[W_X + i] = Q - w[W_CQD + i] - w[W_H + i]  # p = B u - C qd - h
        for j in range(NQ):
            w[W_A + i * NK + j] = w[W_M + i * NQ + j]
        for j in range(NC):
            w[W_A + i * NK + NQ + j] = w[W_J + j * NQ + i]
    for i in range(NC):
        phi_dot = 0.0
        for j in range(NQ):
            w[W_A + (NQ + i) * NK + j] = w[W_J + i * NQ + j]
            phi_dot += w[W_J + i * NQ + j] * y[NQ + j]
        for j in range(NC):
            w[W_A + (NQ + i) * NK + NQ + j] = 0.0
        w[W_X + NQ + i] = gamma_star(i, w[W_GAM + i], w[W_PHI + i], phi_dot, pf, pi)
    if not lu_factor(w, W_A, NK, piv):
        return SINGULAR_KKT
    lu_solve(w, W_A, NK, piv, W_X)
    for i in range(NQ):
        f[i] = y[NQ + i]
        f[NQ + i] = w[W_X + i]
    for kk in range(NL):
        sdot = 0.0
        for i in range(NQ):
            sdot += w[W_B + i * NL + kk] * y[NQ + i]
        f[2 * NQ + kk] = w[W_U + kk] * sdot
    return OK


@njit(cache=True, error_model="numpy")
def feval(t, y, mode, located, par, pf, pi, w, piv, f, info):
    """rhs plus the driver's check of a non-finite result (info = [t, max |y|] then)."""
    code = rhs(y, mode, located, par, pf, pi, w, piv, f)
    if code == OK and not all_finite(f):
        code = NONFINITE_RHS
    if code != OK:
        info[0] = t
        info[1] = max_abs(y)
    return code


# ---------------------------------------------------------------------------------------
# projection onto Phi = 0, Phi_q qd = 0 (csim.solver.stabilizers.Projection)
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _correction(w, mass_metric, res, piv):
    """w[W_DQ:] = W^-1 J^T (J W^-1 J^T)^-1 w[res:] with J = w[W_J:]; False if singular."""
    for i in range(NQ):
        for c in range(NC):
            if mass_metric:
                v = 0.0
                for j in range(NQ):
                    v += w[W_WINV + i * NQ + j] * w[W_J + c * NQ + j]
                w[W_WJT + i * NC + c] = v
            else:
                w[W_WJT + i * NC + c] = w[W_J + c * NQ + i]
    for a in range(NC):
        for b in range(NC):
            v = 0.0
            for j in range(NQ):
                v += w[W_J + a * NQ + j] * w[W_WJT + j * NC + b]
            w[W_S2 + a * NC + b] = v
    for a in range(NC):
        w[W_Z + a] = w[res + a]
    if not lu_factor(w, W_S2, NC, piv):
        return False
    lu_solve(w, W_S2, NC, piv, W_Z)
    for i in range(NQ):
        v = 0.0
        for c in range(NC):
            v += w[W_WJT + i * NC + c] * w[W_Z + c]
        w[W_DQ + i] = v
    return True


@njit(cache=True, error_model="numpy")
def project(y, out, par, pf, pi, w, piv):
    """out = y with (q, qd) projected; returns (status code, max |Phi| of the last iterate)."""
    tol, max_iter = pf[PF_PTOL], pi[3]
    mass_metric = pi[2] == 1
    for i in range(y.size):
        out[i] = y[i]
    if mass_metric:  # W^-1 = M^-1, column by column
        mass(out, par, w)
        for i in range(NQ * NQ):
            w[W_M2 + i] = w[W_M + i]
        if not lu_factor(w, W_M2, NQ, piv):
            return SINGULAR_MASS, 0.0
        for c in range(NQ):
            for i in range(NQ):
                w[W_COL + i] = 1.0 if i == c else 0.0
            lu_solve(w, W_M2, NQ, piv, W_COL)
            for i in range(NQ):
                w[W_WINV + i * NQ + c] = w[W_COL + i]
    converged = False
    mx = 0.0
    for _ in range(max_iter + 1):
        phi_(out, par, w)
        mx = max_abs_range(w, W_PHI, NC)
        if mx <= tol:
            converged = True
            break
        jac(out, par, w)
        if not _correction(w, mass_metric, W_PHI, piv):
            return PROJ_SINGULAR, mx
        for i in range(NQ):
            out[i] -= w[W_DQ + i]
        # at_round_off: the correction is down to the round-off of q
        if max_abs_range(w, W_DQ, NQ) <= 8 * EPS * max(1.0, max_abs_range(out, 0, NQ)):
            converged = True
            break
    if not converged:
        return PROJ_NO_CONVERGENCE, mx
    jac(out, par, w)
    for a in range(NC):
        v = 0.0
        for j in range(NQ):
            v += w[W_J + a * NQ + j] * out[NQ + j]
        w[W_PHI + a] = v  # Phi_q qd (Phi itself is no longer needed)
    if not _correction(w, mass_metric, W_PHI, piv):
        return PROJ_SINGULAR, mx
    for i in range(NQ):
        out[NQ + i] -= w[W_DQ + i]
    return OK, mx


# ---------------------------------------------------------------------------------------
# dense output
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def dense_eval(kind, tau, t_old, h, y_old, F, out):
    """The last step's interpolant at tau into out (kind: DOP853, RK4 (Hermite), 2 constant)."""
    n = y_old.size
    if kind == 2:
        for i in range(n):
            out[i] = y_old[i]
        return
    x = (tau - t_old) / h
    if kind == DOP853:
        # scipy's Dop853DenseOutput: nested products with x and 1 - x over F reversed
        for i in range(n):
            v = 0.0
            for p in range(DOP_POWER):
                v += F[DOP_POWER - 1 - p, i]
                if p % 2 == 0:
                    v *= x
                else:
                    v *= 1 - x
            out[i] = v + y_old[i]
    else:
        # cubic Hermite from F = [y_old, f_old, y_new, f_new]
        h00 = (1 + 2 * x) * (1 - x) ** 2
        h10 = x * (1 - x) ** 2
        h01 = x**2 * (3 - 2 * x)
        h11 = x**2 * (x - 1)
        for i in range(n):
            out[i] = h00 * F[0, i] + h10 * h * F[1, i] + h01 * F[2, i] + h11 * h * F[3, i]


@njit(cache=True, error_model="numpy")
def _g_at(j, tau, kind, t_old, h, y_old, F, par, pf, pi, w, ytmp):
    dense_eval(kind, tau, t_old, h, y_old, F, ytmp)
    loads_(ytmp, par, w)
    switching_from(ytmp, pf, pi, w)
    return w[W_G + j]


@njit(cache=True, error_model="numpy")
def brentq(j, xa, xb, kind, t_old, h, y_old, F, par, pf, pi, w, ytmp):
    """scipy's brentq (xtol = rtol = 4 eps, 100 iterations) on switching function j."""
    xtol = 4 * EPS
    rtol = 4 * EPS
    xpre, xcur = xa, xb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre = _g_at(j, xpre, kind, t_old, h, y_old, F, par, pf, pi, w, ytmp)
    fcur = _g_at(j, xcur, kind, t_old, h, y_old, F, par, pf, pi, w, ytmp)
    if fpre == 0:
        return xpre, True
    if fcur == 0:
        return xcur, True
    if (fpre < 0) == (fcur < 0):
        return xcur, False
    for _ in range(100):
        if fpre != 0 and fcur != 0 and ((fpre < 0) != (fcur < 0)):
            xblk = xpre
            fblk = fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre = xcur
            xcur = xblk
            xblk = xpre
            fpre = fcur
            fcur = fblk
            fblk = fpre
        delta = (xtol + rtol * abs(xcur)) / 2
        sbis = (xblk - xcur) / 2
        if fcur == 0 or abs(sbis) < delta:
            return xcur, True
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)  # interpolate
            else:  # extrapolate
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2 * abs(stry) < min(abs(spre), 3 * abs(sbis) - delta):
                spre = scur
                scur = stry
            else:
                spre = sbis
                scur = sbis
        else:
            spre = sbis
            scur = sbis
        xpre = xcur
        fpre = fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        fcur = _g_at(j, xcur, kind, t_old, h, y_old, F, par, pf, pi, w, ytmp)
    return xcur, True


# ---------------------------------------------------------------------------------------
# the integration loop
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _rms(x, scale):
    s = 0.0
    for i in range(x.size):
        v = x[i] / scale[i]
        s += v * v
    return math.sqrt(s) / x.size**0.5


@njit(cache=True, error_model="numpy")
def integrate(method, y0, t_out, par, pf, pi, iset, fset):
    """Integrate from t = 0, state y0 (n,), sampling at t_out (csim.solver.simulate.integrate).

    ``par``, ``pf``, ``pi``: the problem (module docstring);
    ``iset`` = [locate, event_samples, max_events, max_steps];
    ``fset`` = [t_end, rtol, atol, step, max_step, first_step (NaN: automatic), max_phi,
    min_step]. Returns (n_rec, ts, ys, modes, n_ev, ev_t, ev_switched, nfev, nsteps,
    status, info (2,)).
    """
    locate = iset[0] != 0
    n_interior = iset[1]
    max_events = iset[2]
    max_steps = iset[3]
    t_end, rtol, atol, fixed_h, max_step, first_step, max_phi, min_step_set = \
        fset[0], fset[1], fset[2], fset[3], fset[4], fset[5], fset[6], fset[7]
    projects = pi[0] == 3
    n = y0.size
    n_sw = pi[4]
    w = np.zeros(W_G + n_sw)
    piv = np.zeros(NK, np.int64)
    n_out = t_out.size
    ts = np.empty(n_out)
    ys = np.empty((n_out, n))
    modes = np.zeros((n_out, n_sw), np.bool_)
    cap = 16
    ev_t = np.empty(cap)
    ev_sw = np.zeros((cap, n_sw), np.bool_)
    n_ev = 0
    info = np.zeros(2)
    status = OK
    nfev = 0
    nsteps = 0
    n_rec = 0

    y = y0.copy()
    ytmp = np.empty(n)
    yp = np.empty(n)
    f = np.empty(n)
    f_new = np.empty(n)
    y_new = np.empty(n)
    y_old = np.empty(n)
    K = np.empty((DOP_NX, n))
    F = np.empty((DOP_POWER, n))
    Fh = np.empty((4, n))
    tolv = np.empty(n)
    scl = np.empty(n)
    mode = np.zeros(n_sw, np.bool_)
    # the mode the right-hand side uses: the located one, or a scratch it overwrites
    rmode = mode if locate else np.zeros(n_sw, np.bool_)
    mode_b = np.zeros(n_sw, np.bool_)
    roots = np.empty(n_sw)
    has_root = np.zeros(n_sw, np.bool_)
    t = 0.0

    # ---- start: project (projection), mode, first record ----
    if projects:
        code, mx = project(y, yp, par, pf, pi, w, piv)
        if code != OK:
            info[0] = mx
            info[1] = t
            return n_rec, ts, ys, modes, n_ev, ev_t, ev_sw, nfev, nsteps, code, info
        copy_to(yp, y)
    mode_at(y, par, pf, pi, w, mode)
    if projects:
        code, mx = project(y, yp, par, pf, pi, w, piv)
        if code != OK:
            info[0] = mx
            info[1] = t
            return n_rec, ts, ys, modes, n_ev, ev_t, ev_sw, nfev, nsteps, code, info
        copy_row(yp, ys, 0)
    else:
        copy_row(y, ys, 0)
    ts[0] = t
    for jj in range(n_sw):
        modes[0, jj] = mode[jj]
    n_rec = 1
    i_out = 1

    while t < t_end and status == OK:
        # ---- a new segment: start the integrator at (t, y) ----
        restarted = False
        ke = kinetic(y, par)
        scale_w = max(1.0, abs(ke))
        for i in range(n):
            tolv[i] = atol * scale_w if i >= 2 * NQ else atol
        nfev += 1
        status = feval(t, y, rmode, locate, par, pf, pi, w, piv, f, info)
        if status != OK:
            break
        h_abs = 0.0
        seg_start = t
        seg_steps = 0
        if method == DOP853:
            interval = abs(t_end - t)
            if first_step == first_step:  # given
                h_abs = min(first_step, interval)
            elif interval == 0.0:
                h_abs = 0.0
            else:  # scipy's select_initial_step
                for i in range(n):
                    scl[i] = tolv[i] + abs(y[i]) * rtol
                d0 = _rms(y, scl)
                d1 = _rms(f, scl)
                if d0 < 1e-5 or d1 < 1e-5:
                    h0 = 1e-6
                else:
                    h0 = 0.01 * d0 / d1
                h0 = min(h0, interval)
                for i in range(n):
                    ytmp[i] = y[i] + h0 * f[i]
                nfev += 1
                status = feval(t + h0, ytmp, rmode, locate, par, pf, pi, w, piv, f_new, info)
                if status != OK:
                    break
                for i in range(n):
                    yp[i] = f_new[i] - f[i]
                d2 = _rms(yp, scl) / h0
                if d1 <= 1e-15 and d2 <= 1e-15:
                    h1 = max(1e-6, h0 * 1e-3)
                else:
                    h1 = (0.01 / max(d1, d2)) ** (1 / 8)
                h_abs = min(100 * h0, h1, interval, max_step)
        running = True
        while running:
            # ---- one step of the integrator: t -> t_new, y -> y_new ----
            t_old = t
            dense_kind = method
            step_ok = True
            if t == t_end:
                dense_kind = 2  # scipy: an empty step to t_bound
                t_new = t_end
                for i in range(n):
                    y_new[i] = y[i]
                    f_new[i] = f[i]
                hstep = 0.0
            elif method == DOP853:
                min_step = 10 * spacing(t)
                if h_abs > max_step:
                    h_abs = max_step
                elif h_abs < min_step:
                    h_abs = min_step
                accepted = False
                rejected = False
                hstep = 0.0
                t_new = t
                while not accepted:
                    if h_abs < min_step:
                        step_ok = False
                        break
                    hstep = h_abs
                    t_new = t + hstep
                    if t_new - t_end > 0:
                        t_new = t_end
                    hstep = t_new - t
                    h_abs = abs(hstep)
                    # rk_step
                    for i in range(n):
                        K[0, i] = f[i]
                    for s in range(1, DOP_NS):
                        for i in range(n):
                            acc = 0.0
                            for jj in range(s):
                                acc += K[jj, i] * DOP_A[s, jj]
                            ytmp[i] = y[i] + acc * hstep
                        nfev += 1
                        status = feval(t + DOP_C[s] * hstep, ytmp, rmode, locate, par, pf, pi, w, piv, K[s], info)
                        if status != OK:
                            break
                    if status != OK:
                        break
                    for i in range(n):
                        acc = 0.0
                        for jj in range(DOP_NS):
                            acc += K[jj, i] * DOP_B[jj]
                        y_new[i] = y[i] + hstep * acc
                    nfev += 1
                    status = feval(t + hstep, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
                    if status != OK:
                        break
                    for i in range(n):
                        K[DOP_NS, i] = f_new[i]
                    # error norm (scipy DOP853._estimate_error_norm)
                    e5 = 0.0
                    e3 = 0.0
                    for i in range(n):
                        sc = tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol
                        a5 = 0.0
                        a3 = 0.0
                        for jj in range(DOP_NS + 1):
                            a5 += K[jj, i] * DOP_E5[jj]
                            a3 += K[jj, i] * DOP_E3[jj]
                        a5 /= sc
                        a3 /= sc
                        e5 += a5 * a5
                        e3 += a3 * a3
                    if e5 == 0 and e3 == 0:
                        err = 0.0
                    else:
                        err = abs(hstep) * e5 / math.sqrt((e5 + 0.01 * e3) * n)
                    if err < 1:
                        if err == 0:
                            factor = MAX_FACTOR
                        else:
                            factor = min(MAX_FACTOR, SAFETY * err ** (-1 / 8))
                        if rejected:
                            factor = min(1.0, factor)
                        h_abs *= factor
                        accepted = True
                    else:
                        h_abs *= max(MIN_FACTOR, SAFETY * err ** (-1 / 8))
                        rejected = True
                if status != OK:
                    break
            else:  # RK4 on the grid t_start + n h
                t_new = seg_start + (seg_steps + 1) * fixed_h
                if t_new >= t_end - 1e-9 * fixed_h:
                    t_new = t_end
                hstep = t_new - t
                if not hstep > 0:
                    step_ok = False
                else:
                    for i in range(n):
                        K[0, i] = f[i]
                    for s in range(1, 4):
                        c = 1.0 if s == 3 else 0.5
                        for i in range(n):
                            ytmp[i] = y[i] + (hstep if s == 3 else hstep / 2) * K[s - 1, i]
                        nfev += 1
                        status = feval(t + c * hstep, ytmp, rmode, locate, par, pf, pi, w, piv, K[s], info)
                        if status != OK:
                            break
                    if status != OK:
                        break
                    for i in range(n):
                        y_new[i] = y[i] + hstep / 6 * (K[0, i] + 2 * K[1, i] + 2 * K[2, i] + K[3, i])
                    nfev += 1
                    status = feval(t_new, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
                    if status != OK:
                        break
                    seg_steps += 1
            nsteps += 1
            if nsteps > max_steps:
                status = MAX_STEPS
                info[0] = t_new if step_ok else t
                break
            if not step_ok:
                status = STEP_TOO_SMALL if method == DOP853 else RK4_RESOLUTION
                info[0] = t
                break
            # the step is accepted
            for i in range(n):
                y_old[i] = y[i]
            t = t_new
            for i in range(n):
                y[i] = y_new[i]
            if t_new >= t_end:
                running = False
            # ---- divergence checks (simulate._check_step) ----
            if not all_finite(y):
                status = NONFINITE_STATE
                info[0] = t
                break
            phi_(y, par, w)
            mphi = max_abs_range(w, W_PHI, NC)
            if not mphi <= max_phi:
                status = MAX_PHI
                info[0] = mphi
                info[1] = t
                break
            if method == DOP853 and t != t_end and hstep < min_step_set:
                status = STEP_COLLAPSE
                info[0] = hstep
                info[1] = t
                break
            # ---- the dense output of the step, built on first use ----
            dense_ready = False
            dense_h = t - t_old
            if dense_kind == RK4:
                for i in range(n):
                    Fh[0, i] = y_old[i]
                    Fh[1, i] = f[i]
                    Fh[2, i] = y[i]
                    Fh[3, i] = f_new[i]
            # ---- event location (simulate._find_event, _locate) ----
            event = False
            t_stop = t
            if locate:
                for rep in range(n_interior + 1):
                    i_b = rep + 1
                    if i_b == n_interior + 1:
                        b = t
                    else:
                        b = t_old + (t - t_old) * i_b / (n_interior + 1)
                    if b == t:
                        for i in range(n):
                            ytmp[i] = y[i]
                    else:
                        status, spent = _ensure_dense(dense_ready, dense_kind, t_old, dense_h, y_old, y, f_new, rmode,
                                                      locate, par, pf, pi, w, piv, K, F, ytmp, info)
                        nfev += spent
                        if status != OK:
                            break
                        dense_ready = True
                        dense_eval(dense_kind, b, t_old, dense_h, y_old, F if dense_kind == DOP853 else Fh, ytmp)
                    mode_at(ytmp, par, pf, pi, w, mode_b)
                    found = False
                    for jj in range(n_sw):
                        if mode_b[jj] != mode[jj]:
                            found = True
                    if found:
                        status, spent = _ensure_dense(dense_ready, dense_kind, t_old, dense_h, y_old, y, f_new, rmode,
                                                      locate, par, pf, pi, w, piv, K, F, ytmp, info)
                        nfev += spent
                        if status != OK:
                            break
                        dense_ready = True
                        a = t_old if rep == 0 else t_old + (t - t_old) * rep / (n_interior + 1)
                        FF = F if dense_kind == DOP853 else Fh
                        t_event = np.inf
                        for jj in range(n_sw):
                            has_root[jj] = False
                            if mode_b[jj] != mode[jj]:
                                g_old = _g_at(jj, a, dense_kind, t_old, dense_h, y_old, FF, par, pf, pi, w, ytmp)
                                if (g_old > 0) == mode[jj]:
                                    root, ok = brentq(jj, a, b, dense_kind, t_old, dense_h, y_old, FF, par, pf, pi,
                                                      w, ytmp)
                                    if not ok:
                                        status = NO_SIGN_CHANGE
                                        info[0] = t
                                        break
                                else:
                                    root = a
                                roots[jj] = root
                                has_root[jj] = True
                                t_event = min(t_event, root)
                        if status != OK:
                            break
                        event = True
                        t_stop = t_event
                        break
                    if status != OK:
                        break
                if status != OK:
                    break
            FF = F if dense_kind == DOP853 else Fh
            # ---- sample the output times in (t_old, t_stop] ----
            while i_out < n_out and t_out[i_out] <= t_stop:
                if t_out[i_out] == t and t_stop == t:
                    for i in range(n):
                        ytmp[i] = y[i]
                else:
                    status, spent = _ensure_dense(dense_ready, dense_kind, t_old, dense_h, y_old, y, f_new, rmode,
                                                  locate, par, pf, pi, w, piv, K, F, ytmp, info)
                    nfev += spent
                    if status != OK:
                        break
                    dense_ready = True
                    dense_eval(dense_kind, t_out[i_out], t_old, dense_h, y_old, FF, ytmp)
                if projects:
                    code, mx = project(ytmp, yp, par, pf, pi, w, piv)
                    if code != OK:
                        status = code
                        info[0] = mx
                        info[1] = t_out[i_out]
                        break
                    copy_row(yp, ys, n_rec)
                else:
                    copy_row(ytmp, ys, n_rec)
                ts[n_rec] = t_out[i_out]
                for jj in range(n_sw):
                    modes[n_rec, jj] = mode[jj]
                n_rec += 1
                i_out += 1
            if status != OK:
                break
            if event:
                # restart from the event state with the switched conditions flipped
                if t_stop < t:
                    dense_eval(dense_kind, t_stop, t_old, dense_h, y_old, FF, ytmp)
                else:
                    for i in range(n):
                        ytmp[i] = y[i]
                if projects:
                    code, mx = project(ytmp, yp, par, pf, pi, w, piv)
                    if code != OK:
                        status = code
                        info[0] = mx
                        info[1] = t_stop
                        break
                    for i in range(n):
                        ytmp[i] = yp[i]
                for i in range(n):
                    y[i] = ytmp[i]
                t = t_stop
                tol_ev = 4 * EPS * max(1.0, abs(t_stop)) + 4 * EPS
                if n_ev == cap:  # grow the event arrays
                    cap *= 2
                    new_t = np.empty(cap)
                    new_sw = np.zeros((cap, n_sw), np.bool_)
                    for e in range(n_ev):
                        new_t[e] = ev_t[e]
                        for jj in range(n_sw):
                            new_sw[e, jj] = ev_sw[e, jj]
                    ev_t = new_t
                    ev_sw = new_sw
                ev_t[n_ev] = t
                for jj in range(n_sw):
                    if has_root[jj] and roots[jj] - t_stop <= tol_ev:
                        ev_sw[n_ev, jj] = True
                        mode[jj] = not mode[jj]
                n_ev += 1
                if n_ev > max_events:
                    status = MAX_EVENTS
                    info[0] = t
                    break
                restarted = True
                break
            # ---- after the step: project and hand the state back (swap) ----
            if projects:
                code, mx = project(y, yp, par, pf, pi, w, piv)
                if code != OK:
                    status = code
                    info[0] = mx
                    info[1] = t
                    break
                for i in range(n):
                    y[i] = yp[i]
                nfev += 1
                status = feval(t, y, rmode, locate, par, pf, pi, w, piv, f, info)
                if status != OK:
                    break
            else:
                for i in range(n):
                    f[i] = f_new[i]
        if not restarted:
            break
    return n_rec, ts, ys, modes, n_ev, ev_t, ev_sw, nfev, nsteps, status, info


@njit(cache=True, error_model="numpy")
def _ensure_dense(dense_ready, dense_kind, t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp,
                  info):
    """The step's dense output, built on its first use: (status, right-hand-side evaluations spent).

    DOP853 needs three extra stages (:func:`_dop_dense`); RK4's Hermite data is in place already.
    """
    if dense_ready or dense_kind != DOP853:
        return OK, 0
    return _dop_dense(t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info), 3


@njit(cache=True, error_model="numpy")
def _dop_dense(t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info):
    """scipy's DOP853._dense_output_impl: three extra stages, then the interpolant F (7, n)."""
    n = y_old.size
    for e in range(DOP_NX - DOP_NS - 1):
        s = DOP_NS + 1 + e
        for i in range(n):
            acc = 0.0
            for jj in range(s):
                acc += K[jj, i] * DOP_A_EXTRA[e, jj]
            ytmp[i] = y_old[i] + acc * h
        code = feval(t_old + DOP_C_EXTRA[e] * h, ytmp, mode, locate, par, pf, pi, w, piv, K[s], info)
        if code != OK:
            return code
    for i in range(n):
        dy = y[i] - y_old[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2 * dy - h * (f[i] + K[0, i])
        for r in range(DOP_POWER - 3):
            acc = 0.0
            for jj in range(DOP_NX):
                acc += DOP_D[r, jj] * K[jj, i]
            F[3 + r, i] = h * acc
    return OK


# ---------------------------------------------------------------------------------------
# entry points for the tests and the benchmark
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def rhs_entry(y, mode, par, pf, pi):
    """dy/dt and [qdd, lambda] at one state (mode held), for comparison with the Python path."""
    w = np.zeros(W_G + pi[4])
    piv = np.zeros(NK, np.int64)
    f = np.empty(y.size)
    code = rhs(y, mode.copy(), True, par, pf, pi, w, piv, f)
    return code, f, w[W_X:W_X + NK].copy()


@njit(cache=True, error_model="numpy")
def rhs_repeat(y, mode, par, pf, pi, n_eval):
    """n_eval evaluations of the right-hand side (a timing loop for the benchmark)."""
    w = np.zeros(W_G + pi[4])
    piv = np.zeros(NK, np.int64)
    f = np.empty(y.size)
    acc = 0.0
    for _ in range(n_eval):
        rhs(y, mode, True, par, pf, pi, w, piv, f)
        acc += f[NQ]
    return acc


@njit(cache=True, error_model="numpy")
def project_entry(y, par, pf, pi):
    w = np.zeros(W_G + pi[4])
    piv = np.zeros(NK, np.int64)
    out = np.empty(y.size)
    code, mx = project(y, out, par, pf, pi, w, piv)
    return code, mx, out
