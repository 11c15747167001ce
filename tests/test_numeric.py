"""The numeric model's functions (csim.model.numeric): NaN, never an exception, outside math's domain."""
from __future__ import annotations

import math

import numpy as np

from csim.model.numeric import _nan_outside_domain


def test_domain_errors_become_nan_of_the_right_shape(qr_model, qr_par):
    q = np.array([np.inf, 0.0, 0.0])
    phi = qr_model.phi(q, qr_par)  # math.cos(inf) inside: "math domain error" before
    assert phi.shape == (qr_model.n_constraints,) and np.isnan(phi).all()
    assert np.isnan(qr_model.potential_energy(np.array([np.nan, 0.0, 0.0]), qr_par))
    assert qr_model.phi_q(q, qr_par).shape == (qr_model.n_constraints, 3)


def test_the_guard_keeps_values_and_shapes():
    def f(q, par):
        return np.array([[math.sqrt(q[0]), 1.0], [2.0, 3.0]])

    g = _nan_outside_domain(f)
    assert g(np.array([4.0]), np.zeros(0))[0, 0] == 2.0
    out = g(np.array([-1.0]), np.zeros(0))
    assert out.shape == (2, 2) and np.isnan(out).all()
