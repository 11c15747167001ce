"""Case files: YAML loading, ``--set`` overrides, validation and defaults (library level)."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from csim.case import SCHEMA, CaseLoader, apply_overrides, load_case, parse_yaml, validate_case
from csim.errors import CaseError
from csim.mechanisms import MECHANISMS
from csim.solver.integrators import INTEGRATORS
from csim.solver.stabilizers import STABILIZERS, NoStabilization

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "quick_return.yaml"

MINIMAL = "mechanism:\n  name: quick_return\n"

#: the valid names as messages list them
INTEGRATOR_NAMES = ", ".join(INTEGRATORS)
MECHANISM_NAMES = ", ".join(sorted(MECHANISMS))


def write(tmp_path: Path, text: str, name: str = "case.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def problems_of(excinfo) -> list[str]:
    return excinfo.value.problems


def only_problem(excinfo) -> str:
    problems = problems_of(excinfo)
    assert len(problems) == 1, problems
    return problems[0]


# --------------------------------------------------------------------------- defaults


def test_minimal_case_fills_every_default(tmp_path):
    case = load_case(write(tmp_path, MINIMAL))
    d = case.data
    assert case.mechanism.name == "quick_return"
    assert case.source == str(tmp_path / "case.yaml")
    assert d["simulation"] == {
        "t_end": 5.0, "integrator": "DOP853", "rtol": 1e-8, "atol": 1e-8, "step": 1e-3,
        "max_step": None, "first_step": None, "events": True, "max_events": 100_000, "chatter_events": 20,
        "max_steps": 1_000_000, "event_samples": 4, "max_phi": 0.1, "min_step": 1e-10, "backend": "auto",
    }
    assert d["formulation"] == {"method": "kkt", "independent": None, "max_condition": 1e8}
    assert d["stabilization"] == {"method": "none", "d": 1.0, "w": 10.0, "Lambda": 10.0, "K": 10.0, "k": 1e-6,
                                  "switching": "tanh", "eps": 1e-6, "c": 1e6, "projection_metric": "mass",
                                  "projection_tol": 1e-13, "projection_max_iter": 10,
                                      "minimal_tol": 1e-13, "minimal_max_iter": 20,
                                      "minimal_max_condition": 20.0, "ggl_tol": 1e-12,
                                      "penalty": 1e4, "al_tol": 1e-9, "al_max_iter": 20}
    assert d["output"] == {"dt": 0.01}
    assert d["loads"] == {}
    assert d["initial"]["q"] == {"q1": 3.0020}
    assert d["initial"]["qd"] == {"q1": 6.2832}
    assert d["initial"]["guess"] == {"q2": 2.0, "q3": 2.8}
    assert d["initial"]["tol"] == 1e-12 and d["initial"]["max_iter"] == 50
    assert d["initial"]["q_offset"] == {} and d["initial"]["qd_offset"] == {}


def test_parameters_default_to_the_mechanism_table(tmp_path):
    case = load_case(write(tmp_path, MINIMAL))
    params = case.data["mechanism"]["parameters"]
    expected = {"l1": 1.5, "l2": 4.0, "l3": 1.9, "h1": 2.0, "h2": 4.0, "a1": 0.0, "a2": 2.0, "a3": 0.95,
                "m1": 4000.0, "m2": 100.0, "m3": 30.0, "m4": 5.0, "m5": 50.0,
                "J1": 4000.0, "J2": 100.0, "J3": 10.0, "J4": 0.05, "g": 9.81}
    assert params == expected
    assert list(params) == list(expected)  # the table's order
    assert case.parameters == expected


def test_given_parameters_override_only_themselves(tmp_path):
    case = load_case(write(tmp_path, MINIMAL + "  parameters: {l1: 1.25, m5: 60}\n"))
    params = case.data["mechanism"]["parameters"]
    assert params["l1"] == 1.25 and params["m5"] == 60.0 and isinstance(params["m5"], float)
    assert params["l2"] == 4.0 and params["g"] == 9.81


def test_empty_sections_and_null_mappings_mean_defaults(tmp_path):
    text = "mechanism:\n  name: quick_return\n  parameters:\ninitial:\n  guess:\nloads:\nsimulation:\noutput:\n"
    case = load_case(write(tmp_path, text))
    assert case.data["mechanism"]["parameters"]["l1"] == 1.5
    assert case.data["initial"]["guess"] == {"q2": 2.0, "q3": 2.8}
    assert case.data["loads"] == {}
    assert case.data["simulation"]["integrator"] == "DOP853"
    assert case.data["output"]["dt"] == 0.01


def test_shipped_config_loads(tmp_path):
    case = load_case(CONFIG)
    d = case.data
    assert d["simulation"]["rtol"] == 1e-10 and d["simulation"]["t_end"] == 5.0
    assert d["loads"]["torque"] == 165521.0
    assert d["loads"]["cutting_force"] == {"magnitude": 200000.0, "window": [-4.0, 1.2], "velocity": "negative"}
    settings = case.integration_settings()
    assert settings.integrator == "DOP853" and settings.output_dt == 0.005 and settings.max_step == math.inf
    laws = {law.name: law for law in case.load_set().laws}
    assert set(laws) == {"torque", "cutting_force"}


def test_validated_case_is_a_fixed_point_and_round_trips_through_yaml():
    case = load_case(CONFIG)
    again = validate_case(yaml.safe_load(case.to_yaml()))
    assert again.data == case.data
    assert parse_yaml(case.to_yaml(), "<yaml>") == case.data


def test_validate_case_does_not_modify_its_input():
    data = {"mechanism": {"name": "quick_return", "parameters": {"l1": 2}},
            "loads": {"cutting_force": {"magnitude": 5, "window": [0, 1]}}}
    snapshot = yaml.safe_dump(data)
    validate_case(data)
    assert yaml.safe_dump(data) == snapshot


# --------------------------------------------------------------------------- YAML reading


@pytest.mark.parametrize("text, value", [
    ("1e-8", 1e-8), ("2E3", 2000.0), ("-1.5e-3", -1.5e-3), ("+3e+2", 300.0),
    ("1.0e-8", 1e-8), ("0.5", 0.5), (".inf", math.inf), ("-.inf", -math.inf),
])
def test_exponent_numbers_read_as_floats(text, value):
    got = parse_yaml(f"x: {text}", "<t>")["x"]
    assert isinstance(got, float) and got == value


def test_plain_pyyaml_would_read_1e_minus_8_as_a_string():
    # the reason for CaseLoader: YAML 1.1 needs a dot in the mantissa
    assert yaml.safe_load("x: 1e-8")["x"] == "1e-8"
    assert yaml.load("x: 1e-8", Loader=CaseLoader)["x"] == 1e-8


def test_word_keys_read_as_words_and_boolean_values_as_booleans():
    # a switching law's `on: C_x` is the key 'on'; libyaml marks a plain scalar's style '' where
    # PyYAML's own parser gives None, and both must read it as the word
    data = parse_yaml("on: C_x\noff: 1\nyes: 2\nNo: 3\nb: on\n'true': 4\n", "<t>")
    assert data == {"on": "C_x", "off": 1, "yes": 2, "No": 3, "b": True, "true": 4}


def test_the_case_loader_reads_every_example_as_safe_load_does():
    # the events come from libyaml where PyYAML has it (as here): the same values as from
    # PyYAML's own reader, with the same resolvers and constructors
    from yaml.cyaml import CParser

    assert issubclass(CaseLoader, CParser)
    for path in sorted((Path(__file__).parent.parent / "configs").rglob("*.yaml")):
        text = path.read_text()
        mine = yaml.load(text, Loader=CaseLoader)
        theirs = yaml.load(text, Loader=_PurePythonCaseLoader)
        assert mine == theirs, path.name


class _PurePythonCaseLoader(yaml.SafeLoader):
    """CaseLoader's resolvers and constructors on PyYAML's own reader, scanner and parser."""

    yaml_implicit_resolvers = CaseLoader.yaml_implicit_resolvers
    yaml_constructors = CaseLoader.yaml_constructors


def test_other_scalars_keep_their_yaml_types():
    data = parse_yaml("a: 3\nb: true\nc: RK4\nd: null\ne: '1e-8'\nf: 1_000\n", "<t>")
    assert data == {"a": 3, "b": True, "c": "RK4", "d": None, "e": "1e-8", "f": 1000}
    assert isinstance(data["a"], int) and isinstance(data["f"], int)


def test_tolerances_written_as_1e_minus_8_validate_as_numbers(tmp_path):
    case = load_case(write(tmp_path, MINIMAL + "simulation: {rtol: 1e-6, atol: 1e-9, step: 5e-4}\n"))
    s = case.data["simulation"]
    assert (s["rtol"], s["atol"], s["step"]) == (1e-6, 1e-9, 5e-4)


@pytest.mark.parametrize("text, key, lines", [
    ("a: 1\nb: 2\na: 3\n", "a", (1, 3)),
    ("s:\n  x: 1\n  y: 2\n  x: 1\n", "x", (2, 4)),
    ("s: {t_end: 1, t_end: 2}\n", "t_end", (1, 1)),
])
def test_duplicate_keys_are_rejected(text, key, lines):
    with pytest.raises(CaseError) as excinfo:
        parse_yaml(text, "dup.yaml")
    msg = only_problem(excinfo)
    assert msg.startswith("dup.yaml: not valid YAML")
    assert f"duplicate key {key!r}" in msg
    assert f"first at line {lines[0]}" in msg and f"line {lines[1]}," in msg


def test_duplicate_keys_in_a_case_file_are_rejected(tmp_path):
    path = write(tmp_path, MINIMAL + "simulation:\n  t_end: 1\n  t_end: 2\n")
    with pytest.raises(CaseError) as excinfo:
        load_case(path)
    msg = only_problem(excinfo)
    assert str(path) in msg and "duplicate key 't_end'" in msg


def test_merge_keys_still_work_and_may_be_overridden():
    data = parse_yaml("base: &b {x: 1, y: 2}\nderived:\n  <<: *b\n  y: 3\n", "<t>")
    assert data["derived"] == {"x": 1, "y": 3}


@pytest.mark.parametrize("text, fragment", [
    ("a: [1, 2\n", "line 2"),                 # unclosed flow sequence
    ("a: 1\n  b: 2\n", "line 2"),             # bad indentation
    ("? [a]\n: 1\n", "unhashable key"),       # a list as a key
    ("a: 2001-02-30\n", "day is out of range"),  # a timestamp that cannot exist
    ("a: !!int abc\n", "abc"),               # an explicit tag that cannot apply
    ("a: !!python/object:os.system {}\n", "not valid YAML"),  # unsafe tags
])
def test_invalid_yaml_is_a_case_error(text, fragment):
    with pytest.raises(CaseError) as excinfo:
        parse_yaml(text, "bad.yaml")
    msg = only_problem(excinfo)
    assert msg.startswith("bad.yaml: not valid YAML") and fragment in msg


# --------------------------------------------------------------------------- overrides


@pytest.mark.parametrize("override, section, key, value", [
    ("simulation.t_end=0.25", "simulation", "t_end", 0.25),
    ("simulation.integrator=RK4", "simulation", "integrator", "RK4"),
    ("simulation.rtol=1e-6", "simulation", "rtol", 1e-6),
    ("simulation.atol=1e-9", "simulation", "atol", 1e-9),
    ("simulation.step=2e-4", "simulation", "step", 2e-4),
    ("stabilization.method=other", "stabilization", "method", "other"),
    (" simulation.t_end = 3 ", "simulation", "t_end", 3.0),
])
def test_set_overrides_change_the_validated_case(tmp_path, monkeypatch, override, section, key, value):
    # a second stabilizer to switch to, whatever the registry holds today
    monkeypatch.setitem(STABILIZERS, "other", NoStabilization)
    path = write(tmp_path, MINIMAL + "simulation: {t_end: 1.0, integrator: RK45, rtol: 1e-8, atol: 1e-8, step: 1e-3}\n")
    base = load_case(path)
    assert base.data[section][key] != value
    case = load_case(path, [override])
    assert case.data[section][key] == value
    assert type(case.data[section][key]) is type(value)
    # nothing else changed
    for sec, content in base.data.items():
        for k, v in (content.items() if isinstance(content, dict) else ()):
            if (sec, k) != (section, key):
                assert case.data[sec][k] == v, (sec, k)


def test_set_overrides_reach_into_parameters_loads_and_initial(tmp_path):
    case = load_case(write(tmp_path, MINIMAL), [
        "mechanism.parameters.h2=4.5", "loads.torque=1000", "loads.cutting_force.magnitude=5",
        "initial.q.q1=2.5", "initial.qd.q1=0",
    ])
    assert case.data["mechanism"]["parameters"]["h2"] == 4.5
    assert case.data["loads"]["torque"] == 1000.0
    assert case.data["loads"]["cutting_force"] == {"magnitude": 5.0, "window": None, "velocity": "any"}
    assert case.data["initial"]["q"] == {"q1": 2.5} and case.data["initial"]["qd"] == {"q1": 0.0}


def test_set_overrides_are_validated_like_the_file(tmp_path):
    with pytest.raises(CaseError) as excinfo:
        load_case(write(tmp_path, MINIMAL), ["simulation.t_end=-2"])
    msg = only_problem(excinfo)
    assert msg.startswith("simulation.t_end:") and "-2" in msg and "> 0" in msg


def test_set_value_that_is_not_valid_yaml_is_taken_as_text(tmp_path):
    with pytest.raises(CaseError) as excinfo:
        load_case(write(tmp_path, MINIMAL), ["simulation.t_end=[1"])
    msg = only_problem(excinfo)
    assert msg.startswith("simulation.t_end:") and "'[1'" in msg and "a number" in msg


def test_apply_overrides_works_on_a_dict_in_place():
    data = {"mechanism": {"name": "quick_return"}}
    assert apply_overrides(data, ["simulation.t_end=2", "simulation.integrator=RK4"]) is data
    assert data["simulation"] == {"t_end": 2, "integrator": "RK4"}


def test_unknown_set_key_is_rejected_by_name():
    with pytest.raises(CaseError) as excinfo:
        apply_overrides({}, ["simulation.tend=3"])
    msg = only_problem(excinfo)
    assert msg.startswith("--set simulation.tend: unknown key")
    assert "did you mean 'simulation.t_end'?" in msg
    assert "simulation.integrator" in msg  # lists the settable keys


def test_set_without_equals_sign_is_rejected():
    with pytest.raises(CaseError) as excinfo:
        apply_overrides({}, ["simulation.t_end"])
    msg = only_problem(excinfo)
    assert "'simulation.t_end'" in msg and "expected key=value" in msg


def test_all_bad_overrides_are_reported_together():
    with pytest.raises(CaseError) as excinfo:
        apply_overrides({}, ["bogus.key=1", "simulation.t_end", "simulation.rtol=1e-3", "another=2"])
    problems = problems_of(excinfo)
    assert len(problems) == 3
    assert "bogus.key" in problems[0] and "simulation.t_end" in problems[1] and "another" in problems[2]


def test_set_inside_a_value_that_is_not_a_mapping_is_rejected():
    data = {"mechanism": {"name": "quick_return"}, "simulation": 5}
    with pytest.raises(CaseError) as excinfo:
        apply_overrides(data, ["simulation.t_end=1"])
    msg = only_problem(excinfo)
    assert msg.startswith("--set simulation.t_end:") and "simulation" in msg and "5 (integer)" in msg
    assert data["simulation"] == 5  # the file's error is not hidden by the override


# --------------------------------------------------------------------------- validation messages


def test_all_problems_of_a_file_are_reported_at_once(tmp_path):
    text = (
        "mechanism:\n  name: quick_return\n  parameters: {m1: -4}\n"
        "simulation:\n  t_end: -1\n  integrator: Euler\n"
    )
    with pytest.raises(CaseError) as excinfo:
        load_case(write(tmp_path, text))
    problems = problems_of(excinfo)
    assert len(problems) == 3, problems
    by_path = {p.split(":")[0].split(" [")[0]: p for p in problems}
    assert set(by_path) == {"mechanism.parameters.m1", "simulation.t_end", "simulation.integrator"}
    assert "got -1.0" in by_path["simulation.t_end"] and "expected a number > 0" in by_path["simulation.t_end"]
    assert "'Euler'" in by_path["simulation.integrator"]
    assert f"expected one of {INTEGRATOR_NAMES}" in by_path["simulation.integrator"]
    assert "RK45" in INTEGRATOR_NAMES and "DOP853" in INTEGRATOR_NAMES
    assert "got -4.0" in by_path["mechanism.parameters.m1"] and "> 0" in by_path["mechanism.parameters.m1"]
    assert "[kg]" in by_path["mechanism.parameters.m1"]
    assert str(excinfo.value) == "\n".join(problems)


def test_problems_across_sections_and_mechanism_parts_are_collected(tmp_path):
    text = (
        "mechanism:\n  name: quick_return\n  parameters: {l9: 1}\n"
        "simulaton: {t_end: 1}\n"
        "initial: {q: {q7: 1.0}}\n"
        "loads: {torqe: 1}\n"
        "output: {dt: 0}\n"
    )
    with pytest.raises(CaseError) as excinfo:
        load_case(write(tmp_path, text))
    joined = "\n".join(problems_of(excinfo))
    for fragment in ("simulaton: unknown key (did you mean 'simulation'?)", "mechanism.parameters.l9: unknown key",
                     "initial.q.q7: not a coordinate of quick_return", "loads.torqe: unknown key",
                     "output.dt: got 0.0"):
        assert fragment in joined


@pytest.mark.parametrize("text, path, fragments", [
    ("simulation: {t_end: ten}\n", "simulation.t_end", ["'ten' (string)", "expected a number > 0"]),
    ("simulation: {t_end: 0}\n", "simulation.t_end", ["got 0.0", "expected a number > 0"]),
    ("simulation: {t_end: true}\n", "simulation.t_end", ["True (boolean)", "a number"]),
    ("simulation: {t_end: .nan}\n", "simulation.t_end", ["nan", "not allowed"]),
    pytest.param("simulation: {t_end: 1" + "0" * 400 + "}\n", "simulation.t_end", ["(integer)", "not allowed"],
                 id="integer-beyond-float-range"),
    ("simulation: {rtol: -1e-6}\n", "simulation.rtol", ["-1e-06", ">= ", "<= 1"]),
    ("simulation: {rtol: 2}\n", "simulation.rtol", ["2.0", "<= 1"]),
    ("simulation: {atol: 0}\n", "simulation.atol", ["0.0", ">= 1e-20"]),
    ("simulation: {atol: 1e-300}\n", "simulation.atol", ["1e-300", ">= 1e-20"]),  # not scipy's step-size message
    ("simulation: {event_samples: 1000000000}\n", "simulation.event_samples", ["1000000000", "<= 1000"]),
    ("simulation: {integrator: rk4}\n", "simulation.integrator",
     ["'rk4'", f"one of {INTEGRATOR_NAMES}", "did you mean 'RK4'"]),
    ("simulation: {max_events: 1.5}\n", "simulation.max_events", ["1.5", "an integer >= 1"]),
    ("simulation: {chatter_events: 1}\n", "simulation.chatter_events", ["got 1 (integer)", "an integer >= 2"]),
    ("simulation: {events: 1}\n", "simulation.events", ["1 (integer)", "true or false"]),
    ("simulation: {t_end: null}\n", "simulation.t_end", ["null", "a number > 0"]),
    ("simulation: [1, 2]\n", "simulation", ["[1, 2] (list)", "a mapping"]),
    ("stabilization: {method: magic}\n", "stabilization.method", ["'magic'", f"one of {', '.join(STABILIZERS)}"]),
    ("formulation: {method: lagrange}\n", "formulation.method", ["'lagrange'", "kkt", "elimination"]),
    ("formulation: {method: elimination, independent: [q1, q2]}\n", "formulation.independent",
     ["['q1', 'q2']", "1 distinct"]),
    ("initial: {tol: 0}\n", "initial.tol", ["0.0", "> 0"]),
    ("initial: {q: {q1: 1, q2: 2}}\n", "initial.q", ["2 coordinate(s) (q1, q2)", "exactly 1 independent"]),
    ("initial: {qd: {q2: 1}}\n", "initial.qd.q2", ["not an independent coordinate", "q1"]),
    ("initial: {guess: {q1: 1}}\n", "initial.guess.q1", ["not a dependent coordinate", "q2, q3"]),
    ("initial: {q: {q1: fast}}\n", "initial.q.q1", ["'fast' (string)", "a number"]),
    ("loads: {torque: strong}\n", "loads.torque", ["'strong' (string)", "a number [N m]", "magnitude"]),
    ("loads: {torque: {window: [0, 1]}}\n", "loads.torque.magnitude", ["missing", "a number"]),
    ("loads: {cutting_force: {magnitude: 1, window: [2, 1]}}\n", "loads.cutting_force.window",
     ["[2, 1]", "lo < hi"]),
    ("loads: {cutting_force: {magnitude: 1, window: [0, 1, 2]}}\n", "loads.cutting_force.window",
     ["[0, 1, 2]", "[lo, hi]"]),
    ("loads: {cutting_force: {magnitude: 1, velocity: sideways}}\n", "loads.cutting_force.velocity",
     ["'sideways'", "one of any, positive, negative"]),
    ("loads: {cutting_force: {magnitude: 1, duration: 2}}\n", "loads.cutting_force.duration",
     ["unknown key", "magnitude, window, velocity"]),
])
def test_each_problem_names_path_value_and_expectation(text, path, fragments):
    with pytest.raises(CaseError) as excinfo:
        validate_case(parse_yaml(MINIMAL + text, "<t>"))
    msg = only_problem(excinfo)
    assert msg.split(":")[0].split(" [")[0] == path, msg
    for fragment in fragments:
        assert fragment in msg, (fragment, msg)


@pytest.mark.parametrize("name, value, bound", [("m1", -4, "> 0"), ("l1", 0, "> 0"), ("a2", -0.5, ">= 0"),
                                                 ("J4", -1, ">= 0"), ("g", "9.81 m/s", "not of an acceleration"),
                                                 ("g", "9.81", "a number")])
def test_bad_parameter_values(name, value, bound):
    with pytest.raises(CaseError) as excinfo:
        validate_case({"mechanism": {"name": "quick_return", "parameters": {name: value}}})
    msg = only_problem(excinfo)
    assert msg.startswith(f"mechanism.parameters.{name} [")
    assert repr(float(value) if not isinstance(value, str) else value) in msg and bound in msg


def test_zero_is_allowed_where_the_table_says_so():
    case = validate_case({"mechanism": {"name": "quick_return", "parameters": {"a1": 0, "J4": 0, "g": 0}}})
    assert case.parameters["g"] == 0.0


def test_unknown_parameter_lists_the_valid_ones():
    with pytest.raises(CaseError) as excinfo:
        validate_case({"mechanism": {"name": "quick_return", "parameters": {"mass1": 3}}})
    msg = only_problem(excinfo)
    assert msg.startswith("mechanism.parameters.mass1: unknown key") and "l1, l2, l3" in msg


def test_unknown_mechanism_names_the_valid_ones():
    with pytest.raises(CaseError) as excinfo:
        validate_case({"mechanism": {"name": "quick_retrun"}})
    msg = only_problem(excinfo)
    assert msg.startswith("mechanism.name:") and "'quick_retrun'" in msg
    assert f"one of {MECHANISM_NAMES}" in msg and "did you mean 'quick_return'?" in msg


def test_mechanism_name_is_required(tmp_path):
    for text in ("", "mechanism: {}\n", "simulation: {t_end: 1}\n"):
        with pytest.raises(CaseError) as excinfo:
            load_case(write(tmp_path, text))
        assert only_problem(excinfo) == f"mechanism.name: missing; expected one of {MECHANISM_NAMES}"


def test_top_level_must_be_a_mapping(tmp_path):
    for text, shown in (("- a\n- b\n", "['a', 'b'] (list)"), ("just text\n", "'just text' (string)")):
        with pytest.raises(CaseError) as excinfo:
            load_case(write(tmp_path, text))
        msg = only_problem(excinfo)
        assert shown in msg and "at the top level" in msg and "expected a mapping of sections" in msg


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(CaseError) as excinfo:
        load_case(tmp_path / "nope.yaml")
    assert only_problem(excinfo) == f"{tmp_path / 'nope.yaml'}: no such case file"
    with pytest.raises(CaseError) as excinfo:
        load_case(tmp_path)
    assert only_problem(excinfo).startswith(f"{tmp_path}: cannot read the case file")
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(CaseError) as excinfo:
        load_case(binary)
    assert str(binary) in only_problem(excinfo)


# --------------------------------------------------------------------------- found by fuzzing (tests/test_fuzz.py)

HUGE = "1" + "0" * 400  # a YAML integer beyond the float range


@pytest.mark.parametrize("override, key", [
    (f"stabilization.w={HUGE}", "stabilization.w"),
    (f"stabilization.K=[1, {HUGE}]", "stabilization.K"),
])
def test_integers_beyond_the_float_range_are_rejected_not_a_traceback(override, key):
    with pytest.raises(CaseError) as excinfo:
        load_case(CONFIG, [override])
    assert only_problem(excinfo).startswith(f"{key}: got ")


def test_a_load_window_bound_beyond_the_float_range_is_rejected():
    with pytest.raises(CaseError) as excinfo:
        load_case(CONFIG, [f"loads.torque={{magnitude: 1, window: [0, {HUGE}]}}"])
    assert only_problem(excinfo).startswith("loads.torque.window: got ")
    assert load_case(CONFIG, ["loads.torque={magnitude: 1, window: [0, .inf]}"]).data["loads"]["torque"][
        "window"] == [0.0, math.inf]


@pytest.mark.parametrize("section", ["initial", "simulation", "stabilization", "formulation", "output"])
def test_a_section_that_is_not_a_mapping_is_one_problem(section):
    data = yaml.safe_load(CONFIG.read_text())
    data[section] = ""
    with pytest.raises(CaseError) as excinfo:
        validate_case(data)
    assert only_problem(excinfo) == f"{section}: got '' (string); expected a mapping (key: value lines)"


@pytest.mark.parametrize("key", ["max_step", "first_step"])
def test_an_adaptive_step_limit_below_min_step_is_rejected(key):
    with pytest.raises(CaseError) as excinfo:
        load_case(CONFIG, [f"simulation.{key}=1e-12"])
    msg = only_problem(excinfo)
    assert msg.startswith(f"simulation.{key}: got 1e-12 (number) with simulation.min_step = 1e-10 s")
    load_case(CONFIG, [f"simulation.{key}=1e-12", "simulation.min_step=1e-13"])  # consistent: accepted


def test_too_many_samples_names_t_end_as_well():
    with pytest.raises(CaseError) as excinfo:
        load_case(CONFIG, ["simulation.t_end=1e300"])
    msg = only_problem(excinfo)
    assert msg.startswith("output.dt: ") and "simulation.t_end = 1e+300 s" in msg


def test_the_validated_sections_are_typed_frozen_objects_generated_from_the_schema():
    import dataclasses

    from csim.schema import field_paths

    c = load_case(CONFIG, ["simulation.t_end=7", "stabilization.method=baumgarte", "stabilization.w=[20, 30]"])
    assert (c.simulation.t_end, c.stabilization.method, c.stabilization.w) == (7.0, "baumgarte", [20, 30])
    assert c.output.dt == c.data["output"]["dt"] and c.initial.guess == c.data["initial"]["guess"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.simulation.t_end = 1.0
    # one attribute per leaf of the schema section, typed from the field's type
    for section in ("simulation", "output", "initial", "formulation", "stabilization"):
        names = {path.split(".", 1)[1] for path in field_paths(SCHEMA) if path.startswith(section + ".")}
        assert {f.name for f in dataclasses.fields(getattr(c, section))} == names
    hints = {f.name: f.type for f in dataclasses.fields(c.simulation)}
    assert hints["t_end"] is float and hints["max_steps"] is int and hints["max_step"] == (float | None)


@pytest.mark.parametrize("text, fragment", [
    ("a: &a [*a]\n", "an alias inside the value it names"),
    ("- &x [1, 2]\n- &y [*x, *x, *x]\n- " + "[" * 40 + "]" * 40 + "\n", "nested more than 32"),
    ("a: &a [1,1,1,1,1,1,1,1,1,1]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b,*b]\n"
     "d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c,*c]\ne: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d,*d]\n"
     "f: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e,*e]\n", "once its aliases (*name) are expanded"),
    ("x: 1\n" + "#" * 100_001 + "\n", "characters long; expected at most 100,000"),
])
def test_yaml_beyond_the_bounds_is_a_case_error(text, fragment):
    with pytest.raises(CaseError) as excinfo:
        parse_yaml(text, "f.yaml")
    assert excinfo.value.problems[0].startswith("f.yaml: ") and fragment in excinfo.value.problems[0]


def test_yaml_aliases_within_the_bounds_are_read():
    # 10**4 values with aliases expanded: each list is built once, and shared
    text = ("a: &a [1,1,1,1,1,1,1,1,1,1]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a,*a]\n"
            "c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b,*b]\nd: [*c,*c,*c,*c,*c,*c,*c,*c,*c,*c]\n")
    data = parse_yaml(text, "f.yaml")
    assert sum(len(a) for c in data["d"] for b in c for a in b) == 10**4 and data["d"][0][0][0] is data["a"]


@pytest.mark.parametrize("source, key", [("q", "q_crank"), ("guess", "q_rocker")])
@pytest.mark.parametrize("value", [HUGE, ".nan"])
def test_a_linkage_start_value_beyond_the_float_range_is_rejected_not_a_traceback(source, key, value):
    # found by tests/test_fuzz.py's long profile: float(10**400) raised OverflowError in the assembly's start
    with pytest.raises(CaseError) as excinfo:
        load_case(CONFIG.parent / "fourbar_gravity.yaml", [f"initial.{source}.{key}={value}"])
    assert only_problem(excinfo).startswith(f"initial.{source}.{key}: got ")
