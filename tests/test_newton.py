"""Newton-Raphson for the dependent coordinates, checked against the pendulum's closed form."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS

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


def test_the_branch_prediction_is_the_circles_taylor_polynomial(pendulum):
    # y(x) = -sqrt(L^2 - x^2) on the lower branch, L = 2: y' = -x / y, y'' = -L^2 / y^3
    from csim.solver.newton import BranchPoint

    model, par = pendulum
    x0 = 1.2
    y0 = -np.sqrt(4.0 - x0**2)
    q0 = np.array([x0, y0])
    point = BranchPoint.at(q0, model.phi_q(q0, par), np.array([0]), np.array([1]))
    assert point.tangent[0, 0] == pytest.approx(-x0 / y0, rel=1e-14)
    for dx in (1e-2, 1e-1):
        predicted, du, dv = point.predict(model, par, np.array([x0 + dx]), np.array([0]), np.array([1]))
        taylor = y0 - x0 / y0 * dx - 0.5 * 4.0 / y0**3 * dx**2
        assert predicted[1] == pytest.approx(taylor, abs=1e-14)
        assert du[0] == pytest.approx(dx, abs=1e-15) and dv[0] == pytest.approx(-x0 / y0 * dx, rel=1e-12)
    # third-order remainder: 100 times smaller for a step 10 times shorter (at most 1000)
    errors = [abs(point.predict(model, par, np.array([x0 + dx]), np.array([0]), np.array([1]))[0][1]
                  + np.sqrt(4.0 - (x0 + dx) ** 2)) for dx in (1e-1, 1e-2)]
    assert 500 < errors[0] / errors[1] < 2000


def test_following_the_circle_past_the_prediction_keeps_its_lower_half(pendulum):
    from csim.solver.newton import BranchPoint, follow_branch

    model, par = pendulum
    q0 = np.array([-1.9, -np.sqrt(4.0 - 1.9**2)])
    point = BranchPoint.at(q0, model.phi_q(q0, par), np.array([0]), np.array([1]))
    # 3.8 m along x, from one side of the circle to the other, in pieces
    solution, end = follow_branch(model, par, point, np.array([1.9]), np.array([0]), np.array([1]), 1e-14, 20)
    assert solution.q[1] == pytest.approx(-np.sqrt(4.0 - 1.9**2), abs=1e-13)
    assert end.tangent[0, 0] == pytest.approx(-1.9 / solution.q[1], rel=1e-12)
    # beyond |x| = L there is no assembly: the continuation says so, it does not jump
    with pytest.raises(DependentSolveError):
        follow_branch(model, par, point, np.array([2.5]), np.array([0]), np.array([1]), 1e-14, 20)


def test_the_prediction_through_phi_v_factors_equals_the_explicit_formula():
    """predict applies Phi_v^-1 through the LU factors and pivots a BranchPoint keeps (csim.physics.branch):
    v_pred = v_a + T du + 1/2 Phi_v^-1 gamma(q_a, [du, T du]) with numpy's inverse, on Andrews' mechanism
    (r = 6) in partitions whose factorizations swap rows (a pivot not copied with its factors would show)."""
    from csim.case import load_case
    from csim.pipeline import build_system, initial_state
    from csim.solver.newton import BranchPoint

    case = load_case(CONFIGS / "andrews.yaml")
    system = build_system(case)
    model, par = system.model, system.par
    q0 = initial_state(case, system)[:system.m]
    m, r = system.m, system.r
    rng = np.random.default_rng(3)
    swapped = tried = 0
    for _ in range(60):
        dep = np.sort(rng.choice(m, size=r, replace=False))
        ind = np.setdiff1d(np.arange(m), dep)
        J = model.phi_q(q0, par)
        if np.linalg.cond(J[:, dep]) > 1e8:  # (a singular block: no branch point there)
            continue
        point = BranchPoint.at(q0, J, ind, dep)
        tried += 1
        swapped += int(np.any(point.phi_v_piv != np.arange(r)))
        du = rng.normal(scale=0.01, size=m - r)
        predicted, _, _ = point.predict(model, par, q0[ind] + du, ind, dep)
        T = -np.linalg.solve(J[:, dep], J[:, ind])
        direction = np.zeros(m)
        direction[ind], direction[dep] = du, T @ du
        gamma = model.gamma(q0, direction, par)
        expected = q0[dep] + T @ du + 0.5 * np.linalg.solve(J[:, dep], gamma)
        np.testing.assert_allclose(point.tangent, T, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(predicted[dep], expected, rtol=1e-10, atol=1e-12)
    assert tried >= 8 and swapped >= 3, (tried, swapped)
