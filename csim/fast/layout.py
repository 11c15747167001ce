"""The layout the compiled kernels read at run time: the header of ``pi``, the model's function
pointers, and the offsets of the workspace ``w`` (no numba import).

The kernels (:mod:`csim.fast.kernels`) are compiled once per installation, for every
mechanism, so nothing about a mechanism is a compile-time constant there: its sizes, the
addresses of its model functions and where each term lies in the workspace are entries of
the integer array ``pi`` (:func:`csim.fast.runner.pack_problem`), read where they are used.
The indices below are the kernels' compile-time constants; changing them changes the
kernels' source hash and so recompiles them once.

Model functions (:mod:`csim.fast.ccodegen`, :mod:`csim.fast.codegen`) all have one C
interface, ``void f(double t, const double *y, const double *par, double *out)``: ``out``
is the workspace for the functions that write model terms (absolute offsets), the energy
(``out[0]``) for ``kinetic`` and ``potential``, the observables and their rates for
``observe``.
"""
from __future__ import annotations

from csim.solver.methods.baumgarte import baumgarte_gamma_star
from csim.solver.methods.sliding_mode import sliding_mode_gamma_star

#: the stabilization methods whose gamma* the kernels call by code (pi[PI_MK] = 1, 2, ...; 0 is
#: gamma* = gamma): csim.fast.module.method_dispatch reads this without loading the kernels
BUILTIN_GAMMA = (baumgarte_gamma_star, sliding_mode_gamma_star)
#: the code of a method whose gamma* is called through pi[PI_GAMMA_FN]
EXTERNAL = -1

#: the model functions, in the order of their addresses in pi[PI_FN:]
MODEL_FUNCTIONS = ("terms", "phi_", "jac", "mass", "loads_", "kinetic", "potential", "observe")
F_TERMS, F_PHI, F_JAC, F_MASS, F_LOADS, F_KINETIC, F_POTENTIAL, F_OBSERVE = range(len(MODEL_FUNCTIONS))


def c_symbol(name: str) -> str:
    """The exported C name of a model function (here, not in csim.fast.ccodegen, so that loading a
    built model does not import sympy)."""
    return f"csim_{name.rstrip('_')}"

#: the model terms in the workspace, in their order there (csim.fast.codegen.TERMS) -> their pi index name
MODEL_TERMS = ("W_M", "W_CQD", "W_H", "W_PHI", "W_J", "W_GAM", "W_S", "W_B", "W_SQ", "W_L", "W_PT")
#: the kernels' scratch after the model terms: name -> size from (m, r, k, n_sw)
SCRATCH = (
    ("W_A", lambda m, r, k, n: (m + r) ** 2),  # KKT matrix
    ("W_X", lambda m, r, k, n: m + r),  # [qdd, lambda]
    ("W_P", lambda m, r, k, n: m),  # p = B u - C qd - h
    ("W_U", lambda m, r, k, n: k),  # load values
    ("W_SD", lambda m, r, k, n: k),  # load rates ds/dt
    ("W_PD", lambda m, r, k, n: r),  # Phi_q qd
    ("W_GS", lambda m, r, k, n: r),  # gamma*
    ("W_WINV", lambda m, r, k, n: m * m),  # projection: W^-1
    ("W_M2", lambda m, r, k, n: m * m),  # projection: LU of M
    ("W_WJT", lambda m, r, k, n: m * r),  # projection: W^-1 Phi_q^T
    ("W_S2", lambda m, r, k, n: r * r),  # projection: Phi_q W^-1 Phi_q^T
    ("W_Z", lambda m, r, k, n: r),  # projection
    ("W_DQ", lambda m, r, k, n: m),  # projection: correction
    ("W_COL", lambda m, r, k, n: m),  # projection: a column of the identity
    ("W_E", lambda m, r, k, n: 1),  # kinetic or potential energy
    ("W_G", lambda m, r, k, n: n),  # switching functions
    ("W_YM", lambda m, r, k, n: 2 * m + k),  # a state to call the model functions at (csim.physics.model)
    # minimal: the partition's floats; the elimination's state (fewer) lies there too (never both)
    ("W_PART", lambda m, r, k, n: _region_size(m, r, k)),
    ("W_END", lambda m, r, k, n: 0),  # the size of w
)

# ---- the header of pi ----
#: the method's dispatch code, the number of switching functions, where the method's settings are
PI_MK, PI_NSW, PI_IPAR, PI_NIPAR, PI_FPAR, PI_NFPAR, PI_GAINS, PI_NGAINS = range(8)
#: sizes: coordinates, constraints, loads, observables
PI_NQ, PI_NC, PI_NL, PI_NO = range(8, 12)
#: the address of the gamma* of a method outside the kernels' own dispatch (0: none)
PI_GAMMA_FN = 12
#: what is integrated: CONSTRAINED ([q, qd, W]), PARTITIONED ([u, ud, W], csim.physics.branch) or GGL's DAE
#: ([q, v, W, mu, lambda], csim.physics.ggl: Radau only)
PI_SYS = 13
CONSTRAINED, PARTITIONED, GGL = 0, 1, 2
#: drives (csim.solver.driven): how many of the constraint rows, the last ones, are drives
#: q_j = f_j(t), and where in pi their coordinates j are (each drive's work is a state after the loads')
PI_ND, PI_DRV = 14, 15
#: the address of the kernels' right-hand side ``feval``, whose callers call it through this address
#: (csim.fast.kernels.calls.call_feval) instead of each linking its code into theirs
PI_FEVAL = 16
#: the formulation (KKT or ELIMINATION), where its integers are in pi ([fixed (0/1), the independent
#: coordinates given by formulation.independent (n), ascending]) and where its max_condition is in pf
PI_FORM, PI_FORM_I, PI_FORM_F = 17, 18, 19
KKT, ELIMINATION = 0, 1
#: the address of the elimination's solve ``eliminated``, which the right-hand side calls through it (0 for KKT)
PI_ELIM = 20
#: the addresses of the model functions (MODEL_FUNCTIONS)
PI_FN = 21
#: the workspace offsets (MODEL_TERMS, then SCRATCH)
PI_W = PI_FN + len(MODEL_FUNCTIONS)
_W_NAMES = MODEL_TERMS + tuple(name for name, _ in SCRATCH)
(W_M, W_CQD, W_H, W_PHI, W_J, W_GAM, W_S, W_B, W_SQ, W_L, W_PT, W_A, W_X, W_P, W_U, W_SD, W_PD, W_GS, W_WINV, W_M2,
 W_WJT, W_S2, W_Z, W_DQ, W_COL, W_E, W_G, W_YM, W_PART, W_END) = range(PI_W, PI_W + len(_W_NAMES))
#: the header's length; then sw_load (n_sw), sw_kind (n_sw), ipar (I)
PI_HEAD = PI_W + len(_W_NAMES)


def _region_size(m: int, r: int, k: int) -> int:
    """The floats of w[W_PART:]: minimal's partition (csim.physics.partition), or the elimination's state."""
    from csim.physics.elimination import elimination_sizes
    from csim.physics.partition import partition_sizes

    return max(partition_sizes(m, r, k)[0], elimination_sizes(m, r)[0])


def model_offsets(m: int, r: int, k: int) -> tuple[dict[str, int], int]:
    """The offsets of the model terms in w (the generated functions write there), and their end."""
    sizes = dict(W_M=m * m, W_CQD=m, W_H=m, W_PHI=r, W_J=r * m, W_GAM=r, W_S=k, W_B=m * k, W_SQ=m * k, W_L=k, W_PT=r)
    offsets, at = {}, 0
    for name in MODEL_TERMS:
        offsets[name] = at
        at += sizes[name]
    return offsets, at


def workspace(m: int, r: int, k: int, n_sw: int) -> list[int]:
    """Every offset of w, in the order of pi[PI_W:PI_HEAD] (the last one is w's size)."""
    offsets, at = model_offsets(m, r, k)
    out = [offsets[name] for name in MODEL_TERMS]
    for _, size in SCRATCH:
        out.append(at)
        at += size(m, r, k, n_sw)
    return out
