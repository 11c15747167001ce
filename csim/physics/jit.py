"""``kernel``: compile a core function with numba when numba loads, else leave it as Python.

The functions of :mod:`csim.physics` are called both from Python (the reference driver)
and from inside compiled loops. Compiled, the Python driver calls the machine code (a
dispatcher call costs about a microsecond); without numba the same source runs as plain
Python, slower but identical in what it computes. ``CSIM_PURE_PYTHON=1`` forces the
latter (for debugging, and to test that the core never depends on numba).
"""
from __future__ import annotations

import os

#: no function here allocates, so none needs numba's reference counting of arrays (NRT): without
#: it a call costs no atomic operations per array argument or slice (half of an evaluation's time)
NJIT_OPTIONS = dict(cache=True, error_model="numpy", _nrt=False)


def _numba_njit():
    if os.environ.get("CSIM_PURE_PYTHON", "") not in ("", "0"):
        return None
    try:
        from numba import njit
    except Exception:  # numba missing or broken: the Python driver still runs
        return None
    return njit


_NJIT = _numba_njit()

#: whether core functions are compiled in this process
COMPILED = _NJIT is not None


def kernel(fn):
    """Decorator: ``fn`` compiled by numba (njit, cached on disk, numpy's error model), or ``fn`` itself."""
    return fn if _NJIT is None else _NJIT(**NJIT_OPTIONS)(fn)


def inline_kernel(fn):
    """:func:`kernel`, and inlined into compiled callers in numba's IR, so that the sizes they pass
    as constants fix its loop lengths (the KKT solve of a right-hand side: about 0.6x the time of a
    call). Only for the few functions on the right-hand side's path: inlining costs compile time."""
    return fn if _NJIT is None else _NJIT(inline="always", **NJIT_OPTIONS)(fn)


def jitable(fn):
    """Decorator for a core function that evaluates the model (:mod:`csim.physics.model`): ``fn`` itself
    to a Python caller, compiled into the compiled callers that call it.

    The Python driver passes a Python model object (the functions of :mod:`csim.physics.model`
    call its methods); the compiled kernels pass their tuple (model functions called through
    their addresses, :mod:`csim.fast.kernels`), for which the kernels overload those functions.
    The function is compiled as part of each compiled caller (numba's ``register_jitable``), so
    it is cached with the caller, never on its own. It must not allocate.
    """
    if _NJIT is None:
        return fn
    from numba.extending import register_jitable

    return register_jitable(error_model="numpy", _nrt=False)(fn)
