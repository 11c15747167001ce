"""Values written with their unit in case files (``172 deg``, ``10 ms``, ``4530 N/m``):
converted with pint to the key's unit, a wrong dimension or an unknown unit an exit-2
error naming the key, the value and the expected unit; plain numbers as before."""
from __future__ import annotations

import copy
import json
import math
import sys

import jsonschema
import pytest
import sympy as sp
import yaml
from conftest import CONFIGS, assert_bad_input, invoke
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csim import quantities
from csim.case import CaseLoader, json_schema, parse_yaml, validate_case
from csim.errors import CaseError
from csim.schema import Field, check_value


def read(name: str) -> dict:
    return yaml.load((CONFIGS / name).read_text(), Loader=CaseLoader)


def problems_of(doc: dict) -> list[str]:
    with pytest.raises(CaseError) as excinfo:
        validate_case(doc)
    return excinfo.value.problems


def pendulum(**sections) -> dict:
    return {"mechanism": {"name": "pendulum"}, **sections}


# --------------------------------------------------------------------------- conversions


@pytest.mark.parametrize("text, unit, expected", [
    ("172 deg", "rad", math.radians(172)),
    ("30*deg", "rad", math.radians(30)),
    ("10 ms", "s", 0.01),
    ("4530 N/m", "N/m", 4530.0),
    ("4.53 kN/m", "N/m", 4530.0),
    ("1.5e-3 kg*m^2", "kg m^2", 1.5e-3),
    ("2 g*cm^2", "kg m^2", 2e-7),
    ("350 mm", "m", 0.35),  # 0.35, not pint's 0.35000000000000003
    ("60 rpm", "rad/s", 2 * math.pi),
    ("-9.81 m/s^2", "m/s^2", -9.81),
    ("165.521 kN*m", "N m", 165521.0),
    ("50 %", "1", 0.5),
    ("50 mm", quantities.SI_BASE, 0.05),
    ("4530 N/m", quantities.SI_BASE, 4530.0),
])
def test_a_value_with_a_unit_is_converted_to_the_keys_unit(text, unit, expected):
    number, problem = quantities.convert(text, unit)
    assert problem is None
    assert number == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize("text", ["1e-3", "ten", "", "deg 30", "10 ((", "101/s", ".inf s", "1 2 3", "x" * 200])
def test_only_a_number_followed_by_a_unit_is_a_quantity(text):
    assert not quantities.is_quantity(text)


def test_simulation_times_parameters_and_coordinates_take_units():
    doc = {"mechanism": {"name": "andrews", "parameters": {"c0": "4.53 kN/m", "rr": "7 mm", "I1": "2.194e-6 kg*m^2"}},
           "simulation": {"t_end": "30 ms", "step": "10 us", "min_step": "1e-10 s"}, "output": {"dt": "1 ms"}}
    data = validate_case(doc).data
    assert data["mechanism"]["parameters"]["c0"] == 4530.0
    assert data["mechanism"]["parameters"]["rr"] == 0.007
    assert data["mechanism"]["parameters"]["I1"] == pytest.approx(2.194e-6, rel=1e-15)
    assert (data["simulation"]["t_end"], data["simulation"]["step"], data["output"]["dt"]) == (0.03, 1e-5, 0.001)


def test_initial_q_of_an_angle_in_degrees():
    """The user's report: ``q1: 30*deg`` in initial.q was "expected a number"."""
    doc = read("quick_return.yaml")
    doc["initial"].update(q={"q1": "172 deg"}, qd={"q1": "60 rpm"}, guess={"q2": "115 deg", "q3": "160 deg"})
    data = validate_case(copy.deepcopy(doc)).data
    assert data["initial"]["q"]["q1"] == pytest.approx(math.radians(172), rel=1e-14)
    assert data["initial"]["qd"]["q1"] == pytest.approx(2 * math.pi, rel=1e-14)
    doc["initial"]["q"] = {"q1": "30*deg"}
    assert validate_case(doc).data["initial"]["q"]["q1"] == pytest.approx(math.pi / 6, rel=1e-14)


def test_loads_and_their_windows_take_units():
    doc = read("quick_return.yaml")
    doc["loads"] = {"torque": "165.521 kN*m",
                    "cutting_force": {"magnitude": "200 kN", "window": ["-400 cm", "1200 mm"], "velocity": "negative"}}
    loads = validate_case(doc).data["loads"]
    assert loads == {"torque": 165521.0, "cutting_force": {"magnitude": 200000.0, "window": [-4.0, 1.2],
                                                           "velocity": "negative"}}


def test_a_gain_per_constraint_may_carry_units():
    case = validate_case(pendulum(stabilization={"method": "baumgarte", "w": ["20 1/s"], "K": "0.5 kHz"}))
    assert case.data["stabilization"]["w"] == [20.0] and case.data["stabilization"]["K"] == 500.0
    # an entry that is not a number is still reported as such
    problems: list[str] = []
    assert check_value("stabilization.w", [None, "10 1/s"], Field("any", unit="1/s", check=lambda v: "positive"),
                       problems) is None
    assert problems == ["stabilization.w: got [None, '10 1/s'] (list) = [None, 10.0] 1/s; expected positive"]


def test_plain_numbers_are_unchanged_and_taken_in_the_keys_unit():
    plain = validate_case(read("quick_return.yaml"))
    assert plain.data["initial"]["q"]["q1"] == 3.0020 and plain.data["loads"]["torque"] == 165521.0
    assert validate_case(pendulum(simulation={"t_end": 2})).data["simulation"]["t_end"] == 2.0
    # a word is still "expected a number", as before
    assert problems_of(pendulum(simulation={"t_end": "ten"})) == \
        ["simulation.t_end: got 'ten' (string); expected a number > 0"]


def test_the_plain_path_does_not_import_pint():
    import subprocess

    code = ("import sys; from csim.case import load_case; load_case(sys.argv[1]); "
            "print('pint' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(CONFIGS / "quick_return.yaml")], capture_output=True,
                         text=True, check=True)
    assert out.stdout.strip() == "False"


# --------------------------------------------------------------------------- errors


def test_a_wrong_dimension_names_the_key_the_value_and_the_expected_unit():
    (msg,) = problems_of(pendulum(simulation={"t_end": "10 kg"}))
    assert msg.startswith("simulation.t_end: got '10 kg' (string); 'kg' is the unit of a mass ([mass]), not of a time")
    assert "expected a number in s" in msg and "10 ms" in msg


@pytest.mark.parametrize("doc, key", [
    (pendulum(initial={"q": {"x": "30 deg"}}), "initial.q.x"),  # x is a length
    (pendulum(mechanism={"name": "pendulum", "parameters": {"g": "9.81 m/s"}}), "mechanism.parameters.g [m/s^2]"),
    ({"mechanism": {"name": "quick_return"}, "loads": {"torque": "3 N"}}, "loads.torque [N m]"),
    ({"mechanism": {"name": "quick_return"}, "loads": {"cutting_force": {"magnitude": 1, "window": [0, "2 s"]}}},
     "loads.cutting_force.window[1]"),
    (pendulum(stabilization={"w": ["10 1/s", "3 m"]}), "stabilization.w[1]"),
])
def test_a_wrong_dimension_anywhere_names_its_key(doc, key):
    (msg,) = problems_of(doc)
    assert msg.startswith(f"{key}: got '") and "is the unit of" in msg, msg


def test_an_unknown_unit_names_it():
    (msg,) = problems_of(pendulum(simulation={"step": "1 blorb"}))
    assert msg.startswith("simulation.step: got '1 blorb' (string); unknown unit 'blorb'; expected a number in s")


@pytest.mark.parametrize("key, value, fragment", [
    ("rtol", "1e-3 s", "this key has no unit; expected a plain number"),
    ("max_phi", "1 mm", "unit of Phi, which depends on the mechanism's constraints"),
    ("step", "1 m^123", "a power that is not a small integer"),
])
def test_a_unit_where_none_is_read_is_refused(key, value, fragment):
    (msg,) = problems_of(pendulum(simulation={key: value}))
    assert msg.startswith(f"simulation.{key}: got {value!r} (string); ") and fragment in msg, msg


def test_a_converted_value_out_of_bounds_shows_both():
    (msg,) = problems_of(pendulum(simulation={"t_end": "-5 ms"}))
    assert msg == "simulation.t_end: got '-5 ms' (string) = -0.005 s; expected a number > 0"


def test_without_pint_a_value_with_a_unit_says_to_install_it(monkeypatch):
    quantities.registry.cache_clear()
    monkeypatch.setitem(sys.modules, "pint", None)  # import pint raises ImportError
    try:
        problems: list[str] = []
        assert check_value("simulation.t_end", "10 ms", Field("number", unit="s"), problems) is None
        assert problems == ["simulation.t_end: got '10 ms' (string); a value with a unit needs pint, which is not "
                            "installed (pip install 'pint>=0.23'); expected a number in s"]
        assert check_value("simulation.t_end", 2, Field("number", unit="s"), []) == 2.0
    finally:
        monkeypatch.undo()
        quantities.registry.cache_clear()


def test_the_command_line_exits_2_naming_the_key(tmp_path):
    path = tmp_path / "case.yaml"
    path.write_text("mechanism: {name: quick_return}\ninitial: {q: {q1: 172 deg}}\nsimulation: {t_end: 10 kg}\n")
    assert_bad_input(invoke("run", path, "-o", tmp_path / "r.h5"), "simulation.t_end: got '10 kg'",
                     "expected a number in s")
    assert_bad_input(invoke("run", CONFIGS / "pendulum.yaml", "--set", "output.dt=2 blorbs", "-o", tmp_path / "r.h5"),
                     "output.dt: got '2 blorbs'", "unknown unit 'blorbs'")


@settings(max_examples=200, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(st.lists(st.sampled_from(["1", "-2.5", "1e3", "1e400", " ", "*", "/", "^", "**", "2", "-1", "99999", "(", ")",
                                 "m", "s", "kg", "deg", "N", "rpm", "blorb", "%", "µ", "mm", "degC", "pi", "e",
                                 "__class__", ".", "x"]), min_size=1, max_size=12).map("".join),
       st.sampled_from(["s", "rad", "kg m^2", "N/m", "1", "", "unit of Phi", quantities.SI_BASE]))
def test_any_text_is_converted_or_refused_with_a_sentence(text, unit):
    problems: list[str] = []
    value = check_value("k", text, Field("number", unit=unit), problems)
    assert (value is None) == bool(problems), (text, unit, problems)
    assert all(p.startswith("k: got ") for p in problems)
    if value is not None:
        assert math.isfinite(value)


# --------------------------------------------------------------------------- stored results, schema


def test_a_stored_case_revalidates_to_the_same_si_numbers(tmp_path):
    from csim.io.hdf5 import read_result

    path = tmp_path / "case.yaml"
    path.write_text("mechanism: {name: pendulum, parameters: {L: 50 cm, m: 250 g}}\n"
                    "initial: {q: {x: 10 cm}, qd: {x: 0 m/s}}\n"
                    "simulation: {t_end: 20 ms, backend: python}\noutput: {dt: 10 ms}\n")
    out = tmp_path / "r.h5"
    result = invoke("run", path, "-o", out)
    assert result.exit_code == 0, result.output
    stored = parse_yaml(read_result(out).case_yaml, "stored")
    assert stored["mechanism"]["parameters"] == {"m": 0.25, "L": 0.5, "g": 9.81}
    assert stored["initial"]["q"] == {"x": 0.1} and stored["simulation"]["t_end"] == 0.02
    assert validate_case(copy.deepcopy(stored)).data == stored


def test_the_json_schema_accepts_values_with_units_and_still_refuses_words():
    validator = jsonschema.Draft7Validator(json.loads(json.dumps(json_schema())))
    doc = read("quick_return.yaml")
    doc["initial"]["q"] = {"q1": "172 deg"}
    doc["simulation"].update(t_end="10 ms", step="1 ms")
    doc["mechanism"]["parameters"] = {"l1": "1500 mm"}
    doc["loads"] = {"torque": "165 kN*m", "cutting_force": {"magnitude": "200 kN"}}
    doc["stabilization"] = {"method": "baumgarte", "w": "20 1/s"}
    assert list(validator.iter_errors(doc)) == []
    validate_case(copy.deepcopy(doc))
    for bad in ({"t_end": "long"}, {"t_end": "10"}, {"rtol": "1e-3 s"}):
        wrong = copy.deepcopy(doc)
        wrong["simulation"].update(bad)
        assert list(validator.iter_errors(wrong)), bad
    linkage = read("fourbar_gravity.yaml")
    linkage["mechanism"]["parameters"]["a"] = "10 cm"
    linkage["mechanism"]["links"][1]["mass"] = "500 g"
    assert list(validator.iter_errors(linkage)) == []


# --------------------------------------------------------------------------- link-coupling tables


def test_link_coupling_tables_convert_each_entry_to_its_unit():
    plain = validate_case(read("fourbar_gravity.yaml"))
    doc = read("fourbar_gravity.yaml")
    mech = doc["mechanism"]
    mech["parameters"].update(a="10 cm", b="350 mm")  # a parameter has no unit: SI base units
    mech["gravity"] = [0, "-9.81 m/s^2", 0]
    mech["links"][1]["mass"] = "500 g"
    mech["links"][0]["joints"][1] = ["R", ["400 mm", 0, 0, "0 deg", 0, 0], "D"]
    doc["initial"]["q"] = {"q_crank": "0 deg"}
    case = validate_case(doc)
    assert case.data["mechanism"]["parameters"] == plain.data["mechanism"]["parameters"]
    tables = case.linkage.tables
    assert tables.links[1].mass == sp.Rational(1, 2) and tables.gravity == plain.linkage.tables.gravity
    at = plain.linkage.tables.values
    assert [float(sp.sympify(x).subs(at)) for x in tables.links[0].joints[1].p] == \
        [float(sp.sympify(x).subs(at)) for x in plain.linkage.tables.links[0].joints[1].p]
    assert case.data["initial"]["q"] == plain.data["initial"]["q"]
    # a stored case (the tables as written) validates to the same
    again = validate_case(yaml.load(case.to_yaml(), Loader=CaseLoader))
    assert again.data == case.data


def test_degrees_in_a_table_are_exact():
    doc = read("fourbar_gravity.yaml")
    doc["mechanism"]["links"][0]["joints"][0] = ["R", [0, 0, 0, "90 deg", 0, "-90 deg"], "A"]
    doc["mechanism"]["links"][1]["joints"][0] = ["R", [0, 0, 0, "90 deg", 0, "-90 deg"], "A"]
    p = validate_case(doc).linkage.tables.links[0].joints[0].p
    assert p[3] == sp.pi / 2 and p[5] == -sp.pi / 2


def test_a_force_element_constant_takes_its_unit():
    def spring(**values):
        doc = read("fourbar_gravity.yaml")
        doc["mechanism"]["forces"] = [{"name": "twist", "type": "joint_spring", "joint": "q_B", **values}]
        return doc
    plain = validate_case(spring(stiffness=4530, free_angle=0.5, damping=0.02)).linkage.forces.potential
    written = spring(stiffness="4.53 kN*m/rad", free_angle="0.5 rad", damping="20 mN*m*s/rad")
    assert sp.simplify(validate_case(written).linkage.forces.potential - plain) == 0
    (msg,) = problems_of(spring(stiffness="4.53 kN/m"))
    assert "stiffness: got '4.53 kN/m' (string); 'kN/m' is the unit" in msg, msg
    assert "is the unit of a force per length ([mass] / [time] ** 2), not of a torque or energy" in msg, msg


@pytest.mark.parametrize("where, value, fragment", [
    ("mass", "5 m", "mechanism.links[1].mass: got '5 m' (string); 'm' is the unit of a length"),
    ("inertia", "3 kg", "mechanism.links[1].inertia: got '3 kg' (string); 'kg' is the unit of a mass"),
    ("com", ["1 s", 0, 0], "mechanism.links[1].com[0]: got '1 s' (string); 's' is the unit of a time"),
])
def test_a_wrong_dimension_in_a_table_names_the_entry(where, value, fragment):
    doc = read("fourbar_gravity.yaml")
    doc["mechanism"]["links"][1][where] = value
    (msg,) = problems_of(doc)
    assert msg.startswith(fragment), msg


def test_a_constant_force_law_takes_its_unit_and_a_wrong_one_is_refused():
    doc = read("fourbar_gravity.yaml")
    doc["mechanism"]["forces"] = [{"name": "push", "type": "actuator", "joint": "q_B", "torque": "2 kN*cm"}]
    (load,) = validate_case(copy.deepcopy(doc)).linkage.forces.loads
    assert load.law == 20 and load.unit == "N m"
    doc["mechanism"]["forces"][0]["torque"] = "2 N"
    (msg,) = problems_of(doc)
    assert msg.startswith("mechanism.forces[0] (push).torque: got '2 N' (string); 'N' is the unit of a force"), msg


def test_a_unit_where_a_table_entry_has_none_is_refused_and_expressions_are_unchanged():
    doc = read("fourbar_gravity.yaml")
    doc["mechanism"]["forces"] = [{"name": "push", "type": "torque", "link": 1, "axis": [0, 0, "1 m"], "value": 1}]
    (msg,) = problems_of(doc)
    assert "axis[2]: got '1 m' (string); a unit is not read in this entry" in msg, msg
    doc = read("fourbar_gravity.yaml")
    doc["mechanism"]["parameters"]["a"] = "10 blorbs"
    assert problems_of(doc)[0].startswith("mechanism.parameters.a: got '10 blorbs' (string); unknown unit 'blorbs'")


def test_a_drive_takes_its_joint_variables_unit_and_expressions_stay_expressions():
    doc = read("fourbar.yaml")
    doc["mechanism"]["drive"] = {"crank": "30 deg"}
    assert validate_case(copy.deepcopy(doc)).linkage.drive == {"q_crank": sp.pi / 6}
    doc["mechanism"]["drive"] = {"crank": "2*pi*t"}  # pi (and deg, a parameter, t) make an expression
    assert validate_case(copy.deepcopy(doc)).linkage.drive == {"q_crank": 2 * sp.pi * sp.Symbol("t", real=True)}
    doc["mechanism"]["drive"] = {"crank": "2*pi*t rad"}  # a unit inside an expression is not read
    (msg,) = problems_of(doc)
    assert msg.startswith("mechanism.drive.crank: got '2*pi*t rad' (string); unknown name 'rad'"), msg


def test_set_takes_a_value_with_a_unit():
    from csim.case import load_case

    case = load_case(CONFIGS / "quick_return.yaml", ["initial.q.q1=172 deg", "simulation.t_end=250 ms"])
    assert case.data["initial"]["q"]["q1"] == pytest.approx(math.radians(172), rel=1e-14)
    assert case.data["simulation"]["t_end"] == 0.25


@pytest.mark.parametrize("value, unit, expected", [
    ("1 s^9^9^9", "s", "raises a power to a power"),  # pint would compute 9**(9**9) and not return
    ("1 m^99^99", "SI base units", "raises a power to a power"),
    ("1 Hz", "rad/s", "is a frequency"),  # 1 rad/s to pint, not 2 pi rad/s
    ("50 %", "rad", "is a fraction, not an angle"),
])
def test_units_that_would_hang_or_mislead_are_refused(value, unit, expected):
    from csim.quantities import convert

    number, problem = convert(value, unit)
    assert number is None and expected in problem


def test_angular_velocities_in_rpm_and_degrees_per_second_convert():
    from csim.quantities import convert

    assert convert("60 rpm", "rad/s")[0] == pytest.approx(2 * math.pi)
    assert convert("180 deg/s", "rad/s")[0] == pytest.approx(math.pi)


def test_an_angle_written_as_a_plain_number_beyond_a_turn_is_noted():
    """q1: 172 is taken in rad, as every plain number in its key's unit, but noted: 27 turns
    is most likely 172 degrees written without its unit. 172 deg and 3.0 are not noted."""
    from csim.case import load_case

    noted = load_case(CONFIGS / "quick_return.yaml", ["initial.q.q1=172"])
    assert noted.data["initial"]["q"]["q1"] == 172.0
    assert any(w.startswith("initial.q.q1: 172 rad is 27.4 turns") and "'172 deg'" in w for w in noted.warnings)
    for value in ("172 deg", "3.0"):
        case = load_case(CONFIGS / "quick_return.yaml", [f"initial.q.q1={value}"])
        assert not [w for w in case.warnings if w.startswith("initial.q")], case.warnings
