"""Driven dynamics (csim.solver.driven): the torque that drives an offset slider-crank at
constant crank speed, against the slider-crank's equation of motion written by hand here.

Reference (independent of csim's tables): crank angle theta = w t + theta0, crank r, rod l,
guide offset e above the crank pivot. B = r (cos theta, sin theta); the slider pin
C = (x, e) with x = r cos theta + sqrt(l^2 - (e - r sin theta)^2); the rod angle
phi = atan2(e - r sin theta, x - r cos theta). With E(theta) = T + V at theta' = w,
the one-degree-of-freedom Lagrange equation at theta'' = 0 reads
tau w = dE/dt - F x' (d/dt = w d/dtheta), so tau = dE/dtheta - F dx/dtheta, with F the
horizontal force applied on the slider.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from csim.case import validate_case
from csim.errors import CaseError
from csim.pipeline import run_case

P = dict(r=0.1, l=0.3, e=0.02, m1=0.8, m2=1.5, m3=2.0, w=5.0, F0=30.0, th0=0.3)
GRAVITY = 9.81


def _data(**simulation) -> dict:
    return {
        "mechanism": {
            "label": "slider_crank_driven",
            "parameters": dict(P),
            "gravity": [0, -GRAVITY, 0],
            "links": [
                {"link": 0, "name": "frame", "joints": [["R", 0, "A"], ["P", [0, "e", 0, "90*deg", "90*deg", 0], "G"]]},
                {"link": 1, "name": "crank", "joints": [["R", 0, "A"], ["R", ["r", 0, 0], "B"]], "mass": "m1",
                 "com": ["r/2", 0, 0], "inertia": "m1*r^2/12"},
                {"link": 2, "name": "rod", "joints": [["R", 0, "B"], ["R", ["l", 0, 0], "C"]], "mass": "m2",
                 "com": ["l/2", 0, 0], "inertia": "m2*l^2/12"},
                {"link": 3, "name": "slider", "joints": [["P", [0, 0, 0, "90*deg", "90*deg", 0], "G"], ["R", 0, "C"]],
                 "mass": "m3", "inertia": 0.01},
            ],
            "couplings": [{"name": "crank", "couple": ["frame", "A", "crank", "A"]},
                          {"name": "B", "couple": ["crank", "B", "rod", "B"]},
                          {"name": "slide", "couple": ["frame", "G", "slider", "G"]},
                          {"name": "C", "couple": ["rod", "C", "slider", "C"]}],
            "drive": {"crank": "w*t + th0"},
            "drive_mode": "dynamic",
            "forces": [{"name": "resist", "type": "force", "link": "slider", "point": "C", "direction": [1, 0, 0],
                        "value": "-F0"}],
        },
        "initial": {"guess": {"q_B": -0.2, "s_slide": 0.38}},
        "simulation": {"t_end": 1.3, "rtol": 1e-11, "atol": 1e-11, **simulation},
        "output": {"dt": 0.01},
    }


def _reference():
    """theta -> (tau [N m], E = T + V [J], x [m]) as numpy functions, from the closed-form geometry."""
    th = sp.Symbol("theta")
    r, l, e, m1, m2, m3, w = (P[k] for k in ("r", "l", "e", "m1", "m2", "m3", "w"))
    x = r * sp.cos(th) + sp.sqrt(l ** 2 - (e - r * sp.sin(th)) ** 2)
    phi = sp.atan2(e - r * sp.sin(th), x - r * sp.cos(th))
    G2 = sp.Matrix([r * sp.cos(th), r * sp.sin(th)]) + l / 2 * sp.Matrix([sp.cos(phi), sp.sin(phi)])
    v2 = G2.diff(th) * w
    T = (sp.Rational(1, 2) * (m1 * r ** 2 / 12 + m1 * (r / 2) ** 2) * w ** 2
         + sp.Rational(1, 2) * m2 * (v2.T * v2)[0] + sp.Rational(1, 2) * m2 * l ** 2 / 12 * (phi.diff(th) * w) ** 2
         + sp.Rational(1, 2) * m3 * (x.diff(th) * w) ** 2)
    V = GRAVITY * (m1 * r / 2 * sp.sin(th) + m2 * G2[1] + m3 * e)
    E = T + V
    tau = E.diff(th) - (-P["F0"]) * x.diff(th)
    return (sp.lambdify(th, tau, "numpy"), sp.lambdify(th, E, "numpy"), sp.lambdify(th, x, "numpy"))


@pytest.fixture(scope="module")
def driven_run():
    case = validate_case(_data())
    return case, run_case(case)


def test_drive_torque_of_a_slider_crank_at_constant_speed_against_the_hand_formula(driven_run):
    case, result = driven_run
    assert result.ok, result.message
    assert result.drive_names == ["q_crank"] and result.drive_units == ["N m"]
    crank = result.coordinate_names.index("q_crank")
    theta = result.q[:, crank]
    assert np.allclose(theta, P["w"] * result.t + P["th0"], atol=1e-9)      # the prescribed motion
    assert np.allclose(result.qd[:, crank], P["w"], atol=1e-9)
    tau_ref, _, x_ref = _reference()
    assert np.allclose(result.q[:, result.coordinate_names.index("s_slide")], x_ref(theta), atol=1e-9)
    rng = np.random.default_rng(14)
    samples = rng.choice(theta.size, 25, replace=False)                  # random crank angles over 1 turn+
    tau = result.drive_forces[samples, 0]
    expected = tau_ref(theta[samples])
    scale = np.max(np.abs(tau_ref(np.linspace(0, 2 * np.pi, 400))))
    assert scale > 1.0                                                   # a torque worth measuring
    assert np.max(np.abs(tau - expected)) < 1e-8 * scale                 # measured 1.3e-11


def test_work_of_the_drive_equals_the_change_of_energy_minus_the_load_work(driven_run):
    """W_drive(t) = E(theta(t)) - E(theta0) - W_F, W_F = -F0 (x(t) - x(0)), all from the hand formulas."""
    case, result = driven_run
    _, E, x = _reference()
    theta = result.q[:, result.coordinate_names.index("q_crank")]
    expected = E(theta) - E(theta[0]) + P["F0"] * (x(theta) - x(theta[0]))
    scale = np.max(np.abs(expected))
    assert np.max(np.abs(result.drive_work[:, 0] - expected)) < 1e-8 * scale
    assert result.energy_error_relative < 1e-8                         # csim's own balance closes too
    assert result.backend == "compiled"                                # the drive rows in the compiled model


def test_driven_dynamics_hdf5_and_slider_pin_reaction(driven_run, tmp_path):
    """forces/drive and energy/drive_work in the file, with names and units; the slider's pin C
    carries the rod's force: the slider (mass m3, pushed by F) has x'' = (F_x - F0) / m3."""
    import h5py

    from csim.io.hdf5 import read_result, write_result

    case, result = driven_run
    path = tmp_path / "driven.h5"
    write_result(path, result)
    with h5py.File(path) as fh:
        ds = fh["forces/drive"]
        assert ds.shape == (result.t.size, 1)
        assert [str(n, "utf-8") if isinstance(n, bytes) else n for n in ds.attrs["names"]] == ["q_crank"]
        assert fh["energy/drive_work"].attrs["units"].startswith("J")
    back = read_result(path)
    assert np.array_equal(back.drive_forces, result.drive_forces) and back.drive_units == ["N m"]
    assert np.array_equal(back.energy_error, result.energy_error)
    pin = result.reactions[0]                                           # rod on slider at C (cut)
    assert pin.name == "C"
    # the tree joints (Newton-Euler beyond each): the crank pivot's moment about its axis is its
    # equation of motion with the drive torque applied, so it vanishes; the slider's guide
    # pushes across the guide only (x is its free direction): F_x = 0, F_y balances the pin
    crank, _, slide = result.reactions[1:]
    assert crank.name == "crank"
    assert np.max(np.abs(crank.torque_global[:, 2])) < 1e-8 * np.max(np.abs(result.drive_forces))
    assert np.max(np.abs(slide.force_global[:, 0])) < 1e-8 * np.max(np.abs(slide.force_global))
    s = result.coordinate_names.index("s_slide")
    newton = P["m3"] * result.qdd[:, s] - (pin.force_global[:, 0] - P["F0"])
    assert np.max(np.abs(newton)) < 1e-8 * np.max(np.abs(pin.force_global[:, 0]))


@pytest.mark.parametrize("change, key", [
    ({"stabilization": {"method": "ggl"}}, "stabilization.method"),
    ({"stabilization": {"method": "minimal"}}, "stabilization.method"),
    ({"stabilization": {"method": "baumgarte", "w": [10.0, 10.0]}}, "stabilization.w"),
    ({"formulation": {"method": "elimination"}}, "formulation.method"),
])
def test_driven_dynamics_rejects_what_it_cannot_run(change, key):
    data = _data()
    for section, values in change.items():
        data.setdefault(section, {}).update(values)
    with pytest.raises(CaseError) as err:
        validate_case(data)
    assert key in str(err.value) and "drive_mode" in str(err.value)


def test_drive_mode_without_drive_and_forces_with_a_kinematic_drive_are_rejected():
    data = _data()
    del data["mechanism"]["drive"]
    with pytest.raises(CaseError, match="mechanism.drive_mode"):
        validate_case(data)
    data = _data()
    data["mechanism"]["drive_mode"] = "kinematic"
    with pytest.raises(CaseError, match="mechanism.forces"):
        validate_case(data)
    data = _data()
    data["mechanism"]["drive_mode"] = "inverse"
    with pytest.raises(CaseError, match="mechanism.drive_mode"):
        validate_case(data)


def _drive_error(stabilization: dict):
    """A run started 1 mrad off the drive (initial.q_offset): t, e = q_crank - (w t + th0), result."""
    data = _data(backend="python")
    data["stabilization"] = stabilization
    data["initial"]["q_offset"] = {"q_crank": 1e-3}
    result = run_case(validate_case(data))
    assert result.ok, result.message
    return result.t, result.q[:, result.coordinate_names.index("q_crank")] - (P["w"] * result.t + P["th0"]), result


def test_baumgarte_stabilizes_the_drive_rows_with_its_closed_form_decay():
    """e'' + 2 d w e' + w^2 e = 0 holds exactly for a drive row (its Jacobian is constant), so
    from e(0) = e0, e'(0) = 0 with d = 1: e = e0 (1 + w t) exp(-w t). Without stabilization
    the error stays e0."""
    t, e, _ = _drive_error({"method": "baumgarte", "d": 1.0, "w": 20.0})
    assert np.max(np.abs(e - 1e-3 * (1 + 20.0 * t) * np.exp(-20.0 * t))) < 1e-12  # measured 3.6e-15
    _, e, _ = _drive_error({"method": "none"})
    assert np.max(np.abs(e - 1e-3)) < 1e-12


def test_projection_puts_the_state_on_the_drives_and_keeps_the_drive_torque():
    """Projected at the start and after every step: the drive error is round-off, and the
    torque is the hand formula's (the start's offset is projected away)."""
    t, e, result = _drive_error({"method": "projection"})
    assert np.max(np.abs(e)) < 1e-12
    assert result.max_phi < 1e-10
    crank = result.coordinate_names.index("q_crank")
    assert np.max(np.abs(result.qd[:, crank] - P["w"])) < 1e-9
    tau_ref, _, _ = _reference()
    scale = np.max(np.abs(result.drive_forces[:, 0]))
    assert np.max(np.abs(result.drive_forces[:, 0] - tau_ref(result.q[:, crank]))) < 1e-7 * scale


# --- fewer drives than degrees of freedom ------------------------------------------------

def _five_bar(**changes) -> dict:
    """A planar five-bar (2 DOF) under gravity, its left crank driven at 4 rad/s and its
    right crank free, started at rest relative to the drive."""
    data = {
        "mechanism": {
            "label": "five_bar_half_driven",
            "parameters": {"d": 0.4, "a": 0.2, "b": 0.35, "m": 1.0, "w": 4.0},
            "gravity": [0, -GRAVITY, 0],
            "links": [
                {"link": 0, "name": "ground", "joints": [["R", 0, "A"], ["R", ["d", 0, 0], "E"]]},
                {"link": 1, "name": "left", "joints": [["R", 0, "A"], ["R", ["a", 0, 0], "B"]], "mass": "m",
                 "com": ["a/2", 0, 0], "inertia": "m*a^2/12"},
                {"link": 2, "name": "upper_left", "joints": [["R", 0, "B"], ["R", ["b", 0, 0], "C"]], "mass": "m",
                 "com": ["b/2", 0, 0], "inertia": "m*b^2/12"},
                {"link": 3, "name": "upper_right", "joints": [["R", 0, "C"], ["R", ["b", 0, 0], "D"]], "mass": "m",
                 "com": ["b/2", 0, 0], "inertia": "m*b^2/12"},
                {"link": 4, "name": "right", "joints": [["R", 0, "D"], ["R", ["a", 0, 0], "E"]], "mass": "m",
                 "com": ["a/2", 0, 0], "inertia": "m*a^2/12"},
            ],
            "couplings": [{"name": "A", "couple": ["ground", "A", "left", "A"]},
                          {"name": "B", "couple": ["left", "B", "upper_left", "B"]},
                          {"name": "C", "couple": ["upper_left", "C", "upper_right", "C"]},
                          {"name": "D", "couple": ["upper_right", "D", "right", "D"]},
                          {"name": "E", "couple": ["right", "E", "ground", "E"]}],
            "drive": {"A": "1.2 + w*t"},
            "drive_mode": "dynamic",
        },
        "initial": {"q": {"q_D": 4.0}, "guess": {"q_B": -0.6, "q_C": -1.2}},
        "stabilization": {"method": "projection"},
        "simulation": {"t_end": 0.15, "rtol": 1e-10, "atol": 1e-10, "backend": "python"},
        "output": {"dt": 0.005},
    }
    for section, values in changes.items():
        data[section].update(values)
    return data


@pytest.fixture(scope="module")
def half_driven():
    case = validate_case(_five_bar())
    return case, run_case(case)


def test_a_drive_on_one_of_two_degrees_of_freedom_keeps_its_motion_and_balances_energy(half_driven):
    """The driven crank follows its drive, the other moves under gravity, and the work of the
    drive torque (the drive multiplier, integrated with the motion) closes the energy balance:
    a wrong multiplier or a wrong free motion would leave T + V - T0 - V0 - W_drive != 0."""
    case, result = half_driven
    assert case.linkage.dof == 2 and len(case.linkage.drive_names) == 1
    assert result.ok, result.message
    names = result.coordinate_names
    crank = names.index("q_A")
    assert np.max(np.abs(result.q[:, crank] - (1.2 + 4.0 * result.t))) < 1e-10
    free = result.q[:, names.index("q_D")]
    assert np.ptp(free) > 0.05  # the free crank does move
    assert result.max_phi < 1e-9
    energy = result.kinetic + result.potential
    scale = np.max(np.abs(energy - energy[0]))
    assert np.max(np.abs(result.energy_error)) < 1e-7 * scale
    assert np.max(np.abs(result.drive_forces[:, 0])) > 0.1


def test_each_method_gives_the_same_half_driven_motion(half_driven):
    """Baumgarte and no stabilization (other equations, other rows stabilized) against
    projection: the free crank's motion agrees to the tolerance."""
    _, reference = half_driven
    d = reference.coordinate_names.index("q_D")
    for method in ({"method": "none"}, {"method": "baumgarte", "d": 1.0, "w": 20.0}):
        result = run_case(validate_case(_five_bar(stabilization=method)))
        assert result.ok, result.message
        assert np.max(np.abs(result.q[:, d] - reference.q[:, d])) < 1e-7


@pytest.mark.parametrize("changes, expected", [
    ({"mechanism": {"drive": {"A": "w*t", "D": 1.0, "B": 0.3}}},
     "mechanism.drive: 3 drives for 2 degrees of freedom (q_A, q_D, q_B driven); expected at most 2"),
    ({"mechanism": {"drive_mode": "kinematic"}}, "expected exactly 2 driven joint variable(s) (under-driven"),
    ({"initial": {"q": {"q_A": 0.3, "q_D": 4.0}}}, "initial.q: got"),
    ({"initial": {"q": {"q_D": 4.0, "q_C": -1.2}}}, "initial.q: 2 coordinates besides 1 drive for 2 degrees"),
    ({"initial": {"q": {}}}, "initial.q: got 0 free joint variable(s) (none); expected exactly 1 of the joint "
                             "variables not driven (q_B, q_C, q_D)"),
])
def test_half_driven_input_errors_name_the_key(changes, expected):
    data = _five_bar()
    for section, values in changes.items():
        data[section] = {**data[section], **values}
    with pytest.raises(CaseError) as err:
        validate_case(data)
    assert expected in str(err.value)


def test_no_dead_centre_is_reported_where_the_free_joints_keep_their_rank_at_any_scale():
    """The dead-centre test looks at Phi_q over the joints not driven, in the mechanism's own
    units: the same five-bar, 300 times smaller, reports no singular crossing either."""
    data = _five_bar()
    for name in ("d", "a", "b"):
        data["mechanism"]["parameters"][name] *= 0.003
    result = run_case(validate_case(data))
    assert result.ok, result.message
    assert not result.warnings and result.singular_times.size == 0


def test_half_driven_projection_with_massless_links_and_the_minimum_norm_metric():
    """The velocity projection with fewer drives than degrees of freedom uses the method's
    metric: with ``minimum_norm`` a singular mass matrix is no obstacle."""
    data = _five_bar(stabilization={"method": "projection", "projection_metric": "minimum_norm"})
    for link in data["mechanism"]["links"][2:4]:  # the two upper links without mass
        for key in ("mass", "com", "inertia"):
            link.pop(key)
    result = run_case(validate_case(data))
    assert result.ok, result.message
    assert result.max_phi < 1e-9
    crank = result.coordinate_names.index("q_A")
    assert np.max(np.abs(result.qd[:, crank] - 4.0)) < 1e-9


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_the_mass_metric_with_massless_links_fails_saying_which_setting_to_change(backend):
    """The five-bar with no moving link massive, and the (default) mass metric: M = 0, so the projection
    has no metric. The run fails at t = 0 with a message naming projection_metric, on both backends alike
    (it said "LinAlgError: Singular matrix"), and its result is marked failed."""
    data = _five_bar(stabilization={"method": "projection"}, simulation={"backend": backend})
    for link in data["mechanism"]["links"][1:]:
        for key in ("mass", "com", "inertia"):
            link.pop(key)
    result = run_case(validate_case(data))
    assert not result.ok and result.backend == backend
    assert result.failure == "singular"
    assert result.message == ("projection at t = 0 s: the mass matrix is singular (moving links without mass), so "
                              "it cannot be the projection's metric; set stabilization.projection_metric: "
                              "minimum_norm")


def test_an_overconstrained_linkage_runs_driven_and_records_its_every_equation():
    """Bricard's mechanism (six closure equations, one dependent, removed) with its drive as a rheonomic
    constraint: the samples held the kept equations' four values where the result records the five
    non-trivial ones, and the run stopped with a broadcast error. Now the recorded Phi and multipliers are
    the full set's, and the removed equation is watched; its links are massless, which the summary says."""
    from conftest import CONFIGS

    from csim.case import load_case

    case = load_case(CONFIGS / "bricard.yaml", ["mechanism.drive_mode=dynamic", "simulation.t_end=0.2"])
    result = run_case(case)
    assert result.ok, result.message
    assert result.phi.shape == result.lam.shape == (result.t.size, 5) and result.removed_names
    assert np.max(np.abs(result.phi)) < 1e-6 and np.all(np.isfinite(result.lam))
    assert not result.stays_at_rest and "its moving links have no mass" in result.summary()


def test_a_drive_with_a_parameter_exponent_is_differentiated_at_the_values():
    """A drive w t^n with n = 1: differentiated with n a symbol, its rate n t^n w / t is 0/0 at t = 0, and the
    case stopped with a ZeroDivisionError (helper-28). The values are put in first; the run is the one of
    w t, read back from the linkage cache the second time. (Python path: the compiled drive rows keep the
    parameters as symbols, and n (n - 1) w t^(n - 2) is 0 * inf there, a blow-up at t = 0 that says so.)"""
    data = _data(t_end=0.3, rtol=1e-9, atol=1e-9, backend="python")
    data["mechanism"]["parameters"]["n"] = 1
    data["mechanism"]["drive"] = {"crank": "w*t^n + th0"}
    powered = [run_case(validate_case(data)) for _ in range(2)]  # derived, then read back
    linear = run_case(validate_case(_data(t_end=0.3, rtol=1e-9, atol=1e-9, backend="python")))
    for run in powered:
        assert run.ok, run.message
        np.testing.assert_allclose(run.q, linear.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(run.drive_forces, linear.drive_forces, rtol=0, atol=1e-9)


@pytest.mark.parametrize("name, value, drive", [("n", 1, "w*t^n + th0"), ("b", 0, "w*t + b*t^1.5 + th0")],
                         ids=["exponent", "singular-term"])
def test_a_drive_parameter_the_rows_are_singular_in_runs_compiled_with_its_value(name, value, drive):
    """The compiled drive rows take the values of the parameters in an exponent, or in a term not finite at t = 0
    (the plan's ``drive_substituted``): with n a symbol, gamma_d = n (n - 1) w t^(n - 2) was 0 * inf at t = 0 for
    n = 1, and with b one, 0.75 b / sqrt(t) for b = 0, blow-ups at t = 0 that the Python path (which puts every
    value in first and runs w t) did not have. A parameter elsewhere in the drive (w) stays a parameter of the
    model."""
    data = _data(t_end=0.3, rtol=1e-9, atol=1e-9, backend="compiled")
    data["mechanism"]["parameters"][name] = value
    data["mechanism"]["drive"] = {"crank": drive}
    case = validate_case(data)
    assert case.linkage.plan.drive_substituted == [name]
    run = run_case(case)
    linear = run_case(validate_case(_data(t_end=0.3, rtol=1e-9, atol=1e-9, backend="python")))
    assert run.ok and run.backend == "compiled", run.message
    np.testing.assert_allclose(run.q, linear.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(run.drive_forces, linear.drive_forces, rtol=1e-7, atol=1e-7)
    expressions = case.linkage.drive_expressions(case.parameters, case.mechanism.parameter_names)
    assert f"'{name}'" not in expressions[0] and "'w'" in expressions[0]
    # a warm run writes the value into the filed text: no symbolic linkage (no sympy) for it (helper-33)
    warm = validate_case(data)
    assert warm.linkage.drive_expressions(warm.parameters, warm.mechanism.parameter_names) == expressions
    assert warm.linkage._full is None


@pytest.mark.parametrize("n", [1.5, 1.0000000000000002])
def test_a_drive_with_an_infinite_acceleration_at_t0_is_bad_input(n):
    """A drive w t^n with 1 < n < 2 has an infinite acceleration at t = 0 (0.0 ** negative raised a
    ZeroDivisionError, a traceback of csim run and the end of a whole sweep, helper-33): the case is rejected,
    naming the key and what is expected."""
    from csim.errors import CaseError

    data = _data(t_end=0.3, backend="python")
    data["mechanism"]["parameters"]["n"] = n
    data["mechanism"]["drive"] = {"crank": "w*t^n + th0"}
    with pytest.raises(CaseError, match=r"mechanism.drive: got drives of .* not finite at t = 0"):
        validate_case(data)
