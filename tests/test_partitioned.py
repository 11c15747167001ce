"""Minimal coordinates by coordinate partitioning (``stabilization.method: minimal``)."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS, qr_case
from scipy.integrate import solve_ivp

from csim.case import load_case
from csim.pipeline import build_system, initial_state, run_case
from csim.solver.simulate import integrate

G = 9.81
# a pendulum that goes over the top: x alone cannot describe it at the horizontal (y = 0)
ROTATING = ["stabilization.method=minimal", "initial.q={x: 0.0}", "initial.qd={x: 7.0}", "initial.q_offset={}",
            "simulation.t_end=3", "simulation.rtol=1e-10", "simulation.atol=1e-10"]


def angle_reference(theta_dot0, t):
    """theta(t) of theta'' = -(g / L) sin(theta), L = 1, theta(0) = 0 (independent of csim)."""
    sol = solve_ivp(lambda _, s: [s[1], -G * np.sin(s[0])], (0, t[-1]), [0.0, theta_dot0], method="DOP853",
                    rtol=1e-13, atol=1e-13, dense_output=True)
    return sol.sol(t)[0]


@pytest.mark.parametrize("formulation", ["kkt", "elimination"])
def test_minimal_agrees_with_the_reference_and_holds_the_constraints(formulation, reference):
    res = run_case(qr_case("stabilization.method=minimal", f"formulation.method={formulation}"))
    assert res.ok
    # measured 3.7e-8 rad, as for the other formulations at rtol = 1e-10
    assert abs(res.q[-1, 0] - reference["q1"]) < 1e-6
    assert abs(res.qd[-1, 0] - reference["qd1"]) < 1e-5
    assert res.max_phi < 1e-12 and res.max_phi_dot < 1e-12
    assert len(res.event_times) == len(reference["events"])


def test_minimal_repartitions_through_the_singular_points_of_a_rotating_pendulum():
    case = load_case(CONFIGS / "pendulum.yaml", ROTATING)
    system = build_system(case)
    traj = integrate(system, initial_state(case, system), case.integration_settings())
    assert traj.status == "success", traj.message
    # x and y each fail twice a turn; the partition must have changed at least that often
    turns = 3.0 * 7.0 / (2 * np.pi)
    assert system.repartitions >= 2 * int(turns)
    theta = angle_reference(7.0, traj.t)
    x, y = traj.y[:, 0], traj.y[:, 1]
    assert np.max(np.abs(x - np.sin(theta))) < 1e-6
    assert np.max(np.abs(y + np.cos(theta))) < 1e-6
    assert np.max(np.abs((x**2 + y**2 - 1) / 2)) < 1e-12


def test_minimal_starts_on_the_manifold_from_a_perturbed_state():
    res = run_case(load_case(CONFIGS / "pendulum.yaml", ["stabilization.method=minimal", "simulation.t_end=0.5"]))
    assert res.ok
    assert np.abs(res.phi).max() < 1e-12 and np.abs(res.phi_dot).max() < 1e-12
    # the independent x is kept, y is solved: y0 = -sqrt(L^2 - x0^2)
    assert res.q[0, 0] == pytest.approx(0.5, abs=1e-15)
    assert res.q[0, 1] == pytest.approx(-np.sqrt(0.75), abs=1e-12)


def test_a_newton_failure_of_the_dependent_coordinates_is_reported():
    # one Newton step cannot reach |Phi| <= 1e-300: no partition helps, the run fails and says why
    res = run_case(load_case(CONFIGS / "pendulum.yaml", ["stabilization.method=minimal",
                                                          "stabilization.minimal_tol=1e-300",
                                                          "stabilization.minimal_max_iter=1"]))
    assert res.status == "failed"
    assert "Newton-Raphson for the dependent coordinates" in res.message


def test_a_high_threshold_keeps_the_partition_and_loses_accuracy():
    # choosing again only near the singularity (|y| < L / 1000) integrates x where dy/dx is
    # huge: the error grows (measured 4e-6 against 7e-8 with the default threshold of 20)
    over = [o.replace("simulation.t_end=3", "simulation.t_end=5") for o in ROTATING]
    late = run_case(load_case(CONFIGS / "pendulum.yaml", [*over, "stabilization.minimal_max_condition=1000"]))
    default = run_case(load_case(CONFIGS / "pendulum.yaml", over))
    theta = angle_reference(7.0, default.t)

    def error(res):
        return np.max(np.abs(res.q[:, 0] - np.sin(theta)))

    assert late.ok and default.ok
    assert error(default) < 1e-6 < error(late)
