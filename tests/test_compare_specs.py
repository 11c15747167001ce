"""``csim.compare.specs``: method specs and tolerance values, checked and as text (no case, no run)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from csim.compare.specs import (
    check_methods,
    check_tolerances,
    default_methods,
    method_sets,
    parse_methods,
    parse_tolerances,
    split_method,
    tol_text,
    tolerance_kind,
    tolerance_label,
    tolerance_sets,
)
from csim.errors import CaseError
from csim.solver.stabilizers import STABILIZERS


def problems(call, *args, **kwargs) -> list[str]:
    with pytest.raises(CaseError) as info:
        call(*args, **kwargs)
    return info.value.problems


# --------------------------------------------------------------------------- methods


@pytest.mark.parametrize("spec, expected", [("ggl:Radau", ("ggl", "Radau")), ("none", ("none", None)),
                                            (" none : RK4 ", ("none", "RK4")), ("none:", ("none", None))])
def test_split_method(spec, expected):
    assert split_method(spec) == expected


def test_check_methods_strips_and_keeps_the_order():
    assert check_methods([" projection", "none:RK4 ", "ggl:Radau"]) == ["projection", "none:RK4", "ggl:Radau"]


def test_check_methods_reports_every_problem_at_once():
    found = problems(check_methods, ["none", "bogus", "none", "ggl:Nope"], "--methods")
    assert found[0].startswith("--methods: unknown method 'bogus'; valid names: " + ", ".join(STABILIZERS))
    assert "--methods: method 'none' given twice" in found
    assert any(p.startswith("--methods: unknown integrator 'Nope' in 'ggl:Nope'") for p in found)
    assert len(found) == len(set(found)) == 3


@pytest.mark.parametrize("methods", [[], ["none", ""]])
def test_check_methods_wants_names(methods):
    assert "expected method names separated by commas" in problems(check_methods, methods)[0]


def test_parse_methods_splits_at_commas():
    assert parse_methods("none, ggl:Radau") == ["none", "ggl:Radau"]
    assert problems(parse_methods, "  ") == ["--methods: got ''; expected method names separated by commas, "
                                             "e.g. none,baumgarte"]


def test_default_methods_give_a_method_the_integrator_it_needs():
    assert [split_method(m)[0] for m in default_methods("RK4")] == list(STABILIZERS)
    assert "ggl:Radau" in default_methods("RK4") and "ggl:Radau" in default_methods("DOP853")
    assert "ggl" in default_methods("Radau")  # Radau runs it: no spec of its own


def test_method_sets_select_method_and_integrator():
    assert method_sets("none") == ["stabilization.method=none"]
    assert method_sets("ggl:Radau") == ["stabilization.method=ggl", "simulation.integrator=Radau"]


# --------------------------------------------------------------------------- tolerances


def test_check_tolerances_sorts_loosest_first():
    assert check_tolerances([1e-8, np.float64(1e-4), 1e-6]) == [1e-4, 1e-6, 1e-8]


@pytest.mark.parametrize("bad", [0, -1e-6, math.nan, math.inf, True, "1e-6"])
def test_check_tolerances_rejects(bad):
    assert problems(check_tolerances, [1e-6, bad]) == [
        f"tolerances: got {bad!r}; expected positive numbers separated by commas, e.g. 1e-4,1e-6"]


def test_check_tolerances_rejects_duplicates_and_nothing():
    assert problems(check_tolerances, [1e-6, 1e-6]) == ["tolerances: 1e-06 given twice"]
    assert problems(check_tolerances, [], "--tolerances") == [
        "--tolerances: expected at least one value, e.g. 1e-4,1e-6,1e-8"]


def test_parse_tolerances_names_each_bad_value_as_given():
    assert parse_tolerances("1e-6, 2.5e-7,1e-4") == [1e-4, 1e-6, 2.5e-7]
    found = problems(parse_tolerances, "1e-6,abc,-1,", "--reference-tol")
    assert [p.split(";")[0] for p in found] == ["--reference-tol: got 'abc'", "--reference-tol: got '-1'",
                                                "--reference-tol: got ''"]


def test_what_a_tolerance_sets_depends_on_the_integrator():
    assert (tolerance_kind("DOP853"), tolerance_label("DOP853")) == ("rtol=atol", "rtol = atol")
    assert (tolerance_kind("RK4"), tolerance_label("RK4")) == ("step", "step")
    assert tolerance_sets("Radau", 1e-6) == ["simulation.rtol=1e-06", "simulation.atol=1e-06"]
    assert tolerance_sets("RK4", 5e-4) == ["simulation.step=0.0005"]


@pytest.mark.parametrize("value, text", [(1e-6, "1e-06"), (2.5e-7, "2.5e-07"), (1e-12, "1e-12"), (0.001, "1e-03")])
def test_tol_text(value, text):
    assert tol_text(value) == text
