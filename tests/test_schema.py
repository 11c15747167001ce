"""The declarative schema and its JSON Schema (``csim schema``), checked by an independent
validator (jsonschema): every shipped case file passes, invalid ones fail, and the enums
are the registries."""
from __future__ import annotations

import json

import jsonschema
import pytest
import yaml
from conftest import CONFIGS, invoke

from csim.case import SCHEMA, CaseLoader, json_schema, validate_case
from csim.linkage.joints import JOINT_TYPES
from csim.linkage.json_schema import link_row
from csim.linkage.tables import LINK_KEYS
from csim.mechanisms import MECHANISMS
from csim.physics.switching import SWITCHING_NAMES
from csim.quantities import JSON_QUANTITY
from csim.schema import REQUIRED, Field, Section, field_json_schema, field_paths, section_json_schema
from csim.solver.formulations import FORMULATIONS
from csim.solver.integrators import INTEGRATORS
from csim.solver.methods import STABILIZERS


@pytest.fixture(scope="module")
def validator():
    schema = json_schema()
    jsonschema.Draft7Validator.check_schema(schema)
    return jsonschema.Draft7Validator(schema)


def read(path) -> dict:
    """A shipped case as any YAML reader reads it (``yaml.safe_load``, YAML 1.1: ``1.0e6``
    would be a string there, so the configs write ``1.0e+6``), and as csim's own loader does."""
    text = path.read_text()
    plain = yaml.safe_load(text)
    assert plain == yaml.load(text, Loader=CaseLoader), f"{path.name}: read differently by yaml.safe_load"
    return plain


def errors(validator, document) -> list[str]:
    return [f"{'.'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(document)]


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_case_file_is_valid(validator, path):
    assert errors(validator, read(path)) == []


def test_a_minimal_case_and_empty_sections_are_valid(validator):
    assert errors(validator, {"mechanism": {"name": "pendulum"}}) == []
    assert errors(validator, {"mechanism": {"name": "pendulum"}, "simulation": None, "loads": None}) == []


def pendulum(**sections) -> dict:
    return {"mechanism": {"name": "pendulum"}, **sections}


INVALID = {
    "no mechanism": {"simulation": {"t_end": 1.0}},
    "neither name nor tables": {"mechanism": {"parameters": {"m": 1.0}}},
    "unknown mechanism": {"mechanism": {"name": "pendulun"}},
    "unknown section": pendulum(simulaton={"t_end": 1.0}),
    "unknown key": pendulum(simulation={"t_end": 1.0, "tend": 2.0}),
    "wrong type": pendulum(simulation={"t_end": "long"}),
    "t_end 0": pendulum(simulation={"t_end": 0}),
    "rtol above 1": pendulum(simulation={"rtol": 2.0}),
    "integrator case": pendulum(simulation={"integrator": "rk4"}),
    "max_events 0": pendulum(simulation={"max_events": 0}),
    "max_steps 1.5": pendulum(simulation={"max_steps": 1.5}),
    "events a string": pendulum(simulation={"events": "yes"}),
    "method": pendulum(stabilization={"method": "baumgarte_"}),
    "negative gain": pendulum(stabilization={"w": -1.0}),
    "empty gain list": pendulum(stabilization={"K": []}),
    "gain list entry": pendulum(stabilization={"K": [1.0, 0.0]}),
    "switching": pendulum(stabilization={"switching": "sign"}),
    "eps 0": pendulum(stabilization={"eps": 0.0}),
    "parameter of another mechanism": pendulum(mechanism={"name": "pendulum", "parameters": {"l1": 1.0}}),
    "negative mass": {"mechanism": {"name": "pendulum", "parameters": {"m": -1.0}}},
    "coordinate of another mechanism": pendulum(initial={"q": {"q1": 0.1}}),
    "velocity not a number": pendulum(initial={"qd": {"x": "fast"}}),
    "load of another mechanism": pendulum(loads={"torque": 1.0}),
    "load law key": {"mechanism": {"name": "quick_return"}, "loads": {"torque": {"magnitude": 1, "size": 2}}},
    "load law without magnitude": {"mechanism": {"name": "quick_return"}, "loads": {"torque": {"velocity": "any"}}},
    "velocity condition": {"mechanism": {"name": "quick_return"},
                           "loads": {"torque": {"magnitude": 1, "velocity": "up"}}},
    "link row key": {"mechanism": {"links": [{"link": 0, "joints": ["R"], "weight": 1}], "couplings": [[0, 1, 1, 1]]}},
    "joint type": {"mechanism": {"links": [{"link": 0, "joints": ["X"]}], "couplings": [[0, 1, 1, 1]]}},
    "coupling row": {"mechanism": {"links": [{"link": 0, "joints": ["R"]}], "couplings": [[0, 1, 1]]}},
    "gravity length": {"mechanism": {"links": [{"joints": ["R"]}], "couplings": [[0, 1, 1, 1]], "gravity": [0, 1]}},
    "backend": pendulum(simulation={"backend": "numba"}),
    "output dt": pendulum(output={"dt": -0.1}),
}


@pytest.mark.parametrize("name", list(INVALID))
def test_invalid_cases_are_rejected_by_the_schema_and_by_csim(validator, name):
    document = INVALID[name]
    assert errors(validator, document), name
    from csim.errors import CaseError

    with pytest.raises(CaseError):
        validate_case(json.loads(json.dumps(document)))


def enum_of(schema: dict) -> list:
    if "enum" in schema:
        return schema["enum"]
    return next(s["enum"] for s in schema["anyOf"] if "enum" in s)


def test_enums_are_the_registries():
    props = json_schema()["properties"]
    assert enum_of(props["mechanism"]["properties"]["name"]) == sorted(MECHANISMS)
    assert enum_of(props["simulation"]["properties"]["integrator"]) == list(INTEGRATORS)
    assert enum_of(props["stabilization"]["properties"]["method"]) == list(STABILIZERS)
    assert enum_of(props["stabilization"]["properties"]["switching"]) == list(SWITCHING_NAMES)
    assert enum_of(props["formulation"]["properties"]["method"]) == list(FORMULATIONS)
    row = props["mechanism"]["properties"]["links"]["items"]
    frame = row["properties"]["joints"]["items"]["anyOf"][0]
    assert frame["enum"] == list(JOINT_TYPES)
    assert list(link_row()["properties"]) == list(LINK_KEYS)
    assert [s["if"]["properties"]["mechanism"]["properties"]["name"]["const"] for s in json_schema()["allOf"]] \
        == sorted(MECHANISMS)


def test_every_key_has_a_description_and_the_validated_default():
    schema = json_schema()
    defaults = validate_case({"mechanism": {"name": "pendulum"}}).data
    for path, spec in field_paths(SCHEMA).items():
        node = schema
        for key in path.split("."):
            node = node["properties"][key]
        assert node.get("description"), path
        section, key = path.rsplit(".", 1) if "." in path else ("", path)
        if spec.default is REQUIRED or section in ("mechanism", "initial") or path == "loads":
            continue  # filled from the mechanism, not the schema
        value = defaults
        for k in path.split("."):
            value = value[k]
        assert node["default"] == value, path


def test_units_go_into_the_descriptions():
    props = json_schema()["properties"]
    assert props["simulation"]["properties"]["t_end"]["description"] == "end time [s]"
    pendulum_then = json_schema()["allOf"][1]["then"]["properties"]
    assert pendulum_then["mechanism"]["properties"]["parameters"]["properties"]["L"]["description"] == "rod length [m]"
    assert pendulum_then["initial"]["properties"]["qd"]["properties"]["x"]["description"] == "velocity of x [m/s]"


def test_field_conversion_of_bounds_choices_and_null():
    spec = Field("number", 1.0, "a ratio", gt=0.0, le=5.0, nullable=True)
    assert field_json_schema(spec) == {"type": ["number", "null"], "exclusiveMinimum": 0.0, "maximum": 5.0,
                                       "description": "a ratio", "default": 1.0}
    # a key with a unit may also be written with one (10 Hz): a string of that pattern
    spec = Field("number", 1.0, "a gain", "1/s", gt=0.0, le=5.0, nullable=True)
    assert field_json_schema(spec) == {"anyOf": [{"type": "number", "exclusiveMinimum": 0.0, "maximum": 5.0},
                                                 JSON_QUANTITY, {"type": "null"}],
                                       "description": "a gain [1/s]", "default": 1.0}
    choice = field_json_schema(Field("string", None, "pick", choices=("a", "b"), nullable=True))
    assert choice == {"anyOf": [{"type": "string", "enum": ["a", "b"]}, {"type": "null"}], "description": "pick",
                      "default": None}
    section = section_json_schema(Section({"x": Field("integer", REQUIRED, ge=1)}))
    assert section["required"] == ["x"] and section["additionalProperties"] is False


def test_csim_schema_prints_or_writes_the_schema(tmp_path):
    result = invoke("schema")
    assert result.exit_code == 0, result.output
    assert json.loads(result.output) == json.loads(json.dumps(json_schema()))
    out = tmp_path / "sub" / "csim-case.schema.json"
    result = invoke("schema", "-o", out)
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text()) == json.loads(json.dumps(json_schema()))


def test_csim_schema_to_an_unwritable_place_exits_2(tmp_path):
    (tmp_path / "file").write_text("")
    result = invoke("schema", "-o", tmp_path / "file" / "schema.json")
    assert result.exit_code == 2 and "--output" in result.output and "Traceback" not in result.output


def test_registered_mechanism_with_forces_may_add_the_elements_parameters():
    schema = json_schema()
    forces = [{"name": "s", "type": "joint_spring", "joint": "pivot", "stiffness": "k"}]
    jsonschema.validate({"mechanism": {"name": "pendulum", "parameters": {"k": 4.0}, "forces": forces}}, schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"mechanism": {"name": "pendulum", "parameters": {"k": 4.0}}}, schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"mechanism": {"name": "pendulum", "parameters": {"k": "soft"}, "forces": forces}}, schema)


def test_the_committed_schema_is_what_csim_schema_writes():
    """``csim-case.schema.json`` (what the configs' modelines point to) is current; rewrite
    it with ``csim schema -o csim-case.schema.json``."""
    committed = json.loads((CONFIGS.parent / "csim-case.schema.json").read_text())
    assert committed == json.loads(json.dumps(json_schema()))
    assert committed["$schema"] == "http://json-schema.org/draft-07/schema#"


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_case_names_the_schema_on_its_first_line(path):
    assert path.read_text().splitlines()[0] == "# yaml-language-server: $schema=../csim-case.schema.json"


def test_short_repr_formats_only_what_it_shows():
    from csim.schema import SHOWN_CHARS, describe, short_repr

    itself: list = []
    itself.append(itself)
    assert short_repr(itself) == "[[...]]"
    assert short_repr(10**20_000) == "<an integer of 20,001 digits>"
    assert short_repr(-(10**20_000)).startswith("-<an integer")
    huge = [list(range(1000))] * 10**6  # a billion entries as written; only the first few are formatted
    text = short_repr(huge)
    assert len(text) == SHOWN_CHARS and text.startswith("[[0, 1, 2") and text.endswith("...")
    assert short_repr("x" * 10**7) == "'" + "x" * (SHOWN_CHARS - 4) + "..."
    assert describe({"a": [1, 2.5, None, True]}) == "{'a': [1, 2.5, None, True]} (mapping)"
