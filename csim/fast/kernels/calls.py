"""How the kernels reach the mechanism: its model functions, the stabilization method's gamma*,
the right-hand side ``feval`` and the elimination's solve, each called through an address in
``pi``, and the core's model handle (:mod:`csim.physics.model`).

A compiled copy calls the addresses from machine code (:mod:`.addresses`, the compiled-only
part); the interpreted package calls the same functions from Python (:mod:`.interpreted`).
Everything below is the same source for both.
"""
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
    PI_FN,
    PI_GAMMA_FN,
    W_E,
)
from csim.solver.methods.baumgarte import baumgarte_gamma_star
from csim.solver.methods.sliding_mode import sliding_mode_gamma_star

from .common import hot
from .variant import COMPILED

if COMPILED:
    from .addresses import call_eliminated, call_feval, call_gamma, call_model, model_handle
else:
    from .interpreted import call_eliminated, call_feval, call_gamma, call_model, model_handle

__all__ = ["call_eliminated", "call_feval", "model_handle"]


# the model functions of the mechanism in pi (csim.fast.layout: one C interface for all)
@hot
def terms(t, y, par, pi, w):
    """Every term of the right-hand side at (t, y) into w."""
    call_model(pi[PI_FN + F_TERMS], t, y, par, w)


@hot
def phi_(y, par, pi, w):
    call_model(pi[PI_FN + F_PHI], 0.0, y, par, w)


@hot
def phi_at(t, y, par, pi, w):
    """Phi at time t (drive rows depend on it)."""
    call_model(pi[PI_FN + F_PHI], t, y, par, w)


@hot
def jac(y, par, pi, w):
    call_model(pi[PI_FN + F_JAC], 0.0, y, par, w)


@hot
def mass(y, par, pi, w):
    call_model(pi[PI_FN + F_MASS], 0.0, y, par, w)


@hot
def loads_(y, par, pi, w):
    """Load coordinates s and their Jacobian into w, for the switching functions."""
    call_model(pi[PI_FN + F_LOADS], 0.0, y, par, w)


@hot
def kinetic(y, par, pi, w):
    """Kinetic energy [J] (w[W_E] is its scratch)."""
    call_model(pi[PI_FN + F_KINETIC], 0.0, y, par, w[pi[W_E]:])
    return w[pi[W_E]]


@hot
def potential(y, par, pi, w):
    """Potential energy [J] (w[W_E] is its scratch)."""
    call_model(pi[PI_FN + F_POTENTIAL], 0.0, y, par, w[pi[W_E]:])
    return w[pi[W_E]]


@hot
def observe(y, par, pi, out):
    """The observables and their rates into out (2 o,)."""
    call_model(pi[PI_FN + F_OBSERVE], 0.0, y, par, out)


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
        call_gamma(pi[PI_GAMMA_FN], r, gamma, phi, phi_dot, gains, gains.size, fpar, fpar.size, ipar, ipar.size, out)
    else:
        for i in range(r):
            out[i] = gamma[i]
