"""Bad link-coupling descriptions: clear errors naming the table row, the value, the expectation."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from csim.case import validate_case
from csim.describe import describe_main
from csim.errors import CaseError
from csim.linkage.model import build_linkage

FOURBAR = {
    "parameters": {"a": 0.1, "b": 0.35, "c": 0.3, "d": 0.4},
    "links": [
        {"link": 0, "joints": [["R", 0, "A"], ["R", ["d", 0, 0], "D"]]},
        {"link": 1, "joints": [["R", 0, "A"], ["R", ["a", 0, 0], "B"]]},
        {"link": 2, "joints": [["R", 0, "B"], ["R", ["b", 0, 0], "C"]]},
        {"link": 3, "joints": [["R", 0, "D"], ["R", ["c", 0, 0], "C"]]},
    ],
    "couplings": [[0, 1, 1, 1], [1, 2, 2, 1], [0, 2, 3, 1], [2, 2, 3, 2]],
    "drive": {1: "2*pi*t"},
}
RRR3 = Path(__file__).resolve().parents[1] / "configs" / "rrr3_planar.yaml"
GUESS = {"guess": {"q2": 1.0, "q3": 1.8}}


def problems(mechanism, initial=GUESS):
    with pytest.raises(CaseError) as excinfo:
        build_linkage(mechanism, initial)
    return excinfo.value.problems


def changed(**changes):
    mech = copy.deepcopy(FOURBAR)
    mech.update(changes)
    return mech


def test_the_reference_description_is_fine():
    lk = build_linkage(copy.deepcopy(FOURBAR), GUESS)
    assert lk.dof == 1 and lk.variable_names == ["q1", "q2", "q3"]


def test_coupling_to_an_undefined_link_or_joint():
    msg = problems(changed(couplings=[[0, 1, 1, 1], [1, 2, 2, 1], [0, 2, 9, 1], [2, 2, 3, 2]]))
    assert msg == ["mechanism.couplings[2] (coupling 3): link 9 (integer) is not defined in mechanism.links; "
                   "expected one of 0, 1, 2, 3"]
    msg = problems(changed(couplings=[[0, 1, 1, 1], [1, 2, 2, 1], [0, 2, 3, 1], [2, 2, 3, "E"]]))
    assert len(msg) == 1 and msg[0].startswith("mechanism.couplings[3] (coupling 4): link 3 has no joint 'E'")
    assert "expected a joint number 1..2 or a point name (D, C)" in msg[0]


def test_joint_used_twice():
    msg = problems(changed(couplings=[[0, 1, 1, 1], [1, 2, 2, 1], [0, 2, 3, 1], [2, 2, 3, 2], [0, 1, 2, 1]]))
    assert msg == [
        "mechanism.couplings[4] (coupling 5): joint 1 of link 0 is already coupled by mechanism.couplings[0] "
        "(coupling 1); expected each joint frame in one coupling only" + SHARED,
        "mechanism.couplings[4] (coupling 5): joint 1 of link 2 is already coupled by mechanism.couplings[1] "
        "(coupling 2); expected each joint frame in one coupling only" + SHARED]


#: how the message says to declare a joint shared by three or more links
SHARED = " (a joint shared by three or more links is one row: [[i, k], [j, m], [l, n]])"


def test_coupled_joints_of_different_types():
    mech = changed()
    mech["links"][3]["joints"][0] = ["P", 0, "D"]
    msg = problems(mech)
    assert msg == ["mechanism.couplings[2] (coupling 3): couples a R joint (link 0, joint 2) with a P joint "
                   "(link 3, joint 1); expected two joint frames of the same type"]


def test_links_not_connected_to_the_fixed_link():
    mech = changed(couplings=[[0, 1, 1, 1], [1, 2, 2, 1]], drive={})
    msg = problems(mech)
    assert msg == ["mechanism.links[3] (link 3): not connected to the fixed link 0 through mechanism.couplings; "
                   "expected a chain of couplings from link 0 to every link"]


def test_cannot_be_assembled_names_each_residual():
    mech = changed(parameters={"a": 0.1, "b": 0.05, "c": 0.05, "d": 0.4})  # b + c + a < d: no closure
    (msg,) = problems(mech)
    assert msg.startswith("mechanism: cannot be assembled at the given values")
    assert "joint 4 x: (r_jm - r_ik).e_x = " in msg and "joint 4 y: (r_jm - r_ik).e_y = " in msg
    assert "held fixed: q1 = 0" in msg


def test_bad_tables_are_all_reported_at_once():
    mech = changed(links=[{"link": 0, "joints": ["R"]}, {"link": 0, "joints": ["R"]}, {"link": 4, "joints": [["X", 0]]},
                          {"link": 1, "joints": [["R", [1, 2]]], "mass": "m9"}])
    msg = problems(mech)
    assert "mechanism.links[2].joints[0]: joint type got 'X' (string); expected one of R, P, C, U, S" in msg
    assert any(m.startswith("mechanism.links[1].link: got 0; link 0 is already defined by mechanism.links[0]")
               for m in msg)
    assert any(m.startswith("mechanism.links[3].joints[0][1]: got [1, 2] (list); expected 0 or a list [x, y, z]")
               for m in msg)
    assert any(m.startswith("mechanism.links[3].mass: got 'm9' (string); unknown name 'm9'") for m in msg)


def test_drive_must_match_the_degrees_of_freedom():
    data = yaml.safe_load(RRR3.read_text())
    del data["mechanism"]["drive"][5]
    msg = problems(data["mechanism"], data["initial"])
    assert msg == ["mechanism.drive: 2 drives for 3 degrees of freedom (q1, q4 driven); expected exactly 3 driven "
                   "joint variable(s) (under-driven: a kinematic analysis needs the whole motion prescribed; "
                   "mechanism.drive_mode: dynamic lets the other joints move freely)"]
    msg = problems(changed(drive={"crankshaft": 1.0}))
    assert msg[0].startswith("mechanism.drive.crankshaft: no such joint; expected a coupling number or name")


def test_case_level_checks():
    with pytest.raises(CaseError) as excinfo:
        validate_case({"mechanism": {"name": "pendulum", "links": []}})
    assert excinfo.value.problems[0].startswith("mechanism.links: given with mechanism.name 'pendulum'")
    with pytest.raises(CaseError) as excinfo:
        validate_case({"mechanism": changed(drive=None), "initial": GUESS})
    assert excinfo.value.problems[0].startswith("mechanism.links: no link has mass or inertia, and there is no "
                                                "mechanism.drive")
    with pytest.raises(CaseError) as excinfo:
        validate_case({"mechanism": changed(), "initial": {**GUESS, "q": {"q1": 0.123}}})
    assert excinfo.value.problems[0].startswith("initial.q: got {'q1': 0.123} (mapping) with mechanism.drive")
    # the drive's own start values, as a validated case stored in a result file holds them, may stay
    case = validate_case({"mechanism": changed(), "initial": GUESS})
    assert validate_case(case.data).data["initial"]["q"] == case.data["initial"]["q"]


def test_describe_main_errors(tmp_path):
    with pytest.raises(CaseError, match="no such case file"):
        describe_main(str(tmp_path / "none.yaml"))
    path = tmp_path / "named.yaml"
    path.write_text("mechanism: {name: pendulum}\n")
    with pytest.raises(CaseError, match="csim describe works on link-coupling descriptions"):
        describe_main(str(path))


def test_names_drives_and_expressions_that_would_have_gone_wrong_later():
    # a parameter named like a joint velocity would have been the same symbol as it
    msg = problems(changed(parameters={**FOURBAR["parameters"], "q1_dot": 5.0}))
    assert msg[0].startswith("mechanism.couplings[0] (coupling 1): its joint variable 'q1' (velocity 'q1_dot')")
    # a drive that is not finite, or complex, at t = 0
    assert "at t = 0 it is not finite" in problems(changed(drive={1: "1/t"}))[0]
    assert "at t = 0 it is complex" in problems(changed(drive={1: "sqrt(t - 1)"}))[0]
    # floor division and power towers are not expressions of the README (a^b^c hung sympy)
    links = copy.deepcopy(FOURBAR["links"])
    links[1]["joints"][1][1] = ["a//2", 0, 0]
    assert "no //, ** or a^b^c" in problems(changed(links=links))[0]
    links[1]["joints"][1][1] = ["9^9^9", 0, 0]
    assert "no //, ** or a^b^c" in problems(changed(links=links))[0]
    # a typo in the guess is named, not hidden behind an assembly failure
    msg = problems(copy.deepcopy(FOURBAR), {"guess": {"qB": 1.0}})
    assert msg == ["initial.guess.qB: not a joint variable of this mechanism; expected one of q1, q2, q3"]


def test_a_drive_that_stops_being_finite_fails_the_run_with_a_file():
    from csim.pipeline import run_case

    case = validate_case({"mechanism": changed(drive={1: "sqrt(0.25 - t)"}), "initial": GUESS,
                          "simulation": {"t_end": 0.5}, "output": {"dt": 0.05}})
    result = run_case(case)
    assert result.status == "failed" and "mechanism.drive is not finite at t = 0.25 s" in result.message
    assert result.t[-1] == pytest.approx(0.2)  # the samples before are kept


@pytest.mark.parametrize("text, refused", [
    ("0.5^999999999", True), ("(1/3)^999999999", True), ("deg^999999", True), ("1.0001^100000", True),
    ("0.5^999999999*t", True), ("(0.5^9000)^999999", True), ("1e-300^33", True), ("0.1^5000 + t", True),
    ("1.00000000000000000001^999", True), ("2^1000", False), ("9^300", False), ("(2.5e-3)^4", False),
    ("2^0.5", False), ("pi^2*t", False), ("10^-3", False),
])
def test_a_power_of_constants_with_a_huge_exact_value_is_refused_at_once(text, refused):
    """Tiny or ordinary float values whose exact value (sympy's) has thousands of digits or
    more are refused before sympy sees them (a base that underflows to 0.0 or rounds to 1.0
    included: the digits are counted from the text); small exact powers pass."""
    import time

    import sympy as sp

    from csim.linkage.expressions import parse_expression

    problems: list[str] = []
    start = time.perf_counter()
    expr = parse_expression("mass", text, {"t": sp.Symbol("t", real=True)}, problems)
    assert time.perf_counter() - start < 2.0
    assert (expr is None) == refused, problems
    if refused:
        assert "a power of constants" in problems[0] and "digits" in problems[0], problems
