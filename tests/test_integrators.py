"""Integrators: RK4's order and dense output, the registry."""
from __future__ import annotations

import numpy as np
import pytest

from csim.solver.integrators import INTEGRATORS, make_integrator
from csim.solver.rk4 import RK4


def harmonic(t, y):
    return np.array([y[1], -y[0]])


def integrate_to(solver):
    while solver.status == "running":
        solver.step()
    return solver


def test_rk4_is_fourth_order_on_the_harmonic_oscillator():
    errors = []
    for h in (0.1, 0.05, 0.025):
        s = integrate_to(RK4(harmonic, 0.0, [1.0, 0.0], 2.0, step=h))
        errors.append(abs(s.y[0] - np.cos(2.0)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(orders, 4.0, atol=0.1)


def test_rk4_counts_four_evaluations_per_step_and_ends_on_t_bound():
    s = integrate_to(RK4(harmonic, 0.0, [1.0, 0.0], 1.05, step=0.1))
    assert s.t == 1.05
    assert s.nfev == 1 + 4 * 11


def test_rk4_dense_output_is_third_order_accurate_inside_a_step():
    errs = []
    for h in (0.1, 0.05):
        s = RK4(harmonic, 0.0, [1.0, 0.0], 1.0, step=h)
        s.step()
        errs.append(abs(s.dense_output()(h / 3)[0] - np.cos(h / 3)))
    assert errs[0] / errs[1] > 2**3.5  # local error O(h^4)


def test_rk4_rejects_a_nonpositive_step():
    with pytest.raises(ValueError, match="`step` must be positive"):
        RK4(harmonic, 0.0, [1.0, 0.0], 1.0, step=0.0)


@pytest.mark.parametrize("name", [n for n, info in INTEGRATORS.items() if info.adaptive])
def test_adaptive_integrators_meet_their_tolerance(name):
    s = integrate_to(make_integrator(name, harmonic, 0.0, np.array([1.0, 0.0]), 3.0, rtol=1e-9, atol=1e-9))
    assert abs(s.y[0] - np.cos(3.0)) < 1e-6


def test_unknown_integrator_lists_valid_names():
    with pytest.raises(KeyError, match="valid names: RK45, DOP853"):
        make_integrator("Euler", harmonic, 0.0, np.zeros(2), 1.0, rtol=1e-6, atol=1e-6)


def test_difference_jacobians_stay_finite_for_a_variable_nothing_uses():
    """scipy's num_jac multiplies the step of a column with no effect by 10 at every call,
    without bound (a driven shaft angle reached inf and stopped Radau); csim's caps it."""
    from csim.solver.dae import JAC_MAX_FACTOR, DifferenceJacobian

    def fun(t, y):  # y[1] enters nothing
        return np.array([-y[0], 0.0])

    jac = DifferenceJacobian(fun, 1e-8)
    y = np.array([1.0, 62.8])
    for _ in range(400):
        J = jac(0.0, y)
    assert np.all(np.isfinite(J)) and np.max(jac.factor) <= JAC_MAX_FACTOR
    assert J[0, 0] == pytest.approx(-1.0, rel=1e-6) and J[0, 1] == 0.0
