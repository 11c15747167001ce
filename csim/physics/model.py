"""The model evaluations the core functions make: Phi, Phi_q, Phi_t, gamma and M at given coordinates.

A core function that must evaluate the model (the Newton solve of the dependent coordinates,
the branch prediction, the projection) calls these functions with a ``model`` handle. The
Python driver passes an object with the methods below (:class:`csim.solver.newton.PythonModel`,
over the :class:`csim.model.numeric.NumericModel`); the compiled kernels pass their own tuple,
for which :mod:`csim.fast.kernels` overloads these same functions (the model's C functions
called through their addresses). So the core is written once over both.

Every function writes its result into ``out``; matrices are flat and row-major.
"""
from __future__ import annotations


def model_phi(model, q, out):
    """Phi(q) (r,) into out."""
    model.phi(q, out)


def model_jacobian(model, q, out):
    """Phi_q(q) (r * m,) into out."""
    model.jacobian(q, out)


def model_phi_t(model, q, out):
    """Phi_t (r,) into out: the constraints' rates at fixed q, at the handle's time (zero but for
    the rows of drives, -f_j'(t))."""
    model.phi_t(q, out)


def model_gamma(model, q, qd, out):
    """gamma(q, qd) (r,) into out: Phi_q qdd = gamma is the acceleration-level constraint."""
    model.gamma(q, qd, out)


def model_mass(model, q, out):
    """M(q) (m * m,) into out."""
    model.mass(q, out)
