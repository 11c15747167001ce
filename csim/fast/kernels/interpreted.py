"""The interpreted package's calls: what :mod:`.addresses` does in machine code, done from Python.

The package's own source (``csim.fast.kernels``, :data:`.variant.COMPILED` False) is the
interpreted backend: the loop, the steppers and the event location the compiled copy runs,
run by Python, with the core functions as plain Python where they are not compiled in the
process (:func:`csim.fast.runner.integrate_compiled` runs it inside
:func:`csim.physics.jit.plain`). Only the calls differ, here:

- a model function's address in ``pi`` is a C function (``cc``) or a numba cfunc, called
  through ctypes, so that both backends evaluate the very same machine code of the model;
  where there is neither (no C compiler, and no numba or ``CSIM_PURE_PYTHON=1``) it is the
  key of a Python function of the cfunc source in :data:`PYTHON_FUNCTIONS`
  (:func:`csim.fast.module.load_model`, model backend ``python``);
- a method's gamma* outside the built-in dispatch is always the key of its Python kernel in
  :data:`PYTHON_FUNCTIONS` (:func:`csim.fast.module.method_dispatch` registers it there for the
  interpreted kernels instead of wrapping it in a cfunc);
- ``feval`` and ``eliminated`` are this package's own functions (their addresses in ``pi`` are ids);
- the model handle is a :class:`ModelHandle`, whose methods are the compiled overloads'
  bodies, for the core's :mod:`csim.physics.model`.

Python raises where machine code gives inf or NaN (a Python float divided by zero, a ``math``
function out of its domain): the loop's own norms are numpy's for that reason, but on the way
to a blow-up the interpreted loop can still stop with an exception where the compiled one runs
on to its own failure (:func:`csim.fast.runner.integrate_compiled` returns it as a failed run,
kind ``backend``, saying so).
"""
from __future__ import annotations

import ctypes
from collections.abc import Callable

from csim.fast.layout import F_JAC, F_MASS, F_PHI, F_TERMS, PI_FN, PI_ND, W_GAM, W_J, W_M, W_PHI, W_PT

#: key -> the Python function that stands for a C function at that "address" (model functions:
#: ``f(t, y, par, out)``; gamma*: the method's kernel ``g(r, gamma, phi, phi_dot, gains, fpar, ipar, out)``)
PYTHON_FUNCTIONS: dict[int, Callable] = {}

_P = ctypes.c_void_p
#: the model functions' C interface (csim.fast.layout)
_MODEL = ctypes.CFUNCTYPE(None, ctypes.c_double, _P, _P, _P)
#: address -> its ctypes function (made once)
_CTYPES: dict[int, Callable] = {}


def _c_function(addr: int) -> Callable:
    fn = _CTYPES.get(addr)
    if fn is None:
        if not addr:
            raise ValueError("a function's address in pi is 0")
        fn = _CTYPES[addr] = _MODEL(int(addr))
    return fn


def _data(a) -> int:
    """The address of an array's first element (C-contiguous: the kernels' arrays and their 1-D slices)."""
    if not a.flags.c_contiguous:
        raise RuntimeError("the interpreted kernels passed a strided array to a C function")
    return a.ctypes.data


def call_model(addr, t, y, par, out):
    """``void f(double t, const double *y, const double *par, double *out)`` at ``addr``, or its Python function."""
    fn = PYTHON_FUNCTIONS.get(addr)
    if fn is not None:
        fn(t, y, par, out)
    else:
        _c_function(addr)(t, _data(y), _data(par), _data(out))


def call_gamma(addr, r, gamma, phi, phi_dot, gains, n_gains, fpar, n_fpar, ipar, n_ipar, out):
    """A method's gamma* (:func:`.addresses.call_gamma`'s interface): its Python kernel, registered under ``addr``."""
    PYTHON_FUNCTIONS[addr](r, gamma, phi, phi_dot, gains, fpar, ipar, out)


def call_feval(addr, t, y, mode, located, par, pf, pi, w, piv, f, info):
    """This package's ``feval`` (the compiled copy calls its own through ``addr``)."""
    from .system import feval  # (system imports this module)

    return feval(t, y, mode, located, par, pf, pi, w, piv, f, info)


def call_eliminated(addr, pf, pi, w, piv):
    """This package's ``eliminated`` (the compiled copy calls its own through ``addr``)."""
    from .system import eliminated  # (system imports this module)

    return eliminated(pf, pi, w, piv)


class ModelHandle:
    """The core's model handle (:mod:`csim.physics.model`) over the model functions in ``pi``:
    each method calls one at the state ``ym`` [q, qd, W] and time ``t`` and copies its term out of ``w``."""

    __slots__ = ("par", "pi", "w", "ym", "t")

    def __init__(self, par, pi, w, ym, t):
        self.par, self.pi, self.w, self.ym, self.t = par, pi, w, ym, t

    def _at_q(self, fn, slot, q, out):
        self.ym[:q.size] = q
        call_model(self.pi[PI_FN + fn], self.t, self.ym, self.par, self.w)
        at = self.pi[slot]
        out[:] = self.w[at:at + out.size]

    def phi(self, q, out):
        self._at_q(F_PHI, W_PHI, q, out)

    def phi_t(self, q, out):
        if self.pi[PI_ND] == 0:  # no drive rows: the mechanism's own rows do not depend on t
            out[:] = 0.0
        else:
            self._at_q(F_PHI, W_PT, q, out)  # phi_ writes Phi and Phi_t

    def jacobian(self, q, out):
        self._at_q(F_JAC, W_J, q, out)

    def mass(self, q, out):
        self._at_q(F_MASS, W_M, q, out)

    def gamma(self, q, qd, out):
        m = q.size
        self.ym[:m] = q
        self.ym[m:2 * m] = qd
        call_model(self.pi[PI_FN + F_TERMS], self.t, self.ym, self.par, self.w)
        at = self.pi[W_GAM]
        out[:] = self.w[at:at + out.size]


def model_handle(par, pi, w, ym, t):
    """The core's model handle at time t (:class:`ModelHandle`; the compiled copy's is a tuple)."""
    return ModelHandle(par, pi, w, ym, t)
