"""``csim.compare.plan``: which runs a comparison makes, every case validated before a run.

Planning validates cases but runs nothing, so these tests take a fraction of a second.
"""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from csim.case import load_case
from csim.compare.plan import ReferenceSettings, _prefix, make_case, own_tolerance, plan_comparison, setting_text
from csim.errors import CaseError

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
PENDULUM = CONFIGS / "pendulum.yaml"
QR = CONFIGS / "quick_return.yaml"


def plan(case=PENDULUM, methods=None, tolerances=None, overrides=(), reference=None, jobs=None):
    return plan_comparison(case, methods, tolerances, overrides, reference or ReferenceSettings(), jobs)


def problems(**kwargs) -> list[str]:
    with pytest.raises(CaseError) as info:
        plan(**kwargs)
    return info.value.problems


def simulation(case) -> dict:
    return case.data["simulation"]


# --------------------------------------------------------------------------- reference


def test_reference_settings_may_name_their_own_integrator():
    assert ReferenceSettings().describe() == "projection, DOP853, rtol = atol = 1e-12"
    ref = ReferenceSettings(method="projection:RK4", tol=1e-4)
    assert (ref.run_method, ref.run_integrator) == ("projection", "RK4")
    assert ref.describe() == "projection, RK4, step = 1e-04"


def test_the_reference_case_is_tight_and_stabilized():
    ref = plan(methods=["none"]).reference_case
    assert ref.data["stabilization"]["method"] == "projection"
    assert simulation(ref)["integrator"] == "DOP853" and simulation(ref)["rtol"] == simulation(ref)["atol"] == 1e-12


def test_a_reference_the_case_rejects_names_the_reference():
    found = problems(methods=["none"], reference=ReferenceSettings(method="projection:LSODA"))
    assert len(found) == 1 and found[0].startswith("reference run (projection, LSODA, rtol = atol = 1e-12): ")


# --------------------------------------------------------------------------- runs


def test_one_run_per_method_at_the_case_own_setting():
    p = plan(methods=["none", "baumgarte"], overrides=["simulation.t_end=0.3"])
    assert p.tolerances is None and p.values == [1e-10]  # the case's rtol
    assert [m for m, _ in p.run_cases()] == ["none", "baumgarte"]
    for method, case in p.run_cases():
        assert case.data["stabilization"]["method"] == method and simulation(case)["t_end"] == 0.3
        assert (simulation(case)["rtol"], simulation(case)["atol"]) == (1e-10, 1e-12)


def test_a_study_sets_the_tolerance_of_each_method_own_integrator():
    p = plan(methods=["baumgarte", "ggl:Radau"], tolerances=[1e-6, 1e-4])
    assert p.tolerances == p.values == [1e-4, 1e-6]
    got = [(m, simulation(c)["integrator"], simulation(c)["rtol"], simulation(c)["atol"]) for m, c in p.run_cases()]
    assert got == [("baumgarte", "DOP853", 1e-4, 1e-4), ("baumgarte", "DOP853", 1e-6, 1e-6),
                   ("ggl:Radau", "Radau", 1e-4, 1e-4), ("ggl:Radau", "Radau", 1e-6, 1e-6)]


def test_a_fixed_step_study_sets_steps():
    p = plan(methods=["none", "projection"], tolerances=[1e-3, 5e-4], overrides=["simulation.integrator=RK4"])
    assert [simulation(c)["step"] for _, c in p.run_cases()] == [1e-3, 5e-4, 1e-3, 5e-4]


def test_a_default_study_leaves_out_the_methods_of_the_other_kind():
    p = plan(tolerances=[1e-3], overrides=["simulation.integrator=RK4"])
    assert "ggl:Radau" not in p.methods and list(p.skipped) == ["ggl:Radau"]
    assert p.skipped["ggl:Radau"] == ("its integrator Radau takes rtol = atol, the case's RK4 step: "
                                      "one study sets one kind")


def test_methods_named_in_a_study_must_take_one_kind():
    assert problems(methods=["none", "none:RK4"], tolerances=[1e-4]) == [
        "tolerances: the values set rtol = atol for none but the step or tolerance of another kind for none:RK4; "
        "compare adaptive and fixed-step integrators in separate studies"]


def test_a_default_comparison_leaves_out_what_the_case_rejects():
    p = plan(QR, overrides=["simulation.integrator=LSODA"])
    assert "projection" not in p.methods and "LSODA" in p.skipped["projection"]
    assert "none" in p.methods


def test_a_named_method_the_case_rejects_stops_the_comparison():
    found = problems(case=QR, methods=["none", "projection"], overrides=["simulation.integrator=LSODA"])
    assert len(found) == 1 and found[0].startswith("method projection: stabilization.method: got 'projection'")


def test_a_tolerance_the_case_rejects_is_named():
    found = problems(case=QR, methods=["none", "projection"], tolerances=[1e-4, 1e-20])
    assert found == ["rtol = atol 1e-20: simulation.rtol: got 1e-20 (number); expected a number >= 2.22045e-14 "
                     "and <= 1"]


def test_bad_options_are_reported_together():
    found = problems(methods=["none", "nope"], tolerances=[0.0], jobs=0,
                     reference=ReferenceSettings(method="x", tol=-1.0))
    assert [p.split(":")[0] for p in found] == ["jobs", "methods", "tolerances", "reference tolerance",
                                                "reference method"]


def test_one_backend_for_every_run(monkeypatch):
    import csim.compare.plan as plan_module

    real = plan_module.resolve_backend  # a method the compiled backend could run but does not
    monkeypatch.setattr(plan_module, "resolve_backend",
                        lambda case: "python" if case.stabilization.method == "baumgarte" else real(case))
    p = plan(methods=["none", "baumgarte"])
    assert {simulation(c)["backend"] for _, c in p.run_cases()} == {"python"}
    assert p.backend_note.startswith("python for every run (baumgarte has no compiled path")
    monkeypatch.undo()
    p = plan(methods=["none", "projection:BDF"])  # an integrator only Python has: that method alone runs there
    assert {simulation(c)["backend"] for _, c in p.run_cases()} == {"auto"}
    assert p.backend_note.startswith("python for projection:BDF (no compiled path for its integrator)")
    assert simulation(p.reference_case)["backend"] == "auto"  # the reference runs on its own
    p = plan(methods=["none", "baumgarte"])
    assert {simulation(c)["backend"] for _, c in p.run_cases()} == {"auto"} and p.backend_note == ""


@pytest.mark.parametrize("per_method, methods, values, study, expected", [
    ({"projection": [1e-6]}, ["none", "projection"], [1e-6], False, "method projection: "),
    ({"none": [1e-6], "projection": [1e-6]}, ["none", "projection"], [1e-6], False, ""),
    ({"none": [1e-6]}, ["none"], [1e-6], False, "method none: "),
    ({"none": [1e-8], "projection": [1e-8]}, ["none", "projection"], [1e-6, 1e-8], True, "rtol = atol 1e-08: "),
    ({"none": [1e-6, 1e-8], "projection": [1e-6, 1e-8]}, ["none", "projection"], [1e-6, 1e-8], True, ""),
])
def test_a_problem_names_the_runs_it_concerns(per_method, methods, values, study, expected):
    assert _prefix(per_method, methods, values, study, "DOP853") == expected


# --------------------------------------------------------------------------- cases


def test_make_case_leaves_its_input_alone():
    data = yaml.safe_load(PENDULUM.read_text())
    before = copy.deepcopy(data)
    case = make_case(data, ["simulation.t_end=0.5"])
    assert data == before and case.source == "<dict>" and simulation(case)["t_end"] == 0.5
    again = make_case(case, ["stabilization.method=none"])
    assert again.data["stabilization"]["method"] == "none" and case.data["stabilization"]["method"] == "baumgarte"


@pytest.mark.parametrize("sets, tolerance, text", [
    ([], (1e-10, "rtol"), "rtol = 1e-10, atol = 1e-12"),
    (["simulation.atol=1e-10"], (1e-10, "rtol=atol"), "rtol = atol = 1e-10"),
    (["simulation.integrator=RK4", "simulation.step=5e-4"], (5e-4, "step"), "step = 5.00e-04 s"),
])
def test_a_case_own_setting(sets, tolerance, text):
    case = load_case(PENDULUM, sets)
    assert own_tolerance(case) == tolerance and setting_text(case) == text
