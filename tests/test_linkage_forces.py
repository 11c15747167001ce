"""Force elements of tabled mechanisms (csim/linkage/forces.py) against independent references.

Each reference is written here from first principles, not taken from csim: the closed-form
damped oscillation, hand-written equations of motion integrated by scipy, the small-angle
frequency of a spring pendulum, the energy of a pendulum written by hand, the damper's
dissipation integrated from the recorded elongation rate, and the registered quick-return
mechanism (csim/mechanisms/quick_return.py, written by hand in its own coordinates).
"""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from csim.case import load_case, validate_case
from csim.pipeline import run_case

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
SLIDE = [0, 0, 0, "90*deg", "90*deg", 0]  # a P frame whose z axis is global x


def run(mechanism: dict, initial: dict, **simulation):
    """Run a link-coupling case given as dicts (Python backend unless simulation says otherwise)."""
    dt, stabilization = simulation.pop("dt", 0.01), simulation.pop("stabilization", {})
    sim = {"t_end": 2.0, "rtol": 1e-11, "atol": 1e-11, "backend": "python", **simulation}
    case = validate_case({"mechanism": copy.deepcopy(mechanism), "initial": initial, "simulation": sim,
                          "output": {"dt": dt}, "stabilization": stabilization})
    result = run_case(case)
    assert result.status == "success", result.message
    return result


def slider(forces, **parameters) -> dict:
    """A block of mass m on a horizontal prismatic joint (joint variable s_slide [m], along x)."""
    return {"label": "slider", "parameters": {"m": 2.0, **parameters},
            "links": [{"link": 0, "name": "ground", "joints": [["P", SLIDE, "G"], ["R", [-1, 0, 0], "E"]]},
                      {"link": 1, "name": "block", "joints": [["P", SLIDE, "G"]], "mass": "m"}],
            "couplings": [{"name": "slide", "couple": ["ground", "G", "block", "G"]}],
            "forces": forces}


def pendulum(forces, **parameters) -> dict:
    """A bar pinned at O, centre of mass at a on its x axis, under gravity -y (q_O from +x)."""
    return {"label": "pendulum", "parameters": {"m": 1.5, "a": 0.4, "L": 0.8, "J": 0.02, **parameters},
            "gravity": [0, -9.81, 0],
            "links": [{"link": 0, "name": "ground", "joints": [["R", 0, "O"]]},
                      {"link": 1, "name": "bar", "joints": [["R", 0, "O"], ["R", ["L", 0, 0], "P"]], "mass": "m",
                       "com": ["a", 0, 0], "inertia": "J"}],
            "couplings": [{"name": "O", "couple": ["ground", "O", "bar", "O"]}],
            "forces": forces}


def test_spring_and_damper_on_a_prismatic_joint_is_the_damped_oscillation():
    """m x'' + c x' + k x = 0 with x = s - L0: x = exp(-z w t) (x0 cos wd t + z w x0 / wd sin wd t)."""
    m, k, c, L0, s0 = 2.0, 50.0, 1.5, 0.3, 0.5
    res = run(slider([{"name": "spring", "type": "joint_spring", "joint": "slide", "stiffness": "k",
                       "free_length": "L0", "damping": "c"}], k=k, c=c, L0=L0),
              {"q": {"s_slide": s0}, "qd": {"s_slide": 0.0}}, t_end=3.0)
    w = math.sqrt(k / m)
    z = c / (2 * m * w)
    wd = w * math.sqrt(1 - z * z)
    x0 = s0 - L0
    x = np.exp(-z * w * res.t) * (x0 * np.cos(wd * res.t) + z * w * x0 / wd * np.sin(wd * res.t))
    assert np.max(np.abs(res.q[:, 0] - L0 - x)) < 1e-9
    # the damper's work is the energy lost: T + V + dissipation stays constant
    assert res.energy_error_relative < 1e-9
    assert res.work[-1, 0] < -0.01


def test_point_to_point_spring_law_and_time_dependent_actuator_against_hand_ode():
    """A cubic spring (force: law of l, ldot) from E = (-1, 0) to the block, and a force
    F0 sin(W t) on the slide: m s'' = F0 sin(W t) - k3 (l - L0)^3 - c ldot, l = s + 1."""
    m, k3, c, L0, F0, W = 2.0, 400.0, 0.8, 1.2, 3.0, 7.0
    forces = [{"name": "cubic", "type": "spring", "between": [["ground", "E"], ["block", [0, 0, 0]]],
               "force": "k3*(l - L0)^3 + c*ldot"},
              {"name": "push", "type": "actuator", "joint": "slide", "force": "F0*sin(W*t)"}]
    res = run(slider(forces, k3=k3, c=c, L0=L0, F0=F0, W=W), {"q": {"s_slide": 0.5}, "qd": {"s_slide": 0.1}},
              t_end=3.0)

    def f(t, y):
        s, v = y
        return [v, (F0 * math.sin(W * t) - k3 * (s + 1 - L0) ** 3 - c * v) / m]

    ref = solve_ivp(f, (0, 3.0), [0.5, 0.1], t_eval=res.t, rtol=1e-12, atol=1e-12, method="DOP853")
    assert np.max(np.abs(res.q[:, 0] - ref.y[0])) < 1e-8
    assert np.max(np.abs(res.observables[:, res.observable_names.index("cubic_length")] - (ref.y[0] + 1))) < 1e-8
    assert res.energy_error_relative < 1e-8  # the two loads' work closes the balance


def test_pendulum_with_torsional_spring_conserves_energy_and_has_the_small_angle_frequency():
    m, a, J, g, k = 1.5, 0.4, 0.02, 9.81, 3.0
    down = -math.pi / 2  # hanging: gravity's equilibrium, and the spring's free angle
    spring = [{"name": "torsion", "type": "joint_spring", "joint": "O", "stiffness": "k", "free_angle": "-pi/2"}]
    I_O = J + m * a * a
    w = math.sqrt((k + m * g * a) / I_O)  # I_O x'' = -(k + m g a) x for small x
    theta0 = 1e-4
    res = run(pendulum(spring, k=k), {"q": {"q_O": down + theta0}, "qd": {"q_O": 0.0}}, t_end=3 * 2 * math.pi / w,
              dt=0.002)
    assert np.max(np.abs(res.q[:, 0] - down - theta0 * np.cos(w * res.t))) < 1e-6 * theta0
    # a large swing: T + V written here by hand is constant
    res = run(pendulum(spring, k=k), {"q": {"q_O": down + 1.2}, "qd": {"q_O": 0.0}}, t_end=3.0)
    th, thd = res.q[:, 0], res.qd[:, 0]
    energy = 0.5 * I_O * thd**2 + m * g * a * np.sin(th) + 0.5 * k * (th - down) ** 2
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(energy - m * g * a * np.sin(down)))
    assert np.max(np.abs(res.potential - res.potential[0] - (energy - energy[0] - 0.5 * I_O * thd**2))) < 1e-9


def test_four_bar_with_a_damper_loses_the_integrated_dissipation():
    """E(0) - E(t) = int c ldot^2 dt, the integral taken here from the recorded elongation rate."""
    mech = load_case(CONFIGS / "fourbar_gravity.yaml").data["mechanism"]
    mech = {k: mech[k] for k in ("label", "parameters", "gravity", "links", "couplings")}
    c = 3.0
    mech["parameters"]["cd"] = c
    mech["forces"] = [{"name": "damper", "type": "spring", "between": [["coupler", ["b/2", 0, 0]], [0, [0.2, 0.4, 0]]],
                       "stiffness": 40, "free_length": 0.3, "damping": "cd"}]
    res = run(mech, {"q": {"q_crank": 0.0}, "qd": {"q_crank": 0.0}, "guess": {"q_B": 1.0, "q_rocker": 1.8}},
              dt=0.001, stabilization={"method": "projection"})
    ldot = res.observable_rates[:, res.observable_names.index("damper_length")]
    power = c * ldot**2
    h = res.t[1] - res.t[0]
    dissipated = np.concatenate(([0.0], np.cumsum((power[1:] + power[:-1]) / 2 * h)))  # trapezoid
    # Simpson on the even samples for the final value, the trapezoid's error is O(h^2)
    simpson = h / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
    lost = res.kinetic[0] + res.potential[0] - res.kinetic - res.potential
    assert dissipated[-1] > 0.05  # it does dissipate
    assert abs(lost[-1] - simpson) < 1e-8 * simpson
    assert np.max(np.abs(lost - dissipated)) < 1e-5 * simpson
    assert abs(res.work[-1, 0] + simpson) < 1e-8 * simpson  # the recorded work of the damper


def test_constant_actuator_torque_does_torque_times_angle():
    tau, m, a, J, g = 2.5, 1.5, 0.4, 0.02, 9.81
    res = run(pendulum([{"name": "motor", "type": "actuator", "joint": "O", "torque": tau}]),
              {"q": {"q_O": 0.0}, "qd": {"q_O": 0.0}}, t_end=2.0)
    angle = res.q[:, 0] - res.q[0, 0]
    assert np.max(np.abs(res.work[:, 0] - tau * angle)) < 1e-9 * tau * np.max(np.abs(angle))
    # and it is what the motion gained: T + V by hand
    I_O = J + m * a * a
    energy = 0.5 * I_O * res.qd[:, 0] ** 2 + m * g * a * np.sin(res.q[:, 0])
    assert np.max(np.abs(energy - energy[0] - tau * angle)) < 1e-8 * tau * np.max(np.abs(angle))


def link_frame_loads():
    return [{"name": "tip", "type": "force", "link": "bar", "point": "P", "direction": [0, 1, 0], "frame": "link",
             "value": "F"},
            {"name": "twist", "type": "torque", "link": "bar", "axis": [0, 0, 1], "value": "T0*cos(3*t)"}]


def test_link_frame_force_and_applied_torque_against_hand_ode():
    """A force F normal to the bar at its tip (link frame) and a torque T0 cos(3 t) about z:
    I_O q'' = F L + T0 cos(3 t) - m g a cos q."""
    m, a, L, J, g, F, T0 = 1.5, 0.4, 0.8, 0.02, 9.81, 4.0, 1.5
    res = run(pendulum(link_frame_loads(), F=F, T0=T0), {"q": {"q_O": 0.3}, "qd": {"q_O": 0.0}})
    I_O = J + m * a * a

    def f(t, y):
        return [y[1], (F * L + T0 * math.cos(3 * t) - m * g * a * math.cos(y[0])) / I_O]

    ref = solve_ivp(f, (0, 2.0), [0.3, 0.0], t_eval=res.t, rtol=1e-12, atol=1e-12, method="DOP853")
    assert np.max(np.abs(res.q[:, 0] - ref.y[0])) < 1e-8
    assert res.energy_error_relative < 1e-9
    # the tip force does F L per radian; the torque its own T0 cos(3 t) dq
    assert np.max(np.abs(res.work[:, 0] - F * L * (res.q[:, 0] - 0.3))) < 1e-8 * np.max(np.abs(res.work[:, 0]))


def test_force_elements_take_the_same_steps_on_both_backends():
    """The time-dependent law and the link-frame direction, compiled and on the Python path."""
    mech, ini = pendulum(link_frame_loads(), F=4.0, T0=1.5), {"q": {"q_O": 0.3}, "qd": {"q_O": 0.0}}
    python = run(mech, ini, integrator="DOP853")
    compiled = run(mech, ini, integrator="DOP853", backend="compiled")
    assert compiled.backend == "compiled" and python.nfev == compiled.nfev
    np.testing.assert_allclose(compiled.q, python.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(compiled.work, python.work, rtol=1e-10, atol=1e-10)
    # the samples, evaluated in one compiled call, carry each sample's time into the laws
    np.testing.assert_allclose(compiled.loads[:, 1], 1.5 * np.cos(3 * compiled.t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.loads, python.loads, rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.qdd, python.qdd, rtol=0, atol=1e-9)


def test_quick_return_as_tables_agrees_with_the_registered_mechanism():
    """Same method and tolerance, t = 10 s: crank angle to 1e-8 rad, ram position to 1e-9 m,
    the same switching events (the cutting force's window and velocity sign)."""
    common = ["simulation.t_end=10", "output.dt=0.01", "simulation.rtol=1e-13", "simulation.atol=1e-13",
              "stabilization.method=projection", "simulation.backend=python"]
    registered = run_case(load_case(CONFIGS / "quick_return.yaml", common))
    tables = run_case(load_case(CONFIGS / "quick_return_tables.yaml", common))
    assert registered.status == tables.status == "success"
    crank = registered.q[-1, registered.coordinate_names.index("q1")]
    assert abs(tables.q[-1, tables.coordinate_names.index("q_O")] - crank) < 1e-8
    ram = registered.observables[-1, registered.observable_names.index("ram_x")]
    assert abs(tables.observables[-1, tables.observable_names.index("D_x")] - ram) < 1e-9
    assert len(tables.event_times) == len(registered.event_times) > 100
    assert np.max(np.abs(np.subtract(tables.event_times, registered.event_times))) < 1e-9
    np.testing.assert_allclose(tables.work[-1], registered.work[-1], rtol=1e-9)  # torque, cutting force
    assert tables.energy_error_relative < 1e-10


@pytest.mark.parametrize("element, expected", [
    ({"type": "spring", "between": [["block", "G"], ["ground", "E"]], "stiffness": -5},
     "mechanism.forces[0] (f).stiffness: got -5 (integer), -5 N/m at the parameter values; expected a value >= 0"),
    ({"type": "spring", "between": [["block", "G"], ["ground", "E"]], "stiffness": 5, "free_length": "-m"},
     "mechanism.forces[0] (f).free_length: got '-m' (string), -2 m at the parameter values; expected a value >= 0"),
    ({"type": "joint_spring", "joint": "slide", "damping": -1.0},
     "mechanism.forces[0] (f).damping: got -1.0 (number), -1 N s/m at the parameter values; expected a value >= 0"),
    ({"type": "spring", "between": [["block", "Q"], ["ground", "E"]], "stiffness": 5},
     "mechanism.forces[0] (f).between[0][1]: got 'Q' (string); link 1 'block' has no such point; expected one of "
     "its point names (G) or [x, y, z]"),
    ({"type": "force", "link": "wheel", "point": "G", "direction": [1, 0, 0], "value": 1},
     "mechanism.forces[0] (f).link: got 'wheel' (string); not a link of mechanism.links; expected 0, 1 or a "
     "name (ground, block)"),
    ({"type": "actuator", "joint": "hinge", "force": 1},
     "mechanism.forces[0] (f).joint: got 'hinge' (string); no such joint; expected a coupling number or name "
     "(slide) or a joint variable (s_slide)"),
    ({"type": "actuator", "joint": "slide", "torque": 1},
     "mechanism.forces[0] (f).joint: coupling 1 'slide' P (0,1)-(1,1) has no rotation; expected a force on it, "
     "or another joint"),
    ({"type": "actuator", "joint": "slide", "force": "F0*sin(w*t)"},
     "mechanism.forces[0] (f).force: got 'F0*sin(w*t)' (string); unknown name 'F0', not a parameter of "
     "mechanism.parameters (define it there)"),
    ({"type": "actuator", "joint": "slide", "force": "2 kg"},
     "mechanism.forces[0] (f).force: got '2 kg' (string); 'kg' is the unit of a mass ([mass]), not of a force"),
    ({"type": "force", "link": "block", "point": "G", "direction": [1, 0, 0], "value": 1,
      "window": ["10 deg", "1 m"]},
     "mechanism.forces[0] (f).window[0]: got '10 deg' (string); 'deg' is the unit of a pure number or an angle, "
     "not of a length"),
    ({"type": "force", "link": "block", "point": "G", "direction": [1, 0, 0], "value": 1, "window": [0, 10**400]},
     "mechanism.forces[0] (f).window: got [0, 1000"),
    ({"type": "force", "link": "block", "point": "G", "direction": [1, 0, 0], "value": 1, "window": [1, 0]},
     "mechanism.forces[0] (f).window: got [1, 0] (list); expected [lo, hi] with lo < hi, numbers in m or written "
     "with their unit"),
    ({"type": "damper", "joint": "slide"},
     "mechanism.forces[0] (f).type: got 'damper' (string); expected one of spring, joint_spring, actuator, force, "
     "torque"),
])
def test_bad_force_elements_name_the_row_the_key_and_the_expectation(element, expected):
    data = {"mechanism": slider([{"name": "f", **element}]), "initial": {"q": {"s_slide": 0.5}}}
    with pytest.raises(Exception) as excinfo:
        validate_case(data)
    assert any(p.startswith(expected) for p in excinfo.value.problems), excinfo.value.problems


def test_bad_force_element_exits_2_on_the_command_line(tmp_path):
    import yaml
    from typer.testing import CliRunner

    from csim.cli import app

    data = {"mechanism": slider([{"name": "f", "type": "joint_spring", "joint": "slide", "stiffness": -3}]),
            "initial": {"q": {"s_slide": 0.5}}}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    result = CliRunner().invoke(app, ["run", str(path), "-o", str(tmp_path / "bad.h5")])
    assert result.exit_code == 2
    assert "mechanism.forces[0] (f).stiffness: got -3" in result.output
    assert "Traceback" not in result.output


def test_loads_section_may_not_redefine_a_force_element():
    data = {"mechanism": slider([{"name": "push", "type": "actuator", "joint": "slide", "force": 1.0}]),
            "initial": {"q": {"s_slide": 0.5}}, "loads": {"push": 3.0}}
    with pytest.raises(Exception) as excinfo:
        validate_case(data)
    assert any(p.startswith("loads.push: 'push' is a force element of mechanism.forces") for p in
               excinfo.value.problems)


def test_actuator_on_a_cut_joint_works_on_the_relative_angle():
    """A constant torque in the cut joint C of the four-bar (between coupler and rocker) does
    tau (theta - theta0), theta = rocker angle - coupler angle from the tree's joint angles."""
    mech = load_case(CONFIGS / "fourbar_gravity.yaml").data["mechanism"]
    mech = {k: mech[k] for k in ("label", "parameters", "gravity", "links", "couplings")}
    tau = 0.8
    mech["forces"] = [{"name": "knee", "type": "actuator", "joint": "C", "torque": tau}]
    res = run(mech, {"q": {"q_crank": 0.0}, "qd": {"q_crank": 0.0}, "guess": {"q_B": 1.0, "q_rocker": 1.8}},
              stabilization={"method": "projection"})
    names = res.coordinate_names
    theta = res.q[:, names.index("q_rocker")] - res.q[:, names.index("q_crank")] - res.q[:, names.index("q_B")]
    work = tau * (theta - theta[0])
    assert np.max(np.abs(work)) > 0.05
    assert np.max(np.abs(res.work[:, 0] - work)) < 1e-9 * np.max(np.abs(work))
    gained = res.kinetic + res.potential - res.kinetic[0] - res.potential[0]
    assert np.max(np.abs(gained - work)) < 1e-8 * np.max(np.abs(work))


def test_forces_with_a_drive_are_rejected_not_ignored():
    mech = slider([{"name": "push", "type": "actuator", "joint": "slide", "force": 1.0}])
    mech["drive"] = {"slide": "0.1*t"}
    with pytest.raises(Exception) as excinfo:
        validate_case({"mechanism": mech})
    assert any(p.startswith("mechanism.forces: given with mechanism.drive") for p in excinfo.value.problems)


@pytest.mark.parametrize("on", [None, "G_x", {"distance": [["ground", "E"], ["block", "G"]]}, "units"])
def test_switched_force_stops_at_its_window_bound(on):
    """A constant push F on the block at rest while x <= 0.8 m (or its distance from E = (-1, 0)
    <= 1.8 m): s = F t^2 / (2 m) until t1 = sqrt(1.6 m / F), then s = 0.8 + (F t1 / m) (t - t1).
    ``units``: the same push and window written with units (5000 mN, [-1 km, 800 mm])."""
    m, F = 2.0, 5.0
    force = {"name": "push", "type": "force", "link": "block", "point": "G", "direction": [1, 0, 0], "value": "F",
             "window": [-1e9, 0.8]}
    if on == "units":
        force.update(value="5000 mN", window=["-1 km", "800 mm"])
        on = None
    if isinstance(on, dict):
        force.update(on=on, window=[-1e9, 1.8])
    elif on is not None:
        force["on"] = on
    res = run(slider([force], F=F), {"q": {"s_slide": 0.0}, "qd": {"s_slide": 0.0}}, t_end=1.5)
    t1 = math.sqrt(1.6 * m / F)
    assert len(res.event_times) == 1 and abs(res.event_times[0] - t1) < 1e-10
    s = np.where(res.t < t1, F * res.t**2 / (2 * m), 0.8 + F * t1 / m * (res.t - t1))
    assert np.max(np.abs(res.q[:, 0] - s)) < 1e-10
    assert abs(res.work[-1, 0] - F * 0.8) < 1e-9


def rsur_with_mass() -> dict:
    """configs/rsur_spatial.yaml without its drive, with masses and gravity along -z: a
    spatial 1-DOF loop whose spherical joint B is cut."""
    mech = copy.deepcopy(load_case(CONFIGS / "rsur_spatial.yaml").data["mechanism"])
    mech = {k: mech[k] for k in ("label", "parameters", "links", "couplings")}
    mech["gravity"] = [0, 0, -9.81]
    for n, (mass, length, inertia) in enumerate([(1.0, "a", 2e-3), (0.5, "b", 5e-3), (0.8, "c", 4e-3)], start=1):
        mech["links"][n].update(mass=mass, com=[f"{length}/2", 0, 0], inertia=[1e-3, inertia, inertia])
    return mech


@pytest.mark.slow  # about 15 s: a spatial model derived and integrated on the Python path
def test_springs_damper_and_actuator_on_a_cut_spherical_joint_keep_the_energy_balance():
    """Elements on the three Euler angles of the cut S joint B, measured from its two frames
    (the measure is checked against the joint transform in test_linkage_joints): T + V
    (springs included) - W (damper, actuator) stays constant, and the elements work."""
    mech = rsur_with_mass()
    mech["forces"] = [
        {"name": "twist", "type": "joint_spring", "joint": "q_B_1", "stiffness": 0.5, "free_angle": 0.3,
         "damping": 0.02},
        {"name": "motor", "type": "actuator", "joint": "q_B_3", "torque": 0.2},
        {"name": "bend", "type": "joint_spring", "joint": "q_B_2", "stiffness": 0.3, "free_angle": 1.0}]
    res = run(mech, {"q": {"q_A": 0.0}, "qd": {"q_A": 0.0}, "guess": {"q_D": 1.57, "q_C_1": 0.3, "q_C_2": 1.3}},
              t_end=0.5, rtol=1e-10, atol=1e-10, stabilization={"method": "projection"})
    assert res.load_names == ["twist", "motor"]
    assert np.all(np.abs(res.work[-1]) > 1e-4)  # measured: damper -0.65 J, actuator 1.9e-4 J at t = 0.5 s
    assert res.energy_error_relative < 1e-9  # measured 3.3e-11
    assert res.max_phi < 1e-12


def test_elements_on_cut_joint_variables_are_named_by_the_joint_templates():
    mech = rsur_with_mass()
    mech["forces"] = [{"name": "f", "type": "actuator", "joint": "B", "torque": 1.0}]
    with pytest.raises(Exception) as excinfo:
        validate_case({"mechanism": mech, "initial": {"q": {"q_A": 0.0}, "guess": {"q_D": 1.57}}})
    assert any(p.startswith("mechanism.forces[0] (f).joint: coupling 2 'B' S (1,2)-(2,1) has 3 joint variables; "
                            "expected one of them named (q_B_1, q_B_2, q_B_3)") for p in excinfo.value.problems), \
        excinfo.value.problems
