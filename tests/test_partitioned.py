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


# --- the assembly branch (issue 15) ----------------------------------------------------------

# a crank-rocker four-bar: crank A-B (a), coupler B-C (b), rocker D-C (c), ground A-D (d);
# Grashof (shortest + longest <= the other two): the crank turns fully and the two closures never meet
A, B_, C_, D = 1.0, 1.5, 1.5, 1.2


def fourbar_system():
    """A PartitionedSystem of the four-bar in the angles (q1, q2, q3) of crank, coupler and rocker."""
    import sympy as sp

    from csim.load_laws import LoadSet
    from csim.model import build_numeric_model
    from csim.model.definition import MechanismDefinition, PlanarBody
    from csim.solver.formulations import make_formulation
    from csim.solver.partitioned import PartitionedSystem
    from csim.solver.stabilizers import make_stabilizer

    q = sp.symbols("q1 q2 q3", real=True)
    qd = sp.symbols("q1_dot q2_dot q3_dot", real=True)
    bar = [PlanarBody(f"bar{i}", sp.Integer(1), sp.Rational(1, 12), (sp.Integer(0), sp.Integer(0)), q[i])
           for i in range(3)]  # T only enters the accelerations, not the branch
    definition = MechanismDefinition(
        name="fourbar_branch_test", description="crank-rocker four-bar", coordinates=list(q), velocities=list(qd),
        coordinate_units=["rad"] * 3, parameters=[],
        kinetic_energy=sum(b.kinetic_energy(list(q), list(qd)) for b in bar), potential_energy=sp.Integer(0),
        # C reached through the crank and coupler equals C on the rocker
        constraints=[A * sp.cos(q[0]) + B_ * sp.cos(q[1]) - D - C_ * sp.cos(q[2]),
                     A * sp.sin(q[0]) + B_ * sp.sin(q[1]) - C_ * sp.sin(q[2])])
    model = build_numeric_model(definition)
    return PartitionedSystem(model=model, par=model.parameter_vector(), loads=LoadSet([]),
                             formulation=make_formulation("kkt"), stabilizer=make_stabilizer("minimal", {}))


def closure(q1, sign):
    """(q2, q3) of the closure with C on side ``sign`` of the line B-D: circle intersection, independent of csim."""
    b = np.array([A * np.cos(q1), A * np.sin(q1)])
    bd = np.array([D, 0.0]) - b
    dist = np.hypot(*bd)
    along = (dist**2 + B_**2 - C_**2) / (2 * dist)  # from B towards D, to the chord through both points
    across = np.sqrt(B_**2 - along**2)
    e = bd / dist
    c = b + along * e + sign * across * np.array([-e[1], e[0]])
    return np.arctan2(*(c - b)[::-1]), np.arctan2(*(c - np.array([D, 0.0]))[::-1])


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def test_a_far_trial_stage_does_not_move_the_next_solve_to_the_other_closure():
    # accepted at q1 = 1.6 (the crank independent) on the closure with C left of B-D
    system = fourbar_system()
    system.start(np.array([1.6, *closure(1.6, +1), 0.0, 0.0, 0.0]))
    assert list(system.independent) == [0]
    # a trial stage 3 rad of crank ahead (a step the integrator will reject), then a stage
    # near the accepted state: Newton used to start the second from the first's solution,
    # which it had found on the other closure, and stayed there
    far = system.to_full(np.array([4.6, 0.0]))
    near = system.to_full(np.array([1.7, 0.0]))
    np.testing.assert_allclose(wrap(far[1:3] - closure(4.6, +1)), 0.0, atol=1e-12)
    np.testing.assert_allclose(wrap(near[1:3] - closure(1.7, +1)), 0.0, atol=1e-12)
    assert np.max(np.abs(wrap(near[1:3] - closure(1.7, -1)))) > 0.5  # the closures are far apart


def test_the_branch_is_followed_in_pieces_where_one_newton_solve_would_leave_it():
    from csim.solver.newton import BranchLeftError, BranchPoint, _predicted_solve, follow_branch, solve_dependent

    system = fourbar_system()
    model, par, u, v = system.model, system.par, np.array([0]), np.array([1, 2])
    q0 = np.array([0.6, *closure(0.6, +1)])
    point = BranchPoint.at(q0, model.phi_q(q0, par), u, v)
    # one Newton solve from the linear prediction 1 rad of crank back lands on the other closure
    # (from the second-order one too: below, the check is what catches it)
    predicted = q0.copy()
    predicted[0] = -0.4
    predicted[1:] += point.tangent @ [-1.0]
    plain = solve_dependent(model, par, predicted, v, 1e-13, 20)
    np.testing.assert_allclose(wrap(plain.q[1:] - closure(-0.4, -1)), 0.0, atol=1e-12)
    # the continuity test tells: the solution is farther from the prediction than a branch can bend
    with pytest.raises(BranchLeftError) as info:
        _predicted_solve(model, par, point, np.array([-0.4]), u, v, 1e-13, 20)
    assert "from the branch's prediction" in info.value.detail
    # followed along the way, the branch is kept
    followed, end = follow_branch(model, par, point, np.array([-0.4]), u, v, 1e-13, 20)
    np.testing.assert_allclose(wrap(followed.q[1:] - closure(-0.4, +1)), 0.0, atol=1e-12)
    np.testing.assert_array_equal(end.q, followed.q)


def test_every_closure_is_kept_over_moves_up_to_half_a_turn():
    # from 12 accepted states on each closure, solves 0.25 to 3 rad of crank ahead and behind
    from csim.solver.newton import BranchPoint, follow_branch

    system = fourbar_system()
    model, par, u, v = system.model, system.par, np.array([0]), np.array([1, 2])
    for sign in (+1, -1):
        for q1 in np.linspace(0.0, 2 * np.pi, 12, endpoint=False):
            q0 = np.array([q1, *closure(q1, sign)])
            point = BranchPoint.at(q0, model.phi_q(q0, par), u, v)
            for move in (-3.0, -1.5, -0.25, 0.25, 1.5, 3.0):
                solution, _ = follow_branch(model, par, point, np.array([q1 + move]), u, v, 1e-13, 20)
                np.testing.assert_allclose(wrap(solution.q[1:] - closure(q1 + move, sign)), 0.0, atol=1e-11,
                                           err_msg=f"closure {sign}, from q1 = {q1:.3f} by {move}")


def test_minimal_keeps_the_assembly_of_andrews_mechanism():
    # issue 15: at rtol = atol = 1e-8 the loop H-E flipped to its other closure at t = 0.028 s
    # (Omega from -0.04 to +3.07 rad between two samples), the energy balance jumped by 16 %
    # of the work done, and the run reported success
    from test_andrews import Q_END

    res = run_case(load_case(CONFIGS / "andrews.yaml", ["stabilization.method=minimal", "simulation.rtol=1e-8",
                                                         "simulation.atol=1e-8", "simulation.backend=python"]))
    assert res.ok, res.message
    # the reference solution of the IVP test set at t = 0.03 s; measured 7.9e-7 rad (rtol 1e-8)
    np.testing.assert_allclose(res.q[-1], Q_END, rtol=0, atol=5e-6)
    # gamma .. epsilon swing within a closure (by at most 0.15 rad between samples 0.5 ms
    # apart, measured); a change of closure moves them by about 3 rad
    assert np.max(np.abs(np.diff(res.q[:, 2:], axis=0))) < 0.3
    balance = res.kinetic + res.potential - res.kinetic[0] - res.potential[0] - res.work[:, 0]
    assert np.max(np.abs(balance)) < 2e-6 * np.max(res.work[:, 0])  # measured 2.3e-7; 0.16 before
    assert res.max_phi < 1e-12


def test_a_breakdown_after_a_step_repartitions_from_the_accepted_state(monkeypatch):
    """When after_step raises a partition breakdown, the driver repartitions from the state the
    integrator accepted at the time it reached (not from the state before the step)."""
    from csim.errors import PartitionBreakdown
    from csim.solver.partitioned import PartitionedSystem

    case = qr_case("stabilization.method=minimal", "simulation.backend=python", "simulation.t_end=0.05")
    system = build_system(case)
    seen: dict = {}
    after_step, repartition = PartitionedSystem.after_step, PartitionedSystem.repartition

    def breaking(self, t, y):
        seen["calls"] = seen.get("calls", 0) + 1
        if seen["calls"] == 2:
            seen["accepted"] = np.array(y)
            raise PartitionBreakdown("a test breakdown", "singular")
        return after_step(self, t, y)

    def recording(self, y, exc):
        seen["from"] = np.array(y)
        return repartition(self, y, exc)

    monkeypatch.setattr(PartitionedSystem, "after_step", breaking)
    monkeypatch.setattr(PartitionedSystem, "repartition", recording)
    integrate(system, initial_state(case, system), case.integration_settings())  # (no better partition exists)
    np.testing.assert_array_equal(seen["from"], seen["accepted"])


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_a_mass_matrix_singular_on_the_tangent_space_stops_minimal_saying_so(backend):
    """The four-bar with its coupler and rocker massless and the crank's mass at its pivot without inertia:
    M vanishes on the one direction the mechanism can move, so R^T M R is singular (helper-27). The run stops
    at t = 0 with minimal's own message (it said "singular KKT matrix", a matrix minimal does not form)."""
    import yaml

    from csim.case import validate_case

    data = yaml.safe_load((CONFIGS / "fourbar_gravity.yaml").read_text())
    links = {link["name"]: link for link in data["mechanism"]["links"] if "name" in link}
    for name in ("coupler", "rocker"):
        for key in ("mass", "com", "inertia"):
            links[name].pop(key)
    links["crank"].update(com=[0, 0, 0], inertia=0)
    data.setdefault("stabilization", {})["method"] = "minimal"
    data.setdefault("simulation", {})["backend"] = backend
    result = run_case(validate_case(data))
    assert not result.ok and result.backend == backend and result.failure == "singular"
    assert result.message.startswith("minimal: R^T M R is singular: the mass matrix is singular on the constraints' "
                                     "tangent space"), result.message
