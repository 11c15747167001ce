"""Force elements on registered mechanisms (csim/mechanisms/sites.py) against independent references.

The references are written here by hand: the small-angle frequency of a pendulum with a
spring (sqrt(g/L + k/m) for a spring to the point below the pivot, sqrt(g/L + k/(m L^2))
for a torsional one), its energy, static equilibria solved by hand (m g L sin(theta) = tau),
the test set's reference solution of Andrews' mechanism (its spring and torque given as
elements instead of the mechanism's own), and the quick-return's ``loads`` version of the
same torque and cutting force.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from conftest import CONFIGS
from test_andrews import Q_END, QD_END

from csim.case import load_case, validate_case
from csim.errors import CaseError
from csim.pipeline import run_case

M, L, G = 1.3, 0.9, 9.81


def pendulum(forces, x0=0.01, parameters=None, **simulation):
    """The Cartesian pendulum (m = 1.3 kg, L = 0.9 m) from x = x0 at rest, with ``forces``."""
    sim = {"t_end": 3.0, "rtol": 1e-11, "atol": 1e-12, "backend": "python", **simulation}
    return validate_case({"mechanism": {"name": "pendulum", "parameters": {"m": M, "L": L, "g": G,
                                                                           **(parameters or {})},
                                        "forces": forces},
                          "initial": {"q": {"x": x0}, "qd": {"x": 0.0}}, "simulation": sim,
                          "output": {"dt": 1e-3}})


def period(t, angle):
    """Mean period [s] from the upward zero crossings of ``angle`` (linear interpolation)."""
    i = np.flatnonzero((angle[:-1] < 0) & (angle[1:] >= 0))
    crossings = t[i] - angle[i] * (t[i + 1] - t[i]) / (angle[i + 1] - angle[i])
    assert crossings.size >= 3
    return float(np.mean(np.diff(crossings)))


def angle_of(res):
    return res.observables[:, res.observable_names.index("angle")]


@pytest.mark.parametrize("element, omega2", [
    # V = k/2 |r_bob - (0, -L)|^2 = k L^2 (1 - cos theta) ~ k L^2 theta^2 / 2
    ({"type": "spring", "between": [["rod", "bob"], ["ground", [0, "-L", 0]]], "stiffness": "k"}, G / L + 40 / M),
    # V = k/2 theta^2 about the pivot
    ({"type": "joint_spring", "joint": "pivot", "stiffness": "k"}, G / L + 40 / (M * L**2)),
])
def test_spring_on_the_pendulum_has_the_small_angle_frequency(element, omega2):
    res = run_case(pendulum([{"name": "s", **element}], x0=0.005, parameters={"k": 40.0}))
    assert res.status == "success", res.message
    assert period(res.t, angle_of(res)) == pytest.approx(2 * math.pi / math.sqrt(omega2), rel=1e-5)
    assert res.energy_error_relative < 1e-8  # no stabilization: the drift off the circle (measured 2.3e-9)


def test_spring_and_damper_on_the_pendulum_keep_the_energy_balance():
    """A large swing: T + V (spring included) + the damper's dissipation stays constant, and
    the dissipation is the integral of c (dl/dt)^2 from the recorded spring length."""
    res = run_case(pendulum([{"name": "s", "type": "spring", "between": [["rod", "bob"], ["ground", [0.4, -1.0, 0]]],
                              "stiffness": 25, "free_length": 0.3, "damping": 0.7}], x0=0.8, t_end=4.0))
    assert res.status == "success", res.message
    assert res.energy_error_relative < 1e-8
    rate = res.observable_rates[:, res.observable_names.index("s_length")]
    lost = np.concatenate(([0.0], np.cumsum(0.5 * (rate[1:] ** 2 + rate[:-1] ** 2) * np.diff(res.t)))) * 0.7
    assert lost[-1] > 0.1
    np.testing.assert_allclose(-res.work[:, -1], lost, rtol=0, atol=2e-4 * lost[-1])


@pytest.mark.parametrize("element", [
    {"type": "actuator", "joint": "pivot", "torque": "tau"},
    {"type": "torque", "link": "rod", "axis": [0, 0, 1], "value": "tau"},
    # perpendicular to the rod at the bob, turning with it: moment F L
    {"type": "force", "link": "rod", "point": "bob", "direction": [0, 1, 0], "frame": "link", "value": "tau/L"},
])
def test_torque_holds_the_pendulum_at_the_hand_solved_equilibrium(element):
    """m g L sin(theta) = tau: started there at rest, the pendulum stays."""
    tau = 4.0
    theta = math.asin(tau / (M * G * L))
    res = run_case(pendulum([{"name": "hold", **element}], x0=L * math.sin(theta), parameters={"tau": tau},
                            t_end=1.0))
    assert res.status == "success", res.message
    assert np.max(np.abs(angle_of(res) - theta)) < 1e-9


def quick_return(forces=None, loads=None, t_end=2.0):
    data = load_case(CONFIGS / "quick_return.yaml").data
    data = copy.deepcopy(data)
    data["simulation"].update(t_end=t_end, backend="python")
    data["loads"] = loads or {}
    if forces is not None:
        data["mechanism"]["forces"] = forces
    return validate_case(data)


def test_quick_return_torque_and_cutting_force_as_elements_equal_the_loads():
    """The paper's crank torque as an actuator on joint O and its cutting force as a switched
    force at D on the ram: the run of configs/quick_return.yaml."""
    loads = run_case(quick_return(loads={"torque": 165521.0, "cutting_force": {
        "magnitude": 2e5, "window": [-4.0, 1.2], "velocity": "negative"}}))
    elements = run_case(quick_return([
        {"name": "motor", "type": "actuator", "joint": "O", "torque": 165521.0},
        {"name": "cut", "type": "force", "link": "ram", "point": "D", "direction": [1, 0, 0], "value": 2e5,
         "window": [-4.0, 1.2], "velocity": "negative"}]))
    assert loads.status == elements.status == "success"
    assert len(elements.event_times) == len(loads.event_times) > 20
    np.testing.assert_allclose(elements.event_times, loads.event_times, rtol=0, atol=1e-8)
    # the two differ in round-off only (their step sequences part at rtol = 1e-10)
    np.testing.assert_allclose(elements.q, loads.q, rtol=0, atol=1e-7)
    np.testing.assert_allclose(elements.work[-1, 2:], loads.work[-1], rtol=1e-7)


@pytest.mark.slow  # about 17 s: the extended model is derived anew
def test_andrews_spring_and_torque_as_elements_reach_the_test_sets_solution():
    """The mechanism's own spring switched off (c0 = 0) and given as a spring element
    between D on the triangle and C on the ground, its torque as an actuator on joint O."""
    data = copy.deepcopy(load_case(CONFIGS / "andrews.yaml", ["simulation.backend=python"]).data)
    data["mechanism"]["parameters"] = {"c0": 0.0, "k": 4530.0}
    data["loads"] = {}
    data["mechanism"]["forces"] = [
        {"name": "squeeze", "type": "spring", "between": [["triangle", "D"], ["ground", "C"]], "stiffness": "k",
         "free_length": "l0"},
        {"name": "motor", "type": "actuator", "joint": "O", "torque": 0.033}]
    res = run_case(validate_case(data))
    assert res.status == "success", res.message
    np.testing.assert_allclose(res.q[-1], Q_END, rtol=0, atol=1e-8)
    np.testing.assert_allclose(res.qd[-1], QD_END, rtol=1e-9, atol=1e-6)
    assert res.energy_error_relative < 1e-9


@pytest.mark.parametrize("element, expected", [
    ({"type": "actuator", "joint": "Q", "torque": 1},
     "mechanism.forces[0] (f).joint: got 'Q' (string); no such joint of quick_return; expected one of O, B, A, "
     "slide, C, D, ram"),
    ({"type": "actuator", "joint": "ram", "torque": 1},
     "mechanism.forces[0] (f).torque: joint ram (ram on its guide: x_D, positive along +x) is a translation; "
     "expected force"),
    ({"type": "force", "link": "piston", "point": "D", "direction": [1, 0, 0], "value": 1},
     "mechanism.forces[0] (f).link: got 'piston' (string); not a body of quick_return; expected one of ground, "
     "crank, rocker, rod, block, ram"),
    ({"type": "spring", "between": [["crank", "D"], ["ground", "O"]], "stiffness": 1},
     "mechanism.forces[0] (f).between[0][1]: got 'D' (string); body crank has no such point; expected one of its "
     "points (O, A)"),
    ({"type": "joint_spring", "joint": "O", "stiffness": "-l1"},
     "mechanism.forces[0] (f).stiffness: got '-l1' (string), -1.5 N m/rad at the parameter values; expected a "
     "value >= 0"),
    ({"type": "actuator", "joint": "O", "torque": "T0*sin(w*t)"},
     "mechanism.forces[0] (f).torque: got 'T0*sin(w*t)' (string); unknown name 'T0'"),
])
def test_bad_elements_on_a_registered_mechanism_name_the_row_and_key(element, expected):
    with pytest.raises(CaseError) as excinfo:
        quick_return([{"name": "f", **element}])
    assert any(p.startswith(expected) for p in excinfo.value.problems), excinfo.value.problems


def test_element_named_like_a_load_and_unused_parameter_are_reported():
    with pytest.raises(CaseError) as excinfo:
        quick_return([{"name": "torque", "type": "actuator", "joint": "O", "torque": 1.0}])
    assert any(p.startswith("mechanism.forces[0] (torque).name: the load 'torque' it adds is already a load of "
                            "quick_return") for p in excinfo.value.problems), excinfo.value.problems
    data = copy.deepcopy(quick_return().data)
    data["mechanism"]["parameters"]["kk"] = 3.0  # used by no element: still an unknown parameter
    data["mechanism"]["forces"] = [{"name": "s", "type": "joint_spring", "joint": "O", "stiffness": 2.0}]
    with pytest.raises(CaseError) as excinfo:
        validate_case(data)
    assert any(p.startswith("mechanism.parameters.kk") for p in excinfo.value.problems), excinfo.value.problems


def test_element_parameters_are_parameters_of_the_run():
    """A parameter only the elements use is set like the mechanism's own (sweeps, --set)."""
    case = pendulum([{"name": "s", "type": "joint_spring", "joint": "pivot", "stiffness": "k"}],
                    parameters={"k": 7.0})
    assert case.parameters["k"] == 7.0
    assert case.mechanism.parameter("k").description == "parameter of mechanism.forces"
