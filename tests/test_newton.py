"""Newton-Raphson for the dependent coordinates, checked against the pendulum's closed form."""
from __future__ import annotations

import numpy as np
import pytest

from csim.mechanisms import get_mechanism
from csim.model import build_numeric_model
from csim.solver.newton import (
    DependentSolveError,
    at_round_off,
    dependent_velocities,
    solve_dependent,
)


@pytest.fixture(scope="module")
def pendulum():
    model = build_numeric_model(get_mechanism("pendulum"))
    return model, model.parameter_vector({"L": 2.0})


def test_solves_the_circle_for_y_given_x(pendulum):
    model, par = pendulum
    sol = solve_dependent(model, par, np.array([1.2, -1.0]), np.array([1]), tol=1e-14, max_iter=20)
    # x^2 + y^2 = L^2 on the lower branch: y = -sqrt(L^2 - x^2)
    assert sol.q[0] == 1.2
    assert sol.q[1] == pytest.approx(-np.sqrt(4.0 - 1.2**2), abs=1e-14)
    assert sol.residual <= 1e-14 and 1 <= sol.iterations <= 8
    np.testing.assert_allclose(sol.phi_q, model.phi_q(sol.q, par), rtol=0, atol=0)


def test_dependent_velocities_are_tangent_to_the_circle(pendulum):
    model, par = pendulum
    sol = solve_dependent(model, par, np.array([1.2, -1.0]), np.array([1]), tol=1e-14, max_iter=20)
    qd = dependent_velocities(sol.phi_q, np.array([0.7, 99.0]), np.array([1]))
    # d/dt (x^2 + y^2) = 0: yd = -x xd / y
    assert qd[0] == 0.7 and qd[1] == pytest.approx(-1.2 * 0.7 / sol.q[1], rel=1e-14)


def test_failures_say_why(pendulum):
    model, par = pendulum
    # |x| > L: no real y, the iteration cannot converge
    with pytest.raises(DependentSolveError) as info:
        solve_dependent(model, par, np.array([2.5, -1.0]), np.array([1]), tol=1e-12, max_iter=30)
    assert info.value.reason in ("no_convergence", "singular", "non_finite")
    with pytest.raises(DependentSolveError) as info:
        solve_dependent(model, par, np.array([1.2, -1.0]), np.array([1]), tol=1e-14, max_iter=1)
    assert info.value.reason == "no_convergence" and abs(info.value.phi[0]) > 1e-14
    # y = 0 is where Phi_y = y / L vanishes
    with pytest.raises(DependentSolveError) as info:
        solve_dependent(model, par, np.array([1.2, 0.0]), np.array([1]), tol=1e-14, max_iter=5)
    assert info.value.reason == "singular"


def test_stops_at_the_round_off_of_large_coordinates():
    q = np.array([1e3, 1.0])
    assert at_round_off(np.array([1e-13]), q)  # 8 eps 1e3 = 1.8e-12
    assert not at_round_off(np.array([1e-11]), q)
    # below |q| = 1 the floor is 8 eps = 1.8e-15
    assert at_round_off(np.array([1e-15]), np.array([0.5, 0.1]))
    assert not at_round_off(np.array([1e-14]), np.array([0.5, 0.1]))
