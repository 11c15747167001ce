"""Compiled kernels: the step loops of DOP853, RK4, RK45, Tsit5, Vern7 and Radau with event location, over the shared
core.

One module for every mechanism, compiled once per installation: :mod:`csim.fast.module`
loads it (through a copy named by the hash of everything it depends on, so that numba's
on-disk cache is never stale; two copies, with and without the partitioned system of
``minimal``, see :data:`WITH_PARTITION`) and numba compiles it on first use, then loads the
machine code from its cache in every later process. Nothing about a mechanism is a compile-time
constant here: the sizes, the workspace offsets and the addresses of the mechanism's
model functions are entries of ``pi`` (:mod:`csim.fast.layout`), and the model functions
(C compiled by ``cc``, :mod:`csim.fast.ccodegen`, or numba cfuncs,
:mod:`csim.fast.codegen`) are called through their addresses (:func:`_call_model`).
A new mechanism costs only its own model functions.

The physics is not here: the KKT solve, gamma* of each method, the switching functions,
the load laws, the projection, the step checks, the minimal-coordinate method's solves on
the assembly branch and its partition (:mod:`csim.physics.branch`) and the status codes are
the functions of :mod:`csim.physics` and of the method files (:mod:`csim.solver.methods`),
the same ones the Python driver calls. What is here is what must be compiled: the step
loops, the ports of scipy's ``DOP853`` (step-size control, error estimate, dense output) and
``RungeKutta`` (for the 5(4) pairs RK45 and Tsit5 and Verner's 7(6) pair,
:mod:`csim.physics.tableaus`),
``Radau`` (with the difference Jacobian of ``num_jac``, capped as
:class:`csim.solver.dae.DifferenceJacobian` caps it) and ``brentq``, the cubic Hermite
dense output of :class:`csim.solver.rk4.RK4`, and the glue: the model evaluated into the
workspace, the core's model handle (the tuple ``(par, pi, w, ym)``, for which the functions
of :mod:`csim.physics.model` are overloaded here), and the partitioned system's state
y = [u, ud, W] turned into the full state where the loop needs it (:func:`full_state`).

The problem is passed as three flat arrays, ``par`` (the parameters), ``pf`` and ``pi``
(:func:`csim.fast.runner.pack_problem`), because numba counts a reference to every array
argument at every call of a function it does not inline: few arguments keep the
evaluation as fast as plain C. ``pi`` starts with a header (:mod:`csim.fast.layout`: the
method's code and settings' offsets, the sizes, the function addresses, the workspace
offsets), then the switching functions' loads and kinds (:mod:`csim.physics.loads`) and
the method's integer settings; ``pf`` holds the load magnitudes, the switching bounds, the
method's float settings and its gains (:meth:`csim.solver.methods.base.Method.pack`). The
workspace w holds the model terms, then the scratch of the right-hand side and of the
projection; matrices are flat and row-major, and the core functions get 1-D slices of w
(a slice costs nothing, a 2-D view a reshape).
"""
import importlib.util
import math
import os

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic, overload

from csim.fast.layout import (
    EXTERNAL,
    F_JAC,
    F_KINETIC,
    F_LOADS,
    F_MASS,
    F_OBSERVE,
    F_PHI,
    F_POTENTIAL,
    F_TERMS,
    PARTITIONED,
    PI_DRV,
    PI_FN,
    PI_FPAR,
    PI_GAINS,
    PI_GAMMA_FN,
    PI_HEAD,
    PI_IPAR,
    PI_MK,
    PI_NC,
    PI_ND,
    PI_NFPAR,
    PI_NGAINS,
    PI_NIPAR,
    PI_NL,
    PI_NO,
    PI_NQ,
    PI_NSW,
    PI_SYS,
    W_A,
    W_B,
    W_COL,
    W_CQD,
    W_DQ,
    W_E,
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
from csim.physics.events import check_chatter
from csim.physics.jit import NJIT_OPTIONS, activate
from csim.physics.kkt import constraint_rates, generalized_forces, kkt_solve
from csim.physics.linalg import lu_factor, lu_solve
from csim.physics.loads import load_rates, load_values, mode_of, switching_functions
from csim.physics.model import model_gamma, model_jacobian, model_mass, model_phi
from csim.physics.partition import C_PENDING, D_HEAD, partition_sizes, partition_state
from csim.physics.projection import max_abs
from csim.physics.projection import project as project_state
from csim.physics.radau import (
    JAC_MAX_FACTOR,
    MU_COMPLEX,
    MU_REAL,
    NEWTON_MAXITER,
    NUM_JAC_DIFF_BIG,
    NUM_JAC_DIFF_REJECT,
    NUM_JAC_DIFF_SMALL,
    NUM_JAC_FACTOR_DECREASE,
    NUM_JAC_FACTOR_INCREASE,
    NUM_JAC_MIN_FACTOR,
)
from csim.physics.radau import TI as _RADAU_TI
from csim.physics.radau import TI_COMPLEX as _RADAU_TI_COMPLEX
from csim.physics.radau import C as _RADAU_C
from csim.physics.radau import E as _RADAU_E
from csim.physics.radau import P as _RADAU_P
from csim.physics.radau import T as _RADAU_T
from csim.physics.status import (
    INTERRUPTED,
    MAX_EVENTS,
    MAX_STEPS,
    NO_SIGN_CHANGE,
    NONFINITE_RHS,
    OK,
    RK4_RESOLUTION,
    SINGULAR_KKT,
    STEP_TOO_SMALL,
)
from csim.physics.steps import all_finite, check_step
from csim.physics.tableaus import (
    ERROR_ESTIMATOR_ORDER,
    RK45_A,
    RK45_B,
    RK45_C,
    RK45_E,
    RK45_P,
    TSIT5_A,
    TSIT5_B,
    TSIT5_C,
    TSIT5_E,
    TSIT5_P,
    VERN7_A,
    VERN7_A_EXTRA,
    VERN7_B,
    VERN7_C,
    VERN7_C_EXTRA,
    VERN7_E,
    VERN7_ERROR_ESTIMATOR_ORDER,
    VERN7_P,
)
from csim.solver.methods.baumgarte import baumgarte_gamma_star
from csim.solver.methods.sliding_mode import sliding_mode_gamma_star

activate()  # the core functions compile, and numba types them, from here on

#: whether this copy of the kernels carries the partitioned system (minimal coordinates, the
#: branches ``if WITH_PARTITION and ...``). :mod:`csim.fast.module` loads two copies: this
#: source for ``minimal``, and one written with False for every other method, in which numba
#: prunes those branches before typing them, so that it neither compiles the partitioned
#: path (two thirds of the compile time) nor pays for it at run time
WITH_PARTITION = True

#: the decorator of every loop function that allocates nothing: compiled without numba's
#: reference counting of arrays (NRT), which would cost two atomic operations per array
#: argument and per slice at every call; the arrays live as long as ``integrate`` holds them
hot = njit(**NJIT_OPTIONS)
#: the same, inlined into its callers in numba's IR: a call passes every array argument as a
#: struct of seven words, which for the small functions of every step costs more than their body
inlined = njit(inline="always", **NJIT_OPTIONS)
#: inlined, for functions whose callers pass their sizes as constants (the copy's loops have fixed lengths)
sized = inlined
#: the (m, r) whose right-hand side has a copy with constant sizes: the planar one-loop linkages
#: (quick-return, four-bar, slider-crank) and the Cartesian pendulum
SIZED = ((3, 2), (2, 1))


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

# ---- the loop's constants (status codes are csim.physics.status's) ----
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

# Radau IIA coefficients, scipy's (csim.physics.radau)
RAD_C = np.ascontiguousarray(_RADAU_C)
RAD_E = np.ascontiguousarray(_RADAU_E)
RAD_T = np.ascontiguousarray(_RADAU_T)
RAD_TI = np.ascontiguousarray(_RADAU_TI)
RAD_TI_COMPLEX = np.ascontiguousarray(_RADAU_TI_COMPLEX)
RAD_P = np.ascontiguousarray(_RADAU_P)

# the 5(4) pairs, stacked (index 0: RK45, 1: Tsit5), A and B padded to ERK_NS stages
ERK_NS = 6
ERK_A = np.ascontiguousarray(np.stack([np.pad(a, ((0, 0), (0, ERK_NS - a.shape[1]))) for a in (RK45_A, TSIT5_A)]))
ERK_B = np.ascontiguousarray(np.stack((RK45_B, TSIT5_B)))
ERK_C = np.ascontiguousarray(np.stack((RK45_C, TSIT5_C)))
ERK_E = np.ascontiguousarray(np.stack((RK45_E, TSIT5_E)))
ERK_P = np.ascontiguousarray(np.stack((RK45_P, TSIT5_P)))
# Verner's 7(6) pair: ten stages, the new point, five extra stages for its interpolant
V7_NS = VERN7_C.size
V7_A = np.ascontiguousarray(VERN7_A)
V7_B = np.ascontiguousarray(VERN7_B)
V7_C = np.ascontiguousarray(VERN7_C)
V7_E = np.ascontiguousarray(VERN7_E)
V7_A_EXTRA = np.ascontiguousarray(VERN7_A_EXTRA)
V7_C_EXTRA = np.ascontiguousarray(VERN7_C_EXTRA)
V7_P = np.ascontiguousarray(VERN7_P)

# integrators (csim.fast.runner.INTEGRATOR_CODES), and the dense output of an empty step
DOP853 = 0
RK4 = 1
CONSTANT = 2
RADAU = 3
RK45 = 4
TSIT5 = 5
VERN7 = 6

# scalars of the loop, in one float array ts_ and one int array cs_ (R_*: Radau's)
T, T_OLD, H_ABS, HSTEP, T_STOP, SEG_START, R_H_OLD, R_ERR_OLD, R_NEWTON_TOL, R_SOL_T, R_SOL_H = range(11)
NFEV, NSTEPS, N_REC, I_OUT, N_EV, SEG_STEPS, NJEV, NLU, R_LU_OK, R_SOL, R_CURRENT_JAC = range(11)
# Radau's rows of RM (3 rows: the three stages): Newton's start Z0, the stage increments Z,
# W = T^-1 Z, its Newton increment dW, the stage derivatives F; the error scale, the error,
# E^T Z / h, a trial state, two difference columns, the difference step factors
R_Z0, R_Z, R_W, R_DW, R_F = 0, 3, 6, 9, 12
R_SCALE, R_ERR, R_ZE, R_YT, R_FC, R_FC2, R_FACTOR, R_ROWS = range(15, 23)


@hot
def spacing(t):
    """|nextafter(t, +inf) - t| for t >= 0 (numpy's nextafter without its overload)."""
    if t == 0.0:
        return 5e-324
    _, e = math.frexp(t)  # t = m 2^e, 0.5 <= m < 1
    return 2.0 ** (e - 53)


@hot
def copy_row(src, dst, row):
    for i in range(src.size):
        dst[row, i] = src[i]


# ---------------------------------------------------------------------------------------
# calls through a function's address (a C function, or a numba cfunc)
# ---------------------------------------------------------------------------------------
def _lower_call(context, builder, argtys, args):
    """Call the C function at the address args[0] with args[1:]: arrays as pointers to their
    data (no reference counting), integers and floats by value. Returns nothing."""
    llargs, lltys = [], []
    for ty, value in zip(argtys[1:], args[1:]):
        if isinstance(ty, types.Array):
            llargs.append(context.make_array(ty)(context, builder, value).data)
            lltys.append(context.get_data_type(ty.dtype).as_pointer())
        else:
            llargs.append(value)
            lltys.append(context.get_value_type(ty))
    fnty = ir.FunctionType(ir.VoidType(), lltys)
    builder.call(builder.inttoptr(args[0], fnty.as_pointer()), llargs)
    return context.get_dummy_value()


@intrinsic
def _call_model(typingctx, addr, t, y, par, out):
    """``void f(double t, const double *y, const double *par, double *out)`` at address ``addr``."""
    if not (isinstance(addr, types.Integer) and isinstance(t, types.Float)):
        return None
    sig = types.void(addr, t, y, par, out)

    def codegen(context, builder, signature, args):
        return _lower_call(context, builder, signature.args, args)
    return sig, codegen


@intrinsic
def _call_gamma(typingctx, addr, r, gamma, phi, phi_dot, gains, n_gains, fpar, n_fpar, ipar, n_ipar, out):
    """``void g(int64 r, const double *gamma, const double *phi, const double *phi_dot, const double *gains,
    int64 n_gains, const double *fpar, int64 n_fpar, const int64 *ipar, int64 n_ipar, double *out)``."""
    sig = types.void(addr, r, gamma, phi, phi_dot, gains, n_gains, fpar, n_fpar, ipar, n_ipar, out)

    def codegen(context, builder, signature, args):
        return _lower_call(context, builder, signature.args, args)
    return sig, codegen


# the model functions of the mechanism in pi (csim.fast.layout: one C interface for all)
@hot
def terms(t, y, par, pi, w):
    """Every term of the right-hand side at (t, y) into w."""
    _call_model(pi[PI_FN + F_TERMS], t, y, par, w)


@hot
def phi_(y, par, pi, w):
    _call_model(pi[PI_FN + F_PHI], 0.0, y, par, w)


@hot
def phi_at(t, y, par, pi, w):
    """Phi at time t (drive rows depend on it)."""
    _call_model(pi[PI_FN + F_PHI], t, y, par, w)


@hot
def jac(y, par, pi, w):
    _call_model(pi[PI_FN + F_JAC], 0.0, y, par, w)


@hot
def mass(y, par, pi, w):
    _call_model(pi[PI_FN + F_MASS], 0.0, y, par, w)


@hot
def loads_(y, par, pi, w):
    """Load coordinates s and their Jacobian into w, for the switching functions."""
    _call_model(pi[PI_FN + F_LOADS], 0.0, y, par, w)


@hot
def kinetic(y, par, pi, w):
    """Kinetic energy [J] (w[W_E] is its scratch)."""
    _call_model(pi[PI_FN + F_KINETIC], 0.0, y, par, w[pi[W_E]:])
    return w[pi[W_E]]


@hot
def potential(y, par, pi, w):
    """Potential energy [J] (w[W_E] is its scratch)."""
    _call_model(pi[PI_FN + F_POTENTIAL], 0.0, y, par, w[pi[W_E]:])
    return w[pi[W_E]]


@hot
def observe(y, par, pi, out):
    """The observables and their rates into out (2 o,)."""
    _call_model(pi[PI_FN + F_OBSERVE], 0.0, y, par, out)


# ---------------------------------------------------------------------------------------
# the core's model handle (csim.physics.model) in the kernels: the tuple (par, pi, w, ym),
# ym a state [q, qd, W] to call the model functions at
# ---------------------------------------------------------------------------------------
#: the compile options of the overloads (as the kernels', less the cache: they compile into their callers)
CALL_OPTIONS = dict(error_model="numpy", _nrt=False)


# (A process that runs minimal and another method imports both copies of this module, and each
# registers these overloads; numba takes the first one registered. They are the same source.)
def _is_handle(model):
    return isinstance(model, types.BaseTuple)


def _overload_at_q(core_fn, model_fn, slot):
    """Overload ``core_fn(model, q, out)`` for the kernels' handle: ``model_fn`` at q, then out = its term,
    read from w at the offset pi[slot]."""

    @overload(core_fn, jit_options=CALL_OPTIONS, strict=False, inline="always")
    def _typer(model, q, out):
        if not _is_handle(model):
            return None

        def impl(model, q, out):
            par, pi, w, ym = model
            for i in range(q.size):
                ym[i] = q[i]
            model_fn(ym, par, pi, w)
            for i in range(out.size):
                out[i] = w[pi[slot] + i]
        return impl
    return _typer


_overload_at_q(model_phi, phi_, W_PHI)
_overload_at_q(model_jacobian, jac, W_J)
_overload_at_q(model_mass, mass, W_M)


@overload(model_gamma, jit_options=CALL_OPTIONS, strict=False, inline="always")
def _model_gamma(model, q, qd, out):
    if _is_handle(model):
        def impl(model, q, qd, out):
            par, pi, w, ym = model
            m = q.size
            for i in range(m):
                ym[i] = q[i]
                ym[m + i] = qd[i]
            terms(0.0, ym, par, pi, w)
            for i in range(out.size):
                out[i] = w[pi[W_GAM] + i]
        return impl
    return None


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
    """
    P = _partition(pi, w, piv)
    fpar, ipar = pf[pi[PI_FPAR]:], pi[pi[PI_IPAR]:]
    return (par, pi, w, P.ym), P, pi[PI_NC], pi[PI_NQ], pi[PI_NL], fpar[0], ipar[0], fpar[1]


# The partitioned system's branches in the functions of every step call a function of their own:
# numba zeroes all of a function's variables at each call, and the partition's views (a tuple of
# 39 arrays) would cost every caller a memset of kilobytes even where it is not partitioned.
@inlined
def full_state(y, par, pf, pi, w, piv):
    """(code, the full state [q, qd, W] of the integrated state y): y itself, or for the partitioned
    system its dependent coordinates solved on the branch (csim.physics.branch.to_full), in P.yf."""
    if WITH_PARTITION and pi[PI_SYS] == PARTITIONED:
        return _partitioned_full_state(y, par, pf, pi, w, piv)
    return OK, y


@hot
def _partitioned_full_state(y, par, pf, pi, w, piv):
    """:func:`full_state` of the partitioned system."""
    model, P, r, m, k, tol, max_iter, _ = _partition_call(par, pf, pi, w, piv)
    return branch.to_full(model, P, y, P.yf, r, m, k, tol, max_iter), P.yf


@hot
def _partitioned_rhs(t, y, mode, located, par, pf, pi, w, piv, f):
    """dy/dt = [ud, udd, dW/dt] (2 n + k,) of the partitioned system: the rhs at the full state, reduced."""
    code, yf = full_state(y, par, pf, pi, w, piv)
    if code != OK:
        return code
    P = _partition(pi, w, piv)
    code = rhs(t, yf, mode, located, par, pf, pi, w, piv, P.ff)
    if code == OK:
        branch.reduce(P, P.ff, f, pi[PI_NC], pi[PI_NQ], pi[PI_NL])
    return code


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
    if WITH_PARTITION and pi[PI_SYS] == PARTITIONED:
        return _set_pending(pi, w, piv, OK)
    return OK


@hot
def _set_pending(pi, w, piv, code):
    """Set the partitioned system's pending breakdown to ``code``; returns the one it replaces."""
    P = _partition(pi, w, piv)
    before = P.count[C_PENDING]
    P.count[C_PENDING] = code
    return before


# the stabilization methods' gamma*: the built-in ones by code (csim.fast.layout.BUILTIN_GAMMA),
# any other through its address (EXTERNAL)


@hot
def method_gamma_star(mk, r, gamma, phi, phi_dot, gains, fpar, ipar, out, pi):
    """gamma* (r,) into out by the method's code; 0 is gamma* = gamma."""
    if mk == 1:
        baumgarte_gamma_star(r, gamma, phi, phi_dot, gains, fpar, ipar, out)
    elif mk == 2:
        sliding_mode_gamma_star(r, gamma, phi, phi_dot, gains, fpar, ipar, out)
    elif mk == EXTERNAL:
        _call_gamma(pi[PI_GAMMA_FN], r, gamma, phi, phi_dot, gains, gains.size, fpar, fpar.size, ipar, ipar.size, out)
    else:
        for i in range(r):
            out[i] = gamma[i]


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
def _rhs_sized(t, y, mode, located, par, pf, pi, w, piv, f, nq, nc):
    """:func:`rhs` for nq coordinates and nc constraints (inlined where called: constants there fix the loops)."""
    nl = pi[PI_NL]
    nk = nq + nc
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
    gstar = w[pi[W_GS]:pi[W_GS] + nc]
    gains = pf[pi[PI_GAINS]:pi[PI_GAINS] + pi[PI_NGAINS]]
    fpar = pf[pi[PI_FPAR]:pi[PI_FPAR] + pi[PI_NFPAR]]
    ipar = pi[pi[PI_IPAR]:pi[PI_IPAR] + pi[PI_NIPAR]]
    method_gamma_star(pi[PI_MK], nc, w[pi[W_GAM]:pi[W_GAM] + nc], w[pi[W_PHI]:pi[W_PHI] + nc], phi_dot, gains, fpar,
                      ipar, gstar, pi)
    x = w[pi[W_X]:pi[W_X] + nk]
    A = w[pi[W_A]:pi[W_A] + nk * nk]
    if not kkt_solve(w[pi[W_M]:pi[W_M] + nq * nq], J, p, gstar, A, x, piv, nq, nc):
        return SINGULAR_KKT
    sdot = w[pi[W_SD]:pi[W_SD] + nl]
    load_rates(B, qd, sdot, nq, nl)
    for i in range(nq):
        f[i] = qd[i]
        f[nq + i] = x[i]
    for kk in range(nl):  # dW/dt = u * (B^T qd), the power of each load
        f[2 * nq + kk] = u[kk] * sdot[kk]
    nd = pi[PI_ND]
    for kk in range(nd):  # dW_d/dt = tau qd_j, tau = -lambda_d: the power of each drive (csim.solver.driven)
        f[2 * nq + nl + kk] = -x[nq + nc - nd + kk] * qd[pi[pi[PI_DRV] + kk]]
    return OK


@hot
def rhs(t, y, mode, located, par, pf, pi, w, piv, f):
    """dy/dt = [qd, qdd, u * B^T qd] at time t into f; [qdd, lambda] left in w[W_X:]. Returns OK or SINGULAR_KKT.

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


# (not inlined by numba: LLVM inlines it where it pays; numba's inlining changed the register
# allocation of rhs itself and made the RK4 row 15 % slower than before minimal was compiled, measured alternately)
@hot
def feval(t, y, mode, located, par, pf, pi, w, piv, f, info):
    """rhs plus the driver's check of a non-finite result (info = [t, max |y|] then)."""
    if WITH_PARTITION and pi[PI_SYS] == PARTITIONED:
        code = _partitioned_rhs(t, y, mode, located, par, pf, pi, w, piv, f)
    else:
        code = rhs(t, y, mode, located, par, pf, pi, w, piv, f)
    if code == OK and not all_finite(f):
        code = NONFINITE_RHS
    if code != OK:
        info[0] = t
        info[1] = max_abs(y)
    return code


# ---------------------------------------------------------------------------------------
# projection onto Phi = 0, Phi_q qd = 0 (csim.solver.methods.projection)
# ---------------------------------------------------------------------------------------
@hot
def project(y, out, t, par, pf, pi, w, piv, info):
    """out = y at time t with (q, qd) projected (csim.physics.projection.project); returns the status code.

    On a failure info = [max |Phi| of the last iterate, t], as the status messages read them.
    The method's settings: fpar[0] the tolerance on max |Phi|, ipar = [mass metric (0/1),
    iteration limit].
    """
    fpar = pf[pi[PI_FPAR]:pi[PI_FPAR] + pi[PI_NFPAR]]
    ipar = pi[pi[PI_IPAR]:pi[PI_IPAR] + pi[PI_NIPAR]]
    for i in range(y.size):
        out[i] = y[i]
    nq, nc, nl = pi[PI_NQ], pi[PI_NC], pi[PI_NL]
    model = (par, pi, w, w[pi[W_YM]:pi[W_YM] + 2 * nq + nl])
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


# ---------------------------------------------------------------------------------------
# dense output and the zeros of the switching functions on it
# ---------------------------------------------------------------------------------------
@hot
def _dense_weights(M, P, F):
    """Q^T = (M^T P)^T into F[:P.shape[1]]: the power-basis weights of a step's dense output from
    its stages M (s, n) (Radau's Z, an explicit pair's K) and the method's P (s, powers)."""
    for i in range(M.shape[1]):
        for p in range(P.shape[1]):
            acc = 0.0
            for a in range(P.shape[0]):
                acc += M[a, i] * P[a, p]
            F[p, i] = acc


@hot
def dense_eval(kind, tau, t_old, h, y_old, F, out):
    """The last step's interpolant at tau into out (kind: DOP853, RK4 (Hermite), RADAU, RK45, TSIT5, VERN7 or
    CONSTANT)."""
    n = y_old.size
    if kind == CONSTANT:
        for i in range(n):
            out[i] = y_old[i]
        return
    x = (tau - t_old) / h
    if kind == RADAU:  # scipy's RadauDenseOutput: y_old + Q (x, x^2, x^3), Q^T in F[:3]
        for i in range(n):
            out[i] = F[0, i] * x + F[1, i] * (x * x) + F[2, i] * (x * x * x) + y_old[i]
        return
    if kind in (RK45, TSIT5):  # scipy's RkDenseOutput: y_old + h Q (x, x^2, x^3, x^4), Q^T in F[:4]
        x2 = x * x
        x3 = x2 * x
        for i in range(n):
            out[i] = h * (F[0, i] * x + F[1, i] * x2 + F[2, i] * x3 + F[3, i] * (x3 * x)) + y_old[i]
        return
    if kind == VERN7:  # scipy's RkDenseOutput: y_old + h Q (x, ..., x^7), Q^T in F[:7], by Horner
        for i in range(n):
            v = 0.0
            for p in range(VERN7_P.shape[1] - 1, -1, -1):
                v = (v + F[p, i]) * x
            out[i] = h * v + y_old[i]
        return
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


@hot
def _g_at(j, tau, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp):
    """Switching function j on the dense output at tau (NaN, and the code pending, where the full state fails)."""
    dense_eval(kind, tau, t_old, h, y_old, F, ytmp)
    code, yv = full_state(ytmp, par, pf, pi, w, piv)
    if WITH_PARTITION and code != OK:  # (only the partitioned system's full state can fail)
        _set_pending(pi, w, piv, code)
        return np.nan
    loads_(yv, par, pi, w)
    switching_from(yv, pf, pi, w)
    return w[pi[W_G] + j]


@hot
def brentq(j, xa, xb, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp):
    """scipy's brentq (xtol = rtol = 4 eps, 100 iterations) on switching function j: (root, ok)."""
    xtol = 4 * EPS
    rtol = 4 * EPS
    xpre, xcur = xa, xb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre = _g_at(j, xpre, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp)
    fcur = _g_at(j, xcur, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp)
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
        fcur = _g_at(j, xcur, kind, t_old, h, y_old, F, par, pf, pi, w, piv, ytmp)
    return xcur, True


# ---------------------------------------------------------------------------------------
# one step of each integrator
# ---------------------------------------------------------------------------------------
@hot
def _rms(x, scale):
    s = 0.0
    for i in range(x.size):
        v = x[i] / scale[i]
        s += v * v
    return math.sqrt(s) / x.size**0.5


@hot
def _initial_step(t, y, f, t_end, rtol, tolv, max_step, first_step, par, pf, pi, rmode, locate, w, piv, ytmp, f1, scl,
                  cs, info, order):
    """The first step of DOP853 (error estimator ``order`` 7) or Radau (3): given, or scipy's
    select_initial_step (one evaluation). Returns (status, h)."""
    n = y.size
    interval = abs(t_end - t)
    if first_step == first_step:  # given (NaN: automatic)
        return OK, min(first_step, interval)
    if interval == 0.0:
        return OK, 0.0
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
    cs[NFEV] += 1
    status = feval(t + h0, ytmp, rmode, locate, par, pf, pi, w, piv, f1, info)
    if status != OK:
        return status, 0.0
    for i in range(n):
        f1[i] = f1[i] - f[i]
    d2 = _rms(f1, scl) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1 / (order + 1))
    return OK, min(100 * h0, h1, interval, max_step)


@hot
def _dop853_error(K, y, y_new, tolv, rtol, hstep):
    """scipy DOP853._estimate_error_norm: the scaled error norm of the step."""
    n = y.size
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
        return 0.0
    return abs(hstep) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@sized
def _rk_stages(A, B, C, ns, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode, locate, w, piv, cs, info):
    """scipy's rk_step with the tableau (A, B, C) of ns stages (DOP853's, or a 5(4) pair's): the
    stages, y_new and f_new = f(t + h, y_new) into K[ns]. Returns the status. (Inlined where
    called: DOP853's tables and stage count stay constants of its loop.)"""
    n = y.size
    for i in range(n):
        K[0, i] = f[i]
    for s in range(1, ns):
        for i in range(n):  # dy = (K[:s]^T a[:s]) h
            acc = 0.0
            for jj in range(s):
                acc += K[jj, i] * A[s, jj]
            ytmp[i] = y[i] + acc * hstep
        cs[NFEV] += 1
        status = feval(t + C[s] * hstep, ytmp, rmode, locate, par, pf, pi, w, piv, K[s], info)
        if status != OK:
            return status
    for i in range(n):  # y_new = y + h K[:s]^T B
        acc = 0.0
        for jj in range(ns):
            acc += K[jj, i] * B[jj]
        y_new[i] = y[i] + hstep * acc
    cs[NFEV] += 1
    status = feval(t + hstep, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
    if status != OK:
        return status
    for i in range(n):
        K[ns, i] = f_new[i]
    return OK


@inlined
def _error_order(method):
    """The order of an adaptive integrator's error estimator (scipy's ``error_estimator_order``):
    DOP853 7, Vern7 6, the 5(4) pairs 4, Radau 3. It sets the first step and the step factor
    err^(-1 / (order + 1))."""
    if method == DOP853:
        return 7
    if method == VERN7:
        return VERN7_ERROR_ESTIMATOR_ORDER
    if method == RADAU:
        return 3
    return ERROR_ESTIMATOR_ORDER


@hot
def _explicit_step(method, ts_, t_end, rtol, tolv, max_step, y, f, K, F, ytmp, y_new, f_new, par, pf, pi, rmode, locate,
                   w, piv, cs, info):
    """One accepted step of DOP853, RK45, Tsit5 or Vern7 from ts_[T] (scipy's RungeKutta._step_impl,
    the error estimate each one's). Returns (status, t_new, step_ok).

    ts_[H_ABS] carries the step size over; ts_[HSTEP] gets the accepted step. The 5(4) pairs'
    dense output Q = K^T P goes to F[:4] (DOP853's and Vern7's, which need extra stages, are
    built when first needed: _ensure_dense).
    """
    k = method - RK45  # a 5(4) pair's row of the ERK_* tables
    exponent = -1 / (_error_order(method) + 1)
    t = ts_[T]
    min_step = 10 * spacing(t)
    h_abs = ts_[H_ABS]
    if h_abs > max_step:
        h_abs = max_step
    elif h_abs < min_step:
        h_abs = min_step
    rejected = False
    while True:
        if h_abs < min_step:
            ts_[H_ABS] = h_abs
            return OK, t, False
        t_new = t + h_abs
        if t_new - t_end > 0:
            t_new = t_end
        hstep = t_new - t
        h_abs = abs(hstep)
        if method == DOP853:
            status = _rk_stages(DOP_A, DOP_B, DOP_C, DOP_NS, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode,
                                locate, w, piv, cs, info)
        elif method == VERN7:
            status = _rk_stages(V7_A, V7_B, V7_C, V7_NS, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode,
                                locate, w, piv, cs, info)
        else:
            status = _rk_stages(ERK_A[k], ERK_B[k], ERK_C[k], ERK_NS, t, hstep, y, f, K, ytmp, y_new, f_new, par, pf,
                                pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        if method == DOP853:
            err = _dop853_error(K, y, y_new, tolv, rtol, hstep)
        elif method == VERN7:
            err = _erk_error(V7_E, K, y, y_new, tolv, rtol, hstep)
        else:
            err = _erk_error(ERK_E[k], K, y, y_new, tolv, rtol, hstep)
        if err < 1:
            factor = MAX_FACTOR if err == 0 else min(MAX_FACTOR, SAFETY * err ** exponent)
            if rejected:
                factor = min(1.0, factor)
            ts_[H_ABS] = h_abs * factor
            ts_[HSTEP] = hstep
            if method in (RK45, TSIT5):
                _dense_weights(K[:ERK_NS + 1], ERK_P[k], F)
            return OK, t_new, True
        h_abs *= max(MIN_FACTOR, SAFETY * err ** exponent)
        rejected = True


@hot
def _rk4_step(ts_, t_end, fixed_h, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode, locate, w, piv, cs, info):
    """One classic RK4 step on the grid seg_start + n h (csim.solver.rk4.RK4). Returns (status, t_new, step_ok)."""
    n = y.size
    t = ts_[T]
    t_new = ts_[SEG_START] + (cs[SEG_STEPS] + 1) * fixed_h
    if t_new >= t_end - 1e-9 * fixed_h:
        t_new = t_end
    hstep = t_new - t
    if not hstep > 0:
        return OK, t, False
    for i in range(n):
        K[0, i] = f[i]
    for s in range(1, 4):
        c = 1.0 if s == 3 else 0.5
        for i in range(n):
            ytmp[i] = y[i] + (hstep if s == 3 else hstep / 2) * K[s - 1, i]
        cs[NFEV] += 1
        status = feval(t + c * hstep, ytmp, rmode, locate, par, pf, pi, w, piv, K[s], info)
        if status != OK:
            return status, t, True
    for i in range(n):
        y_new[i] = y[i] + hstep / 6 * (K[0, i] + 2 * K[1, i] + 2 * K[2, i] + K[3, i])
    cs[NFEV] += 1
    status = feval(t_new, y_new, rmode, locate, par, pf, pi, w, piv,
                   f_new, info)
    if status != OK:
        return status, t, True
    cs[SEG_STEPS] += 1
    ts_[HSTEP] = hstep
    return OK, t_new, True


# ---------------------------------------------------------------------------------------
# Radau IIA of order 5: scipy's Radau (step, Newton iteration, error estimate, step-size
# control, dense output) with csim's capped forward-difference Jacobian
# (csim.solver.dae.DifferenceJacobian: scipy's num_jac)
# ---------------------------------------------------------------------------------------
@hot
def _radau_rms(M, row0, rows, scale):
    """scipy's norm(M[row0:row0 + rows] / scale): the root mean square over all rows x n entries."""
    n = scale.size
    s = 0.0
    for a in range(rows):
        for i in range(n):
            v = M[row0 + a, i] / scale[i]
            s += v * v
    return math.sqrt(s / (rows * n))


@hot
def _radau_column(t, yt, j, value, f, fc, par, pf, pi, rmode, locate, w, piv, cs, info):
    """One difference column: fc = F(t, yt) with yt[j] = value, then num_jac's (max_diff, scale):
    the largest |fc - f| and max(|f|, |fc|) where it is. Returns (status, max_diff, scale); a
    non-finite column is no failure (status OK)."""
    yt[j] = value
    cs[NFEV] += 1
    status = feval(t, yt, rmode, locate, par, pf, pi, w, piv, fc, info)
    if status == NONFINITE_RHS:
        status = OK
    best, at = -1.0, 0
    for i in range(f.size):
        v = abs(fc[i] - f[i])
        if v > best:
            best, at = v, i
    return status, best, max(abs(f[at]), abs(fc[at]))


@hot
def _radau_jacobian(t, y, f, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info):
    """J = df/dy (RJ, n * n row-major) by scipy's num_jac, column by column, its step factors
    (RM[R_FACTOR]) capped at JAC_MAX_FACTOR as csim.solver.dae.DifferenceJacobian does. Returns the status.

    Each column's step h_j = (y_j + factor_j y_scale_j) - y_j, y_scale_j = sign(f_j) max(atol_j, |y_j|);
    where the largest difference is below EPS^0.875 of the values, a ten times larger step is
    tried and kept if its difference is relatively larger; then the factor grows (x10) where
    the difference is below EPS^0.75 of the values and shrinks (x0.1) where above EPS^0.25.
    A non-finite column is kept as it is (the Newton iteration then fails and the step shrinks).
    """
    n = y.size
    cs[NJEV] += 1
    factor, yt, fc, fc2 = RM[R_FACTOR], RM[R_YT], RM[R_FC], RM[R_FC2]
    for i in range(n):
        yt[i] = y[i]
    for j in range(n):
        y_scale = (1.0 if f[j] >= 0 else -1.0) * max(tolv[j], abs(y[j]))
        hj = (y[j] + factor[j] * y_scale) - y[j]
        while hj == 0:
            factor[j] *= NUM_JAC_FACTOR_INCREASE
            hj = (y[j] + factor[j] * y_scale) - y[j]
        status, max_diff, scale = _radau_column(t, yt, j, y[j] + hj, f, fc, par, pf, pi, rmode, locate, w, piv, cs,
                                                info)
        if status != OK:
            return status
        if max_diff < NUM_JAC_DIFF_REJECT * scale:
            new_factor = NUM_JAC_FACTOR_INCREASE * factor[j]
            h_new = (y[j] + new_factor * y_scale) - y[j]
            status, max_diff_new, scale_new = _radau_column(t, yt, j, y[j] + h_new, f, fc2, par, pf, pi, rmode, locate,
                                                            w, piv, cs, info)
            if status != OK:
                return status
            if max_diff * scale_new < max_diff_new * scale:
                factor[j], hj, max_diff, scale = new_factor, h_new, max_diff_new, scale_new
                for i in range(n):
                    fc[i] = fc2[i]
        yt[j] = y[j]
        for i in range(n):
            RJ[i * n + j] = (fc[i] - f[i]) / hj
        if max_diff < NUM_JAC_DIFF_SMALL * scale:
            factor[j] *= NUM_JAC_FACTOR_INCREASE
        elif max_diff > NUM_JAC_DIFF_BIG * scale:
            factor[j] *= NUM_JAC_FACTOR_DECREASE
        factor[j] = min(max(factor[j], NUM_JAC_MIN_FACTOR), JAC_MAX_FACTOR)
    return OK


@hot
def _radau_lu(h, RJ, RLR, RLC, rpiv, n, cs):
    """LU factors of MU_REAL / h I - J (RLR) and MU_COMPLEX / h I - J (RLC); False if one is singular."""
    mr = MU_REAL / h
    mc = MU_COMPLEX / h
    for i in range(n):
        for j in range(n):
            RLR[i * n + j] = -RJ[i * n + j]
            RLC[i * n + j] = -RJ[i * n + j]
        RLR[i * n + i] += mr
        RLC[i * n + i] += mc
    cs[NLU] += 2
    ok_real = lu_factor(RLR, n, rpiv[:n])
    return ok_real and lu_factor(RLC, n, rpiv[n:])


@hot
def _radau_newton(t, y, h, scale, tol, RM, RLR, RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info):
    """scipy's solve_collocation_system: the stage increments Z (RM[R_Z:R_Z + 3]) by the simplified
    Newton iteration from Z0 (RM[R_Z0:]), in the variables W = T^-1 Z, where the iteration matrix
    splits into one real and one complex system. Returns (status, converged, iterations, rate)."""
    n = y.size
    mr = MU_REAL / h
    mc = MU_COMPLEX / h
    yt, F = RM[R_YT], RM[R_F:R_F + 3]
    for i in range(n):  # W = TI Z0, Z = Z0
        for a in range(3):
            acc = 0.0
            for b in range(3):
                acc += RAD_TI[a, b] * RM[R_Z0 + b, i]
            RM[R_W + a, i] = acc
            RM[R_Z + a, i] = RM[R_Z0 + a, i]
    dw_norm_old, rate, converged, k = -1.0, np.nan, False, 0
    while k < NEWTON_MAXITER:
        finite = True
        for s in range(3):
            for i in range(n):
                yt[i] = y[i] + RM[R_Z + s, i]
            cs[NFEV] += 1
            status = feval(t + h * RAD_C[s], yt, rmode, locate, par, pf, pi, w, piv, F[s], info)
            if status == NONFINITE_RHS:
                finite = False
            elif status != OK:
                return status, False, k + 1, rate
        if not finite:
            break
        # f_real = F^T TI_REAL - MU_REAL / h W_0; f_complex = F^T TI_COMPLEX - MU_COMPLEX / h (W_1 + i W_2)
        for i in range(n):
            fr = 0.0
            fcx = 0j
            for s in range(3):
                fr += F[s, i] * RAD_TI[0, s]
                fcx += F[s, i] * RAD_TI_COMPLEX[s]
            RM[R_DW, i] = fr - mr * RM[R_W, i]
            rcv[i] = fcx - mc * (RM[R_W + 1, i] + 1j * RM[R_W + 2, i])
        lu_solve(RLR, n, rpiv[:n], RM[R_DW])
        lu_solve(RLC, n, rpiv[n:], rcv)
        for i in range(n):
            RM[R_DW + 1, i] = rcv[i].real
            RM[R_DW + 2, i] = rcv[i].imag
        dw_norm = _radau_rms(RM, R_DW, 3, scale)
        if dw_norm_old >= 0:
            rate = dw_norm / dw_norm_old
            if rate >= 1 or rate ** (NEWTON_MAXITER - k) / (1 - rate) * dw_norm > tol:
                break
        for i in range(n):  # W += dW; Z = T W
            for a in range(3):
                RM[R_W + a, i] += RM[R_DW + a, i]
            for a in range(3):
                acc = 0.0
                for b in range(3):
                    acc += RAD_T[a, b] * RM[R_W + b, i]
                RM[R_Z + a, i] = acc
        if dw_norm == 0 or (dw_norm_old >= 0 and rate / (1 - rate) * dw_norm < tol):
            converged = True
            break
        dw_norm_old = dw_norm
        k += 1
    return OK, converged, min(k + 1, NEWTON_MAXITER), rate


@hot
def _radau_predict(h_abs, h_abs_old, error_norm, error_norm_old):
    """scipy's predict_factor (the predictive Gustafsson controller); NaN stands for None."""
    if error_norm == 0:
        return np.inf
    multiplier = 1.0
    if error_norm_old == error_norm_old and h_abs_old == h_abs_old:
        multiplier = h_abs / h_abs_old * (error_norm_old / error_norm) ** 0.25
    return min(1.0, multiplier) * error_norm ** -0.25


@hot
def _radau_start(ts_, y, f, tolv, rtol, RM, RJ, par, pf, pi, rmode, locate, w, piv, cs, info):
    """A new Radau integrator at (t, y): scipy's __init__ after the first step size (the Jacobian
    from a fresh difference factor, no LU, no dense output to start Newton from). Returns the status."""
    ts_[R_H_OLD] = np.nan
    ts_[R_ERR_OLD] = np.nan
    ts_[R_NEWTON_TOL] = max(10 * EPS / rtol, min(0.03, rtol ** 0.5))
    cs[R_LU_OK] = 0
    cs[R_SOL] = 0
    cs[R_CURRENT_JAC] = 1
    for i in range(y.size):
        RM[R_FACTOR, i] = EPS ** 0.5
    return _radau_jacobian(ts_[T], y, f, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)


@hot
def _radau_solve(t, y, f, h, scale, tolv, newton_tol, RM, RJ, RLR, RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv,
                 cs, info):
    """Newton on the collocation system at step h, with a new Jacobian (and LU factors) once if
    it does not converge with the current ones. Returns (status, converged, n_iter, rate)."""
    n = y.size
    converged, n_iter, rate = False, 0, np.nan
    while not converged:
        lu_ok = True
        if cs[R_LU_OK] == 0:
            lu_ok = _radau_lu(h, RJ, RLR, RLC, rpiv, n, cs)
            cs[R_LU_OK] = 1 if lu_ok else 0
        if lu_ok:
            status, converged, n_iter, rate = _radau_newton(t, y, h, scale, newton_tol, RM, RLR, RLC, rpiv, rcv, par,
                                                            pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, n_iter, rate
        if not converged:
            if cs[R_CURRENT_JAC] == 1:
                break
            status = _radau_jacobian(t, y, f, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                return status, False, n_iter, rate
            cs[R_CURRENT_JAC] = 1
            cs[R_LU_OK] = 0
    return OK, converged, n_iter, rate


@hot
def _radau_error(t, h, y, f, y_new, tolv, rtol, rejected, RM, RLR, rpiv, par, pf, pi, rmode, locate, w, piv, cs, info):
    """y_new = y + Z_3 and the error estimate's norm: (E^T Z / h + f) solved with the real factor,
    once more from f at y + error after a rejected step (scipy's Radau). Returns (status, err_norm)."""
    n = y.size
    scale, err, ze = RM[R_SCALE], RM[R_ERR], RM[R_ZE]
    for i in range(n):
        y_new[i] = y[i] + RM[R_Z + 2, i]
        acc = 0.0
        for a in range(3):
            acc += RM[R_Z + a, i] * RAD_E[a]
        ze[i] = acc / h
        err[i] = f[i] + ze[i]
        scale[i] = tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol
    lu_solve(RLR, n, rpiv[:n], err)
    err_norm = _radau_rms(RM, R_ERR, 1, scale)
    if rejected and err_norm > 1:
        for i in range(n):
            RM[R_YT, i] = y[i] + err[i]
        cs[NFEV] += 1
        status = feval(t, RM[R_YT], rmode, locate, par, pf, pi, w, piv, err, info)
        if status != OK and status != NONFINITE_RHS:
            return status, err_norm
        for i in range(n):
            err[i] += ze[i]
        lu_solve(RLR, n, rpiv[:n], err)
        err_norm = _radau_rms(RM, R_ERR, 1, scale)
    return OK, err_norm


@hot
def _radau_step(ts_, t_end, rtol, tolv, max_step, y, f, F, y_old, y_new, f_new, RM, RJ, RLR, RLC, rpiv, rcv, par, pf,
                pi, rmode, locate, w, piv, cs, info):
    """One accepted Radau step from ts_[T] (scipy's Radau._step_impl). Returns (status, t_new, step_ok).

    The Newton iteration starts from the last step's dense output, extrapolated (its data: Q in
    F[:3], y_old, ts_[R_SOL_T], ts_[R_SOL_H]); the accepted step's Q = Z^T P goes to F[:3].
    """
    n = y.size
    t = ts_[T]
    min_step = 10 * spacing(t)
    if ts_[H_ABS] > max_step:
        h_abs, h_abs_old, err_old = max_step, np.nan, np.nan
    elif ts_[H_ABS] < min_step:
        h_abs, h_abs_old, err_old = min_step, np.nan, np.nan
    else:
        h_abs, h_abs_old, err_old = ts_[H_ABS], ts_[R_H_OLD], ts_[R_ERR_OLD]
    scale = RM[R_SCALE]
    rejected = False
    converged = False
    n_iter, rate, err_norm, safety, t_new = 0, np.nan, 0.0, 0.0, t
    while True:
        if h_abs < min_step:
            return OK, t, False
        t_new = t + h_abs
        if t_new - t_end > 0:
            t_new = t_end
        h = t_new - t
        h_abs = abs(h)
        for a in range(3):  # Z0: the last step's dense output at t + c h, less y (zero at a start)
            if cs[R_SOL] == 1:
                dense_eval(RADAU, t + h * RAD_C[a], ts_[R_SOL_T], ts_[R_SOL_H], y_old, F, RM[R_Z0 + a])
            for i in range(n):
                RM[R_Z0 + a, i] = RM[R_Z0 + a, i] - y[i] if cs[R_SOL] == 1 else 0.0
        for i in range(n):
            scale[i] = tolv[i] + abs(y[i]) * rtol
        status, converged, n_iter, rate = _radau_solve(t, y, f, h, scale, tolv, ts_[R_NEWTON_TOL], RM, RJ, RLR,
                                                       RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        if not converged:
            h_abs *= 0.5
            cs[R_LU_OK] = 0
            continue
        status, err_norm = _radau_error(t, h, y, f, y_new, tolv, rtol, rejected, RM, RLR, rpiv, par, pf, pi, rmode,
                                        locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
        if err_norm > 1:
            h_abs *= max(MIN_FACTOR, safety * _radau_predict(h_abs, h_abs_old, err_norm, err_old))
            cs[R_LU_OK] = 0
            rejected = True
        else:
            break
    recompute_jac = n_iter > 2 and rate > 1e-3
    factor = min(MAX_FACTOR, safety * _radau_predict(h_abs, h_abs_old, err_norm, err_old))
    if not recompute_jac and factor < 1.2:
        factor = 1.0
    else:
        cs[R_LU_OK] = 0
    cs[NFEV] += 1
    status = feval(t_new, y_new, rmode, locate, par, pf, pi, w, piv, f_new, info)
    if status != OK and status != NONFINITE_RHS:
        return status, t, True
    if recompute_jac:
        status = _radau_jacobian(t_new, y_new, f_new, tolv, RJ, RM, par, pf, pi, rmode, locate, w, piv, cs, info)
        if status != OK:
            return status, t, True
        cs[R_CURRENT_JAC] = 1
    else:
        cs[R_CURRENT_JAC] = 0
    ts_[R_H_OLD] = ts_[H_ABS]
    ts_[R_ERR_OLD] = err_norm
    ts_[H_ABS] = h_abs * factor
    ts_[HSTEP] = h
    _dense_weights(RM[R_Z:R_Z + 3], RAD_P, F)  # the dense output y_old + Q (x, x^2, x^3), Q = Z^T P
    ts_[R_SOL_T] = t
    ts_[R_SOL_H] = h
    cs[R_SOL] = 1
    return OK, t_new, True


# ---------------------------------------------------------------------------------------
# the pairs RK45, Tsit5 and Vern7: scipy's RungeKutta step (csim.physics.tableaus)
# ---------------------------------------------------------------------------------------
@hot
def _erk_error(E, K, y, y_new, tolv, rtol, hstep):
    """scipy RungeKutta._estimate_error_norm: rms of h K^T E / (atol + max(|y|, |y_new|) rtol), E
    over the stages and the new point."""
    n = y.size
    s = 0.0
    for i in range(n):
        acc = 0.0
        for jj in range(E.size):
            acc += K[jj, i] * E[jj]
        v = acc * hstep / (tolv[i] + max(abs(y[i]), abs(y_new[i])) * rtol)
        s += v * v
    return math.sqrt(s / n)


@inlined
def _extra_stages(A, C, first, t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K, ytmp, info):
    """The stages an interpolant adds after a step (DOP853's three, Vern7's five) into
    K[first:]: K_s = f(t_old + c_s h, y_old + h sum_j a_sj K_j), j over every stage before s
    (the step's own, its new point and the extra stages before s). Returns the status."""
    n = y_old.size
    for e in range(C.size):
        s = first + e
        for i in range(n):
            acc = 0.0
            for jj in range(s):
                acc += K[jj, i] * A[e, jj]
            ytmp[i] = y_old[i] + acc * h
        code = feval(t_old + C[e] * h, ytmp, mode, locate, par, pf, pi, w, piv, K[s], info)
        if code != OK:
            return code
    return OK


@hot
def _dop_dense(t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info):
    """scipy's DOP853._dense_output_impl: three extra stages, then the interpolant F (7, n)."""
    n = y_old.size
    code = _extra_stages(DOP_A_EXTRA, DOP_C_EXTRA, DOP_NS + 1, t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K,
                         ytmp, info)
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


@hot
def _vern7_dense(t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info):
    """Vern7's dense output (csim.solver.vern7): five extra stages after the ten and the new
    point in K[:11], then Q = K^T P into F[:7]."""
    code = _extra_stages(V7_A_EXTRA, V7_C_EXTRA, V7_NS + 1, t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K,
                         ytmp, info)
    if code != OK:
        return code
    _dense_weights(K[:V7_P.shape[0]], V7_P, F)
    return OK


@hot
def _ensure_dense(dense_ready, dense_kind, t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, cs,
                  info):
    """The step's dense output, built on its first use (DOP853's three extra stages, Vern7's five);
    returns the status.

    RK4's Hermite data, an empty step's constant and the 5(4) pairs' interpolant need no evaluation.
    """
    if dense_ready:
        return OK
    if dense_kind == VERN7:
        cs[NFEV] += V7_C_EXTRA.size
        return _vern7_dense(t_old, h, y_old, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info)
    if dense_kind != DOP853:
        return OK
    cs[NFEV] += DOP_C_EXTRA.size
    return _dop_dense(t_old, h, y_old, y, f, mode, locate, par, pf, pi, w, piv, K, F, ytmp, info)


# ---------------------------------------------------------------------------------------
# events: where a switching function leaves the sign its mode says
# ---------------------------------------------------------------------------------------
@hot
def _locate(a, b, dense_kind, t_old, h, y_old, FF, mode, mode_b, par, pf, pi, w, piv, ytmp, roots,
            has_root, info):
    """Earliest zero in (a, b] of the switching functions whose mode differs at b. Returns (status, t_event).

    A function already on the other side at a (the last event was located a hair early)
    switches at a. ``roots`` and ``has_root`` record each function's zero.
    """
    t_event = np.inf
    for jj in range(pi[PI_NSW]):
        has_root[jj] = False
        if mode_b[jj] != mode[jj]:
            g_old = _g_at(jj, a, dense_kind, t_old, h, y_old, FF, par, pf, pi, w, piv, ytmp)
            pending = _pending(pi, w, piv)
            if pending != OK:
                return pending, t_event
            if (g_old > 0) == mode[jj]:
                root, ok = brentq(jj, a, b, dense_kind, t_old, h, y_old, FF, par, pf, pi, w, piv, ytmp)
                pending = _pending(pi, w, piv)
                if pending != OK:
                    return pending, t_event
                if not ok:
                    info[0] = t_old + h
                    return NO_SIGN_CHANGE, t_event
            else:
                root = a
            roots[jj] = root
            has_root[jj] = True
            t_event = min(t_event, root)
    return OK, t_event


@hot
def _find_event(ts_, n_interior, dense_kind, y_old, y, f_new, mode, mode_b, rmode, locate, par, pf, pi, w, piv, K, F,
                Fh, ytmp, roots, has_root, dense, cs, info):
    """The earliest switch inside the last step (csim.solver.simulate._find_event). Returns (status, event).

    The mode is checked at ``n_interior`` equally spaced points of the step and at its end,
    so that a function that crosses zero and back within one step is not missed. On an
    event, ts_[T_STOP] is its time. ``dense`` [0] says whether the dense output is built.
    """
    t_old, t = ts_[T_OLD], ts_[T]
    h = t - t_old
    FF = Fh if dense_kind == RK4 else F
    for rep in range(n_interior + 1):
        b = t if rep == n_interior else t_old + (t - t_old) * (rep + 1) / (n_interior + 1)
        if b == t:
            for i in range(y.size):
                ytmp[i] = y[i]
        else:
            status = _ensure_dense(dense[0], dense_kind, t_old, h, y_old, y, f_new, rmode, locate, par, pf, pi, w, piv,
                                   K, F, ytmp, cs, info)
            if status != OK:
                return status, False
            dense[0] = True
            dense_eval(dense_kind, b, t_old, h, y_old, FF, ytmp)
        status = mode_at(ytmp, par, pf, pi, w, piv, mode_b)
        if status != OK:
            return status, False
        found = False
        for jj in range(pi[PI_NSW]):
            if mode_b[jj] != mode[jj]:
                found = True
        if found:
            status = _ensure_dense(dense[0], dense_kind, t_old, h, y_old, y, f_new, rmode, locate, par, pf, pi, w, piv,
                                   K, F, ytmp, cs, info)
            if status != OK:
                return status, False
            dense[0] = True
            a = t_old if rep == 0 else t_old + (t - t_old) * rep / (n_interior + 1)
            status, t_event = _locate(a, b, dense_kind, t_old, h, y_old, FF, mode, mode_b, par, pf, pi, w, piv, ytmp,
                                      roots, has_root, info)
            if status != OK:
                return status, False
            ts_[T_STOP] = t_event
            return OK, True
    return OK, False


@hot
def _sample(ts_, t_out, dense_kind, y_old, y, f_new, mode, rmode, locate, projects, par, pf, pi, w, piv, K, F, Fh, ytmp,
            yp, dense, tr, ys, modes, cs, info):
    """Record the output times in (t_old, t_stop] from the step's dense output (projected, for projection)."""
    t_old, t, t_stop = ts_[T_OLD], ts_[T], ts_[T_STOP]
    FF = Fh if dense_kind == RK4 else F
    while cs[I_OUT] < t_out.size and t_out[cs[I_OUT]] <= t_stop:
        t_i = t_out[cs[I_OUT]]
        if t_i == t and t_stop == t:
            for i in range(y.size):
                ytmp[i] = y[i]
        else:
            status = _ensure_dense(dense[0], dense_kind, t_old, t - t_old, y_old, y, f_new, rmode, locate, par, pf, pi,
                                   w, piv, K, F, ytmp, cs, info)
            if status != OK:
                return status
            dense[0] = True
            dense_eval(dense_kind, t_i, t_old, t - t_old, y_old, FF, ytmp)
        if projects:
            code = project(ytmp, yp, t_i, par, pf, pi, w, piv, info)
            if code != OK:
                return code
            copy_row(yp, ys, cs[N_REC])
        else:
            code, yv = full_state(ytmp, par, pf, pi, w, piv)
            if code != OK:
                return code
            copy_row(yv, ys, cs[N_REC])
        tr[cs[N_REC]] = t_i
        for jj in range(mode.size):
            modes[cs[N_REC], jj] = mode[jj]
        cs[N_REC] += 1
        cs[I_OUT] += 1
    return OK


@hot
def _event_state(ts_, dense_kind, y_old, y, F, Fh, projects, par, pf, pi, w, piv, ytmp, yp, info):
    """y = the state at the event ts_[T_STOP] (projected, for projection); t = t_stop. Returns the status."""
    t_old, t, t_stop = ts_[T_OLD], ts_[T], ts_[T_STOP]
    if t_stop < t:
        dense_eval(dense_kind, t_stop, t_old, t - t_old, y_old, Fh if dense_kind == RK4 else F, ytmp)
    else:
        for i in range(y.size):
            ytmp[i] = y[i]
    if projects:
        code = project(ytmp, yp, t_stop, par, pf, pi, w, piv, info)
        if code != OK:
            return code
        for i in range(y.size):
            ytmp[i] = yp[i]
    for i in range(y.size):
        y[i] = ytmp[i]
    ts_[T] = t_stop
    return OK


@njit(cache=True, error_model="numpy")
def _record_event(t, mode, roots, has_root, ev_t, ev_sw, n_ev):
    """Flip the conditions that switch at t (zeros within 4 eps of it) and record the event.

    Returns the event arrays, grown when full.
    """
    n_sw = mode.size
    if n_ev == ev_t.size:  # grow the event arrays
        new_t = np.empty(2 * ev_t.size)
        new_sw = np.zeros((2 * ev_t.size, n_sw), np.bool_)
        for e in range(n_ev):
            new_t[e] = ev_t[e]
            for jj in range(n_sw):
                new_sw[e, jj] = ev_sw[e, jj]
        ev_t = new_t
        ev_sw = new_sw
    tol_ev = 4 * EPS * max(1.0, abs(t)) + 4 * EPS
    ev_t[n_ev] = t
    for jj in range(n_sw):
        if has_root[jj] and roots[jj] - t <= tol_ev:
            ev_sw[n_ev, jj] = True
            mode[jj] = not mode[jj]
    return ev_t, ev_sw


# ---------------------------------------------------------------------------------------
# the integration loop (csim.solver.simulate.integrate)
# ---------------------------------------------------------------------------------------
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


@hot
def _start(y0, y, yp, mode, projects, par, pf, pi, w, piv, tr, ys, modes, info):
    """The integrated state y from the full initial state y0: projected (projection), partitioned and reduced
    (minimal), else y0 itself; then its mode, and the record of it. Returns the status."""
    if WITH_PARTITION and pi[PI_SYS] == PARTITIONED:
        model, P, r, m, k, tol, max_iter, _ = _partition_call(par, pf, pi, w, piv)
        code = branch.start(model, P, y0, y, r, m, k, tol, max_iter)
        if code != OK:
            return code
    else:
        for i in range(y.size):
            y[i] = y0[i]
    if projects:
        code = project(y, yp, 0.0, par, pf, pi, w, piv, info)
        if code != OK:
            return code
        for i in range(y.size):
            y[i] = yp[i]
    code = mode_at(y, par, pf, pi, w, piv, mode)
    if code != OK:
        return code
    if projects:  # the recorded sample, projected as every recorded sample is
        code = project(y, yp, 0.0, par, pf, pi, w, piv, info)
        if code != OK:
            return code
        copy_row(yp, ys, 0)
    else:
        code, yv = full_state(y, par, pf, pi, w, piv)
        if code != OK:
            return code
        copy_row(yv, ys, 0)
    tr[0] = 0.0
    for jj in range(mode.size):
        modes[0, jj] = mode[jj]
    return OK


@hot
def _start_segment(method, ts_, y, f, t_end, rtol, atol, max_step, first_step, tolv, par, pf, pi, rmode, locate, w, piv,
                   ytmp, f1, scl, RM, RJ, cs, info):
    """Start the integrator at (t, y): tolerances, f(t, y), the first step of DOP853 and Radau, and
    Radau's Jacobian. Returns the status."""
    n = y.size
    status, yv = full_state(y, par, pf, pi, w, piv)
    if status != OK:
        return status
    scale_w = max(1.0, abs(kinetic(yv, par, pi, w)))  # the work states are in J: atol scaled to the energy
    for i in range(n):
        tolv[i] = atol * scale_w if i >= n - pi[PI_NL] - pi[PI_ND] else atol
    cs[NFEV] += 1
    status = feval(ts_[T], y, rmode, locate, par, pf, pi, w, piv, f,
                   info)
    if status != OK:
        return status
    ts_[H_ABS] = 0.0
    ts_[SEG_START] = ts_[T]
    cs[SEG_STEPS] = 0
    if method != RK4:
        status, h = _initial_step(ts_[T], y, f, t_end, rtol, tolv, max_step, first_step, par, pf, pi, rmode, locate, w,
                                  piv, ytmp, f1, scl, cs, info, _error_order(method))
        ts_[H_ABS] = h
    if status == OK and method == RADAU:
        status = _radau_start(ts_, y, f, tolv, rtol, RM, RJ, par, pf, pi, rmode, locate, w, piv, cs, info)
    return status


@hot
def _take_step(method, ts_, t_end, rtol, tolv, fixed_h, max_step, y, f, K, F, y_old, ytmp, y_new, f_new, RM, RJ, RLR,
               RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info):
    """One step of the integrator from (t, y), or scipy's empty step at t_end.

    Returns (status, t_new, step_ok, dense kind); step_ok is False where no step can be
    taken (DOP853's or Radau's step below the spacing of t, RK4's below the resolution of t).
    """
    if ts_[T] == t_end:  # scipy: an empty step to t_bound
        for i in range(y.size):
            y_new[i] = y[i]
            f_new[i] = f[i]
        ts_[HSTEP] = 0.0
        return OK, t_end, True, CONSTANT
    if method in (DOP853, RK45, TSIT5, VERN7):
        status, t_new, ok = _explicit_step(method, ts_, t_end, rtol, tolv, max_step, y, f, K, F, ytmp, y_new, f_new,
                                           par, pf, pi, rmode, locate, w, piv, cs, info)
    elif method == RADAU:
        status, t_new, ok = _radau_step(ts_, t_end, rtol, tolv, max_step, y, f, F, y_old, y_new, f_new, RM, RJ, RLR,
                                        RLC, rpiv, rcv, par, pf, pi, rmode, locate, w, piv, cs, info)
    else:
        status, t_new, ok = _rk4_step(ts_, t_end, fixed_h, y, f, K, ytmp, y_new, f_new, par, pf, pi, rmode, locate, w,
                                      piv, cs, info)
    return status, t_new, ok, method


@hot
def _after_step(ts_, y, f, f_new, yp, projects, par, pf, pi, rmode, locate, w, piv, cs, info):
    """Go on from the accepted step: project and hand the state back (projection); anchor the branch and
    maybe choose the partition again (minimal); else keep f_new. Returns (status, restart)."""
    if WITH_PARTITION and pi[PI_SYS] == PARTITIONED:
        code, restart = _partition_after_step(y, par, pf, pi, w, piv)
        if code != OK or restart:
            return code, restart
    if not projects:
        for i in range(y.size):
            f[i] = f_new[i]
        return OK, False
    code = project(y, yp, ts_[T], par, pf, pi, w, piv, info)
    if code != OK:
        return code, False
    for i in range(y.size):
        y[i] = yp[i]
    cs[NFEV] += 1
    return feval(ts_[T], y, rmode, locate, par, pf, pi, w, piv, f, info), False


@hot
def _accept_step(ts_, t_new, dense_kind, y, y_old, y_new, f, f_new, Fh, dense, t_end, adaptive, max_phi, min_step, par,
                 pf, pi, w, piv, info):
    """Take the step to (t_new, y_new) (y_old keeps the state before it) and check it (csim.physics.steps);
    the cubic Hermite data of an RK4 step into Fh. Returns the status."""
    n = y.size
    for i in range(n):
        y_old[i] = y[i]
        y[i] = y_new[i]
    ts_[T] = t_new
    status, max_phi_now = _max_phi(t_new, y, par, pf, pi, w, piv)
    if status != OK:
        return status
    status = check_step(y, max_phi_now, ts_[HSTEP], t_new, t_end, adaptive, max_phi, min_step, info)
    if status != OK:
        return status
    if dense_kind == RK4:  # the cubic Hermite interpolant's data
        for i in range(n):
            Fh[0, i] = y_old[i]
            Fh[1, i] = f[i]
            Fh[2, i] = y[i]
            Fh[3, i] = f_new[i]
    dense[0] = False
    ts_[T_STOP] = t_new
    return OK


@hot
def _after_event(ts_, y, ev_t, ev_sw, n_chatter, max_events, min_step, par, pf, pi, w, piv, cs, info):
    """After an event recorded at index cs[N_EV]: anchor the partitioned system at the event state (maybe in a
    new partition; on a failure the event is not counted, its conditions stay flipped, as the Python driver
    leaves them), count the event, and check for chatter and too many events. Returns the status."""
    if WITH_PARTITION and pi[PI_SYS] == PARTITIONED:
        status, _ = _partition_after_step(y, par, pf, pi, w, piv)
        if status != OK:
            for jj in range(ev_sw.shape[1]):
                ev_sw[cs[N_EV], jj] = False
            return status
    cs[N_EV] += 1
    status = check_chatter(ev_t, cs[N_EV], n_chatter, min_step, info)
    if status != OK:
        return status
    if cs[N_EV] > max_events:
        info[0] = ts_[T]
        return MAX_EVENTS
    return OK


@hot
def _accept(ts_, y, ya):
    """ya = y, the state a restart goes back to after a breakdown of the partition; returns its time."""
    for i in range(y.size):
        ya[i] = y[i]
    return ts_[T]


#: steps between two looks at ``control`` (the interrupt request, the time reached): reading
#: one element costs nothing next to a step, and a few hundred steps take milliseconds
POLL_STEPS = 256


@njit(cache=True, error_model="numpy")  # _record_event may grow the records: numba's allocator
def _event_restart(t_a, ts_, dense_kind, y_old, y, ya, F, Fh, projects, mode, roots, has_root, ev_t, ev_sw, n_chatter,
                   max_events, min_step, par, pf, pi, w, piv, ytmp, yp, cs, info):
    """Move to the located event's state, accept it, record the event and check the events'
    count and chattering. Returns (status, t_a, ev_t, ev_sw): the accepted time (t_a as given
    where the event's state failed) and the event records (grown where full)."""
    status = _event_state(ts_, dense_kind, y_old, y, F, Fh, projects, par, pf, pi, w, piv, ytmp, yp, info)
    if status != OK:
        return status, t_a, ev_t, ev_sw
    t_a = _accept(ts_, y, ya)
    ev_t, ev_sw = _record_event(ts_[T], mode, roots, has_root, ev_t, ev_sw, cs[N_EV])
    status = _after_event(ts_, y, ev_t, ev_sw, n_chatter, max_events, min_step, par, pf, pi, w, piv, cs, info)
    return status, t_a, ev_t, ev_sw


@hot
def _poll(control, ts_, cs, info):
    """Every POLL_STEPS steps: the time reached to control[1] (every sample up to it is
    recorded), and INTERRUPTED where control[0] asks to stop; else OK."""
    if cs[NSTEPS] % POLL_STEPS == 0:
        control[1] = ts_[T]
        if control[0] != 0.0:
            info[0] = ts_[T]
            return INTERRUPTED
    return OK


@hot
def _count_step(method, ok, t_new, max_steps, ts_, cs, info):
    """Count a step taken; MAX_STEPS beyond max_steps, or why the step could not be taken
    (``ok`` False: RK4's step below the time's resolution, else the step size below the
    smallest allowed); else OK."""
    cs[NSTEPS] += 1
    if cs[NSTEPS] > max_steps:
        info[0] = t_new if ok else ts_[T]
        return MAX_STEPS
    if not ok:
        info[0] = ts_[T]
        return RK4_RESOLUTION if method == RK4 else STEP_TOO_SMALL
    return OK


@njit(cache=True, error_model="numpy", nogil=True)
def integrate(method, y0, t_out, par, pf, pi, projects, iset, fset, control):
    """Integrate from t = 0, state y0 (n,), sampling at t_out (csim.solver.simulate.integrate).

    The problem arrays are the module docstring's; ``projects``: project after every step;
    ``iset`` = [locate, event_samples, max_events, max_steps, chatter_events]; ``fset`` = [t_end, rtol, atol,
    step, max_step, first_step (NaN: automatic), max_phi, min_step]; ``control`` (2,), shared
    with the caller, which runs this without the GIL in a thread: every POLL_STEPS steps the
    time reached goes to control[1], and a nonzero control[0] (Ctrl-C) ends the run with
    status INTERRUPTED and the samples so far. Returns (n_rec, ts, ys, modes, n_ev, ev_t,
    ev_switched, nfev, nsteps, status, info (2,), njev, nlu).
    """
    locate, n_interior, max_events, max_steps, n_chatter = iset[0] != 0, iset[1], iset[2], iset[3], iset[4]
    t_end, rtol, atol, fixed_h, max_step, first_step, max_phi, min_step = fset[0], fset[1], fset[2], fset[3], \
        fset[4], fset[5], fset[6], fset[7]
    # (`partitioned` is a run-time value: the branches below test WITH_PARTITION as well, so that
    # numba prunes them in the copy without the partitioned system)
    partitioned = WITH_PARTITION and pi[PI_SYS] == PARTITIONED
    if pi[PI_SYS] == PARTITIONED and not WITH_PARTITION:
        raise ValueError("the partitioned system needs the kernels built with WITH_PARTITION")
    n_free = pi[PI_NQ] - pi[PI_NC] if partitioned else pi[PI_NQ]  # the integrated state: 2 n_free + k
    n, n_sw = 2 * n_free + pi[PI_NL] + pi[PI_ND], pi[PI_NSW]
    w = np.zeros(pi[W_END])
    # the KKT solve's pivots, then the partition's integers
    piv = np.zeros(pi[PI_NQ] + pi[PI_NC] + partition_sizes(pi[PI_NQ], pi[PI_NC], pi[PI_NL])[1], np.int64)
    tr, ys, modes = np.empty(t_out.size), np.empty((t_out.size, y0.size)), np.zeros((t_out.size, n_sw), np.bool_)
    ev_t, ev_sw = np.empty(16), np.zeros((16, n_sw), np.bool_)
    info, ts_, cs = np.zeros(2 + D_HEAD + 2 * n_free), np.zeros(11), np.zeros(11, np.int64)
    y, ytmp, yp, f, f_new, y_new, y_old, ya = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), \
        np.empty(n), np.empty(n), np.empty(n)
    K, F, Fh = np.empty((DOP_NX, n)), np.empty((DOP_POWER, n)), np.empty((4, n))
    nr = n if method == RADAU else 0  # Radau's rows, Jacobian, LU factors (real and complex) and their pivots
    RM, RJ, RLR, RLC = np.zeros((R_ROWS, nr)), np.zeros(nr * nr), np.zeros(nr * nr), np.zeros(nr * nr, np.complex128)
    rpiv, rcv = np.zeros(2 * nr, np.int64), np.zeros(nr, np.complex128)
    tolv, scl = np.empty(n), np.empty(n)
    mode, mode_b = np.zeros(n_sw, np.bool_), np.zeros(n_sw, np.bool_)
    rmode = mode if locate else np.zeros(n_sw, np.bool_)  # the right-hand side's mode, or a scratch it overwrites
    roots, has_root, dense = np.empty(n_sw), np.zeros(n_sw, np.bool_), np.zeros(1, np.bool_)
    status = _start(y0, y, yp, mode, projects, par, pf, pi, w, piv, tr, ys, modes, info)
    cs[I_OUT] = 1
    if status == OK:
        cs[N_REC] = 1
    t_a = 0.0
    while status == OK and ts_[T] < t_end:
        restarted = False
        t_a = _accept(ts_, y, ya)
        status = _start_segment(method, ts_, y, f, t_end, rtol, atol, max_step, first_step, tolv, par, pf, pi, rmode,
                                locate, w, piv, ytmp, f_new, scl, RM, RJ, cs, info)
        while status == OK:
            status = _poll(control, ts_, cs, info)
            if status != OK:
                break
            ts_[T_OLD] = ts_[T]
            status, t_new, ok, dense_kind = _take_step(method, ts_, t_end, rtol, tolv, fixed_h, max_step, y, f, K, F,
                                                       y_old, ytmp, y_new, f_new, RM, RJ, RLR, RLC, rpiv, rcv, par, pf,
                                                       pi, rmode, locate, w, piv, cs, info)
            if status != OK:
                break
            status = _count_step(method, ok, t_new, max_steps, ts_, cs, info)
            if status != OK:
                break
            status = _accept_step(ts_, t_new, dense_kind, y, y_old, y_new, f, f_new, Fh, dense, t_end,
                                  method != RK4, max_phi, min_step, par, pf, pi, w, piv, info)
            if status != OK:
                break
            event = False
            if locate:
                status, event = _find_event(ts_, n_interior, dense_kind, y_old, y, f_new, mode, mode_b, rmode, locate,
                                            par, pf, pi, w, piv, K, F,
                                            Fh, ytmp, roots, has_root, dense, cs, info)
                if status != OK:
                    break
            status = _sample(ts_, t_out, dense_kind, y_old, y, f_new, mode, rmode, locate, projects, par, pf, pi, w,
                             piv, K, F, Fh, ytmp, yp, dense, tr, ys,
                             modes, cs, info)
            if status != OK:
                break
            if event:  # restart from the event state with the switched conditions flipped
                status, t_a, ev_t, ev_sw = _event_restart(t_a, ts_, dense_kind, y_old, y, ya, F, Fh, projects, mode,
                                                          roots, has_root, ev_t, ev_sw, n_chatter, max_events,
                                                          min_step, par, pf, pi, w, piv, ytmp, yp, cs, info)
                restarted = status == OK
                break
            status, restart = _after_step(ts_, y, f, f_new, yp, projects, par, pf, pi, rmode, locate, w, piv, cs, info)
            if status == OK:
                t_a = _accept(ts_, y, ya)
            if restart:
                restarted = True
                break
            if t_new >= t_end:
                break
        if WITH_PARTITION and partitioned and branch.is_breakdown(status):
            # a stage left the region of the partition: restart from the last accepted state
            ts_[T] = t_a
            status = _repartition(ya, y, par, pf, pi, w, piv)
            restarted = status == OK
        if not restarted:
            break
    if WITH_PARTITION and partitioned and status != OK:
        _failure_details(pi, w, piv, info)
    return cs[N_REC], tr, ys, modes, cs[N_EV], ev_t, ev_sw, cs[NFEV], cs[NSTEPS], status, info, cs[NJEV], cs[NLU]


# ---------------------------------------------------------------------------------------
# the recorded quantities at the output samples (csim.pipeline.assemble_result)
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
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
        False where the KKT matrix is singular (the row's other outputs are then NaN).
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
    piv = np.zeros(nk, np.int64)
    f = np.empty(ys.shape[1])
    mode = np.empty(pi[PI_NSW], np.bool_)
    ok = np.ones(N, np.bool_)
    x, Q = np.full((N, nk), np.nan), np.full((N, nq), np.nan)
    phi, phi_dot = np.full((N, nc), np.nan), np.full((N, nc), np.nan)
    u, energy = np.full((N, nl), np.nan), np.full((N, 2), np.nan)
    obs = np.empty((N, 2 * no))
    for i in range(N):
        y = ys[i]
        if no > 0:
            observe(y, par, pi, obs[i])
        mode[:] = modes[i]
        if rhs(ts[i], y, mode, True, par, pf, pi, w, piv, f) != OK:
            ok[i] = False
            continue
        x[i] = w[pi[W_X]:pi[W_X] + nk]
        phi[i] = w[pi[W_PHI]:pi[W_PHI] + nc]
        phi_dot[i] = w[pi[W_PD]:pi[W_PD] + nc]
        u[i] = w[pi[W_U]:pi[W_U] + nl]
        for a in range(nq):  # Q = B u, B (m, k) row-major
            acc = 0.0
            for kk in range(nl):
                acc += w[pi[W_B] + a * nl + kk] * w[pi[W_U] + kk]
            Q[i, a] = acc
        energy[i, 0] = kinetic(y, par, pi, w)
        energy[i, 1] = potential(y, par, pi, w)
    return ok, x, phi, phi_dot, u, Q, energy, obs


# ---------------------------------------------------------------------------------------
# entry points for the tests and the benchmark
# ---------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def rhs_entry(t, y, mode, par, pf, pi):
    """dy/dt and [qdd, lambda] at time t and one state (mode held), for comparison with the Python path."""
    w = np.zeros(pi[W_END])
    piv = np.zeros(pi[PI_NQ] + pi[PI_NC], np.int64)
    f = np.empty(y.size)
    code = rhs(t, y, mode.copy(), True, par, pf, pi, w, piv, f)
    return code, f, w[pi[W_X]:pi[W_X] + pi[PI_NQ] + pi[PI_NC]].copy()


@njit(cache=True, error_model="numpy")
def rhs_repeat(y, mode, par, pf, pi, n_eval):
    """n_eval evaluations of the right-hand side (a timing loop for the benchmark)."""
    w = np.zeros(pi[W_END])
    piv = np.zeros(pi[PI_NQ] + pi[PI_NC], np.int64)
    f = np.empty(y.size)
    acc = 0.0
    for _ in range(n_eval):
        rhs(0.0, y, mode, True, par, pf, pi, w, piv, f)
        acc += f[pi[PI_NQ]]
    return acc


@njit(cache=True, error_model="numpy")
def project_entry(y, par, pf, pi):
    w = np.zeros(pi[W_END])
    piv = np.zeros(pi[PI_NQ] + pi[PI_NC], np.int64)
    out = np.empty(y.size)
    info = np.zeros(2)
    code = project(y, out, 0.0, par, pf, pi, w, piv, info)
    return code, info[0], out
