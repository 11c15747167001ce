"""What every file of the kernels shares: the decorators, the integrators' codes and the
loop's scalar slots.

In a compiled copy (:data:`.variant.COMPILED`), importing this file activates the core
(:func:`csim.physics.jit.activate`): from here on the functions of :mod:`csim.physics` compile,
and numba types them, inside the kernels. In the interpreted package every decorator returns
the function itself, and numba is not imported.
"""
import math

import numpy as np

from csim.physics.jit import inlining_root

from .variant import COMPILED

if COMPILED:
    from numba import njit

    from csim.physics.jit import NJIT_OPTIONS, activate, inline_always, kernel

    activate()  # the core functions compile, and numba types them, from here on

    #: the decorator of every loop function that allocates nothing: compiled without numba's
    #: reference counting of arrays (NRT), which would cost two atomic operations per array
    #: argument and per slice at every call; the arrays live as long as ``integrate`` holds them.
    #: A core function's decorator: a dispatcher from the first compile on, which a warm run never
    #: makes (it loads the entry points below, whose machine code holds what they call)
    hot = kernel
    #: the same, inlined in numba's IR into its callers: a call passes every array argument as a
    #: struct of seven words, which for the small functions of every step costs more than their body
    #: (the core's larger ones are inlined only into the right-hand side, :data:`rhs_root`)
    inlined = inline_always
    #: a function that allocates nothing and is compiled on its own, whose address the loop calls
    #: (``feval``): a dispatcher at once, as the entry points below
    addressed = njit(**NJIT_OPTIONS)
    #: a function that allocates (numba's allocator and reference counting: the entry points, the event records)
    allocating = njit(cache=True, error_model="numpy")
    #: the loop itself: allocates, and runs without the GIL (:func:`csim.fast.runner.integrate_compiled`)
    loop = njit(cache=True, error_model="numpy", nogil=True)
else:
    def hot(fn):
        """The interpreted package: the function itself."""
        return fn
    inlined = addressed = allocating = loop = hot
#: inlined, for functions whose callers pass their sizes as constants (the copy's loops have fixed lengths)
sized = inlined
#: the right-hand side, whose copies with constant sizes need the core's functions inlined in numba's IR
#: (:func:`csim.physics.jit.inline_kernel`, :func:`csim.physics.jit.inlining_root`)
rhs_root = inlining_root
#: the (m, r) whose right-hand side has a copy with constant sizes: the planar one-loop linkages
#: (quick-return, four-bar, slider-crank) and the Cartesian pendulum (without its copy: 1.5x the
#: time of its RK4 run, for 2.5 s less of the right-hand side's compile, 2026-11-27)
SIZED = ((3, 2), (2, 1))


# ---- the loop's constants (status codes are csim.physics.status's) ----
EPS = 2.220446049250313e-16
#: ``located`` for the right-hand side at a recorded state (the load laws held in ``mode``): numpy's True,
#: which numba types as ``boolean``, the type the loop's ``feval`` passes; a literal True (or a global
#: Python bool, which numba freezes as a constant of the same type) is typed ``Literal[bool](True)``, and
#: numba compiled the whole right-hand side a second time for it (10 s)
LOCATED = np.bool_(True)


# integrators (csim.fast.runner.INTEGRATOR_CODES), and the dense output of an empty step
DOP853 = 0
RK4 = 1
CONSTANT = 2
RADAU = 3
RK45 = 4
TSIT5 = 5
VERN7 = 6

# scalars of the loop, in one float array ts_ and one int array cs_ (R_*: Radau's; R_FAIL*: the reason of its
# last failed Newton attempt on a DAE, with its numbers; R_NSING: its singular iteration matrices in this step)
(T, T_OLD, H_ABS, HSTEP, T_STOP, SEG_START, R_H_OLD, R_ERR_OLD, R_NEWTON_TOL, R_SOL_T, R_SOL_H, R_FAIL_VALUE,
 R_FAIL_TOL, N_TS) = range(14)
(NFEV, NSTEPS, N_REC, I_OUT, N_EV, SEG_STEPS, NJEV, NLU, R_LU_OK, R_SOL, R_CURRENT_JAC, R_FAIL, R_NSING,
 N_CS) = range(14)


@hot
def spacing(t):
    """|nextafter(t, +inf) - t| for t >= 0 (numpy's nextafter without its overload)."""
    if t == 0.0:
        return 5e-324
    _, e = math.frexp(t)  # t = m 2^e, 0.5 <= m < 1
    return 2.0 ** (e - 53)


@hot
def copy_row(src, dst, row):
    """dst[row] = src[:dst.shape[1]] (a recorded state: the full state [q, qd, W] leads GGL's integrated one)."""
    for i in range(dst.shape[1]):
        dst[row, i] = src[i]
